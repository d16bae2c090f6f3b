#!/usr/bin/env bash
# The README's first command: builds the built-in default model (tests/data/cow.off,
# the "Cow" of the MTS paper, shipped in the repository), verifies it at every
# level, and shows it at a few levels of detail.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=build/bin
out=build/demo
mkdir -p "$out"

echo "== mts-build tests/data/cow.off -o $out/cow.mtsm"
"$bin/mts-build" tests/data/cow.off -o "$out/cow.mtsm"
echo
echo "== mts-inspect $out/cow.mtsm --verify"
"$bin/mts-inspect" "$out/cow.mtsm" --verify
echo
for f in 0.5 0.1 0.01; do
  echo "== mts-inspect $out/cow.mtsm --fraction $f --obj $out/cow_$f.obj"
  "$bin/mts-inspect" "$out/cow.mtsm" --fraction "$f" --obj "$out/cow_$f.obj" | sed -n '4,5p'
done
echo
echo "Model and meshes are in $out/. Next: mts-build your own mesh (OFF, OBJ, PLY, STL)."
