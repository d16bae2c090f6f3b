#!/usr/bin/env bash
# Part of `make bench`: the client's threaded stream decoder (docs/threads.md).
#   1. Apply time against threads: mts-bench-apply --runs 7 --threads 1,..,P
#      (P = processors online, the counts alternated within each run) on cow,
#      bunny00, fandisk_large, the 1.2M mesh (OUT/bunny00_l2.mtsm, which
#      bench/run.sh makes; built here from OUT/bunny00_l2.off when only that
#      is left) and cow Sqrt3-subdivided once by OpenMesh, a mesh no test uses.
#   2. Time to the full picture over loopback at 10, 25 and 100 Mbit/s:
#      bunny00 from mts-server, fresh mts-client --no-render --json
#      processes, the splits form at --threads 1 and at the default and the
#      records form, interleaved, median of 3 (ms_base: first picture,
#      ms_final: the final level). Beside it Draco: bunny00 encoded by
#      draco_encoder -cl 7 -qp 14 (the stream's 14-bit grid), downloaded with
#      curl from nginx at the same rate, plus draco_decoder's decode time.
#      Both meet the same link where one can be made (below, part 2).
# Usage: bench/threads.sh OUT SHARED_MODELS_DIR. Writes OUT/threads.json and
# prints the tables. Environment: MTS_BENCH_BIN (default build/bin),
# MTS_BENCH_BIG=0 leaves out the 1.2M mesh, MTS_BENCH_LINK=0 paces part 2
# with the servers' own limits, not a shaped link, MTS_BENCH_THREADS_QUICK=1 a
# quick check (cow alone, 3 runs, one rate, one run each). Absent tools and
# models are skipped with the reason in the JSON; exit status 1 when a
# requested figure could not be measured.
set -uo pipefail
cd "$(dirname "$0")/.." || exit 1
out=$1
shared=$2
mkdir -p "$out"
out=$(cd "$out" && pwd) # nginx wants absolute paths
bin=${MTS_BENCH_BIN:-build/bin}
quick=${MTS_BENCH_THREADS_QUICK:-0}
json="$out/threads.json"
dir="$out/threads"
rm -rf "$dir" "$json"
mkdir -p "$dir/models" "$dir/www" "$dir/nginx/tmp"
status=0
now() { printf '%s\n' "$EPOCHREALTIME"; }
elapsed() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.3f", b - a }'; }
free_port() { echo $((20000 + RANDOM % 20000)); }
skipped="$dir/skipped.txt" # "what reason" lines for the JSON
: >"$skipped"
skip() { printf '%s\t%s\n' "$1" "$2" >>"$skipped"; echo "bench: threads: $1 skipped: $2" >&2; }
# whatever this script started goes with it, interrupted or not
pids=()
trap 'kill -TERM "${pids[@]}" 2>/dev/null; wait 2>/dev/null' EXIT

procs=$(getconf _NPROCESSORS_ONLN 2>/dev/null || echo 1)
# Past two, the counts are the layout that cuts growth at its keys (3k, 4k,
# ...: stream.h threads_at_keys), since --threads 3 or more decode as two.
counts=""
for t in 1 2 3 4 5 6 7 8; do # mts-bench-apply times at most 8 counts
  [ "$t" -le "$procs" ] && counts="$counts${counts:+,}$t$([ "$t" -gt 2 ] && echo k)"
done
if [ "$procs" -gt 8 ]; then
  counts="1,2,4k,8k"
  for t in 16 32 64; do [ "$t" -lt "$procs" ] && counts="$counts,${t}k"; done
  counts="$counts,$((procs < 64 ? procs : 64))k"
fi
runs=7 stream_runs=3 names=(cow bunny00 fandisk_large) rates=(1250000 3125000 12500000)
stream_model=bunny00
if [ "$quick" = 1 ]; then
  runs=3 stream_runs=1 names=(cow) rates=(3125000) stream_model=cow
fi

# --- the models ---------------------------------------------------------------
models=()
build_model() { # NAME MESH
  if "$bin/mts-build" "$2" -o "$dir/models/$1.mtsm" --quiet 2>"$dir/build_$1.err"; then
    models+=("$dir/models/$1.mtsm")
  else
    skip "$1" "mts-build: $(tail -n 1 "$dir/build_$1.err")"
    status=1
  fi
}
for m in "${names[@]}"; do
  if [ -f "$shared/$m.off" ]; then build_model "$m" "$shared/$m.off"; else skip "$m" "$shared/$m.off not found"; fi
done
if [ "$quick" = 1 ]; then
  :
elif [ "${MTS_BENCH_BIG:-1}" = 0 ]; then
  skip bunny00_l2 "MTS_BENCH_BIG=0"
elif [ -f "$out/bunny00_l2.mtsm" ]; then
  models+=("$out/bunny00_l2.mtsm")
elif [ -f "$out/bunny00_l2.off" ]; then
  echo "bench: threads: mts-build $out/bunny00_l2.off (about a minute) ..." >&2
  build_model bunny00_l2 "$out/bunny00_l2.off"
else
  skip bunny00_l2 "neither $out/bunny00_l2.mtsm nor its .off (bench/run.sh makes them)"
fi
if [ "$quick" = 1 ]; then
  :
elif ! command -v OpenMesh-commandlineSubdivider >/dev/null; then
  skip cow_sqrt3 "OpenMesh-commandlineSubdivider not installed (Debian libopenmesh-apps)"
elif [ ! -f "$shared/cow.off" ]; then
  skip cow_sqrt3 "$shared/cow.off not found"
elif OpenMesh-commandlineSubdivider -s 1 "$shared/cow.off" "$dir/tmp_sqrt3.off" >"$dir/subdivide.log" 2>&1 &&
  mv "$dir/tmp_sqrt3.off" "$out/cow_sqrt3.off"; then
  build_model cow_sqrt3 "$out/cow_sqrt3.off"
else
  skip cow_sqrt3 "OpenMesh-commandlineSubdivider failed: $(tail -n 1 "$dir/subdivide.log")"
  status=1
fi

# --- 1. apply time against threads ------------------------------------------
if [ ${#models[@]} -gt 0 ]; then
  echo "bench: threads: mts-bench-apply --threads $counts on ${#models[@]} model(s) ..." >&2
  "$bin/mts-bench-apply" "${models[@]}" --runs "$runs" --threads "$counts" \
    --json "$dir/apply.json" >"$dir/apply.txt" 2>&1 || status=1
fi

# --- 1b. the same with every other core busy -----------------------------------
# A client shares its machine: with all but one core held by busy loops, two
# threads would share the one left, and the decoder is meant to notice and go
# on alone (docs/threads.md, "On a busy machine"). bunny00 and fandisk_large
# (cow in the quick check) at 1 and 2 threads.
busy_models=()
for m in bunny00 fandisk_large; do
  [ -f "$dir/models/$m.mtsm" ] && busy_models+=("$dir/models/$m.mtsm")
done
[ ${#busy_models[@]} -gt 0 ] || [ ! -f "$dir/models/cow.mtsm" ] || busy_models=("$dir/models/cow.mtsm")
if [ "$procs" -lt 2 ]; then
  skip apply_busy "one processor online"
elif [ ${#busy_models[@]} -gt 0 ]; then
  echo "bench: threads: mts-bench-apply --threads 1,2 with $((procs - 1)) core(s) busy ..." >&2
  busy=()
  for _ in $(seq 2 "$procs"); do
    sh -c 'while :; do :; done' &
    busy+=($!)
    pids+=($!)
  done
  "$bin/mts-bench-apply" "${busy_models[@]}" --runs "$runs" --threads 1,2 \
    --json "$dir/apply_busy.json" >"$dir/apply_busy.txt" 2>&1 || status=1
  kill "${busy[@]}" 2>/dev/null
  wait "${busy[@]}" 2>/dev/null
fi

# --- 2. time to the full picture at a rate ------------------------------------
# Both streams meet the same link. Where this runs as root with unshare and
# tc, this part runs in a network namespace of its own whose loopback (MTU
# 1500) is shaped to the rate by Linux's tbf qdisc, a link emulator both
# servers send into as fast as they can. Elsewhere mts-server --rate-limit
# paces ours (the rate from the first byte, in 5 ms quanta) and nginx's
# limit_rate Draco's, which lets the first second's bytes go at once, so
# Draco's download over a link is also computed (the bytes over the rate).
: >"$dir/stream.txt" # RATE WAY RUN JSON
: >"$dir/draco.txt"  # RATE WAY RUN SECONDS
: >"$dir/decode.txt" # MS (draco_decoder's own) WALL_S
smodel="$dir/models/$stream_model.mtsm"
drc="$dir/www/$stream_model.drc"
nginx_bin=$(command -v nginx || { [ -x /usr/sbin/nginx ] && echo /usr/sbin/nginx; })
wait_listen() { # PORT
  for _ in $(seq 1 600); do
    (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null && return 0
    sleep 0.05
  done
  return 1
}
wait_stream() { # PORT: the splits form encoded, then the records form too
  local ok=1
  for _ in $(seq 1 1200); do
    list=$("$bin/mts-client" "127.0.0.1:$1" --list 2>/dev/null) &&
      ! printf '%s\n' "$list" | awk '{ print $(NF-2) }' | grep -qx 0 && { ok=0; break; }
    sleep 0.05
  done
  [ "$ok" = 0 ] || return 1
  for _ in $(seq 1 1200); do
    "$bin/mts-client" "127.0.0.1:$1" "$stream_model" --records --level 0 --no-render --json 2>/dev/null |
      grep -q '"form":"records"' && return 0
    sleep 0.05
  done
  return 1
}
shape() { # RATE (bytes/s): the namespace's loopback becomes a link at that rate
  tc qdisc replace dev lo root tbf rate "$(($1 * 8))bit" burst 6000 latency 200ms
}
clients() { # PORT RATE: the three ways, interleaved, so drift hits all alike
  echo "bench: threads: $stream_model at $2 B/s ($how), $stream_runs run(s) of each form ..." >&2
  for run in $(seq 1 "$stream_runs"); do
    for way in splits_t1 splits_default records; do
      case $way in
      splits_t1) flags=(--threads 1) ;;
      splits_default) flags=() ;;
      records) flags=(--records) ;;
      esac
      if line=$(timeout 120 "$bin/mts-client" "127.0.0.1:$1" "$stream_model" --no-render \
        --json "${flags[@]}" 2>>"$dir/client.err"); then
        echo "$2 $way $run $line" >>"$dir/stream.txt"
      else
        echo "bench: threads: mts-client $way at $2 failed: $(tail -n 1 "$dir/client.err")" >&2
        echo 1 >"$dir/stream_failed"
      fi
    done
  done
}
streams() { # the mts-server part, paced by the link or by --rate-limit
  local port server
  if [ "$how" = link ]; then
    port=$(free_port)
    "$bin/mts-server" --model "$stream_model=$smodel" --listen "127.0.0.1:$port" \
      --quiet 2>"$dir/server.log" &
    server=$!
    if ! wait_listen "$port" || ! wait_stream "$port"; then
      skip stream "mts-server did not have the streams ready in 60 s: $(tail -n 1 "$dir/server.log")"
      echo 1 >"$dir/stream_failed"
    else
      for rate in "${rates[@]}"; do
        shape "$rate" && clients "$port" "$rate"
      done
    fi
    kill -TERM "$server" 2>/dev/null
    wait "$server" 2>/dev/null
    return
  fi
  for rate in "${rates[@]}"; do
    port=$(free_port)
    "$bin/mts-server" --model "$stream_model=$smodel" --listen "127.0.0.1:$port" \
      --rate-limit "$rate" --quiet 2>"$dir/server_$rate.log" &
    server=$!
    if ! wait_listen "$port" || ! wait_stream "$port"; then
      skip "stream_$rate" "mts-server did not have the streams ready in 60 s: $(tail -n 1 "$dir/server_$rate.log")"
      echo 1 >"$dir/stream_failed"
    else
      clients "$port" "$rate"
    fi
    kill -TERM "$server" 2>/dev/null
    wait "$server" 2>/dev/null
  done
}
downloads() { # Draco's file by curl from nginx, through the link or limit_rate
  local nport npid
  nport=$(free_port)
  # shellcheck disable=SC2016 # $arg_rate is nginx's: the rate comes in the URL
  sed -e "s#@PORT@#$nport#g" -e "s#@ROOT@#$dir/www#g" -e "s#@PREFIX@#$dir/nginx#g" \
    -e 's#^\( *\)root \(.*\)#\1root \2\n\1limit_rate $arg_rate;#' \
    bench/nginx-static.conf >"$dir/nginx/nginx.conf"
  "$nginx_bin" -c "$dir/nginx/nginx.conf" -p "$dir/nginx" 2>"$dir/nginx/stderr.log" &
  npid=$!
  if ! wait_listen "$nport"; then
    skip draco "nginx did not start: $(tail -n 1 "$dir/nginx/stderr.log")"
    echo 1 >"$dir/stream_failed"
  else
    for rate in "${rates[@]}"; do
      # through the link, nginx sends as fast as it can (limit_rate 0)
      local q=$rate
      [ "$how" = link ] && { shape "$rate" || continue; q=0; }
      for run in $(seq 1 "$stream_runs"); do
        s=$(curl -sS -o /dev/null -w '%{time_total}' "http://127.0.0.1:$nport/$stream_model.drc?rate=$q" \
          2>>"$dir/curl.err")
        if [ -n "$s" ]; then echo "$rate $how $run $s" >>"$dir/draco.txt"; else echo 1 >"$dir/stream_failed"; fi
      done
    done
  fi
  kill -TERM "$npid" 2>/dev/null
  wait "$npid" 2>/dev/null
}
stream_part() { # in the namespace (how=link) or not (how=pace)
  trap 'kill -TERM $(jobs -p) 2>/dev/null; wait 2>/dev/null' EXIT
  if [ "$how" = link ]; then
    if ! ip link set lo up || ! ip link set lo mtu 1500; then
      echo 1 >"$dir/stream_failed"
      return
    fi
  fi
  [ -f "$smodel" ] && streams
  [ -f "$drc" ] && [ -n "$nginx_bin" ] && downloads
}

if [ ! -f "$smodel" ]; then
  skip stream "$stream_model's model was not built"
fi
# Draco: the same mesh, single-rate, encoded and decoded here
if [ ! -f "$shared/$stream_model.off" ]; then
  skip draco "$shared/$stream_model.off not found"
elif ! command -v draco_encoder >/dev/null || ! command -v draco_decoder >/dev/null; then
  skip draco "draco_encoder / draco_decoder not installed (Debian draco)"
elif [ -z "$nginx_bin" ]; then
  skip draco "nginx not installed (Debian nginx-light)"
elif ! command -v curl >/dev/null; then
  skip draco "curl not installed"
else
  # OFF to OBJ (positions and triangles only: what the stream carries)
  awk 'BEGIN { s = 0 }
       { sub(/#.*/, "") } NF == 0 { next }
       s == 0 { s = 1; if ($1 == "OFF" && NF == 1) next; if ($1 == "OFF") { $1 = "" ; $0 = $0 } }
       s == 1 { nv = $1; nf = $2; s = 2; next }
       s == 2 && nv > 0 { print "v", $1, $2, $3; nv--; next }
       s == 2 && nf > 0 { for (i = 3; i <= $1; i++) print "f", $2 + 1, $(i) + 1, $(i + 1) + 1; nf-- }' \
    "$shared/$stream_model.off" >"$dir/$stream_model.obj"
  if ! draco_encoder -i "$dir/$stream_model.obj" -o "$drc" -cl 7 -qp 14 >"$dir/draco_encoder.log" 2>&1; then
    skip draco "draco_encoder failed: $(tail -n 1 "$dir/draco_encoder.log")"
    rm -f "$drc"
    status=1
  else
    for _ in 1 2 3 4 5; do
      t0=$(now)
      msg=$(draco_decoder -i "$drc" -o "$dir/decoded.ply" 2>&1)
      wall=$(elapsed "$t0" "$(now)")
      ms=$(printf '%s\n' "$msg" | sed -n 's/.*(\([0-9.]*\) ms to decode).*/\1/p')
      echo "${ms:-none} $wall" >>"$dir/decode.txt"
    done
  fi
fi
how=pace
if [ "${MTS_BENCH_LINK:-1}" != 0 ] && [ "$(id -u)" = 0 ] && command -v unshare >/dev/null && command -v tc >/dev/null &&
  unshare -n sh -c 'ip link set lo up && tc qdisc add dev lo root tbf rate 10mbit burst 6000 latency 200ms' \
    2>"$dir/link_probe.err"; then
  how="link"
else
  echo "bench: threads: no link emulation (needs root, unshare and tc's tbf: $(tail -n 1 "$dir/link_probe.err" 2>/dev/null)); mts-server --rate-limit and nginx limit_rate pace instead" >&2
fi
echo "$how" >"$dir/how"
if [ "$how" = link ]; then
  export -f stream_part streams downloads clients shape wait_listen wait_stream skip free_port
  export bin dir smodel drc nginx_bin stream_model stream_runs how skipped
  export rates_list="${rates[*]}"
  # shellcheck disable=SC2016 # expanded by the bash in the namespace
  unshare -n bash -c 'read -r -a rates <<<"$rates_list"; stream_part'
else
  (stream_part)
fi
[ -f "$dir/stream_failed" ] && status=1

# --- merge and print ------------------------------------------------------------
python3 - "$dir" "$json" "$procs" "$counts" "$runs" "$stream_runs" "$stream_model" "$quick" <<'PY' || status=1
import json, os, sys
d, dest, procs, counts, runs, sruns, smodel, quick = sys.argv[1:9]
counts = counts.split(",")  # 1, 2, 3k ...: k cut at keys

def med(v):
    v = sorted(x for x in v if x is not None)
    return v[len(v) // 2] if v else None

def lines(name):
    try:
        with open(os.path.join(d, name)) as f:
            return [l.rstrip("\n") for l in f if l.strip()]
    except OSError:
        return []

res = {"processors": procs and int(procs), "quick": quick == "1"}
skipped = dict(l.split("\t", 1) for l in lines("skipped.txt"))
if skipped:
    res["skipped"] = skipped

# 1. apply time against threads
apply = {"runs": int(runs), "threads": counts, "models": {}}
try:
    with open(os.path.join(d, "apply.json")) as f:
        rows = json.load(f)["models"]
except (OSError, ValueError):
    rows = {}
for row, r in rows.items():
    name, _, t = row.rpartition("@t")
    if not name:
        name, t = row, str(r["threads"])
    m = apply["models"].setdefault(name, {"triangles": r["triangles"], "splits": r["splits"],
                                          "records_ms": r["records_ms"], "splits_ms": {},
                                          "splits_ms_min": {}, "over_one_thread": {},
                                          "alone_runs": {}, "cpu_ms": {},
                                          "decode_cpu_ms": {}, "balanced_over_one": {},
                                          "over_one_paired": {}})
    m["splits_ms"][t] = r["splits_ms"]
    m["splits_ms_min"][t] = r["splits_ms_min"]
    m["alone_runs"][t] = r.get("alone_runs")
    m["cpu_ms"][t] = r.get("cpu_ms")
    m["decode_cpu_ms"][t] = r.get("decode_cpu_ms")
    # T over one thread run by run (counts alternate from 1): q1, median, q3
    m["over_one_paired"][t] = r.get("over_first_paired") if counts[0] == "1" else None
for m in apply["models"].values():
    one = m["splits_ms"].get("1")
    for t, ms in m["splits_ms"].items():
        m["over_one_thread"][t] = round(ms / one, 3) if one else None
        # the work of all T threads spread evenly over them, against one
        # thread: no schedule of that work on T cores does better
        cpu = m["cpu_ms"].get(t)
        m["balanced_over_one"][t] = round(cpu / int(t.rstrip("k")) / one, 3) if one and cpu else None
res["apply"] = apply


def paired_cell(q):
    return f"{q[1]:.2f} [{q[0]:.2f}-{q[2]:.2f}]" if q else "-"


print(f"\nThreads: apply time against the decoder's threads (mts-bench-apply, splits form, "
      f"median of {runs}, counts alternated in each run; {procs} processors online)")
hdr = f"{'model':<14} {'triangles':>9} {'splits':>8} " + " ".join(
    f"{f'{t} thr ms':>10}" for t in counts) + " " + " ".join(
    f"{f'{t}/1':>6}" for t in counts[1:]) + " " + " ".join(
    f"{f'{t} even':>6}" for t in counts[1:]) + " " + " ".join(
    f"{f'{t}/1 by run':>15}" for t in counts[1:]) + f" {'records ms':>10} {'alone':>5}"
print(hdr)
print("-" * len(hdr))
for name, m in apply["models"].items():
    print(f"{name:<14} {m['triangles']:>9} {m['splits']:>8} " + " ".join(
        f"{m['splits_ms'].get(str(t), float('nan')):>10.2f}" for t in counts) + " " + " ".join(
        f"{m['over_one_thread'].get(str(t)) or float('nan'):>6.2f}" for t in counts[1:]) + " " +
        " ".join(f"{m['balanced_over_one'].get(str(t)) or float('nan'):>6.2f}"
                 for t in counts[1:]) + " " +
        " ".join(f"{paired_cell(m['over_one_paired'].get(str(t))):>15}" for t in counts[1:]) +
        f" {m['records_ms']:>10.2f} {m['alone_runs'].get('2') or 0:>5}")
print(("  (Tk: T threads with growth cut at its keys, the layout --threads T no longer takes "
       "(it decodes as two): docs/threads.md, \"Three threads or more\";\n   "
       if any(t.endswith("k") for t in counts) else "  (") +
      "T even: the processor time of all T threads, spread evenly over T cores, over one "
      "thread's time: the least any schedule of that work could take;\n"
      "   T/1 by run: T threads over one within each run, median [quartiles]: the spread is "
      "the noise the medians' ratio carries)")
for name, why in skipped.items():
    if not name.startswith(("stream", "draco")):
        print(f"{name:<14} skipped: {why}")

# 1b. the same with every other core busy
try:
    with open(os.path.join(d, "apply_busy.json")) as f:
        rows = json.load(f)["models"]
except (OSError, ValueError):
    rows = None
if rows is not None:
    busy = {"runs": int(runs), "busy_cores": int(procs) - 1, "models": {}}
    for row, r in rows.items():
        name, _, t = row.rpartition("@t")
        m = busy["models"].setdefault(name, {"splits_ms": {}, "alone_runs": {}})
        m["splits_ms"][t] = r["splits_ms"]
        m["alone_runs"][t] = r.get("alone_runs")
    for m in busy["models"].values():
        one, two = m["splits_ms"].get("1"), m["splits_ms"].get("2")
        m["two_over_one"] = round(two / one, 3) if one and two else None
    res["apply_busy"] = busy
    print(f"\nThreads with {int(procs) - 1} of {procs} cores held by busy loops "
          f"(mts-bench-apply --threads 1,2, median of {runs})")
    print(f"{'model':<14} {'1 thr ms':>10} {'2 thr ms':>10} {'2/1':>6} {'alone':>5}")
    for name, m in busy["models"].items():
        print(f"{name:<14} {m['splits_ms'].get('1', float('nan')):>10.2f} "
              f"{m['splits_ms'].get('2', float('nan')):>10.2f} "
              f"{m['two_over_one'] or float('nan'):>6.2f} {m['alone_runs'].get('2') or 0:>5}")
print(f"  (alone: of the {runs} timed runs at 2 threads, those that went on as one thread, "
      "finding the pool thread without a core)")

# 2. time to the full picture at a rate
runs_by = {}
for l in lines("stream.txt"):
    rate, way, run, js = l.split(" ", 3)
    try:
        runs_by.setdefault(rate, {}).setdefault(way, []).append(json.loads(js))
    except ValueError:
        pass
drc = {}
for l in lines("draco.txt"):
    rate, way, run, s = l.split()
    drc.setdefault(rate, {}).setdefault(way, []).append(float(s) * 1e3)
dec = [l.split() for l in lines("decode.txt")]
dec_ms = med([float(a) for a, _ in dec if a != "none"])
dec_wall_ms = med([float(b) * 1e3 for _, b in dec])
drc_bytes = None
try:
    drc_bytes = os.path.getsize(os.path.join(d, "www", smodel + ".drc"))
except OSError:
    pass
how = (lines("how") or ["pace"])[0]
stream = {"model": smodel, "runs": int(sruns), "rates": {},
          "paced_by": {"link": "a link: a network namespace whose loopback Linux's tbf qdisc "
                               "shapes to the rate (MTU 1500), mts-server and nginx unpaced",
                       "pace": "mts-server --rate-limit (the rate from the first byte, 5 ms "
                               "quanta) and nginx limit_rate (the first second's bytes at once)"}[how],
          "draco": {"bytes": drc_bytes, "encoder": "draco_encoder -cl 7 -qp 14",
                    "decode_ms": dec_ms, "decoder_process_ms": dec_wall_ms}}
for rate in sorted(set(runs_by) | set(drc), key=float):
    mbit = float(rate) * 8 / 1e6
    e = {"bytes_per_s": float(rate)}
    for way, rs in runs_by.get(rate, {}).items():
        e[way] = {"first_ms": med([r.get("ms_base") for r in rs]),
                  "full_ms": med([r.get("ms_final") for r in rs]),
                  "apply_ms": med([r.get("ms_apply") for r in rs]),
                  "bytes": med([r.get("bytes") for r in rs]),
                  "threads": rs[0].get("threads"), "form": rs[0].get("form"),
                  "complete": all(r.get("complete") for r in rs),
                  "checksums": sorted({r.get("checksum") for r in rs if r.get("checksum")}),
                  "alone_runs": sum(1 for r in rs if r.get("threads_alone_from")),
                  "runs": len(rs)}
    dr = drc.get(rate, {})
    if dr or drc_bytes:
        got = dr.get(how, [])
        e["draco"] = {"download_ms_measured": med(got), "runs": len(got),
                      "download_ms_link": drc_bytes / float(rate) * 1e3 if drc_bytes else None}
        for way in ("measured", "link"):
            v = e["draco"]["download_ms_" + way]
            e["draco"]["full_ms_" + way] = v + dec_ms if v is not None and dec_ms is not None else None
    stream["rates"][f"{mbit:g}Mbit"] = e
stream["same_checksum"] = len({c for e in stream["rates"].values() for w in e.values()
                                if isinstance(w, dict) for c in w.get("checksums", [])}) <= 1
res["stream"] = stream
fmt = lambda v, p=1: f"{v:.{p}f}" if isinstance(v, (int, float)) else "-"
print(f"\nThreads: time to the full picture, {smodel} from mts-server over loopback ({how}), "
      f"fresh mts-client --no-render, median of {sruns} interleaved; Draco {drc_bytes} B "
      f"(cl 7, 14 bits) by curl from nginx, plus draco_decoder's {fmt(dec_ms)} ms")
print(f"{'rate':<9} {'way':<15} {'thr':>3} {'bytes':>9} {'link ms':>8} {'first ms':>9} "
      f"{'full ms':>9} {'apply ms':>9} {'vs t1':>6} {'alone':>5}")
print("-" * 91)
for key, e in stream["rates"].items():
    t1 = e.get("splits_t1", {}).get("full_ms")
    for way in ("splits_t1", "splits_default", "records"):
        r = e.get(way)
        if not r:
            continue
        link = r["bytes"] / e["bytes_per_s"] * 1e3 if r["bytes"] else None
        print(f"{key:<9} {way:<15} {r['threads'] or '-':>3} {fmt(r['bytes'], 0):>9} "
              f"{fmt(link):>8} {fmt(r['first_ms']):>9} {fmt(r['full_ms']):>9} {fmt(r['apply_ms']):>9} "
              f"{fmt(r['full_ms'] / t1 if t1 and r['full_ms'] else None, 2):>6} "
              f"{r['alone_runs'] if r['threads'] == 2 else '':>5}")
    dr = e.get("draco")
    for way, label in (("measured", "draco " + how), ("link", "draco computed")):
        v = dr and dr.get("full_ms_" + way)
        if v is not None:
            print(f"{key:<9} {label:<15} {'':>3} {fmt(drc_bytes, 0):>9} "
                  f"{fmt(dr.get('download_ms_link')):>8} {'':>9} {fmt(v):>9} "
                  f"{'':>9} {fmt(v / t1 if t1 else None, 2):>6}")
print("  (link ms: the bytes over the rate; first: ms_base, the base drawn; full: ms_final; "
      "Draco's full: download + decode. Paced by " + stream["paced_by"] + "; draco "
      + how + ": curl's download measured so, draco computed: the bytes over the rate)")
for name, why in skipped.items():
    if name.startswith(("stream", "draco")):
        print(f"{name}: skipped: {why}")

with open(dest + ".tmp", "w") as f:
    json.dump(res, f, indent=2)
    f.write("\n")
os.replace(dest + ".tmp", dest)
PY
exit "$status"
