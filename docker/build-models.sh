#!/bin/sh
# mts-build-models SRC_DIR... : builds every mesh (OFF, OBJ, PLY, STL) of the
# source folders into $MODELS_OUT (default /models) as NAME.mtsm, and copies
# any ready .mtsm there. A model newer than its source is left as it is; when
# two sources give the same NAME, the first folder listed wins.
#
# With $STREAMS_OUT set, each model's stream file (mts-build --stream) is
# written there too as NAME.mts, for a web server to serve (compose.yaml's
# `tls` service); also only when older than its model.
#
# compose.yaml's one-shot `models` service and the Kubernetes init container
# run it, so that the mts-server replicas only ever read the models folder:
# one writer, before any server starts.
set -eu
out="${MODELS_OUT:-/models}"
streams="${STREAMS_OUT:-}"
mkdir -p "$out"
[ -z "$streams" ] || mkdir -p "$streams"
# NAME.mts from NAME.mtsm, when missing or older than the model
stream_file() {
  [ -n "$streams" ] || return 0
  s="$streams/$1.mts"
  if [ -e "$s" ] && [ -z "$(find "$2" -newer "$s")" ]; then
    return 0
  fi
  # written beside, then renamed: a web server never serves half a file
  mts-build "$2" --stream "$s.tmp.$$.mts" --quiet && mv -f "$s.tmp.$$.mts" "$s"
  echo "mts-build-models: $1: $s"
}
seen=" "
built=0
for dir in "$@"; do
  [ -d "$dir" ] || { echo "mts-build-models: $dir: no such folder, skipped" >&2; continue; }
  for f in "$dir"/*; do
    [ -f "$f" ] || continue
    base=$(basename "$f")
    name=${base%.*}
    ext=$(printf '%s' "${base##*.}" | tr '[:upper:]' '[:lower:]')
    case "$ext" in
      off|obj|ply|stl|mtsm) ;;
      *) continue ;;
    esac
    case "$seen" in
      *" $name "*) echo "mts-build-models: $f: $name comes from an earlier folder, skipped" >&2; continue ;;
    esac
    seen="$seen$name "
    dest="$out/$name.mtsm"
    # (find -newer: POSIX sh has no -nt)
    if [ -e "$dest" ] && [ -z "$(find "$f" -newer "$dest")" ]; then
      echo "mts-build-models: $name: up to date"
      stream_file "$name" "$dest"
      continue
    fi
    if [ "$ext" = mtsm ]; then
      # copy then rename: a server never sees half a file
      cp "$f" "$dest.tmp.$$" && mv -f "$dest.tmp.$$" "$dest"
    else
      mts-build "$f" -o "$dest" --quiet
    fi
    echo "mts-build-models: $name: $dest"
    stream_file "$name" "$dest"
    built=$((built + 1))
  done
done
echo "mts-build-models: $built built or copied into $out"
