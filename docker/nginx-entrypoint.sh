#!/bin/sh
# mts-nginx CONF [NGINX ARGS...]: the lb image's entrypoint. Runs nginx in the
# foreground on CONF (it replaces this shell, so it is the container's main
# process and gets the stop signal, SIGQUIT), after two things:
#
# 1. Rendering. CONF's lines marked @...@ (docker/nginx-tls.conf's, say) name
#    loopback addresses for the tests; here a line marked @..._UPSTREAM@ gets
#    $MTS_UPSTREAM_HOST (default `server`, compose's service) for 127.0.0.1, a
#    line marked @..._LISTEN@ listens on every address, and when no
#    certificate is mounted at /etc/ssl/mtstream/{cert,key}.pem the @CERT@ and
#    @KEY@ lines point at a self-signed one made here (names: localhost, tls,
#    $MTS_TLS_NAMES). The rendered copy is /tmp/mts-nginx/nginx.conf; a file
#    with no such lines (nginx-stream.conf) is used as it is.
#
# 2. Following the replicas. nginx (open-source 1.22) resolves the names in
#    `upstream` blocks once, when it reads its configuration, and a replica
#    restarted with a new address would never get traffic again. Here a
#    watcher looks the upstream names up every $MTS_RESOLVE_S seconds
#    (default 2) and, when their addresses change, sends nginx SIGHUP: a
#    reload re-resolves them; old workers finish the streams they carry while
#    new ones take new connections, so nothing in flight is cut. It also waits
#    (up to 60 s) for the names to resolve before nginx starts, so the
#    balancer may start before the replicas. Round-robin, max_fails and
#    proxy_next_upstream stay nginx's own (a `resolver` with a variable
#    proxy_pass would lose them).
set -eu
conf=${1:?usage: mts-nginx CONF [nginx arguments]}
shift
run=/tmp/mts-nginx
mkdir -p "$run"
host=${MTS_UPSTREAM_HOST:-server}
cert=/etc/ssl/mtstream/cert.pem
key=/etc/ssl/mtstream/key.pem

if grep -q '# @[A-Z_]*@' "$conf"; then
  if grep -q '# @CERT@' "$conf" && ! [ -r "$cert" ] && ! [ -r "$run/cert.pem" ]; then
    san="DNS:localhost,DNS:tls,IP:127.0.0.1"
    for n in ${MTS_TLS_NAMES:-}; do
      case "$n" in *[!0-9.]*) san="$san,DNS:$n" ;; *) san="$san,IP:$n" ;; esac
    done
    openssl req -x509 -newkey rsa:2048 -nodes -days 825 -subj "/CN=mtstream" \
      -addext "subjectAltName=$san" -keyout "$run/key.pem" -out "$run/cert.pem" 2>/dev/null
    echo "mts-nginx: no certificate at $cert: made a self-signed one ($san), $run/cert.pem" >&2
  fi
  if [ -r "$run/cert.pem" ] && ! [ -r "$cert" ]; then
    cert=$run/cert.pem
    key=$run/key.pem
  fi
  sed -e "/# @[A-Z_]*UPSTREAM@/s/127\\.0\\.0\\.1:/$host:/" \
      -e "/# @[A-Z_]*LISTEN@/s/ 127\\.0\\.0\\.1:/ /" \
      -e "/# @[A-Z_]*CERT@/s|ssl_certificate [^;]*;|ssl_certificate $cert;|" \
      -e "/# @[A-Z_]*KEY@/s|ssl_certificate_key [^;]*;|ssl_certificate_key $key;|" \
      "$conf" >"$run/nginx.conf"
  conf=$run/nginx.conf
fi

# The names nginx resolves: `server NAME:PORT` lines (upstream members) whose
# NAME is not an address.
names=$(sed -n 's/^[[:space:]]*server[[:space:]][[:space:]]*\([A-Za-z][A-Za-z0-9.-]*\):[0-9].*/\1/p' \
  "$conf" | sort -u)
addresses() {
  for n in $names; do getent ahostsv4 "$n" | awk '{ print $1 }'; done | sort -u | tr '\n' ' '
}
all_resolve() {
  for n in $names; do getent ahostsv4 "$n" >/dev/null || return 1; done
}
if [ -n "$names" ]; then
  i=0
  until all_resolve; do
    i=$((i + 1))
    if [ "$i" -ge 120 ]; then
      echo "mts-nginx: $names do not resolve after 60 s; starting nginx anyway" >&2
      break
    fi
    sleep 0.5
  done
  nginx_pid=$$ # this shell's pid is nginx's once it execs
  (
    set +e
    last=$(addresses)
    echo "mts-nginx: upstream $names: $last" >&2
    while sleep "${MTS_RESOLVE_S:-2}"; do
      now=$(addresses)
      if [ -n "$now" ] && [ "$now" != "$last" ]; then
        echo "mts-nginx: upstream $names now $now (was $last): reloading nginx" >&2
        kill -HUP "$nginx_pid" 2>/dev/null || exit 0
        last=$now
      fi
    done
  ) &
fi
exec nginx -e stderr -p "$run/" -c "$conf" "$@"
