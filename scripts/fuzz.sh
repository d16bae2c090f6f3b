#!/usr/bin/env bash
# Runs the libFuzzer targets `make fuzz` built (Makefile, "fuzzing"):
#
#   scripts/fuzz.sh [--jobs N] [--keep] [--json FILE] \
#       BUILD_DIR SECONDS MIN_RUNS MAX_SECONDS TARGET:MAX_LEN...
#
# Each target runs SECONDS on BUILD_DIR/corpus/<target> (kept between runs;
# new inputs go there) plus the seeds, tests/fuzz/regressions/<target> and the
# corpus kept in the tree, tests/fuzz/corpus/<target>. A target that ran fewer
# than MIN_RUNS executions in that time gets a second run until it has, for at
# most MAX_SECONDS in all, so a fast target is not held back and a slow one
# still reaches MIN_RUNS within a bound (`make fuzz-long`: SECONDS 1, so each
# target runs to MIN_RUNS or MAX_SECONDS, whichever comes first).
#
# --jobs N runs N targets at once (a target is one process: libFuzzer's own
# -jobs would split one corpus across workers, which the figures per target
# then have to add up). --keep merges what a target grew into
# tests/fuzz/corpus/<target> afterwards, keeping only inputs that add
# coverage (libFuzzer -merge=1 into an empty folder), so the tree holds the
# smallest corpus that reaches the depth reached. --json writes a line per
# target: executions, seconds, edges covered of those instrumented, features,
# corpus kept.
#
# Prints executions and coverage per target; exits 1 when any target found a
# crash, a hang (-timeout) or an out-of-memory (-rss_limit_mb,
# -malloc_limit_mb), with the input in BUILD_DIR/artifacts/<target>/.
set -uo pipefail
cd "$(dirname "$0")/.." || exit 1
jobs=1 keep=0 json=""
while [ $# -gt 0 ]; do
  case $1 in
    --jobs) jobs=$2; shift 2 ;;
    --keep) keep=1; shift ;;
    --json) json=$2; shift 2 ;;
    *) break ;;
  esac
done
dir=$1 seconds=$2 min_runs=$3 max_seconds=$4
shift 4
# A small ASan quarantine (16 MB instead of 256): the targets free and
# allocate the same buffers every execution, and cycling 256 MB of fresh
# pages through the kernel made them several times slower. A use after free
# within one input is still caught; shorter allocation stacks, likewise.
export ASAN_OPTIONS="${ASAN_OPTIONS:-quarantine_size_mb=16:malloc_context_size=5}"
mkdir -p "$dir/logs"

# run_target TARGET MAX_LEN: fuzzes one target, then writes
# "runs secs edges_covered edges_total features kept_files kept_bytes result"
# to BUILD_DIR/logs/<target>.result.
run_target() {
  local t=$1 max_len=$2
  local corpus="$dir/corpus/$t" log="$dir/logs/$t.log" kept="tests/fuzz/corpus/$t"
  mkdir -p "$corpus" "$dir/artifacts/$t"
  local dirs=("$corpus" "$dir/seeds/$t")
  [ -d "tests/fuzz/regressions/$t" ] && dirs+=("tests/fuzz/regressions/$t")
  [ -d "$kept" ] && dirs+=("$kept")
  # a dictionary of the tokens a target's format is made of, where the
  # fuzzer cannot learn them from the comparisons it sees
  local dict=()
  [ -f "tests/fuzz/$t.dict" ] && dict=(-dict="tests/fuzz/$t.dict")
  echo "fuzz: $t for $seconds s (log: $log)"
  : > "$log"
  local result=ok runs=0 secs=0 phase limit time_limit n s
  for phase in 1 2; do
    limit=() time_limit=$seconds
    if [ "$phase" -eq 2 ]; then
      [ "$runs" -lt "$min_runs" ] && [ "$secs" -lt "$max_seconds" ] || break
      limit=(-runs=$((min_runs - runs)))
      time_limit=$((max_seconds - secs))
    fi
    if ! "$dir/bin/fuzz_$t" -max_total_time="$time_limit" "${limit[@]}" "${dict[@]}" -max_len="$max_len" \
         -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=2048 -print_final_stats=1 \
         -artifact_prefix="$dir/artifacts/$t/" "${dirs[@]}" >> "$log" 2>&1; then
      result=FAILED
    fi
    n=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
    s=$(sed -n 's/^Done [0-9]* runs in \([0-9]*\) second.*/\1/p' "$log" | tail -n 1)
    runs=$((runs + ${n:-0})) secs=$((secs + ${s:-0}))
    [ "$result" = ok ] || break
  done
  # libFuzzer's last status line: "#N DONE cov: C ft: F corp: ..."
  local cov ft total
  cov=$(sed -n 's/^#[0-9]*[[:space:]]*DONE[[:space:]]*cov: \([0-9]*\) ft: \([0-9]*\).*/\1/p' "$log" | tail -n 1)
  ft=$(sed -n 's/^#[0-9]*[[:space:]]*DONE[[:space:]]*cov: [0-9]* ft: \([0-9]*\).*/\1/p' "$log" | tail -n 1)
  total=$(sed -n 's/^INFO: Loaded 1 modules *(\([0-9]*\) inline 8-bit counters).*/\1/p' "$log" | head -n 1)
  local files=0 bytes=0
  if [ "$keep" -eq 1 ] && [ "$result" = ok ]; then
    local fresh="$dir/merge/$t"
    rm -rf "$fresh" && mkdir -p "$fresh"
    local from=("$corpus")
    [ -d "$kept" ] && from+=("$kept")
    if "$dir/bin/fuzz_$t" -merge=1 -max_len="$max_len" -timeout=10 -rss_limit_mb=2048 \
         -malloc_limit_mb=2048 "$fresh" "${from[@]}" >> "$log" 2>&1; then
      rm -rf "$kept" && mkdir -p "$(dirname "$kept")" && mv "$fresh" "$kept"
    else
      result=FAILED
    fi
  fi
  if [ -d "$kept" ]; then
    files=$(find "$kept" -type f | wc -l)
    bytes=$(du -sb "$kept" | cut -f1)
  fi
  echo "$runs $secs ${cov:-0} ${total:-0} ${ft:-0} $files $bytes $result" > "$dir/logs/$t.result"
  [ "$result" = ok ] || tail -n 40 "$log"
}

names=()
for spec in "$@"; do
  t=${spec%%:*}
  names+=("$t")
  rm -f "$dir/logs/$t.result"
  while [ "$(jobs -rp | wc -l)" -ge "$jobs" ]; do wait -n; done
  run_target "$t" "${spec#*:}" &
done
wait

failed="" summary="" lines=""
for t in "${names[@]}"; do
  read -r runs secs cov total ft files bytes result < "$dir/logs/$t.result" \
    || { runs=0 secs=0 cov=0 total=0 ft=0 files=0 bytes=0 result=FAILED; }
  [ "$result" = ok ] || failed="$failed $t"
  rate=$((secs > 0 ? runs / secs : runs))
  summary+=$(printf '%-14s %10d executions in %4d s (%6d/s)  cov %5d of %6d edges, ft %6d  %s' \
    "$t" "$runs" "$secs" "$rate" "$cov" "$total" "$ft" "$result")$'\n'
  lines+=$(printf '{"target":"%s","executions":%d,"seconds":%d,"edges_covered":%d,"edges_instrumented":%d,"features":%d,"corpus_files":%d,"corpus_bytes":%d,"result":"%s"}' \
    "$t" "$runs" "$secs" "$cov" "$total" "$ft" "$files" "$bytes" "$result")$'\n'
done
printf 'fuzz: executions per target (at least %s s each, more up to %s s while under %s)\n%s' \
  "$seconds" "$max_seconds" "$min_runs" "$summary"
if [ -n "$json" ]; then
  mkdir -p "$(dirname "$json")"
  printf '%s' "$lines" > "$json"
  echo "fuzz: figures in $json"
fi
if [ -n "$failed" ]; then
  echo "fuzz: FAILED:$failed -- the inputs are in $dir/artifacts/<target>/; reproduce with" \
       "$dir/bin/fuzz_<target> FILE, fix, and keep the input in tests/fuzz/regressions/<target>/"
  exit 1
fi
