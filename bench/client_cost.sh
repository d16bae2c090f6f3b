#!/usr/bin/env bash
# The client's cost figures of `make bench`, into OUT/client.json:
#   - both stream forms applied in one process, warm (mts-bench-apply): ms,
#     splits/s, ratio, ns per split against the mesh's size;
#   - the same as fresh mts-client processes over loopback (median of 5 each);
#   - mts-server's time to listen and to have each model's stream ready,
#     each model served alone from its .mtsm;
#   - frames/s of mts-client --window under Xvfb (800x600) while bunny00
#     streams (median of 5);
#   - 1,000 applying mts-stress clients of bunny00: failures, wall, CPU.
# Usage: bench/client_cost.sh OUT MODEL.mtsm... (the big mesh's model last,
# or none). Skips what it cannot run, with the reason in the JSON.
set -uo pipefail
cd "$(dirname "$0")/.." || exit 1
out=$1
shift
models=("$@")
bin=build/bin
status=0
now() { printf '%s\n' "$EPOCHREALTIME"; }
elapsed() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.3f", b - a }'; }
free_port() { echo $((20000 + RANDOM % 20000)); }
# whatever this script started goes with it, interrupted or not
pids=()
trap 'kill -TERM "${pids[@]}" 2>/dev/null' EXIT
rm -rf "$out/client"
mkdir -p "$out/client"
: >"$out/client/fresh.txt"
: >"$out/client/ready.txt"
: >"$out/client/window.txt"
: >"$out/client/notes.txt"

# --- warm, in one process ---------------------------------------------------
$bin/mts-bench-apply "${models[@]}" --runs 7 --json "$out/client/warm.json" || status=1

name_of() { local b; b=$(basename "$1"); echo "${b%.*}"; }

# --- server ready, each model alone -------------------------------------------
for m in "${models[@]}"; do
  name=$(name_of "$m")
  port=$(free_port)
  t0=$(now)
  $bin/mts-server --model "$name=$m" --listen "127.0.0.1:$port" --quiet 2>"$out/client/server_$name.log" &
  pid=$!
  pids+=("$pid")
  listen=""
  ready=""
  for _ in $(seq 1 1200); do # up to 60 s
    list=$($bin/mts-client "127.0.0.1:$port" --list 2>/dev/null) || { sleep 0.05; continue; }
    [ -n "$listen" ] || listen=$(elapsed "$t0" "$(now)")
    bytes=$(printf '%s\n' "$list" | awk -v n="$name" '$1 == n { print $(NF-2) }')
    if [ -n "$bytes" ] && [ "$bytes" != 0 ]; then
      ready=$(elapsed "$t0" "$(now)")
      break
    fi
    sleep 0.05
  done
  kill -TERM "$pid" 2>/dev/null
  wait "$pid" 2>/dev/null
  echo "$name ${listen:-none} ${ready:-none}" >>"$out/client/ready.txt"
  [ -n "$ready" ] || { echo "ready: $name's stream not ready in 60 s" >>"$out/client/notes.txt"; status=1; }
done

# --- fresh client processes over loopback, one server with every model ------
dir="$out/client/models"
rm -rf "$dir"
mkdir -p "$dir"
for m in "${models[@]}"; do ln -sf "$(realpath "$m")" "$dir/$(name_of "$m").mtsm"; done
port=$(free_port)
$bin/mts-server --models "$dir" --listen "127.0.0.1:$port" --quiet 2>"$out/client/server.log" &
server=$!
pids+=("$server")
wait_ready() { # every model's stream encoded (LIST stream_bytes > 0)
  for _ in $(seq 1 1200); do
    list=$($bin/mts-client "127.0.0.1:$port" --list 2>/dev/null) &&
      ! printf '%s\n' "$list" | awk '{ print $(NF-2) }' | grep -qx 0 && return 0
    sleep 0.05
  done
  return 1
}
wait_ready || { echo "server: streams not ready in 60 s" >>"$out/client/notes.txt"; status=1; }
# the records forms come after the splits forms, and until then a records
# HELLO gets the splits form: wait until a level-0 request gets records
records_ready() {
  for _ in $(seq 1 1200); do
    $bin/mts-client "127.0.0.1:$port" "$1" --records --level 0 --no-render --json 2>/dev/null |
      grep -q '"form":"records"' && return 0
    sleep 0.05
  done
  return 1
}
for m in "${models[@]}"; do
  name=$(name_of "$m")
  records_ready "$name" || { echo "fresh: $name's records form not ready in 60 s" >>"$out/client/notes.txt"; status=1; }
  for form in splits records; do
    flag=""
    [ "$form" = records ] && flag=--records
    for _ in 1 2 3 4 5; do
      t0=$(now)
      if line=$(timeout 120 $bin/mts-client "127.0.0.1:$port" "$name" --no-render --json $flag \
        2>>"$out/client/fresh.err"); then
        echo "$name $form $(elapsed "$t0" "$(now)") $line" >>"$out/client/fresh.txt"
      else
        echo "fresh: $name $form: $(tail -n 1 "$out/client/fresh.err")" >>"$out/client/notes.txt"
        status=1
      fi
    done
  done
done

# --- the window while bunny00 streams -----------------------------------------
if [ -f "$dir/bunny00.mtsm" ]; then
  if command -v xvfb-run >/dev/null; then
    printf '4 key q\n' >"$out/client/window_script.txt"
    for _ in 1 2 3 4 5; do
      timeout 120 xvfb-run -a -s "-screen 0 1024x768x24" $bin/mts-client "127.0.0.1:$port" bunny00 --window \
        --size 800x600 --script "$out/client/window_script.txt" --json \
        >>"$out/client/window.txt" 2>>"$out/client/window.err" || status=1
    done
  else
    echo "window: xvfb-run not installed (Debian xvfb)" >>"$out/client/notes.txt"
  fi

  # --- a thousand applying clients ---------------------------------------------
  n=${MTS_BENCH_APPLYING_CLIENTS:-1000}
  if [ "$n" -gt 0 ]; then
    echo "bench: $n applying mts-stress clients of bunny00 (a minute or two) ..." >&2
    timeout 1200 $bin/mts-stress "127.0.0.1:$port" bunny00 --clients "$n" --json \
      >"$out/client/stress.json" 2>"$out/client/stress.err" ||
      { echo "stress: $(tail -n 1 "$out/client/stress.err")" >>"$out/client/notes.txt"; status=1; }
  fi
fi
kill -TERM "$server" 2>/dev/null
wait "$server" 2>/dev/null
exit "$status"
