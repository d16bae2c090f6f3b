#!/usr/bin/env bash
# `make demo-web`: the browser client. Builds the default model
# (tests/data/cow.off) and, where ../shared/models has them, bunny00 and
# fandisk_large; serves them with mts-server, TCP on 127.0.0.1:7447 and
# WebSocket plus the page (build/web, `make web`) on 127.0.0.1:7448, and
# says the address to open. Ctrl-C stops it. MTS_DEMO_WEB_LISTEN=0.0.0.0:7448
# serves other machines too.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=build/bin
out=build/demo-web
ws=${MTS_DEMO_WEB_LISTEN:-127.0.0.1:7448}
tcp=${MTS_DEMO_PORT:-7447}
shared=${MTS_SHARED:-../shared}
mkdir -p "$out/models"
echo "== mts-build tests/data/cow.off -o $out/models/cow.mtsm"
"$bin/mts-build" tests/data/cow.off -o "$out/models/cow.mtsm" --quiet
for m in bunny00 fandisk_large; do
  if [ -f "$shared/models/$m.off" ] && [ ! -f "$out/models/$m.mtsm" ]; then
    echo "== mts-build $shared/models/$m.off -o $out/models/$m.mtsm"
    "$bin/mts-build" "$shared/models/$m.off" -o "$out/models/$m.mtsm" --quiet
  fi
done
echo
echo "== mts-server --models $out/models --listen 127.0.0.1:$tcp --ws-listen $ws --web-root build/web"
host=${ws%:*}
[ "$host" = 0.0.0.0 ] && host=$(hostname -I 2>/dev/null | awk '{print $1}')
echo
echo "Open http://${host:-127.0.0.1}:${ws##*:}/ in a browser: pick a model, watch it stream, drag to"
echo "orbit, wheel to zoom, the slider to move through the levels received. Ctrl-C stops the server."
echo
exec "$bin/mts-server" --models "$out/models" --listen "127.0.0.1:$tcp" --ws-listen "$ws" \
  --web-root build/web
