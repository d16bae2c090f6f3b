#!/usr/bin/env bash
# Part of `make bench`: mts-server under many clients, beside nginx
# serving the same bytes as a static file to the same number of connections,
# both measured by the same client (mts-stress; --http for nginx) on this
# machine. Writes $1/stress.json; bench/run.sh merges and prints it.
#
#   throughput: 100, 1,000 and 10,000 clients each fetch bunny00's full stream
#     once (mts-stress --no-apply: the clients only walk the frames, so the
#     figures are the servers'); 3 runs each, the median by MB/s is kept;
#     server CPU seconds and peak resident memory come from /proc.
#   concurrency: 10,000 clients held open at once (streams paced with
#     --rate-limit), the server's resident memory before and at the peak.
set -uo pipefail
cd "$(dirname "$0")/.." || exit 1
out="${1:-bench/out}"
shared="${MTS_SHARED:-../shared}"
runs="${MTS_BENCH_STRESS_RUNS:-3}"
json="$out/stress.json"
mkdir -p "$out"
out=$(cd "$out" && pwd) # nginx wants absolute paths
: >"$out/stress.lines"

skip() {
  printf '{"skipped": "%s"}\n' "$1" >"$json"
  echo "bench: stress skipped: $1" >&2
  exit 0
}
[ -f "$shared/models/bunny00.off" ] || skip "$shared/models/bunny00.off not found"
ulimit -n "$(ulimit -Hn)" 2>/dev/null
[ "$(ulimit -n)" -ge 10100 ] || skip "open-file limit $(ulimit -n) is below the 10,100 that 10,000 clients need"

dir="$out/stress_models"
mkdir -p "$dir"
# a model kept from an earlier run is reused only if this build still loads it
# (the file format has a version) and it is newer than the builder (a builder
# that orders splits otherwise makes other streams of the same format)
if [ -f "$dir/bunny00.mtsm" ] && { ! build/bin/mts-inspect "$dir/bunny00.mtsm" >/dev/null 2>&1 ||
  [ build/bin/mts-build -nt "$dir/bunny00.mtsm" ]; }; then
  rm -f "$dir/bunny00.mtsm"
fi
[ -f "$dir/bunny00.mtsm" ] || build/bin/mts-build "$shared/models/bunny00.off" -o "$dir/bunny00.mtsm" --quiet ||
  skip "mts-build failed"

free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }
wait_port() {
  for _ in $(seq 1 200); do
    python3 -c "import socket,sys; socket.create_connection(('127.0.0.1',$1),1)" 2>/dev/null && return 0
    sleep 0.05
  done
  return 1
}

# /proc figures of a process: CPU seconds (user+system) and resident KiB
cpu_s() { awk -v hz="$(getconf CLK_TCK)" '{ printf "%.3f", ($14 + $15) / hz }' "/proc/$1/stat"; }
rss_kb() { awk '/^VmRSS/ { print $2 }' "/proc/$1/status"; }

# Samples a process's resident memory every 20 ms into a file (max wins).
sample_rss() {
  local pid=$1 file=$2 max=0 r
  while kill -0 "$pid" 2>/dev/null; do
    r=$(rss_kb "$pid" 2>/dev/null) || break
    # written aside and renamed: killed mid-write, it must not leave the
    # file empty for measure() to read
    [ -n "$r" ] && [ "$r" -gt "$max" ] && { max=$r; echo "$max" >"$file.new" && mv "$file.new" "$file"; }
    sleep 0.02
  done
}

# one measured run: server name, pid, clients, then the mts-stress arguments
measure() {
  local name=$1 pid=$2 clients=$3
  shift 3
  local cpu0 cpu1 peak result
  echo 0 >"$out/rss.peak"
  sample_rss "$pid" "$out/rss.peak" &
  local sampler=$!
  cpu0=$(cpu_s "$pid")
  result=$(build/bin/mts-stress "$@" --clients "$clients" --no-apply --json --io-timeout 60 2>/dev/null)
  cpu1=$(cpu_s "$pid")
  kill "$sampler" 2>/dev/null
  wait "$sampler" 2>/dev/null
  peak=$(cat "$out/rss.peak" 2>/dev/null)
  [ -n "$peak" ] || peak=null
  [ -n "$result" ] || result='{"clients": '"$clients"', "succeeded": 0, "failed": '"$clients"'}'
  printf '{"server": "%s", "server_cpu_s": %s, "server_peak_rss_kb": %s, "stress": %s}\n' \
    "$name" "$(awk -v a="$cpu0" -v b="$cpu1" 'BEGIN { printf "%.3f", b - a }')" "$peak" "$result" \
    >>"$out/stress.lines"
}

pids=()
cleanup() { for p in "${pids[@]}"; do kill -TERM "$p" 2>/dev/null; wait "$p" 2>/dev/null; done; }
trap cleanup EXIT

mport=$(free_port)
build/bin/mts-server --models "$dir" --listen "127.0.0.1:$mport" --max-clients 20000 --quiet \
  2>"$out/stress_server.log" &
mpid=$!
pids+=("$mpid")
wait_port "$mport" || skip "mts-server did not start: $(tail -n 1 "$out/stress_server.log")"
idle_kb=$(rss_kb "$mpid")

# the same bytes for nginx: one client's whole stream, as a file
one=$(build/bin/mts-stress "127.0.0.1:$mport" bunny00 --no-apply --json)
bytes=$(printf '%s' "$one" | python3 -c 'import json,sys; print(json.load(sys.stdin)["bytes"])')
www="$out/stress_www"
mkdir -p "$www" "$out/nginx/tmp"
head -c "$bytes" /dev/urandom >"$www/bunny00.stream"

nginx_note=""
nport=""
if ! command -v nginx >/dev/null && [ ! -x /usr/sbin/nginx ]; then
  nginx_note="nginx not installed (Debian nginx-light)"
else
  nginx_bin=$(command -v nginx || echo /usr/sbin/nginx)
  nport=$(free_port)
  sed -e "s#@PORT@#$nport#g" -e "s#@ROOT@#$www#g" -e "s#@PREFIX@#$out/nginx#g" \
    bench/nginx-static.conf >"$out/nginx/nginx.conf"
  "$nginx_bin" -c "$out/nginx/nginx.conf" -p "$out/nginx" 2>"$out/nginx/stderr.log" &
  npid=$!
  pids+=("$npid")
  wait_port "$nport" || { nginx_note="nginx did not start: $(tail -n 1 "$out/nginx/stderr.log")"; nport=""; }
fi

for clients in 100 1000 10000; do
  for _ in $(seq 1 "$runs"); do
    echo "bench: stress $clients clients: mts-server ..." >&2
    measure mts-server "$mpid" "$clients" "127.0.0.1:$mport" bunny00
    if [ -n "$nport" ]; then
      echo "bench: stress $clients clients: nginx ..." >&2
      measure nginx "$npid" "$clients" "127.0.0.1:$nport" --http /bunny00.stream
    fi
  done
done
kill -TERM "$mpid" 2>/dev/null
wait "$mpid" 2>/dev/null

# 10,000 at once: paced so that every stream is still open when the last
# client connects; the server reports its peak in a stats line
cport=$(free_port)
build/bin/mts-server --models "$dir" --listen "127.0.0.1:$cport" --max-clients 20000 \
  --rate-limit 20000 --stats-interval 1 2>"$out/stress_concurrent.log" &
cpid=$!
pids+=("$cpid")
wait_port "$cport"
cidle_kb=$(rss_kb "$cpid")
echo "bench: 10,000 concurrent clients (paced streams, ~15 s) ..." >&2
measure concurrent "$cpid" 10000 "127.0.0.1:$cport" bunny00 --fraction 0.1
kill -TERM "$cpid" 2>/dev/null
wait "$cpid" 2>/dev/null
peak_conns=$(grep -o 'peak=[0-9]*' "$out/stress_concurrent.log" | tail -n 1 | cut -d= -f2)

python3 - "$out/stress.lines" "$json" "$bytes" "$idle_kb" "$cidle_kb" "${peak_conns:-0}" "$nginx_note" <<'PY'
import json, sys
lines, out, stream_bytes, idle_kb, cidle_kb, peak, nginx_note = sys.argv[1:8]
rows = [json.loads(l) for l in open(lines) if l.strip()]
res = {"stream_bytes": int(stream_bytes), "model": "bunny00", "mode": "no-apply",
       "runs_per_point": 0, "throughput": [], "nginx": nginx_note or "nginx 1 worker, sendfile"}
def median(rs):
    rs = sorted(rs, key=lambda r: r["stress"].get("mb_per_s", 0))
    return rs[len(rs) // 2]
for clients in (100, 1000, 10000):
    point = {"clients": clients}
    for name in ("mts-server", "nginx"):
        rs = [r for r in rows if r["server"] == name and r["stress"].get("clients") == clients]
        if not rs:
            continue
        res["runs_per_point"] = len(rs)
        m = median(rs)
        s = m["stress"]
        point[name] = {"mb_per_s": s.get("mb_per_s"), "p99_ms_final": s.get("p99_ms_final"),
                       "p50_ms_final": s.get("p50_ms_final"), "succeeded": s.get("succeeded"),
                       "failed": s.get("failed"), "failures": s.get("failures"),
                       "server_cpu_s": m["server_cpu_s"],
                       "server_peak_rss_mb": round(m["server_peak_rss_kb"] / 1024, 1),
                       "client_cpu_s": s.get("cpu_s")}
    if "mts-server" in point and "nginx" in point and point["nginx"]["mb_per_s"]:
        point["ratio_mts_to_nginx"] = round(point["mts-server"]["mb_per_s"] / point["nginx"]["mb_per_s"], 3)
    res["throughput"].append(point)
conc = [r for r in rows if r["server"] == "concurrent"]
if conc:
    c = conc[0]
    grow = (c["server_peak_rss_kb"] - int(cidle_kb)) * 1024.0
    res["concurrent"] = {"clients": 10000, "peak_connections": int(peak),
                         "succeeded": c["stress"].get("succeeded"), "failed": c["stress"].get("failed"),
                         "server_idle_rss_mb": round(int(cidle_kb) / 1024, 1),
                         "server_peak_rss_mb": round(c["server_peak_rss_kb"] / 1024, 1),
                         "bytes_per_connection": round(grow / max(int(peak), 1)),
                         "p99_ms_final": c["stress"].get("p99_ms_final"),
                         "how": "--rate-limit 20000 --fraction 0.1: every stream stays open ~10 s"}
json.dump(res, open(out, "w"), indent=2)
PY
