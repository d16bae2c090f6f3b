#!/usr/bin/env bash
# `make demo-web`: the browser client as a user would serve it. Builds the
# default model (tests/data/cow.off) and, where ../shared/models has them,
# bunny00 and fandisk_large; runs mts-server (TCP on 127.0.0.1:7447,
# WebSocket on 127.0.0.1:7449) and, in front of it, nginx with
# web/nginx.conf: the page (build/web, `make web`) and the stream at
# /stream on 127.0.0.1:7448. Says the address to open; Ctrl-C stops both.
# MTS_DEMO_WEB_LISTEN=0.0.0.0:7448 serves other machines too.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=build/bin
out=build/demo-web
web=${MTS_DEMO_WEB_LISTEN:-127.0.0.1:7448}
tcp=${MTS_DEMO_PORT:-7447}
ws=127.0.0.1:${MTS_DEMO_WS_PORT:-7449}
shared=${MTS_SHARED:-../shared}
nginx=$(command -v nginx || true)
for n in /usr/sbin/nginx /usr/local/sbin/nginx; do
  [ -z "$nginx" ] && [ -x "$n" ] && nginx=$n
done
if [ -z "$nginx" ]; then
  echo "demo-web: no nginx (make deps installs it): it serves the page" >&2
  exit 1
fi
mkdir -p "$out/models" "$out/nginx"
echo "== mts-build tests/data/cow.off -o $out/models/cow.mtsm"
"$bin/mts-build" tests/data/cow.off -o "$out/models/cow.mtsm" --quiet
for m in bunny00 fandisk_large; do
  if [ -f "$shared/models/$m.off" ] && [ ! -f "$out/models/$m.mtsm" ]; then
    echo "== mts-build $shared/models/$m.off -o $out/models/$m.mtsm"
    "$bin/mts-build" "$shared/models/$m.off" -o "$out/models/$m.mtsm" --quiet
  fi
done

# web/nginx.conf as it is, with the three marked lines set to this demo's
# addresses and page folder.
sed -e "s|^\( *\)listen .*# @LISTEN@|\1listen $web;|" \
    -e "s|^\( *\)server .*# @UPSTREAM@|\1server $ws;|" \
    -e "s|^\( *\)root .*# @ROOT@|\1root $PWD/build/web;|" \
    web/nginx.conf > "$out/nginx/nginx.conf"

echo
echo "== mts-server --models $out/models --listen 127.0.0.1:$tcp --ws-listen $ws"
"$bin/mts-server" --models "$out/models" --listen "127.0.0.1:$tcp" --ws-listen "$ws" &
server=$!
# One nginx process (no master and workers): it runs as this user and
# reads the page where it is; Ctrl-C stops it with the server.
echo "== nginx -p $out/nginx/ -c $out/nginx/nginx.conf (web/nginx.conf on $web)"
"$nginx" -p "$out/nginx/" -e stderr -c "$PWD/$out/nginx/nginx.conf" -g 'master_process off;' \
  > "$out/nginx/access.log" &
front=$!
trap 'kill $server $front 2>/dev/null; wait 2>/dev/null' EXIT INT TERM
host=${web%:*}
[ "$host" = 0.0.0.0 ] && host=$(hostname -I 2>/dev/null | awk '{print $1}')
sleep 0.5
echo
echo "Open http://${host:-127.0.0.1}:${web##*:}/ in a browser: pick a model, watch it stream, drag to"
echo "orbit, wheel to zoom, the slider to move through the levels received. Ctrl-C stops it."
echo "(nginx's access log: $out/nginx/access.log)"
echo
wait -n $server $front
