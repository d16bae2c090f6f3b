#!/usr/bin/env bash
# `make bench`: measures the shared models with build/bin/mts-bench, then a
# 1.2M-triangle mesh (bunny00 Loop-subdivided twice by OpenMesh) with
# build/bin/mts-build, and OpenMesh's own progressive-mesh builder for scale.
# Prints the tables and writes bench/results.json (everything merged).
#
# Environment: MTS_SHARED (default ../shared) holds models/; MTS_BENCH_BIG=0
# skips the big mesh (a minute of the run), MTS_BENCH_STRESS=0 the many-client
# runs, MTS_BENCH_CLIENT=0 the client's cost, MTS_BENCH_WEB=0 the browser
# client, MTS_BENCH_BUILDER=0 the builder at scale (MTS_BENCH_HUGE=0 its 6M
# mesh), MTS_BENCH_COLORS=0 the vertex colours' figures (bench/colors.sh);
# MTS_BENCH_APPLYING_CLIENTS (default 1000) sets the applying
# mts-stress clients, MTS_BENCH_FILES=0 the stream files on nginx
# (bench/files.sh), MTS_BENCH_STRESS_FILES=0 the applying mts-stress clients
# of a stream file on nginx beside mts-server's (bench/stress_files.sh),
# MTS_BENCH_THREADS=0 the decoder's threads (bench/threads.sh). Exit status 1 when a requested
# figure could not be measured; absent tools and models are skipped, with a
# reason, and do not fail the run.
set -uo pipefail
cd "$(dirname "$0")/.." || exit 1

shared="${MTS_SHARED:-../shared}"
out=bench/out
mkdir -p "$out"
status=0

# --- the shared models -------------------------------------------------------
models=()
for m in cow bunny00 fandisk_large; do
  models+=("$shared/models/$m.off") # mts-bench prints why a missing one is skipped
done
rm -f "$out/models.json" # never merge a previous run's figures
build/bin/mts-bench "${models[@]}" --json "$out/models.json" || status=1
[ -s "$out/models.json" ] || { echo "bench: mts-bench wrote no figures" >&2; exit 1; }

# --- streaming ----------------------------------------------------------------
rm -f "$out/stream.json" "$out/loopback.txt"
build/bin/mts-bench-stream "${models[@]}" --json "$out/stream.json" || status=1
# time to first frame over loopback: the real server and client, bunny00
if [ -f "$shared/models/bunny00.off" ]; then
  port=$((20000 + RANDOM % 20000))
  build/bin/mts-server --model "bunny00=$shared/models/bunny00.off" --listen "127.0.0.1:$port" \
    --quiet 2>"$out/server.log" &
  server=$!
  for _ in $(seq 1 200); do
    build/bin/mts-client "127.0.0.1:$port" --list >/dev/null 2>&1 && break
    sleep 0.1
  done
  for _ in 1 2 3 4 5; do
    build/bin/mts-client "127.0.0.1:$port" bunny00 --json >>"$out/loopback.txt" 2>/dev/null || status=1
  done
  # previews that fetch what the view needs: the distance policy's
  # bytes beside one stream stopped at the triangles it asked for
  : >"$out/previews.txt"
  for d in 4 8; do
    p=$(build/bin/mts-client "127.0.0.1:$port" bunny00 --lod-policy distance --distance "$d" \
      --json 2>/dev/null) || status=1
    tri=$(printf '%s' "$p" | python3 -c 'import json,sys; print(json.load(sys.stdin).get("triangles_asked", 0))' 2>/dev/null)
    r=$(build/bin/mts-client "127.0.0.1:$port" bunny00 --triangles "${tri:-0}" --no-render \
      --json 2>/dev/null) || status=1
    printf '{"distance": %s, "policy": %s, "reference": %s}\n' "$d" "${p:-null}" "${r:-null}" \
      >>"$out/previews.txt"
  done
  kill -TERM "$server" 2>/dev/null
  wait "$server" 2>/dev/null
fi

# --- vertex colours -----------------------------------------------------------
# what they cost on the wire beside Draco with colours, and the rate-distortion
# series with a colour error, the builder's colour term on and off
# (bench/colors.sh, docs/colors.md)
rm -f "$out"/colors_*.json
if [ "${MTS_BENCH_COLORS:-1}" = 0 ]; then
  printf '{"skipped": "MTS_BENCH_COLORS=0"}\n' >"$out/colors_stream.json"
else
  bench/colors.sh "$out" "$shared/models" || status=1
fi

# --- many clients: mts-server beside nginx on the same bytes ------------------
rm -f "$out/stress.json"
if [ "${MTS_BENCH_STRESS:-1}" = 0 ]; then
  printf '{"skipped": "MTS_BENCH_STRESS=0"}\n' >"$out/stress.json"
else
  bench/stress.sh "$out" || status=1
fi

# --- stream files: nginx (http, https) beside mts-server (TCP, TLS) ------------
rm -f "$out/files.json"
if [ "${MTS_BENCH_FILES:-1}" = 0 ]; then
  printf '{"skipped": "MTS_BENCH_FILES=0"}\n' >"$out/files.json"
else
  bench/files.sh "$out" || status=1
fi

# --- many applying clients of a stream file on nginx, and of mts-server -------
rm -f "$out/stress_files.json"
if [ "${MTS_BENCH_STRESS_FILES:-1}" = 0 ]; then
  printf '{"skipped": "MTS_BENCH_STRESS_FILES=0"}\n' >"$out/stress_files.json"
else
  bench/stress_files.sh "$out" || status=1
fi

# seconds since some epoch, with microseconds (bash 5)
now() { printf '%s\n' "$EPOCHREALTIME"; }
elapsed() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.3f", b - a }'; }

# --- the big mesh ------------------------------------------------------------
# Facts for the merge go into $out/big.env as KEY=VALUE lines; python reads them.
big_env="$out/big.env"
: >"$big_env"
note() { printf '%s=%s\n' "$1" "$2" >>"$big_env"; }

bunny="$shared/models/bunny00.off"
big="$out/bunny00_l2.off"
big_model="$out/bunny00_l2.mtsm"
if [ "${MTS_BENCH_BIG:-1}" = 0 ]; then
  note big_skipped "MTS_BENCH_BIG=0"
elif ! command -v OpenMesh-commandlineSubdivider >/dev/null; then
  note big_skipped "OpenMesh-commandlineSubdivider not installed (Debian libopenmesh-apps)"
elif [ ! -f "$bunny" ] && [ ! -f "$big" ]; then
  note big_skipped "$bunny not found"
else
  if [ -f "$big" ]; then
    note big_generated "cached"
  else
    # Usage: subdivide [type] iterations input [output]; -l is uniform Loop.
    # Written under a temporary name first so that an interrupted run never
    # leaves a truncated mesh behind to be taken for the cache.
    echo "bench: generating $big (Loop subdivision x2 of bunny00) ..." >&2
    t0=$(now)
    if OpenMesh-commandlineSubdivider -l 2 "$bunny" "$out/tmp_l2.off" >"$out/subdivide.log" 2>&1; then
      mv "$out/tmp_l2.off" "$big"
      note big_generated "now"
      note big_generate_seconds "$(elapsed "$t0" "$(now)")"
    else
      rm -f "$out/tmp_l2.off"
      note big_error "OpenMesh-commandlineSubdivider failed: $(tail -n 1 "$out/subdivide.log")"
      status=1
    fi
  fi
  if [ -f "$big" ]; then
    note big_input_bytes "$(stat -c %s "$big")"
    note big_input_header "$(head -c 16 "$big" | head -n 1 | tr -cd '[:print:]')"
    echo "bench: mts-build $big (about a minute) ..." >&2
    t0=$(now)
    if build/bin/mts-build "$big" -o "$big_model" --json >"$out/bunny00_l2.json" 2>"$out/bunny00_l2.err"; then
      note big_wall_seconds "$(elapsed "$t0" "$(now)")"
      # strip quality and ACMR at the full level against meshopt
      echo "bench: mts-bench $big (a few minutes) ..." >&2
      build/bin/mts-bench "$big" --runs 1 --reps 1 --json "$out/bunny00_l2_bench.json" \
        >"$out/bunny00_l2_bench.txt" 2>&1 || status=1
    else
      rm -f "$out/bunny00_l2.json"
      note big_error "mts-build: $(tail -n 1 "$out/bunny00_l2.err" | sed 's/^mts-build: //')"
      status=1
    fi
  fi
fi

# --- the client's cost --------------------------------------------------------
# both forms warm and as fresh processes, server ready, the window, a thousand
# applying clients: on the shared models' .mtsm and the big mesh's
rm -rf "$out/client" # never merge a previous run's figures
mkdir -p "$out/client"
if [ "${MTS_BENCH_CLIENT:-1}" = 0 ]; then
  printf '{"skipped": "MTS_BENCH_CLIENT=0"}\n' >"$out/client/warm.json"
else
  mkdir -p "$out/mtsm"
  client_models=()
  for m in cow bunny00 fandisk_large; do
    if [ -f "$shared/models/$m.off" ] &&
      build/bin/mts-build "$shared/models/$m.off" -o "$out/mtsm/$m.mtsm" --quiet; then
      client_models+=("$out/mtsm/$m.mtsm")
    fi
  done
  [ -f "$big_model" ] && client_models+=("$big_model")
  if [ ${#client_models[@]} -gt 0 ]; then
    echo "bench: the client's cost (a few minutes) ..." >&2
    bench/client_cost.sh "$out" "${client_models[@]}" || status=1
  fi
fi
# --- the decoder's threads ------------------------------------------------------
# apply time against threads on the shared models, the big mesh's model (before
# it goes) and a Sqrt3-subdivided cow; time to the full picture at 10, 25 and
# 100 Mbit/s beside Draco from nginx (bench/threads.sh, docs/threads.md)
rm -f "$out/threads.json"
if [ "${MTS_BENCH_THREADS:-1}" = 0 ]; then
  printf '{"skipped": "MTS_BENCH_THREADS=0"}\n' >"$out/threads.json"
else
  echo "bench: the decoder's threads (a few minutes) ..." >&2
  bench/threads.sh "$out" "$shared/models" || status=1
fi
rm -f "$big_model" # ~67 MB by-product of the timing; its figures are in the JSON

# OpenMesh's progressive mesh of bunny00, for scale against our build: it
# decimates down to a few vertices (we stop at 1%) and writes a .pm file.
if ! command -v OpenMesh-mkbalancedpm >/dev/null; then
  note pm_skipped "OpenMesh-mkbalancedpm not installed (Debian libopenmesh-apps)"
elif [ ! -f "$bunny" ]; then
  note pm_skipped "$bunny not found"
else
  echo "bench: OpenMesh-mkbalancedpm bunny00 ..." >&2
  t0=$(now)
  if OpenMesh-mkbalancedpm -o "$out/bunny00.pm" "$bunny" >"$out/mkbalancedpm.log" 2>&1; then
    note pm_seconds "$(elapsed "$t0" "$(now)")"
    note pm_bytes "$(stat -c %s "$out/bunny00.pm")"
  else
    note pm_error "OpenMesh-mkbalancedpm failed: $(tail -n 1 "$out/mkbalancedpm.log")"
    status=1
  fi
fi

# --- the builder at scale -----------------------------------------------------
# time and peak memory per stage on bunny00, 1.2M and 6.1M triangles, threads 2
# and 1, beside OpenMesh-mkbalancedpm on the same meshes
rm -f "$out/builder.json"
if [ "${MTS_BENCH_BUILDER:-1}" = 0 ]; then
  printf '{"skipped": "MTS_BENCH_BUILDER=0"}\n' >"$out/builder.json"
else
  echo "bench: the builder at scale (several minutes) ..." >&2
  bench/builder.sh "$out" "$shared/models" || status=1
fi

# --- the browser client -------------------------------------------------------
# the WebAssembly decoder beside the native one, the page in headless Chromium
rm -f "$out/web.json"
if [ "${MTS_BENCH_WEB:-1}" = 0 ]; then
  printf '{"skipped": "MTS_BENCH_WEB=0"}\n' >"$out/web.json"
else
  mkdir -p "$out/web_mtsm"
  for m in cow bunny00 fandisk_large; do
    [ -f "$shared/models/$m.off" ] || continue
    if [ -f "$out/mtsm/$m.mtsm" ]; then
      cp "$out/mtsm/$m.mtsm" "$out/web_mtsm/"
    else
      build/bin/mts-build "$shared/models/$m.off" -o "$out/web_mtsm/$m.mtsm" --quiet || status=1
    fi
  done
  [ -f "$out/web_mtsm/cow.mtsm" ] || build/bin/mts-build tests/data/cow.off -o "$out/web_mtsm/cow.mtsm" --quiet
  echo "bench: the browser client ..." >&2
  bench/web.sh "$out" "$out/web_mtsm" || status=1
fi
# the page's web server (nginx with web/nginx.conf) under hostile load
rm -f "$out/web_front.json"
if [ "${MTS_BENCH_WEB:-1}" = 0 ]; then
  printf '{"skipped": "MTS_BENCH_WEB=0"}\n' >"$out/web_front.json"
else
  echo "bench: the page's web server ..." >&2
  bench/web_front.py --json "$out/web_front.json" || status=1
fi

# --- walkthrough, rate-distortion and plots -----------------------------------
# mts-bench-walk: the walkthrough of papers 000/002 (model moving away, linear
# and exponential, 20 s at 60 Hz, distance LOD policy; strips coherent / from
# the base / triangle list) and each stream's rate-distortion series beside
# Draco single-rate; bench/plot.py draws bench/plots/*.png. matplotlib is
# Debian's python3-matplotlib, in /usr/bin/python3 (which a python3 earlier on
# PATH, e.g. pyenv's, may not see).
rm -f "$out/walk.json" "$out/rd.json"
build/bin/mts-bench-walk "${models[@]}" --json "$out/walk.json" --rd-json "$out/rd.json" || status=1
plot_py=python3
if ! python3 -c 'import matplotlib' 2>/dev/null && [ -x /usr/bin/python3 ]; then
  plot_py=/usr/bin/python3
fi
"$plot_py" bench/plot.py "$out" bench/plots || status=1

# --- merge, print, write -----------------------------------------------------
python3 - "$out" bench/results.json <<'PY' || status=1
import json, os, platform, sys, time

out, dest = sys.argv[1], sys.argv[2]
with open(os.path.join(out, "models.json")) as f:
    res = json.load(f)

env = {}
with open(os.path.join(out, "big.env")) as f:
    for line in f:
        k, _, v = line.rstrip("\n").partition("=")
        env[k] = v

def cpu():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"

res = {
    "generated": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    "machine": {"cpu": cpu(), "cores": os.cpu_count(), "system": platform.platform()},
    **res,
}

print("\nBig mesh: bunny00 Loop-subdivided twice (OpenMesh), one mts-build run; "
      "write = save to file")
big = {"mesh": "bunny00_l2.off"}
if "big_skipped" in env:
    big["status"] = "skipped"
    big["reason"] = env["big_skipped"]
    print(f"  skipped: {env['big_skipped']}")
else:
    big["generated"] = env.get("big_generated")
    if "big_generate_seconds" in env:
        big["generate_seconds"] = float(env["big_generate_seconds"])
    if "big_input_bytes" in env:
        big["input_bytes"] = int(env["big_input_bytes"])
        big["input_header"] = env.get("big_input_header", "")
    if "big_error" in env:
        big["status"] = "failed"
        big["error"] = env["big_error"]
        print(f"  FAILED: {env['big_error']}")
        if big.get("input_header", "").startswith("OFF BINARY"):
            print("  (the subdivider writes binary OFF, which the mesh loader does not read)")
    else:
        with open(os.path.join(out, "bunny00_l2.json")) as f:
            b = json.load(f)
        big["status"] = "ok"
        big["wall_seconds"] = float(env["big_wall_seconds"])
        big.update(b)
        s = b["seconds"]
        print(f"{'model':<14} {'vertices':>9} {'triangles':>9} {'load s':>8} {'strip s':>8} "
              f"{'simpl s':>8} {'recs s':>8} {'write s':>8} {'total s':>8} {'levels':>8}")
        print("-" * 97)
        print(f"{'bunny00_l2':<14} {b['vertices']:>9} {b['triangles']:>9} {s['load']:>8.3f} "
              f"{s['stripify']:>8.3f} {s['simplify']:>8.3f} {s['records']:>8.3f} "
              f"{s['write']:>8.3f} {s['total']:>8.3f} {b['levels']:>8}")
        print(f"  strips {b['strips_full']}, {b['indices_per_triangle_full']:.3f} indices/triangle "
              f"with restarts, {b['swaps']} swaps, model file {b['file_bytes']} B "
              f"({b['file_bytes'] / 1e6:.2f} MB) from {big['input_bytes']} B of "
              f"{'binary ' if 'BINARY' in big.get('input_header', '') else ''}OFF")
        try:
            with open(os.path.join(out, "bunny00_l2_bench.json")) as f:
                bb = json.load(f)["models"]["bunny00_l2"]
            big["full_strips"] = bb["full"]
            big["worst_level"] = bb.get("worst_level")
            mts_f, mo = bb["full"]["mts"], bb["full"]["meshopt"]
            print(f"  full level: {mts_f['indices_per_triangle']:.3f} idx/tri, ACMR-16/32 "
                  f"{mts_f['acmr16']:.3f}/{mts_f['acmr32']:.3f}; meshopt strips "
                  f"{mo['indices_per_triangle']:.3f}, {mo['acmr16']:.3f}/{mo['acmr32']:.3f}; "
                  f"optimized list ACMR-32 {bb['full']['list']['acmr32']:.3f}")
        except (OSError, ValueError, KeyError) as e:
            print(f"  (no strip figures: {e})")
    if "big_generate_seconds" in env:
        print(f"  (generated in {big['generate_seconds']:.2f} s; cached in {out} for later runs)")
res["big_mesh"] = big

pm = {"tool": "OpenMesh-mkbalancedpm", "mesh": "bunny00.off"}
if "pm_skipped" in env:
    pm.update(status="skipped", reason=env["pm_skipped"])
    print(f"\nOpenMesh-mkbalancedpm: skipped: {env['pm_skipped']}")
elif "pm_error" in env:
    pm.update(status="failed", error=env["pm_error"])
    print(f"\nOpenMesh-mkbalancedpm: FAILED: {env['pm_error']}")
else:
    pm.update(status="ok", seconds=float(env["pm_seconds"]), pm_bytes=int(env["pm_bytes"]))
    ours = res.get("models", {}).get("bunny00", {})
    line = (f"\nFor scale, OpenMesh-mkbalancedpm on bunny00 (decimates to 4 vertices, writes a PM): "
            f"{pm['seconds']:.2f} s wall, {pm['pm_bytes']} B ({pm['pm_bytes'] / 1e6:.3f} MB)")
    if ours.get("status") == "ok":
        line += (f"\n  mts on bunny00: {ours['build_seconds']['total']:.2f} s (median, in process), "
                 f"{ours['size']['model_file_bytes']} B ({ours['size']['model_file_mb']:.3f} MB)")
    print(line)
res["openmesh_pm"] = pm

stream = {}
try:
    with open(os.path.join(out, "stream.json")) as f:
        stream = json.load(f)
except (OSError, ValueError):
    pass
runs = []
try:
    with open(os.path.join(out, "loopback.txt")) as f:
        runs = [json.loads(line) for line in f if line.strip()]
except (OSError, ValueError):
    pass
if runs:
    def median(key):
        v = sorted(r[key] for r in runs)
        return v[len(v) // 2]
    loop = {"model": "bunny00", "runs": len(runs), "ms_base_median": median("ms_base"),
            "ms_final_median": median("ms_final"), "ms_apply_median": median("ms_apply"),
            "ms_render_median": median("ms_render"), "bytes": runs[0]["bytes"]}
    stream["loopback"] = loop
    print(f"\nOver loopback (mts-server + mts-client, bunny00, median of {len(runs)}): first frame "
          f"(base decoded and drawn) {loop['ms_base_median']:.1f} ms after connect, full level "
          f"{loop['ms_final_median']:.1f} ms, decode+apply {loop['ms_apply_median']:.1f} ms, "
          f"render {loop['ms_render_median']:.1f} ms, {loop['bytes']} bytes")
previews = []
try:
    with open(os.path.join(out, "previews.txt")) as f:
        for line in f:
            if not line.strip():
                continue
            x = json.loads(line)
            p, r = x.get("policy") or {}, x.get("reference") or {}
            if not p or not r:
                continue
            got = p.get("bytes", 0) + p.get("list_bytes", 0)
            previews.append({"distance": x["distance"], "level": p.get("level"),
                             "triangles_asked": p.get("triangles_asked"), "bytes": p.get("bytes"),
                             "list_bytes": p.get("list_bytes"),
                             "stream_stopped_there_bytes": r.get("bytes"),
                             "ratio": got / r["bytes"] if r.get("bytes") else None,
                             "same_checksum": p.get("checksum") == r.get("checksum"),
                             "full_stream_bytes": p.get("full_stream_bytes")})
except (OSError, ValueError, KeyError):
    pass
if previews:
    stream["previews"] = previews
    print("\nPreviews: --lod-policy distance asks for its stop (bunny00; bytes with "
          "the listing, against one stream stopped at the triangles asked)")
    for v in previews:
        print(f"  distance {v['distance']}x: level {v['level']}, {v['bytes']} + {v['list_bytes']} B "
              f"against {v['stream_stopped_there_bytes']} B ({v['ratio']:.3f}x), checksum "
              f"{'the same' if v['same_checksum'] else 'DIFFERS'}; the whole stream "
              f"{v['full_stream_bytes']} B")
res["stream"] = stream

# --- vertex colours ---
colors = {}
try:
    with open(os.path.join(out, "colors_stream.json")) as f:
        colors["stream"] = json.load(f)
except (OSError, ValueError):
    colors["stream"] = {"skipped": "bench/colors.sh wrote nothing"}
cs = colors["stream"]
if "skipped" in cs:
    print(f"\nVertex colours: skipped: {cs['skipped']}")
else:
    print("\nVertex colours: full stream with and without them beside Draco cl 7 / 10 with "
          "colours (same 14-bit grid; docs/colors.md)")
    print(f"{'model':<14} {'colours':<13} {'without B':>10} {'with B':>9} {'b/vertex':>8} "
          f"{'b/split':>8} {'Draco7+c':>9} {'ratio':>6} {'Draco10+c':>10}")
    for name, c in cs.get("models", {}).items():
        print(f"{name:<14} {c['colors']:<13} {c['stream_bytes_without']:>10} "
              f"{c['stream_bytes_with']:>9} {c['added_bits_per_vertex']:>8.2f} "
              f"{c['color_bits_per_split']:>8.2f} {c['draco_cl7_with_colors']:>9} "
              f"{c['stream_over_draco_cl7_with_colors']:>6.2f} {c['draco_cl10_with_colors']:>10}")
rdc = {}
for field in ("smooth", "patches", "curvature"):
    d = {}
    for key, fname in (("with_color_term", "default"), ("without_color_term", "0"),
                       ("compare", "compare")):
        try:
            with open(os.path.join(out, f"colors_rd_{field}_{fname}.json")) as f:
                d[key] = json.load(f)
        except (OSError, ValueError):
            pass
    if d:
        rdc[field] = d
if rdc:
    print("  rate-distortion, the colour term against none at equal bytes (geometric mean of "
          "error ratios over 15 stops; < 1: less error)")
    for field, d in rdc.items():
        for name, r in d.get("compare", {}).items():
            print(f"  {field:<9} {name:<14} geometric {r.get('rms_ratio_geomean', 0):.3f} "
                  f"(worst {r.get('rms_ratio_worst', 0):.3f}), colour "
                  f"{r.get('color_rms_ratio_geomean', 0):.3f} (worst "
                  f"{r.get('color_rms_ratio_worst', 0):.3f}); full stream "
                  f"{r['full_bytes_base']} -> {r['full_bytes_other']} B")
    colors["rate_distortion"] = rdc
res["colors"] = colors

stress = {}
try:
    with open(os.path.join(out, "stress.json")) as f:
        stress = json.load(f)
except (OSError, ValueError):
    stress = {"skipped": "bench/stress.sh wrote nothing"}
if "skipped" in stress:
    print(f"\nMany clients: skipped: {stress['skipped']}")
else:
    print(f"\nMany clients (mts-stress --no-apply, bunny00 full stream {stress['stream_bytes']} B "
          f"each; nginx: {stress['nginx']}; median of {stress['runs_per_point']} runs)")
    print(f"{'clients':>8} {'server':<11} {'MB/s':>8} {'p50 ms':>9} {'p99 ms':>9} {'failed':>7} "
          f"{'srv CPU s':>9} {'srv RSS MB':>10} {'mts/nginx':>9}")
    print("-" * 88)
    for p in stress["throughput"]:
        for name in ("mts-server", "nginx"):
            r = p.get(name)
            if not r:
                continue
            ratio = f"{p['ratio_mts_to_nginx']:.2f}" if name == "nginx" and "ratio_mts_to_nginx" in p else ""
            print(f"{p['clients']:>8} {name:<11} {r['mb_per_s']:>8.1f} {r['p50_ms_final']:>9.1f} "
                  f"{r['p99_ms_final']:>9.1f} {r['failed']:>7} {r['server_cpu_s']:>9.2f} "
                  f"{r['server_peak_rss_mb']:>10.1f} {ratio:>9}")
    c = stress.get("concurrent")
    if c:
        print(f"  10,000 at once ({c['how']}): peak {c['peak_connections']} connections, "
              f"{c['failed']} failed, server RSS {c['server_idle_rss_mb']} -> "
              f"{c['server_peak_rss_mb']} MB = {c['bytes_per_connection']} B per connection")
res["stress"] = stress

files = {}
try:
    with open(os.path.join(out, "files.json")) as f:
        files = json.load(f)
except (OSError, ValueError):
    files = {"skipped": "bench/files.sh wrote nothing"}
if "skipped" in files:
    print(f"\nStream files: skipped: {files['skipped']}")
else:
    fb, ib = files.get("file_bytes"), files.get("index_bytes")
    print(f"\nStream files: bunny00 from nginx (http; https with HTTP/2) beside mts-server (TCP; "
          f"TCP in TLS through nginx), mts-client --no-render, loopback, median of "
          f"{files['runs']} interleaved runs; file {fb} B, index {ib} B")
    print(f"{'stop':<16} {'way':<6} {'first ms':>9} {'full ms':>9} {'bytes':>8} {'vs TCP':>7} "
          f"{'failed':>6} checksum")
    print("-" * 78)
    for stop, table in files["stops"].items():
        tcp = table.get("tcp", {})
        for way in ("tcp", "tls", "http", "https"):
            r = table.get(way, {})
            if "full_ms" not in r:
                print(f"{stop:<16} {way:<6} {'':>9} {'':>9} {'':>8} {'':>7} {r.get('failed', '?'):>6}")
                continue
            ratio = f"{r['full_ms'] / tcp['full_ms']:.2f}" if tcp.get("full_ms") else ""
            r["full_vs_tcp"] = float(ratio) if ratio else None
            print(f"{stop:<16} {way:<6} {r['first_ms']:>9.1f} {r['full_ms']:>9.1f} "
                  f"{r['bytes']:>8.0f} {ratio:>7} {r['failed']:>6} {r['checksum']}")
    full = files["stops"].get("full", {})
    if "bytes" in full.get("tcp", {}) and ib:
        print(f"  the index adds {ib} B = {100 * ib / full['tcp']['bytes']:.2f}% to the full "
              f"stream; a file read fetches {full['http']['bytes'] - full['tcp']['bytes']:.0f} B "
              f"more than TCP at the full level; {files.get('first_picture_extra_bytes')} B more "
              f"before the first picture")
res["stream_files"] = files

sf = {}
try:
    with open(os.path.join(out, "stress_files.json")) as f:
        sf = json.load(f)
except (OSError, ValueError):
    sf = {"skipped": "bench/stress_files.sh wrote nothing"}
if "skipped" in sf:
    print(f"\nMany clients of a stream file: skipped: {sf['skipped']}")
else:
    print(f"\nMany clients of a stream file: {sf['clients']} applying mts-stress clients "
          f"(--verify) of {sf['model']} ({sf['file_bytes']} B file) from nginx over http and "
          f"https (HTTP/2, each client its own connection) beside mts-server over TCP, same "
          f"run, loopback; median of {sf['runs_per_way']} run(s)")
    print(f"{'way':<6} {'server':<11} {'wall s':>7} {'clients/s':>9} {'failed':>6} "
          f"{'p99 ms':>8} {'stress CPU s':>12} {'stress RSS MB':>13} {'srv CPU s':>9} end")
    print("-" * 100)
    for way in ("tcp", "http", "https"):
        r = sf["ways"].get(way, {})
        if "wall_s" not in r:
            print(f"{way:<6} {r.get('error', '?')}")
            continue
        rss = r["stress_max_rss_kb"] / 1024 if r.get("stress_max_rss_kb") else 0
        print(f"{way:<6} {r['server']:<11} {r['wall_s']:>7.2f} {r['clients_per_s']:>9.1f} "
              f"{r['failed']:>6} {r['p99_ms_final']:>8.0f} {r['stress_cpu_s']:>12.2f} "
              f"{rss:>13.1f} {r['server_cpu_s']:>9.2f} level {r['level']} {r['checksum']}")
    print(f"  every way ended at {'the same' if sf['same_end'] else 'DIFFERENT'} level and "
          f"checksum; the clients' decoding, not the servers, bounds clients/s here")
res["stress_files"] = sf

def median_of(v):
    v = sorted(v)
    return v[len(v) // 2] if v else None

# --- the client's cost ---
cc = {}
cdir = os.path.join(out, "client")
try:
    with open(os.path.join(cdir, "warm.json")) as f:
        cc["warm"] = json.load(f)
except (OSError, ValueError):
    cc["warm"] = {"skipped": "bench/client_cost.sh did not run"}
warm = cc["warm"].get("models", {})
fresh = {}
try:
    with open(os.path.join(cdir, "fresh.txt")) as f:
        for line in f:
            name, form, wall, js = line.split(" ", 3)
            d = json.loads(js)
            e = fresh.setdefault(name, {}).setdefault(form, {"wall": [], "apply": []})
            e["wall"].append(float(wall) * 1e3)
            e["apply"].append(d["ms_apply"])
except (OSError, ValueError):
    pass
cc["fresh"] = {n: {form: {"process_ms_median": median_of(e["wall"]),
                          "apply_ms_median": median_of(e["apply"]), "runs": len(e["wall"])}
                   for form, e in forms.items()} for n, forms in fresh.items()}
ready = {}
try:
    with open(os.path.join(cdir, "ready.txt")) as f:
        for line in f:
            name, listen, rdy = line.split()
            ready[name] = {"listening_s": None if listen == "none" else float(listen),
                           "stream_ready_s": None if rdy == "none" else float(rdy)}
except (OSError, ValueError):
    pass
cc["server_ready"] = ready
win = []
try:
    with open(os.path.join(cdir, "window.txt")) as f:
        win = [json.loads(l) for l in f if l.strip().startswith("{")]
except (OSError, ValueError):
    pass
if win:
    cc["window"] = {"model": "bunny00", "size": "800x600", "runs": len(win),
                    "fps_streaming_median": median_of([w["fps_streaming"] for w in win]),
                    "fps_streaming_runs": [w["fps_streaming"] for w in win],
                    "frames_streaming_median": median_of([w["frames_streaming"] for w in win]),
                    "seconds_streaming_median": median_of([w["seconds_streaming"] for w in win])}
try:
    with open(os.path.join(cdir, "stress.json")) as f:
        st = json.load(f)
    cc["stress_applying"] = {k: st.get(k) for k in ("clients", "succeeded", "failed", "failures",
                                                    "seconds", "cpu_s", "p50_ms_final",
                                                    "p99_ms_final")}
except (OSError, ValueError):
    pass
try:
    with open(os.path.join(cdir, "notes.txt")) as f:
        notes = [l.strip() for l in f if l.strip()]
    if notes:
        cc["notes"] = notes
except OSError:
    pass
if warm:
    print("\nThe client's cost: splits form (records derived) against records form")
    print(f"{'model':<14} {'triangles':>9} {'splits':>8} {'warm split':>11} {'warm rec':>9} "
          f"{'ratio':>6} {'ns/split':>9} {'fresh split':>12} {'fresh rec':>10} {'ratio':>6} "
          f"{'listen s':>9} {'ready s':>8}")
    print("-" * 118)
    bunny_ns = warm.get("bunny00", {}).get("ns_per_split")
    for name, w in warm.items():
        fr = cc["fresh"].get(name, {})
        fs, frc = fr.get("splits", {}), fr.get("records", {})
        fsm, frm = fs.get("apply_ms_median"), frc.get("apply_ms_median")
        rd = ready.get(name, {})
        fmt = lambda x, p=1: f"{x:.{p}f}" if isinstance(x, (int, float)) else "-"
        print(f"{name:<14} {w['triangles']:>9} {w['splits']:>8} {w['splits_ms']:>9.1f}ms "
              f"{w['records_ms']:>7.1f}ms {w['ratio']:>6.2f} {w['ns_per_split']:>9.0f} "
              f"{fmt(fsm):>10}ms {fmt(frm):>8}ms "
              f"{fmt(fsm / frm if fsm and frm else None, 2):>6} "
              f"{fmt(rd.get('listening_s'), 2):>9} {fmt(rd.get('stream_ready_s'), 2):>8}")
    for name, w in warm.items():
        if bunny_ns and name != "bunny00":
            w["ns_per_split_over_bunny00"] = round(w["ns_per_split"] / bunny_ns, 3)
    print("  (warm: mts-bench-apply, median of 7 in one process; fresh: mts-client --no-render "
          "[--records] over loopback, median ms_apply of 5; ready: mts-server with that model "
          "alone, seconds to listen and until its stream is encoded)")
    big_w = warm.get("bunny00_l2")
    if big_w and bunny_ns:
        print(f"  cost per split, 1.2M-triangle mesh against bunny00: "
              f"{big_w['ns_per_split'] / bunny_ns:.2f}x")
if "window" in cc:
    w = cc["window"]
    print(f"  window (Xvfb, 800x600, bunny00 over loopback, median of {w['runs']}): "
          f"{w['fps_streaming_median']:.1f} frames/s while it streams "
          f"({w['frames_streaming_median']} frames in {w['seconds_streaming_median']:.3f} s)")
if "stress_applying" in cc:
    a = cc["stress_applying"]
    print(f"  {a['clients']} applying mts-stress clients of bunny00: {a['failed']} failed, "
          f"{a['seconds']:.1f} s wall, {a['cpu_s']:.1f} CPU s")
res["client_cost"] = cc

def load_out(name):
    try:
        with open(os.path.join(out, name)) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None

# --- the decoder's threads (bench/threads.sh printed the full tables) ---
thr = load_out("threads.json") or {"skipped": "bench/threads.sh wrote nothing"}
if list(thr) == ["skipped"]:
    print(f"\nThreads in the decoder: skipped: {thr['skipped']}")
else:
    print(f"\nThreads in the decoder ({thr.get('processors')} processors online): apply time "
          f"at each count over one thread's (mts-bench-apply, splits form)")
    for name, m in thr.get("apply", {}).get("models", {}).items():
        print(f"  {name:<14} 1 thread {m['splits_ms'].get('1', 0):9.2f} ms; " + ", ".join(
            f"{t}: {r:.2f}x" for t, r in m["over_one_thread"].items() if t != "1"))
    st = thr.get("stream", {})
    for key, e in st.get("rates", {}).items():
        f = lambda w: (e.get(w) or {}).get("full_ms")
        dr = e.get("draco") or {}
        cells = [f"{w} {f(w):.1f}" for w in ("splits_t1", "splits_default", "records") if f(w)]
        cells += [f"Draco {dr['full_ms_' + k]:.1f} ({k})"
                  for k in ("measured", "link") if dr.get("full_ms_" + k) is not None]
        print(f"  {st.get('model')} at {key}, full picture ms: " + ", ".join(cells))
    if st.get("paced_by"):
        print(f"  (paced by {st['paced_by']})")
    for name, why in thr.get("skipped", {}).items():
        print(f"  {name}: skipped: {why}")
res["threads"] = thr

# --- the builder at scale ---
builder = load_out("builder.json") or {"skipped": "bench/builder.sh wrote no figures"}
if "skipped" in builder:
    print(f"\nBuilder at scale: skipped: {builder['skipped']}")
else:
    print("\nBuilder at scale: mts-build (2 threads, 1 thread) beside OpenMesh-mkbalancedpm, same run")
    print(f"{'mesh':<12} {'triangles':>10} {'build s':>8} {'1 thr s':>8} {'mkbpm s':>8} {'ratio':>6} "
          f"{'us/tri':>7} {'vs bunny':>8} {'peak MB':>8} {'B/tri':>6} {'idx/tri':>7} {'worst':>6}")
    print("-" * 104)
    for name, m in builder.items():
        b, b1, pm = m.get("mts-build_t2", {}), m.get("mts-build_t1", {}), m.get("mkbalancedpm", {})
        f = lambda v, fmt: (format(v, fmt) if isinstance(v, (int, float))
                            else "-".rjust(int(fmt[1:].split(".")[0])))
        print(f"{name:<12} {f(m.get('triangles'), '>10')} {f(b.get('wall_s'), '>8.2f')} "
              f"{f(b1.get('wall_s'), '>8.2f')} {f(pm.get('wall_s'), '>8.2f')} "
              f"{f(m.get('ratio_to_mkbalancedpm'), '>6.2f')} {f(m.get('us_per_triangle'), '>7.2f')} "
              f"{f(m.get('per_triangle_vs_bunny00'), '>8.2f')} {f(b.get('peak_mb'), '>8.1f')} "
              f"{f(b.get('peak_bytes_per_triangle'), '>6.0f')} "
              f"{f(b.get('indices_per_triangle_full'), '>7.4f')} {f(b.get('indices_per_triangle_worst'), '>6.3f')}")
        if b.get("seconds"):
            print("   stages: " + ", ".join(f"{k} {v:.2f}" for k, v in b["seconds"].items()) +
                  "; peak MB: " + ", ".join(f"{k} {v:.0f}" for k, v in b.get("stage_peak_mb", {}).items()))
res["builder"] = builder

# --- the browser client ---
web = load_out("web.json") or {"skipped": "bench/web.sh wrote no figures"}
if "skipped" in web:
    print(f"\nBrowser client: skipped: {web['skipped']}")
else:
    print("\nBrowser client: the WebAssembly decoder (node, median of 7 warm; first run) "
          "against the native one (mts-bench-apply, median of 7), splits form")
    print(f"{'model':<14} {'splits':>8} {'wasm ms':>9} {'first ms':>9} {'native ms':>10} "
          f"{'wasm M/s':>9} {'native M/s':>11} {'ratio':>7} {'first':>7}")
    print("-" * 92)
    for name, d in web.get("decoder", {}).items():
        print(f"{name:<14} {d['splits']:>8} {d['wasm_ms']:>9.1f} {d['wasm_ms_first']:>9.1f} "
              f"{d['native_ms']:>10.1f} {d['wasm_splits_per_s'] / 1e6:>9.3f} "
              f"{d['native_splits_per_s'] / 1e6:>11.3f} {d['ratio']:>7.2f} {d['ratio_first']:>7.2f}"
              + ("" if d["checksum_match"] else "  CHECKSUM DIFFERS"))
    pg = web.get("page", {})
    if "skipped" in pg:
        print(f"  page: skipped: {pg['skipped']}")
    else:
        s = pg["streaming"]
        print(f"  page ({pg['model']}, headless Chromium + SwiftShader, {pg['width']}x{pg['height']}, "
              f"median of {pg['runs']}): connect {pg['ms_connect']:.1f} ms, first frame "
              f"{pg['ms_first_frame']:.1f} ms (worst {pg['ms_first_frame_max']:.1f}), full level "
              f"{pg['ms_final']:.1f} ms")
        print(f"  while streaming at {s['rate_limit']} B/s: {s['fps']:.1f} fps drawing every frame; "
              f"script {s['script_ms_mean']:.2f} ms a frame (max {s['script_ms_max']:.2f})")
        print("  pictures: " + ", ".join(p["path"] for p in pg.get("pictures", [])))
res["web"] = web

front = load_out("web_front.json") or {"skipped": "bench/web_front.py wrote no figures"}
if "skipped" in front:
    print(f"\nThe page's web server: skipped: {front['skipped']}")
else:
    print(f"\nThe page's web server ({front['nginx']}, {front['config']}): RSS idle "
          f"{front['idle_rss_mb']:.1f} MB; {front['non_readers']} clients not reading "
          f"{front['largest_page_file']} {front['non_readers_rss_mb']:.1f} MB; "
          f"{front['slow_readers']} slow readers of {front['big_file_mb']} MB "
          f"{front['slow_readers_rss_mb']:.1f} MB; the page for a good client meanwhile "
          f"{front['idle_page_ms']:.1f} / {front['non_readers_page_ms']:.1f} / "
          f"{front['slow_readers_page_ms']:.1f} ms")
res["web_front"] = front

walk = load_out("walk.json")
if walk and walk.get("models"):
    wsum = {k: walk[k] for k in ("renderer", "seconds", "hz", "far", "width", "height", "policy")}
    wsum["models"] = {}
    print(f"\nWalkthrough (papers 000/002; {walk['seconds']:g} s at {walk['hz']:g} Hz, moving away "
          f"to {walk['far']:g}x, {walk['width']}x{walk['height']}, distance policy; "
          f"bench/plots/walkthrough.png)")
    print(f"{'model':<14} {'schedule':<12} {'mode':<13} {'mean fps':>9} {'extr ms':>9} "
          f"{'max extr':>9} {'triangles':>10}")
    print("-" * 82)
    for name, mod in walk["models"].items():
        wsum["models"][name] = {}
        for sched, runs in mod["runs"].items():
            wsum["models"][name][sched] = {k: r["summary"] for k, r in runs.items()}
            for mode, r in runs.items():
                s = r["summary"]
                print(f"{name:<14} {sched:<12} {mode:<13} {s['mean_fps']:>9.1f} "
                      f"{s['mean_extract_ms']:>9.3f} {s['max_extract_ms']:>9.3f} "
                      f"{s['mean_triangles']:>10.0f}")
    res["walkthrough"] = wsum
elif walk:
    res["walkthrough"] = {"skipped": walk.get("skipped", "no models")}
    print(f"\nWalkthrough: skipped: {res['walkthrough']['skipped']}")

rd = load_out("rd.json")
if rd and rd.get("models"):
    rsum = {}
    print("\nRate-distortion (symmetric RMS / bbox diagonal; bench/plots/rd_<model>.png)")
    for name, m in rd["models"].items():
        pts = m["points"]
        def at(frac):
            want = frac * m["full_triangles"]
            return next((p for p in pts if p["triangles"] >= want), pts[-1])
        d = m["draco"]
        rsum[name] = {"points": len(pts), "base": pts[0], "half_triangles": at(0.5),
                      "full": pts[-1], "draco": d}
        print(f"  {name}: base {pts[0]['bytes']} B rms {pts[0]['rms']:.2e}; "
              f"50% triangles {at(0.5)['bytes']} B rms {at(0.5)['rms']:.2e}; "
              f"full {pts[-1]['bytes']} B rms {pts[-1]['rms']:.2e}; "
              f"Draco {d['bytes']} B rms {d['rms']:.2e}")
    res["rate_distortion"] = rsum

with open(dest + ".tmp", "w") as f:
    json.dump(res, f, indent=2)
    f.write("\n")
os.replace(dest + ".tmp", dest)
print(f"\nwrote {dest}")
PY

[ "$status" -eq 0 ] || echo "bench: some figures could not be measured (see above)" >&2
exit "$status"
