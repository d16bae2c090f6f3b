#!/usr/bin/env bash
# The builder's figures of `make bench`, into OUT/builder.json:
# per mesh -- bunny00, the 1.2M-triangle mesh (bunny00 Loop-subdivided
# twice) and one of at least 5M triangles (fandisk_large sqrt3-subdivided
# once, then Loop three times: 6.1M), all made by OpenMesh's own
# subdivider -- mts-build's time and peak memory per stage (--json), with
# two threads and with one, and OpenMesh-mkbalancedpm's time and peak on the
# same mesh in the same run, for scale.
# Usage: bench/builder.sh OUT SHARED_MODELS_DIR. MTS_BENCH_HUGE=0 leaves the
# 5M mesh out (its builds take minutes); MTS_BENCH_PM_HUGE=1 runs
# mkbalancedpm on it too (longer still).
set -uo pipefail
cd "$(dirname "$0")/.." || exit 1
out=$1
models=$2
bin=build/bin
dest=$out/builder.json
mkdir -p "$out/builder"
status=0
now() { printf '%s\n' "$EPOCHREALTIME"; }

meshes=()
[ -f "$models/bunny00.off" ] && meshes+=("bunny00=$models/bunny00.off")
if command -v OpenMesh-commandlineSubdivider >/dev/null; then
  big=$out/bunny00_l2.off
  if [ ! -f "$big" ] && [ -f "$models/bunny00.off" ]; then
    OpenMesh-commandlineSubdivider -l 2 "$models/bunny00.off" "$out/tmp_l2.off" >/dev/null 2>&1 &&
      mv "$out/tmp_l2.off" "$big"
  fi
  [ -f "$big" ] && meshes+=("bunny00_l2=$big")
  huge=$out/fandisk_5m.off
  if [ "${MTS_BENCH_HUGE:-1}" != 0 ] && [ -f "$models/fandisk_large.off" ]; then
    if [ ! -f "$huge" ]; then
      OpenMesh-commandlineSubdivider -s 1 "$models/fandisk_large.off" "$out/tmp_s.off" >/dev/null 2>&1 &&
        OpenMesh-commandlineSubdivider -l 3 "$out/tmp_s.off" "$out/tmp_5m.off" >/dev/null 2>&1 &&
        mv "$out/tmp_5m.off" "$huge"
      rm -f "$out/tmp_s.off"
    fi
    [ -f "$huge" ] && meshes+=("fandisk_5m=$huge")
  fi
fi

# a program's wall seconds and peak resident MB: "SECONDS MB"
timed() {
  local log=$1
  shift
  local t0
  t0=$(now)
  /usr/bin/time -f '%M' -o "$log.rss" "$@" >"$log" 2>"$log.err" || return 1
  awk -v a="$t0" -v b="$(now)" -v kb="$(tail -n 1 "$log.rss")" 'BEGIN { printf "%.3f %.1f", b - a, kb / 1024 }'
}

: >"$out/builder/runs.txt"
for entry in "${meshes[@]}"; do
  name=${entry%%=*}
  mesh=${entry#*=}
  echo "bench: mts-build $name (two threads, then one) ..." >&2
  for threads in 2 1; do
    if [ "$name" = fandisk_5m ] && [ "$threads" = 1 ]; then continue; fi # minutes more, same figures
    r=$(timed "$out/builder/${name}_t$threads.json" $bin/mts-build "$mesh" -o "$out/builder/$name.mtsm" \
      --threads "$threads" --json) || { status=1; continue; }
    echo "$name mts-build_t$threads $r" >>"$out/builder/runs.txt"
  done
  rm -f "$out/builder/$name.mtsm"
  if command -v OpenMesh-mkbalancedpm >/dev/null &&
    { [ "$name" != fandisk_5m ] || [ "${MTS_BENCH_PM_HUGE:-0}" = 1 ]; }; then
    echo "bench: OpenMesh-mkbalancedpm $name ..." >&2
    r=$(timed "$out/builder/${name}_pm.log" OpenMesh-mkbalancedpm -o "$out/builder/$name.pm" "$mesh") ||
      { status=1; continue; }
    echo "$name mkbalancedpm $r" >>"$out/builder/runs.txt"
    rm -f "$out/builder/$name.pm"
  fi
done

python3 - "$out/builder" "$dest" <<'PY' || status=1
import json, os, sys
d, dest = sys.argv[1], sys.argv[2]
res = {}
for line in open(os.path.join(d, "runs.txt")):
    name, tool, secs, mb = line.split()
    m = res.setdefault(name, {})
    entry = {"wall_s": float(secs), "peak_mb": float(mb)}
    if tool.startswith("mts-build"):
        try:
            j = json.load(open(os.path.join(d, f"{name}_{tool.split('_')[1]}.json")))
            entry.update({k: j[k] for k in ("threads", "seconds", "peak_bytes_per_triangle",
                                             "indices_per_triangle_full",
                                             "indices_per_triangle_worst", "file_bytes")})
            entry["stage_peak_mb"] = j["peak_mb"]
            # mts-build resets the kernel's peak per stage (clear_refs), which
            # /usr/bin/time's figure then shows: the stages' own peaks hold
            entry["peak_mb"] = max(j["peak_mb"].values())
            m["triangles"] = j["triangles"]
        except (OSError, ValueError, KeyError):
            pass
    m[tool] = entry
for name, m in res.items():
    b, pm = m.get("mts-build_t2"), m.get("mkbalancedpm")
    if b and pm:
        m["ratio_to_mkbalancedpm"] = round(b["wall_s"] / pm["wall_s"], 3)
    if b and m.get("triangles"):
        m["us_per_triangle"] = round(1e6 * b["wall_s"] / m["triangles"], 2)
if "bunny00" in res and res["bunny00"].get("us_per_triangle"):
    base = res["bunny00"]["us_per_triangle"]
    for name, m in res.items():
        if m.get("us_per_triangle"):
            m["per_triangle_vs_bunny00"] = round(m["us_per_triangle"] / base, 3)
json.dump(res, open(dest, "w"), indent=1)
PY
exit $status
