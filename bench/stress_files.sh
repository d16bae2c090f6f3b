#!/usr/bin/env bash
# Part of `make bench`: many applying clients of one model read from a
# stream file on nginx (docker/nginx-tls.conf, over http and over https with
# HTTP/2) beside the same number streamed by mts-server over TCP, by the
# same client (mts-stress --verify: every client decodes and applies, and
# its end is checked), in the same run, on loopback. Each file client is its
# own user: its own connection, never shared or multiplexed with another's
# (stress.h). Per way: wall time, clients/s, failures, the end reached (all
# three must agree), mts-stress's own CPU and peak resident memory, and the
# CPU seconds the server (nginx, or mts-server) spent, from /proc. Ways are
# interleaved when there are several runs; the median run by wall time is
# kept. Writes $1/stress_files.json; bench/run.sh merges and prints it.
#
# Environment: MTS_BENCH_FILES_CLIENTS (default 1000) clients a run,
# MTS_BENCH_FILES_MODEL (default cow: a thousand applying clients of
# bunny00 take minutes of CPU on two cores) and MTS_BENCH_FILES_STRESS_RUNS
# (default 1); MTS_BIN (default build/bin) the programs.
set -uo pipefail
cd "$(dirname "$0")/.." || exit 1
out="${1:-bench/out}"
shared="${MTS_SHARED:-../shared}"
clients="${MTS_BENCH_FILES_CLIENTS:-1000}"
model="${MTS_BENCH_FILES_MODEL:-cow}"
runs="${MTS_BENCH_FILES_STRESS_RUNS:-1}"
bin="${MTS_BIN:-build/bin}" # the programs measured
json="$out/stress_files.json"
mkdir -p "$out"
out=$(cd "$out" && pwd) # nginx wants absolute paths

skip() {
  printf '{"skipped": "%s"}\n' "$1" >"$json"
  echo "bench: stream-file stress skipped: $1" >&2
  exit 0
}
mesh="$shared/models/$model.off"
[ "$model" = cow ] && [ ! -f "$mesh" ] && mesh=tests/data/cow.off
[ -f "$mesh" ] || skip "$mesh not found"
. bench/tls_front.sh
missing=$(tls_front_missing) && skip "$missing"
ulimit -n "$(ulimit -Hn)" 2>/dev/null
[ "$(ulimit -n)" -ge $((clients + 200)) ] ||
  skip "open-file limit $(ulimit -n) is below the $((clients + 200)) that $clients clients need"

dir="$out/stress_files"
rm -rf "$dir"
mkdir -p "$dir/www" "$dir/models"
$bin/mts-build "$mesh" -o "$dir/models/$model.mtsm" --stream "$dir/www/$model.mts" \
  --quiet || skip "mts-build failed"

tls_front_ca "$dir" || skip "openssl could not make a certificate"

cpu_s() { awk -v hz="$(getconf CLK_TCK)" '{ printf "%.3f", ($14 + $15) / hz }' "/proc/$1/stat"; }

tcp=$(free_port) http=$(free_port) https=$(free_port) tls=$(free_port)
$bin/mts-server --models "$dir/models" --listen "127.0.0.1:$tcp" --quiet 2>"$dir/server.log" &
server=$!
tls_front_conf "$dir" "$dir/www" "$http" "$https" "$tls" "$tcp" quiet
tls_front_start "$dir"
front=$TLS_FRONT_PID
stop() {
  kill -TERM "$front" "$server" 2>/dev/null
  wait "$front" "$server" 2>/dev/null
}
for p in "$tcp" "$http" "$https" "$tls"; do
  wait_port "$p" || { stop; skip "mts-server or nginx did not listen (see $dir/*.log)"; }
done
for _ in $(seq 1 300); do
  $bin/mts-client "127.0.0.1:$tcp" --list 2>/dev/null | grep -q "$model" && break
  sleep 0.1
done

declare -A how=(
  [tcp]="127.0.0.1:$tcp $model"
  [http]="http://127.0.0.1:$http/$model.mts"
  [https]="https://127.0.0.1:$https/$model.mts --cacert $dir/ca.pem"
)
declare -A pid_of=([tcp]=$server [http]=$front [https]=$front)
status=0
: >"$dir/runs.jsonl"
for _ in $(seq 1 "$runs"); do
  for way in tcp http https; do
    p=${pid_of[$way]}
    c0=$(cpu_s "$p")
    t0=$EPOCHREALTIME
    # shellcheck disable=SC2086 # the way's words are separate arguments
    r=$($bin/mts-stress ${how[$way]} --clients "$clients" --verify --json \
      --connect-timeout 30 --io-timeout 60 2>>"$dir/stress.log") || status=1
    t1=$EPOCHREALTIME
    c1=$(cpu_s "$p")
    printf '{"way": "%s", "wall_s": %s, "server_cpu_s": %s, "run": %s}\n' "$way" \
      "$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f", b - a }')" \
      "$(awk -v a="$c0" -v b="$c1" 'BEGIN { printf "%.3f", b - a }')" "${r:-null}" \
      >>"$dir/runs.jsonl"
  done
done
stop

python3 - "$dir/runs.jsonl" "$json" "$model" "$clients" "$dir/www/$model.mts" <<'PY' || status=1
import json, os, statistics, sys
runs = [json.loads(l) for l in open(sys.argv[1])]
res = {"model": sys.argv[3], "clients": int(sys.argv[4]), "runs_per_way": 0,
       "file_bytes": os.path.getsize(sys.argv[5]), "ways": {}}
for way in ("tcp", "http", "https"):
    rs = [r for r in runs if r["way"] == way]
    res["runs_per_way"] = max(res["runs_per_way"], len(rs))
    ok = [r for r in rs if r["run"]]
    if not ok:
        res["ways"][way] = {"error": "mts-stress printed nothing (see stress.log)"}
        continue
    ok.sort(key=lambda r: r["wall_s"])
    m = ok[len(ok) // 2]
    s = m["run"]
    res["ways"][way] = {
        "server": "mts-server" if way == "tcp" else "nginx",
        "wall_s": m["wall_s"],
        "seconds": s["seconds"],
        "clients_per_s": round(s["succeeded"] / s["seconds"], 1) if s["seconds"] else 0,
        "succeeded": s["succeeded"],
        "failed": s["failed"],
        "failures": s["failures"],
        "bytes": s["bytes"],
        "p50_ms_final": s["p50_ms_final"],
        "p99_ms_final": s["p99_ms_final"],
        "level": s.get("level"),
        "checksum": s.get("checksum"),
        "ended_elsewhere": s.get("ended_elsewhere"),
        "stress_cpu_s": s["cpu_s"],
        "stress_max_rss_kb": s.get("max_rss_kb"),
        "server_cpu_s": m["server_cpu_s"],
    }
ends = {(w["level"], w["checksum"]) for w in res["ways"].values() if "checksum" in w}
res["same_end"] = len(ends) == 1
json.dump(res, open(sys.argv[2], "w"), indent=1)
bad = any(w.get("failed", 1) or w.get("ended_elsewhere") for w in res["ways"].values())
sys.exit(1 if bad or not res["same_end"] else 0)
PY
exit $status
