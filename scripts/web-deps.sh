#!/usr/bin/env bash
# Puts Draco's own WebAssembly decoder (npm draco3d, pinned) into DIR for
# the browser client: draco_decoder_nodejs.js and draco_decoder.wasm (the
# same file runs in a page and in node). npm checks the package's integrity;
# the tarball is kept in build/web-deps/ so later builds need no network.
set -euo pipefail
dir=${1:?usage: scripts/web-deps.sh DIR}
version=1.5.9
cache=build/web-deps
tgz=$cache/draco3d-$version.tgz
mkdir -p "$cache" "$dir"
if [ ! -f "$tgz" ]; then
  command -v npm >/dev/null || { echo "web-deps: npm is needed once to fetch draco3d@$version (apt-get install npm)" >&2; exit 1; }
  echo "web-deps: fetching draco3d@$version from the npm registry"
  (cd "$cache" && npm pack --silent "draco3d@$version" >/dev/null)
fi
tar -xzf "$tgz" -C "$cache" package/draco_decoder_nodejs.js package/draco_decoder.wasm package/package.json
cp "$cache/package/draco_decoder_nodejs.js" "$cache/package/draco_decoder.wasm" "$dir/"
