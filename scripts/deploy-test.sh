#!/usr/bin/env bash
# make deploy-test: the deployment files of docker/ run for real, under podman.
#
#  1. base images: debian:bookworm and :bookworm-slim made with debootstrap
#     from the machine's own Debian mirror where podman has none (no registry
#     is needed; kept between runs, so later runs skip this)
#  2. builds docker/Dockerfile's runtime and lb images
#  3. docker/compose.yaml under podman-compose: models, 2 servers, the lb, the
#     TLS terminator; 1,000 mts-stress clients through the lb (0 failed, both
#     replicas serving), one mts-client from the host (checksum = the
#     model's, as a server on loopback built here streams it), the stream file
#     over https and the TCP stream in TLS (same checksum), 200 clients of the
#     stream file over https
#  4. restarts one server: the lb, untouched, sends it traffic again
#  5. stops everything with paced streams in flight (the servers run with
#     --rate-limit): none is cut
#  6. docker/k8s.yaml under podman kube play (with its two lines marked
#     `# podman:`), streamed through
#
# Prints a table; exit status 0 when every row passed, 1 otherwise. Cleans up
# the containers, pods, networks and volumes it started (images stay).
# Needs root (or sudo-free rootful podman), podman, runc, podman-compose and
# debootstrap (scripts/deps.sh), and the host's programs in $BIN.
#
# Environment: MTS_DEPLOY_BIN (default build/bin), MTS_DEPLOY_PROJECT
# (compose project, default mtsdeploy), MTS_DEPLOY_PORT_BASE (host ports
# BASE+7447, +8080, +8443, +7443; default 10000), CONTAINERS_CONF (default: a
# file written here, see ../shared/containers.md), MTS_DEPLOY_KEEP=1 (leave
# the topology up after a failure, to look at it).
set -uo pipefail
cd "$(dirname "$0")/.."
# rootful podman (as ../shared/containers.md ran it) and debootstrap need root
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "deploy-test: needs root (or sudo)" >&2; exit 1; }
  exec sudo --preserve-env=MTS_DEPLOY_BIN,MTS_DEPLOY_PROJECT,MTS_DEPLOY_PORT_BASE,MTS_DEPLOY_KEEP,CONTAINERS_CONF "$0" "$@"
fi
t_start=$(date +%s.%N)

BIN=${MTS_DEPLOY_BIN:-build/bin}
PROJECT=${MTS_DEPLOY_PROJECT:-mtsdeploy}
base=${MTS_DEPLOY_PORT_BASE:-10000}
LB_PORT=$((base + 7447))
HTTP_PORT=$((base + 8080))
HTTPS_PORT=$((base + 8443))
TLS_PORT=$((base + 7443))
NET=${PROJECT}_default
RATE=5000      # bytes/s per connection: cow's 15 KB stream takes 3 s
INFLIGHT=100   # clients in flight when everything stops

work=$(mktemp -d /tmp/mts-deploy.XXXXXX)
mkdir "$work/pub" && chmod 755 "$work/pub" # mounted into the stress containers
if [ -z "${CONTAINERS_CONF:-}" ]; then
  # podman's defaults fail on these machines: crun refuses hybrid cgroups, and
  # runc cannot set limits above the hard nofile (20000) without explicit ones
  cat >"$work/containers.conf" <<'EOF'
[containers]
default_ulimits = ["nofile=20000:20000", "nproc=4096:4096"]
[engine]
runtime = "runc"
cgroup_manager = "cgroupfs"
EOF
  export CONTAINERS_CONF=$work/containers.conf
fi
export MTS_LB_PORT=$LB_PORT MTS_HTTP_PORT=$HTTP_PORT MTS_HTTPS_PORT=$HTTPS_PORT MTS_TLS_PORT=$TLS_PORT
export MTS_SERVER_ARGS="--rate-limit $RATE --stats-interval 60"

rows=()
failed=0
now() { date +%s.%N; }
# row STEP ok|FAIL DETAIL SINCE
row() {
  local secs
  secs=$(awk -v a="$4" -v b="$(now)" 'BEGIN { printf "%.1f", b - a }')
  rows+=("$1|$2|$3|$secs")
  [ "$2" = ok ] || failed=$((failed + 1))
  printf 'deploy-test: %-28s %-4s %s (%s s)\n' "$1" "$2" "$3" "$secs"
}
say() { echo "deploy-test: $*"; }
log() { "$@" >>"$work/log" 2>&1; }
compose() { podman-compose -p "$PROJECT" -f docker/compose.yaml "$@" >>"$work/log" 2>&1; }
json_field() { # json_field FIELD < one line of JSON (numbers and strings)
  sed -n "s/.*\"$1\":\"\\{0,1\\}\\([^,\"}]*\\).*/\\1/p" | head -1
}

composed=0
kube_file=""
cleanup() {
  local rc=$?
  if [ "${MTS_DEPLOY_KEEP:-0}" = 1 ] && [ "$failed" -gt 0 ]; then
    say "MTS_DEPLOY_KEEP=1: left up, and $work; podman-compose -p $PROJECT -f docker/compose.yaml down -t 30 -v ends it"
    return
  fi
  podman rm -f "${PROJECT}_inflight" >/dev/null 2>&1
  if [ "$composed" = 1 ]; then
    podman-compose -p "$PROJECT" -f docker/compose.yaml down -t 30 -v >>"$work/log" 2>&1
  fi
  # whatever podman-compose left behind (its `down` keeps the network)
  podman ps -a -q --filter "label=io.podman.compose.project=$PROJECT" | xargs -r podman rm -f >/dev/null 2>&1
  podman volume rm -f "${PROJECT}_models" "${PROJECT}_streams" >/dev/null 2>&1
  podman network rm -f "$NET" >/dev/null 2>&1
  if [ -n "$kube_file" ]; then
    podman kube down "$kube_file" >/dev/null 2>&1
    podman pod rm -f mts-server-pod-0 >/dev/null 2>&1
    podman pod rm -f mts-server-pod-0 >/dev/null 2>&1
    podman network rm podman-default-kube-network >/dev/null 2>&1 # unless in use
  fi
  rm -rf "$work"
  exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

print_table() {
  local total
  total=$(awk -v a="$t_start" -v b="$(now)" 'BEGIN { printf "%.0f", b - a }')
  echo
  printf '%-28s %-5s %7s  %s\n' "step" "ok" "seconds" "detail"
  printf '%-28s %-5s %7s  %s\n' "----" "--" "-------" "------"
  for r in "${rows[@]}"; do
    IFS='|' read -r s o d t <<<"$r"
    printf '%-28s %-5s %7s  %s\n' "$s" "$o" "$t" "$d"
  done
  echo
  if [ "$failed" -eq 0 ]; then
    echo "deploy-test: all ${#rows[@]} steps passed in ${total} s"
  else
    echo "deploy-test: $failed of ${#rows[@]} steps FAILED (${total} s); the log's end:"
    tail -n 40 "$work/log" | sed 's/^/  | /'
  fi
}

# ---------------------------------------------------------------- prerequisites
t=$(now)
missing=""
for c in podman runc podman-compose debootstrap catatonit; do
  command -v "$c" >/dev/null || missing="$missing $c"
done
for p in mts-client mts-stress mts-build mts-server; do
  [ -x "$BIN/$p" ] || missing="$missing $BIN/$p"
done
if [ -n "$missing" ]; then
  row prerequisites FAIL "missing:$missing (scripts/deps.sh; make programs)" "$t"
  print_table
  exit 1
fi
for p in $LB_PORT $HTTP_PORT $HTTPS_PORT $TLS_PORT 7447; do
  if ss -Hltn "sport = :$p" 2>/dev/null | grep -q .; then
    missing="$missing $p"
  fi
done
if [ -n "$missing" ]; then
  row prerequisites FAIL "host ports in use:$missing (MTS_DEPLOY_PORT_BASE moves all but 7447, k8s.yaml's)" "$t"
  print_table
  exit 1
fi
# a project left over from an interrupted run
podman ps -a -q --filter "label=io.podman.compose.project=$PROJECT" | xargs -r podman rm -f >/dev/null 2>&1
podman pod rm -f mts-server-pod-0 >/dev/null 2>&1
podman volume rm -f "${PROJECT}_models" "${PROJECT}_streams" >/dev/null 2>&1
row prerequisites ok "$(podman --version), podman-compose $(podman-compose version 2>/dev/null | sed -n 's/^podman-compose[a-z]* version *//p' | head -1)" "$t"

# ---------------------------------------------------------------- base images
t=$(now)
if podman image exists docker.io/library/debian:bookworm &&
   podman image exists docker.io/library/debian:bookworm-slim; then
  row "base images" ok "cached (debian:bookworm, :bookworm-slim)" "$t"
else
  mirror=$(sed -n 's/^URIs: *\([^ ]*debian\/*\)$/\1/p' /etc/apt/sources.list.d/*.sources 2>/dev/null | head -1)
  [ -n "$mirror" ] || mirror=$(sed -n 's/^deb \(\[[^]]*\] \)\{0,1\}\([^ ]*\) bookworm .*/\2/p' /etc/apt/sources.list 2>/dev/null | head -1)
  [ -n "$mirror" ] || mirror=http://deb.debian.org/debian
  rootfs=$work/rootfs
  if log debootstrap --variant=minbase bookworm "$rootfs" "$mirror"; then
    rm -f "$rootfs/etc/apt/sources.list"
    if ls /etc/apt/sources.list.d/*.sources >/dev/null 2>&1; then
      cp /etc/apt/sources.list.d/*.sources "$rootfs/etc/apt/sources.list.d/"
    else
      echo "deb $mirror bookworm main" >"$rootfs/etc/apt/sources.list"
    fi
    chroot "$rootfs" apt-get clean
    rm -rf "$rootfs"/var/lib/apt/lists/*
    if tar -C "$rootfs" -c . | log podman import --change 'CMD ["bash"]' - docker.io/library/debian:bookworm &&
       log podman tag docker.io/library/debian:bookworm docker.io/library/debian:bookworm-slim; then
      row "base images" ok "debootstrap minbase from $mirror, imported" "$t"
    else
      row "base images" FAIL "podman import" "$t"
    fi
  else
    row "base images" FAIL "debootstrap from $mirror (see the log)" "$t"
  fi
  rm -rf "$rootfs"
  [ "$failed" -eq 0 ] || { print_table; exit 1; }
fi

# ---------------------------------------------------------------- images
size_mb() { podman image inspect --format '{{.Size}}' "$1" 2>/dev/null | awk '{ printf "%.0f MB", $1 / 1e6 }'; }
t=$(now)
if log podman build -f docker/Dockerfile -t mtstream:latest .; then
  row "image mtstream" ok "$(size_mb mtstream:latest) (runtime, Mesa, stripped)" "$t"
else
  row "image mtstream" FAIL "podman build (see the log)" "$t"
fi
t=$(now)
if log podman build -f docker/Dockerfile --target lb -t mtstream-lb:latest .; then
  row "image mtstream-lb" ok "$(size_mb mtstream-lb:latest) (nginx, stream module)" "$t"
else
  row "image mtstream-lb" FAIL "podman build --target lb (see the log)" "$t"
fi
[ "$failed" -eq 0 ] || { print_table; exit 1; }

# The reference: what a server on loopback, from meshes built here, streams.
t=$(now)
mkdir -p "$work/ref"
ref_port=$((base + 7446))
log "$BIN/mts-build" tests/data/cow.off -o "$work/ref/cow.mtsm" --quiet
"$BIN/mts-server" --models "$work/ref" --listen "127.0.0.1:$ref_port" --quiet >>"$work/log" 2>&1 &
ref_pid=$!
ref_sum=""
for _ in $(seq 50); do
  ref_sum=$("$BIN/mts-client" "127.0.0.1:$ref_port" cow --no-render --json 2>/dev/null | json_field checksum)
  [ -n "$ref_sum" ] && break
  sleep 0.2
done
kill "$ref_pid" 2>/dev/null
wait "$ref_pid" 2>/dev/null

# ---------------------------------------------------------------- compose up
compose_up() {
  local t
  t=$(now)
  composed=1
  compose up -d
  # models exits 0; both servers answer; the balancers answer through their names
  local ok=0
  for _ in $(seq 120); do
    if [ "$(podman inspect --format '{{.State.Status}} {{.State.ExitCode}}' "${PROJECT}_models_1" 2>/dev/null)" = "exited 0" ] &&
       podman exec "${PROJECT}_server_1" mts-client 127.0.0.1:7447 --list >/dev/null 2>&1 &&
       podman exec "${PROJECT}_server_2" mts-client 127.0.0.1:7447 --list >/dev/null 2>&1 &&
       "$BIN/mts-client" "127.0.0.1:$LB_PORT" --list >/dev/null 2>&1 &&
       curl -fsS -o /dev/null "http://127.0.0.1:$HTTP_PORT/cow.mts" 2>/dev/null; then
      ok=1
      break
    fi
    sleep 0.5
  done
  local health
  health=$(podman healthcheck run "${PROJECT}_server_1" 2>&1 && echo healthy)
  if [ "$ok" = 1 ]; then
    row "compose up" ok "models built, 2 servers ($health), lb, tls" "$t"
  else
    row "compose up" FAIL "not up within 60 s: $(podman ps -a --filter "label=io.podman.compose.project=$PROJECT" --format '{{.Names}}={{.Status}}' | tr '\n' ' ')" "$t"
  fi
  return $((1 - ok))
}
# served NAME: the cow streams a server container has completed (its log lines)
served() { podman logs "$1" 2>&1 | grep -c 'model=cow .*outcome=ok'; }
# stress ARGS...: mts-stress in a container on the compose network; JSON out
stress() {
  podman run --rm --network "$NET" -v "$work/pub:/w:ro" --entrypoint mts-stress \
    mtstream:latest "$@" --json 2>>"$work/log"
}

if compose_up; then
  # ------------------------------------------------------------ 1,000 clients
  t=$(now)
  a1=$(served "${PROJECT}_server_1")
  a2=$(served "${PROJECT}_server_2")
  out=$(stress lb:7447 cow --clients 1000)
  echo "$out" >>"$work/log"
  done_=$(echo "$out" | json_field succeeded)
  fail_=$(echo "$out" | json_field failed)
  b1=$(($(served "${PROJECT}_server_1") - a1))
  b2=$(($(served "${PROJECT}_server_2") - a2))
  if [ "${done_:-0}" = 1000 ] && [ "${fail_:-1}" = 0 ] && [ "$b1" -gt 0 ] && [ "$b2" -gt 0 ]; then
    row "1,000 clients via lb" ok "1000 completed, 0 failed; replicas $b1 + $b2" "$t"
  else
    row "1,000 clients via lb" FAIL "completed ${done_:-?}, failed ${fail_:-?}; replicas $b1 + $b2" "$t"
  fi

  # ------------------------------------------------------------ host client
  t=$(now)
  sum=""
  for _ in 1 2 3; do # host port forwarding has been seen to refuse once in a while
    sum=$("$BIN/mts-client" "127.0.0.1:$LB_PORT" cow --no-render --json 2>>"$work/log" | json_field checksum)
    [ -n "$sum" ] && break
    sleep 1
  done
  if [ -n "$sum" ] && [ "$sum" = "$ref_sum" ]; then
    row "host client via lb" ok "checksum $sum = the model's" "$t"
  else
    row "host client via lb" FAIL "checksum '${sum}', the model's '${ref_sum}'" "$t"
  fi

  # ------------------------------------------------------------ TLS terminator
  t=$(now)
  # the terminator's self-signed certificate, to trust (readable by uid 10001)
  podman cp "${PROJECT}_tls_1:/tmp/mts-nginx/cert.pem" "$work/pub/cert.pem" >>"$work/log" 2>&1
  chmod 644 "$work/pub/cert.pem"
  s1=$("$BIN/mts-client" "https://localhost:$HTTPS_PORT/cow.mts" --cacert "$work/pub/cert.pem" --no-render --json 2>>"$work/log" | json_field checksum)
  s2=$("$BIN/mts-client" "localhost:$TLS_PORT" cow --tls --cacert "$work/pub/cert.pem" --no-render --json 2>>"$work/log" | json_field checksum)
  if [ -n "$s1" ] && [ "$s1" = "$ref_sum" ] && [ "$s2" = "$ref_sum" ]; then
    row "host client via tls" ok "https stream file and TCP in TLS: checksum $s1" "$t"
  else
    row "host client via tls" FAIL "https '${s1}', TCP in TLS '${s2}', the model's '${ref_sum}'" "$t"
  fi
  t=$(now)
  out=$(stress "https://tls:8443/cow.mts" --clients 200 --cacert /w/cert.pem)
  echo "$out" >>"$work/log"
  done_=$(echo "$out" | json_field succeeded)
  fail_=$(echo "$out" | json_field failed)
  if [ "${done_:-0}" = 200 ] && [ "${fail_:-1}" = 0 ]; then
    row "200 clients, https file" ok "200 completed, 0 failed" "$t"
  else
    row "200 clients, https file" FAIL "completed ${done_:-?}, failed ${fail_:-?}" "$t"
  fi

  # ------------------------------------------------------------ restart a replica
  t=$(now)
  ip() { podman inspect --format '{{range .NetworkSettings.Networks}}{{.IPAddress}}{{end}}' "$1" 2>/dev/null; }
  lb_started=$(podman inspect --format '{{.State.StartedAt}}' "${PROJECT}_lb_1")
  old_ip=$(ip "${PROJECT}_server_1")
  log podman restart -t 25 "${PROJECT}_server_1"
  new_ip=$(ip "${PROJECT}_server_1")
  # the lb reloads once its watcher sees the new address (every 2 s)
  for _ in $(seq 40); do
    podman logs "${PROJECT}_lb_1" 2>&1 | grep -q "now .*$new_ip .*reloading" && break
    sleep 0.5
  done
  for _ in $(seq 40); do
    podman exec "${PROJECT}_server_1" mts-client 127.0.0.1:7447 --list >/dev/null 2>&1 && break
    sleep 0.5
  done
  a1=$(served "${PROJECT}_server_1")
  a2=$(served "${PROJECT}_server_2")
  out=$(stress lb:7447 cow --clients 200)
  echo "$out" >>"$work/log"
  done_=$(echo "$out" | json_field succeeded)
  fail_=$(echo "$out" | json_field failed)
  b1=$(($(served "${PROJECT}_server_1") - a1))
  b2=$(($(served "${PROJECT}_server_2") - a2))
  same_lb=$([ "$(podman inspect --format '{{.State.StartedAt}}' "${PROJECT}_lb_1")" = "$lb_started" ] && echo yes || echo no)
  if [ "${done_:-0}" = 200 ] && [ "${fail_:-1}" = 0 ] && [ "$b1" -gt 0 ] && [ "$same_lb" = yes ]; then
    row "restarted replica" ok "$old_ip -> $new_ip; 200 clients, 0 failed, it served $b1 (other $b2); lb not restarted" "$t"
  else
    row "restarted replica" FAIL "$old_ip -> $new_ip; completed ${done_:-?}, failed ${fail_:-?}; served $b1 + $b2; lb untouched: $same_lb" "$t"
  fi

  # ------------------------------------------------------------ stop in flight
  t=$(now)
  a1=$(served "${PROJECT}_server_1")
  a2=$(served "${PROJECT}_server_2")
  podman run -d --name "${PROJECT}_inflight" --network "$NET" --entrypoint mts-stress \
    mtstream:latest lb:7447 cow --clients "$INFLIGHT" --json >>"$work/log" 2>&1
  sleep 1.5
  at_stop=$(($(served "${PROJECT}_server_1") + $(served "${PROJECT}_server_2") - a1 - a2))
  t_stop=$(now)
  compose stop -t 30
  stop_s=$(awk -v a="$t_stop" -v b="$(now)" 'BEGIN { printf "%.1f", b - a }')
  podman wait "${PROJECT}_inflight" >/dev/null 2>&1
  out=$(podman logs "${PROJECT}_inflight" 2>&1 | grep -o '{"model".*}' | tail -1)
  echo "$out" >>"$work/log"
  podman rm -f "${PROJECT}_inflight" >/dev/null 2>&1
  done_=$(echo "$out" | json_field succeeded)
  fail_=$(echo "$out" | json_field failed)
  lb_exit=$(podman inspect --format '{{.State.ExitCode}}' "${PROJECT}_lb_1")
  if [ "${done_:-0}" = "$INFLIGHT" ] && [ "${fail_:-1}" = 0 ] && [ "$at_stop" -lt "$INFLIGHT" ]; then
    row "stop with streams in flight" ok "$((INFLIGHT - at_stop)) of $INFLIGHT in flight at stop, 0 cut; stop took $stop_s s (lb exit $lb_exit)" "$t"
  else
    row "stop with streams in flight" FAIL "$((INFLIGHT - at_stop)) in flight at stop; completed ${done_:-?}, failed ${fail_:-?} of $INFLIGHT" "$t"
  fi
fi

t=$(now)
if [ "$composed" = 1 ]; then
  compose down -t 30 -v
  composed=0
  podman volume rm -f "${PROJECT}_models" "${PROJECT}_streams" >/dev/null 2>&1
  podman network rm -f "$NET" >/dev/null 2>&1
  left=$(podman ps -a -q --filter "label=io.podman.compose.project=$PROJECT" | wc -l)
  if [ "$left" = 0 ]; then
    row "compose down" ok "containers, volumes, network removed" "$t"
  else
    row "compose down" FAIL "$left containers left" "$t"
  fi
fi

# ---------------------------------------------------------------- kube play
t=$(now)
kube_file=$work/k8s-podman.yaml
sed -e '/^[^#]*# podman: 1$/s/replicas: 2/replicas: 1/' \
    -e '/^[^#]*# podman: OnFailure$/s/Always/OnFailure/' docker/k8s.yaml >"$kube_file"
changed=$(diff docker/k8s.yaml "$kube_file" | grep -c '^>')
if [ "$changed" != 2 ]; then
  row "kube play" FAIL "k8s.yaml's two '# podman:' lines not found ($changed changed)" "$t"
elif ! log podman kube play "$kube_file"; then
  row "kube play" FAIL "podman kube play (see the log)" "$t"
else
  ctr=$(podman pod ps --filter name=mts-server-pod-0 -q | head -1)
  ctr=$(podman ps -a --filter "pod=$ctr" --format '{{.Names}}' | grep -- '-mts-server$' | head -1)
  sum=""
  for _ in $(seq 60); do
    sum=$("$BIN/mts-client" 127.0.0.1:7447 cow --no-render --json 2>/dev/null | json_field checksum)
    [ -n "$sum" ] && break
    sleep 0.5
  done
  probe=$(podman healthcheck run "$ctr" >/dev/null 2>&1 && echo "probe healthy" || echo "probe FAILED")
  if [ -n "$sum" ] && [ "$sum" = "$ref_sum" ] && [ "$probe" = "probe healthy" ]; then
    row "kube play" ok "init container built the models; checksum $sum from 127.0.0.1:7447; liveness $probe" "$t"
  else
    row "kube play" FAIL "checksum '${sum}' (model's '${ref_sum}'); liveness $probe" "$t"
  fi
  t=$(now)
  out=$("$BIN/mts-stress" 127.0.0.1:7447 cow --clients 200 --json 2>>"$work/log")
  done_=$(echo "$out" | json_field succeeded)
  fail_=$(echo "$out" | json_field failed)
  if [ "${done_:-0}" = 200 ] && [ "${fail_:-1}" = 0 ]; then
    row "200 clients via kube pod" ok "200 completed, 0 failed" "$t"
  else
    row "200 clients via kube pod" FAIL "completed ${done_:-?}, failed ${fail_:-?}" "$t"
  fi
  t=$(now)
  log podman kube down "$kube_file"
  podman pod rm -f mts-server-pod-0 >/dev/null 2>&1
  podman network rm podman-default-kube-network >/dev/null 2>&1 # kube play made it; unless in use
  kube_file=""
  row "kube down" ok "pod removed" "$t"
fi

print_table
[ "$failed" -eq 0 ]
