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
[ -f "$shared/models/bunny00.off" ] || skip "$shared/models/bunny00.off not found"
nginx=$(command -v nginx || echo /usr/sbin/nginx)
[ -x "$nginx" ] || skip "nginx is not installed (scripts/deps.sh)"
[ -f /usr/lib/nginx/modules/ngx_stream_module.so ] || skip "nginx's stream module is not installed"
command -v openssl >/dev/null || skip "openssl is not installed"

dir="$out/files"
rm -rf "$dir"
mkdir -p "$dir/www" "$dir/models" "$dir/nginx"
build/bin/mts-build "$shared/models/bunny00.off" -o "$dir/models/bunny00.mtsm" \
  --stream "$dir/www/bunny00.mts" --json --quiet >"$dir/build.json" || skip "mts-build failed"

# a throwaway CA and a certificate for 127.0.0.1, as a private deployment has
(cd "$dir" &&
  openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -keyout ca.key \
    -out ca.pem -days 2 -subj '/CN=mtstream bench CA' &&
  openssl req -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -keyout key.pem -out srv.csr \
    -subj /CN=127.0.0.1 &&
  printf 'subjectAltName=IP:127.0.0.1\n' >ext.cnf &&
  openssl x509 -req -in srv.csr -CA ca.pem -CAkey ca.key -CAcreateserial -out cert.pem -days 2 \
    -extfile ext.cnf) >"$dir/openssl.log" 2>&1 || skip "openssl could not make a certificate"

free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }
wait_port() {
  for _ in $(seq 1 200); do
    python3 -c "import socket,sys; socket.create_connection(('127.0.0.1',$1),1)" 2>/dev/null && return 0
    sleep 0.05
  done
  return 1
}
tcp=$(free_port) http=$(free_port) https=$(free_port) tls=$(free_port)
build/bin/mts-server --models "$dir/models" --listen "127.0.0.1:$tcp" --quiet 2>"$dir/server.log" &
server=$!
# the marked lines of the shipped configuration, replaced; nothing else
python3 - docker/nginx-tls.conf "$dir/nginx.conf" <<PY
import sys
lines = {
    "@HTTP_LISTEN@": "listen 127.0.0.1:$http;",
    "@HTTPS_LISTEN@": "listen 127.0.0.1:$https ssl http2;",
    "@CERT@": "ssl_certificate $dir/cert.pem;",
    "@KEY@": "ssl_certificate_key $dir/key.pem;",
    "@STREAM_CERT@": "ssl_certificate $dir/cert.pem;",
    "@STREAM_KEY@": "ssl_certificate_key $dir/key.pem;",
    "@ROOT@": "root $dir/www;",
    "@WS_UPSTREAM@": "server 127.0.0.1:9;",
    "@TCP_UPSTREAM@": "server 127.0.0.1:$tcp;",
    "@TLS_LISTEN@": "listen 127.0.0.1:$tls ssl;",
    "@LIMIT_RATE@": "limit_rate 0;",
}
with open(sys.argv[1]) as f, open(sys.argv[2], "w") as o:
    for line in f:
        mark = next((m for m in lines if m in line and not line.lstrip().startswith("#")), None)
        o.write(lines[mark] + "\n" if mark else line)
PY
"$nginx" -e stderr -p "$dir/nginx/" -c "$dir/nginx.conf" -g "master_process off; pid nginx.pid;" \
  >/dev/null 2>"$dir/nginx.log" &
front=$!
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
