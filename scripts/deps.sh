#!/usr/bin/env bash
# Installs the Debian packages mtstream builds, tests and benchmarks with.
# Idempotent: installs only what is missing and says what that is; a no-op
# when everything is there. Uses sudo when not run as root.
set -euo pipefail

packages=(
  build-essential pkg-config
  libopenmesh-dev        # mesh topology and the quadric decimater
  libopenmesh-apps       # OpenMesh-commandlineSubdivider for the 1M-triangle bench mesh
  libdraco-dev           # base-mesh compression
  draco                  # `make bench`: draco_encoder/draco_decoder, the Draco anchor of bench/threads.sh
  libtinygltf-dev        # glTF 2.0 / GLB input (builder/gltf_read.cpp; a compiled library, no JSON or image headers needed)
  libcurl4-openssl-dev   # models from http(s) URLs
  libegl-dev libgles-dev libegl-mesa0 libgl1-mesa-dri  # headless EGL rendering
  libx11-dev             # mts-client --window: the X11 window EGL draws on
  xvfb xauth             # tests/test_window.c: a virtual X server for the windowed client
  libpng-dev
  libmeshoptimizer-dev   # benchmark anchor (meshopt_stripify)
  clang libclang-rt-14-dev  # `make fuzz`: libFuzzer + ASan/UBSan runtimes (the -rt package is only recommended by clang)
  nginx libnginx-mod-stream  # the TCP balancer of tests/test_scaleout.c (docker/nginx-stream.conf)
  openssl                    # tests/test_https.c: a throwaway CA and the server certificate nginx terminates TLS with
  curl                       # tests/test_https.c: the headers nginx sends with stream files
  yamllint                   # lints docker/compose.yaml and docker/k8s.yaml (tests/test_scaleout.c)
  podman runc podman-compose catatonit  # `make deploy-test`: docker/'s images, compose file and k8s.yaml run (scripts/deploy-test.sh); catatonit: kube play's pause image
  golang-github-containernetworking-plugin-dnsname  # podman's CNI networks: containers find each other by service name
  debootstrap            # `make deploy-test`: the Debian base images, made from the mirror (no registry needed)
  python3-matplotlib     # `make bench`'s plots (bench/plot.py; it skips without)
  time                   # `make bench`: peak memory of mts-build and mkbalancedpm (bench/builder.sh)
  emscripten             # `make web`: the decoder in WebAssembly for the browser client
  chromium               # tests/test_web.c: the page in headless Chromium
  assimp-testmodels      # tests/test_assimp_models.c: real OFF/OBJ/PLY/STL/glTF/GLB files (exporters' quirks, UTF-16, broken ones) built or refused by name
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
# npm fetches Draco's WebAssembly decoder once (scripts/web-deps.sh). A
# Node.js from elsewhere (nodesource's package) brings its own npm, which
# Debian's npm package would conflict with: only where there is none.
if ! command -v npm >/dev/null; then
  missing+=(nodejs npm)
fi

if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi

echo "deps: installing ${missing[*]}"
sudo=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "deps: not root and no sudo; install: ${missing[*]}" >&2; exit 1; }
  sudo="sudo"
fi
export DEBIAN_FRONTEND=noninteractive
# Debian's nginx package starts the system nginx when installed, and its
# install fails when that start fails (say, no IPv6 for the default site).
# The tests run their own nginx on a loopback port and want no system one:
# while installing, a policy-rc.d denies service starts, unless the machine
# already has one (containers do), which is then left as it is.
policy=/usr/sbin/policy-rc.d
if [ ! -e "$policy" ]; then
  printf '#!/bin/sh\n# mtstream deps.sh: no service starts while installing\nexit 101\n' |
    $sudo tee "$policy" >/dev/null
  $sudo chmod 755 "$policy"
  trap '$sudo rm -f "$policy"' EXIT
fi
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "deps: done"
