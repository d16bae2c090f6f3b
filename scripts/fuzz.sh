#!/usr/bin/env bash
# Runs the libFuzzer targets `make fuzz` built (Makefile, "fuzzing"):
#
#   scripts/fuzz.sh BUILD_DIR SECONDS MIN_RUNS MAX_SECONDS TARGET:MAX_LEN...
#
# Each target runs SECONDS on build/fuzz/corpus/<target> (kept between runs;
# new inputs go there) plus the seeds and tests/fuzz/regressions/<target>. A
# target that ran fewer than MIN_RUNS executions in that time gets a second
# run until it has, for at most MAX_SECONDS in all, so a fast target is not
# held back and a slow one still reaches MIN_RUNS within a bound. Prints executions per target; exits 1 when any target found
# a crash, a hang (-timeout) or an out-of-memory (-rss_limit_mb,
# -malloc_limit_mb), with the input in BUILD_DIR/artifacts/<target>/.
set -uo pipefail
cd "$(dirname "$0")/.." || exit 1
dir=$1 seconds=$2 min_runs=$3 max_seconds=$4
shift 4
# A small ASan quarantine (16 MB instead of 256): the targets free and
# allocate the same buffers every execution, and cycling 256 MB of fresh
# pages through the kernel made them several times slower. A use after free
# within one input is still caught; shorter allocation stacks, likewise.
export ASAN_OPTIONS="${ASAN_OPTIONS:-quarantine_size_mb=16:malloc_context_size=5}"
mkdir -p "$dir/logs"
failed="" summary=""
for spec in "$@"; do
  t=${spec%%:*} max_len=${spec#*:}
  corpus="$dir/corpus/$t" log="$dir/logs/$t.log"
  mkdir -p "$corpus" "$dir/artifacts/$t"
  dirs=("$corpus" "$dir/seeds/$t")
  [ -d "tests/fuzz/regressions/$t" ] && dirs+=("tests/fuzz/regressions/$t")
  echo "fuzz: $t for $seconds s (log: $log)"
  : > "$log"
  result=ok runs=0 secs=0
  for phase in 1 2; do
    limit=() time_limit=$seconds
    if [ "$phase" -eq 2 ]; then
      [ "$runs" -lt "$min_runs" ] && [ "$secs" -lt "$max_seconds" ] || break
      limit=(-runs=$((min_runs - runs)))
      time_limit=$((max_seconds - secs))
    fi
    if ! "$dir/bin/fuzz_$t" -max_total_time="$time_limit" "${limit[@]}" -max_len="$max_len" \
         -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=2048 -print_final_stats=1 \
         -artifact_prefix="$dir/artifacts/$t/" "${dirs[@]}" >> "$log" 2>&1; then
      result=FAILED
    fi
    n=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
    s=$(sed -n 's/^Done [0-9]* runs in \([0-9]*\) second.*/\1/p' "$log" | tail -n 1)
    runs=$((runs + ${n:-0})) secs=$((secs + ${s:-0}))
    [ "$result" = ok ] || break
  done
  if [ "$result" != ok ]; then
    failed="$failed $t"
    tail -n 40 "$log"
  fi
  rate=$((secs > 0 ? runs / secs : runs))
  summary+=$(printf '%-14s %10d executions in %4d s (%6d/s)  %s' "$t" "$runs" "$secs" "$rate" "$result")$'\n'
done
printf 'fuzz: executions per target (at least %s s each, more up to %s s while under %s)\n%s' \
  "$seconds" "$max_seconds" "$min_runs" "$summary"
if [ -n "$failed" ]; then
  echo "fuzz: FAILED:$failed -- the inputs are in $dir/artifacts/<target>/; reproduce with" \
       "$dir/bin/fuzz_<target> FILE, fix, and keep the input in tests/fuzz/regressions/<target>/"
  exit 1
fi
