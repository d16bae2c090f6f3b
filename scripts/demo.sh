#!/usr/bin/env bash
# The README's first command. Builds the built-in default model
# (tests/data/cow.off, the "Cow" of the MTS paper, shipped in the repository),
# verifies it at every level, starts mts-server on loopback, streams the model
# to mts-client to the full level with PNGs at three levels on the way, stops
# the server and says where the pictures are. With MTS_DEMO_SERVE=1 (or
# `make demo-serve`) the server keeps running afterwards, for
# `mts-client cow --window` in another terminal, until Ctrl-C.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=build/bin
out=build/demo
port=${MTS_DEMO_PORT:-7447}
mkdir -p "$out/models"
cp tests/data/cow.off "$out/models/cow.off"

echo "== mts-build tests/data/cow.off -o $out/cow.mtsm"
"$bin/mts-build" tests/data/cow.off -o "$out/cow.mtsm"
echo
echo "== mts-inspect $out/cow.mtsm --verify"
"$bin/mts-inspect" "$out/cow.mtsm" --verify
echo
echo "== mts-server --models $out/models --listen 127.0.0.1:$port"
"$bin/mts-server" --models "$out/models" --listen "127.0.0.1:$port" &
server=$!
trap 'kill "$server" 2>/dev/null || true' EXIT
for _ in $(seq 1 50); do  # until it listens
  "$bin/mts-client" "127.0.0.1:$port" --list >/dev/null 2>&1 && break
  sleep 0.1
done
echo
echo "== mts-client 127.0.0.1:$port cow --png $out/cow.png --png-levels 0,300,1500 --verify --model-file $out/cow.mtsm"
"$bin/mts-client" "127.0.0.1:$port" cow --png "$out/cow.png" --png-levels 0,300,1500 \
  --verify --model-file "$out/cow.mtsm"
echo
echo "Pictures: $out/cow_L0.png (base), $out/cow_L300.png, $out/cow_L1500.png, $out/cow.png (full)."
if [ "${MTS_DEMO_SERVE:-0}" = 1 ]; then
  echo
  echo "The server keeps serving cow on 127.0.0.1:$port. In another terminal (with a display):"
  echo "  $bin/mts-client 127.0.0.1:$port cow --window"
  echo "Ctrl-C stops it."
  trap 'kill -TERM "$server" 2>/dev/null || true' INT TERM
  wait "$server" || true
  trap - EXIT
  exit 0
fi
kill -TERM "$server"
wait "$server" || true
trap - EXIT
echo "Next: mts-build your own mesh (OFF, OBJ, PLY, STL, glTF/GLB), or serve a folder: mts-server --models DIR"
