#!/usr/bin/env bash
# Part of `make bench`: bunny00 read from a stream file on nginx (docker/
# nginx-tls.conf: over http, and over https with HTTP/2) beside mts-server
# over TCP and TCP through nginx's TLS terminator, by the same client
# (mts-client --no-render --json), in the same run, on loopback. Runs are
# interleaved (one of each way in turn) so that drift hits all alike;
# medians of first picture (the base drawn: ms_base), full level (ms_final)
# and bytes. Also the file's index: its bytes beside the stream's. Writes
# $1/files.json; bench/run.sh merges and prints it.
set -uo pipefail
cd "$(dirname "$0")/.." || exit 1
out="${1:-bench/out}"
shared="${MTS_SHARED:-../shared}"
runs="${MTS_BENCH_FILES_RUNS:-9}"
json="$out/files.json"
mkdir -p "$out"
out=$(cd "$out" && pwd) # nginx wants absolute paths

skip() {
  printf '{"skipped": "%s"}\n' "$1" >"$json"
  echo "bench: stream files skipped: $1" >&2
  exit 0
}
. bench/tls_front.sh
[ -f "$shared/models/bunny00.off" ] || skip "$shared/models/bunny00.off not found"
missing=$(tls_front_missing) && skip "$missing"

dir="$out/files"
rm -rf "$dir"
mkdir -p "$dir/www" "$dir/models"
build/bin/mts-build "$shared/models/bunny00.off" -o "$dir/models/bunny00.mtsm" \
  --stream "$dir/www/bunny00.mts" --json --quiet >"$dir/build.json" || skip "mts-build failed"
tls_front_ca "$dir" || skip "openssl could not make a certificate"

tcp=$(free_port) http=$(free_port) https=$(free_port) tls=$(free_port)
build/bin/mts-server --models "$dir/models" --listen "127.0.0.1:$tcp" --quiet 2>"$dir/server.log" &
server=$!
tls_front_conf "$dir" "$dir/www" "$http" "$https" "$tls" "$tcp"
tls_front_start "$dir"
front=$TLS_FRONT_PID
stop() {
  kill -TERM "$front" "$server" 2>/dev/null
  wait "$front" "$server" 2>/dev/null
}
for p in "$tcp" "$http" "$https" "$tls"; do
  wait_port "$p" || { stop; skip "mts-server or nginx did not listen (see $dir/*.log)"; }
done
for _ in $(seq 1 300); do # the server builds nothing here, but loads the model
  build/bin/mts-client "127.0.0.1:$tcp" --list 2>/dev/null | grep -q bunny00 && break
  sleep 0.1
done

declare -A how=(
  [tcp]="127.0.0.1:$tcp bunny00"
  [tls]="127.0.0.1:$tls bunny00 --tls --cacert $dir/ca.pem"
  [http]="http://127.0.0.1:$http/bunny00.mts"
  [https]="https://127.0.0.1:$https/bunny00.mts --cacert $dir/ca.pem"
)
status=0
: >"$dir/runs.jsonl"
for stop_args in "" "--fraction 0.25"; do
  for _ in $(seq 1 "$runs"); do
    for way in tcp tls http https; do
      # shellcheck disable=SC2086 # the way's words are separate arguments
      r=$(build/bin/mts-client ${how[$way]} $stop_args --no-render --json 2>>"$dir/client.log") ||
        status=1
      printf '{"way": "%s", "stop": "%s", "run": %s}\n' "$way" "${stop_args:-full}" "${r:-null}" \
        >>"$dir/runs.jsonl"
    done
  done
done
stop

python3 - "$dir/runs.jsonl" "$dir/build.json" "$json" "$dir/www/bunny00.mts" <<'PY' || status=1
import json, statistics, struct, sys
runs = [json.loads(l) for l in open(sys.argv[1])]
build = json.load(open(sys.argv[2]))
res = {"model": "bunny00", "runs": 0, "stops": {}}
for stop in ("full", "--fraction 0.25"):
    table = {}
    for way in ("tcp", "tls", "http", "https"):
        rs = [r["run"] for r in runs if r["way"] == way and r["stop"] == stop and r["run"]]
        ok = [r for r in rs if r.get("complete")]
        res["runs"] = max(res["runs"], len(rs))
        if not ok:
            table[way] = {"failed": len(rs)}
            continue
        table[way] = {
            "first_ms": statistics.median(r["ms_base"] for r in ok),
            "full_ms": statistics.median(r["ms_final"] for r in ok),
            "bytes": statistics.median(r["bytes"] for r in ok),
            "level": ok[0]["level"],
            "checksum": ok[0]["checksum"],
            "same_checksum": len({r["checksum"] for r in ok}) == 1,
            "failed": len(rs) - len(ok),
        }
    res["stops"][stop] = table
sf = build.get("stream_file", {})
res["file_bytes"] = sf.get("bytes")
res["index_bytes"] = sf.get("index_bytes")
# Before the first picture a file reader has the header, MODEL_INFO, the table
# and BASE; a TCP client MODEL_INFO and BASE: the difference is the header and
# the table (PROTOCOL.md, "Stream files")
with open(sys.argv[4], "rb") as f:
    head = f.read(32)
info_size, table_size = struct.unpack_from("<II", head, 8)
res["first_picture_extra_bytes"] = 32 + table_size
json.dump(res, open(sys.argv[3], "w"), indent=1)
PY
exit $status
