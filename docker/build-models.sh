#!/bin/sh
# mts-build-models SRC_DIR... : builds every mesh (OFF, OBJ, PLY, STL) of the
# source folders into $MODELS_OUT (default /models) as NAME.mtsm, and copies
# any ready .mtsm there. A model newer than its source is left as it is; when
# two sources give the same NAME, the first folder listed wins.
#
# compose.yaml's one-shot `models` service and the Kubernetes init container
# run it, so that the mts-server replicas only ever read the models folder:
# one writer, before any server starts.
set -eu
out="${MODELS_OUT:-/models}"
mkdir -p "$out"
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
      continue
    fi
    if [ "$ext" = mtsm ]; then
      # copy then rename: a server never sees half a file
      cp "$f" "$dest.tmp.$$" && mv -f "$dest.tmp.$$" "$dest"
    else
      mts-build "$f" -o "$dest" --quiet
    fi
    echo "mts-build-models: $name: $dest"
    built=$((built + 1))
  done
done
echo "mts-build-models: $built built or copied into $out"
