#!/usr/bin/env bash
# The browser client's figures of `make bench`, into OUT/web.json:
#   - the WebAssembly decoder (node tests/web/decode.js: median of 7 warm
#     decodes, and the first, in one process) beside the native one
#     (mts-bench-apply, median of 7) on the same models in the same run:
#     ms, splits/s, their ratio;
#   - the page in headless Chromium (build/bin/mts-bench-web): connect, first
#     frame, full level, frames while streaming, pictures in bench/plots/.
# Usage: bench/web.sh OUT MODELS_DIR (the .mtsm files, cow among them).
# Skips, with the reason in the JSON, without build/web, node or chromium.
set -uo pipefail
cd "$(dirname "$0")/.." || exit 1
out=$1
models_dir=$2
bin=build/bin
dest=$out/web.json
rm -f "$dest" "$out"/web_*.json
skip() { printf '{"skipped": "%s"}\n' "$1" >"$dest"; echo "bench: browser client skipped: $1" >&2; exit 0; }
[ -f build/web/mts_web.js ] || skip "no build/web (make web needs emscripten; scripts/deps.sh installs it)"
command -v node >/dev/null || skip "no node"
status=0

port=$((20000 + RANDOM % 20000))
$bin/mts-server --models "$models_dir" --listen "127.0.0.1:$port" --quiet 2>"$out/web_server.log" &
pid=$!
trap 'kill -TERM "$pid" 2>/dev/null' EXIT
for _ in $(seq 1 600); do
  $bin/mts-client "127.0.0.1:$port" --list 2>/dev/null | grep -q '^cow ' && break
  sleep 0.1
done

models=()
for m in "$models_dir"/*.mtsm; do
  name=$(basename "$m" .mtsm)
  models+=("$m")
  node tests/web/decode.js build/web "tcp:127.0.0.1:$port:$name" 32768 7 \
    >"$out/web_wasm_$name.json" 2>>"$out/web_server.log" || status=1
done
$bin/mts-bench-apply "${models[@]}" --runs 7 --json "$out/web_native.json" >/dev/null || status=1
kill -TERM "$pid" 2>/dev/null
wait "$pid" 2>/dev/null

if command -v chromium >/dev/null; then
  $bin/mts-bench-web "$models_dir" --json "$out/web_page.json" --png-dir bench/plots || status=1
else
  printf '{"skipped": "no chromium (scripts/deps.sh installs it)"}\n' >"$out/web_page.json"
fi

python3 - "$out" "$dest" <<'PY' || status=1
import glob, json, os, sys
out, dest = sys.argv[1], sys.argv[2]
native = json.load(open(os.path.join(out, "web_native.json")))["models"]
res = {"decoder": {}}
for path in sorted(glob.glob(os.path.join(out, "web_wasm_*.json"))):
    name = os.path.basename(path)[len("web_wasm_"):-len(".json")]
    try:
        w = json.load(open(path))
    except (OSError, ValueError):
        continue
    n = native.get(name)
    if not n or w.get("rc") != 0:
        continue
    splits = w["level"]
    res["decoder"][name] = {
        "splits": splits,
        "wasm_ms": w["decode_ms"], "wasm_ms_first": w["decode_ms_first"],
        "native_ms": n["splits_ms"],
        "wasm_splits_per_s": round(splits / (w["decode_ms"] / 1e3)),
        "native_splits_per_s": n["splits_per_s"],
        "ratio": round(n["splits_ms"] / w["decode_ms"], 3),
        "ratio_first": round(n["splits_ms"] / w["decode_ms_first"], 3),
        "checksum_match": w["checksum"] == w["server_checksum"],
    }
try:
    res["page"] = json.load(open(os.path.join(out, "web_page.json")))
except (OSError, ValueError):
    res["page"] = {"skipped": "mts-bench-web wrote no figures"}
json.dump(res, open(dest, "w"), indent=1)
PY
exit $status
