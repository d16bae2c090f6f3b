# Sourced by the bench scripts that run docker/nginx-tls.conf (files.sh,
# stress_files.sh): nginx in front of a loopback mts-server with a throwaway
# CA, as tests/test_proc.h's mts_test_tls_front does for the tests.
#   tls_front_missing          prints what is missing (nginx, its stream
#                              module, openssl) and fails; quiet when all is here
#   tls_front_ca DIR           DIR/ca.pem and nginx's DIR/cert.pem, DIR/key.pem
#   tls_front_conf DIR ROOT HTTP HTTPS TLS TCP [quiet]
#                              DIR/nginx.conf: the shipped file, only its
#                              marked lines replaced (quiet: no access log)
#   tls_front_start DIR        runs it (one process: its CPU is all of
#                              nginx's); the pid in TLS_FRONT_PID
#   free_port, wait_port PORT

free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }
wait_port() {
  for _ in $(seq 1 200); do
    python3 -c "import socket,sys; socket.create_connection(('127.0.0.1',$1),1)" 2>/dev/null && return 0
    sleep 0.05
  done
  return 1
}

TLS_FRONT_NGINX=$(command -v nginx || echo /usr/sbin/nginx)

tls_front_missing() {
  if [ ! -x "$TLS_FRONT_NGINX" ]; then echo "nginx is not installed (scripts/deps.sh)"
  elif [ ! -f /usr/lib/nginx/modules/ngx_stream_module.so ]; then echo "nginx's stream module is not installed"
  elif ! command -v openssl >/dev/null; then echo "openssl is not installed"
  else return 1
  fi
}

# a throwaway CA and a certificate for 127.0.0.1, as a private deployment has
tls_front_ca() {
  (cd "$1" &&
    openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -keyout ca.key \
      -out ca.pem -days 2 -subj '/CN=mtstream bench CA' &&
    openssl req -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -keyout key.pem -out srv.csr \
      -subj /CN=127.0.0.1 &&
    printf 'subjectAltName=IP:127.0.0.1\n' >ext.cnf &&
    openssl x509 -req -in srv.csr -CA ca.pem -CAkey ca.key -CAcreateserial -out cert.pem -days 2 \
      -extfile ext.cnf) >"$1/openssl.log" 2>&1
}

tls_front_conf() {
  python3 - docker/nginx-tls.conf "$1/nginx.conf" "$@" <<'PY'
import sys
src, dst, d, root, http, https, tls, tcp = sys.argv[1:9]
quiet = len(sys.argv) > 9 and sys.argv[9] == "quiet"
lines = {
    "@HTTP_LISTEN@": f"listen 127.0.0.1:{http};",
    "@HTTPS_LISTEN@": f"listen 127.0.0.1:{https} ssl http2;",
    "@CERT@": f"ssl_certificate {d}/cert.pem;",
    "@KEY@": f"ssl_certificate_key {d}/key.pem;",
    "@STREAM_CERT@": f"ssl_certificate {d}/cert.pem;",
    "@STREAM_KEY@": f"ssl_certificate_key {d}/key.pem;",
    "@ROOT@": f"root {root};",
    "@WS_UPSTREAM@": "server 127.0.0.1:9;",
    "@TCP_UPSTREAM@": f"server 127.0.0.1:{tcp};",
    "@TLS_LISTEN@": f"listen 127.0.0.1:{tls} ssl;",
    "@LIMIT_RATE@": "limit_rate 0;",
}
with open(src) as f, open(dst, "w") as o:
    for line in f:
        live = not line.lstrip().startswith("#")
        mark = next((m for m in lines if m in line and live), None)
        if mark:
            o.write(lines[mark] + "\n")
        elif quiet and live and "access_log" in line:
            # a thousand lines a run is the disk's work, not the server's
            o.write("    access_log off;\n")
        else:
            o.write(line)
PY
}

tls_front_start() {
  mkdir -p "$1/nginx"
  "$TLS_FRONT_NGINX" -e stderr -p "$1/nginx/" -c "$1/nginx.conf" \
    -g "master_process off; pid nginx.pid;" >/dev/null 2>"$1/nginx.log" &
  TLS_FRONT_PID=$!
}
