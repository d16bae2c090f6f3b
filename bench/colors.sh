#!/usr/bin/env bash
# Vertex colours in `make bench` (docs/colors.md):
#   - what they cost on the wire: mts-bench-stream --colors on cow_colors.ply
#     (its own colours), bunny00 and fandisk_large (the tests' smooth field,
#     tests/color_field.h, put on the mesh before it is built): the full
#     stream with and without colours beside Draco with colours on the same
#     grid, colour bits a vertex and a split;
#   - the rate-distortion series with a colour error beside the geometric one
#     (mts-bench-walk --colors, 17 stops along each stream), built with the
#     builder's colour term in the collapse cost (its default) and without it
#     (--color-cost 0), on the smooth field, on sharp colour patches and on
#     the baked mean curvature (cow.off for cow_colors.ply in those two), and
#     the two compared at equal bytes (bench/rd_compare.py).
# Writes $out/colors_*.json (and .txt, the tables as printed); bench/run.sh
# merges them into bench/results.json under "colors".
#
#   bench/colors.sh [OUT [MODELS_DIR]]     MTS_BIN: the programs (build/bin)
set -uo pipefail
cd "$(dirname "$0")/.." || exit 1
out="${1:-bench/out}"
models="${2:-../shared/models}"
bin="${MTS_BIN:-build/bin}"
mkdir -p "$out"
rm -f "$out"/colors_*.json "$out"/colors_*.txt
status=0

smooth=(tests/data/cow_colors.ply)
patches=(tests/data/cow.off)
for m in bunny00 fandisk_large; do
  if [ -f "$models/$m.off" ]; then
    smooth+=("$models/$m.off")
    patches+=("$models/$m.off")
  else
    echo "bench/colors.sh: $models/$m.off not found, skipped" >&2
  fi
done

echo "bench: colours on the wire ..." >&2
"$bin/mts-bench-stream" --colors "${smooth[@]}" --json "$out/colors_stream.json" \
  | tee "$out/colors_stream.txt" || status=1

echo "bench: colours' rate-distortion, colour term on and off ..." >&2
for field in smooth patches curvature; do
  if [ "$field" = smooth ]; then meshes=("${smooth[@]}"); else meshes=("${patches[@]}"); fi
  for cost in default 0; do
    extra=()
    [ "$cost" = 0 ] && extra=(--color-cost 0)
    "$bin/mts-bench-walk" "${meshes[@]}" --no-walk --colors --color-field "$field" \
      --rd-points 17 "${extra[@]}" --rd-json "$out/colors_rd_${field}_${cost}.json" \
      >"$out/colors_rd_${field}_${cost}.txt" || status=1
  done
  echo "colour term (default weight) against none, $field field, at equal bytes:" \
    | tee "$out/colors_rd_${field}_compare.txt"
  python3 bench/rd_compare.py "$out/colors_rd_${field}_0.json" \
    "$out/colors_rd_${field}_default.json" --json "$out/colors_rd_${field}_compare.json" \
    | tee -a "$out/colors_rd_${field}_compare.txt" || status=1
done
exit "$status"
