#!/usr/bin/env bash
# run_fuzz.sh BUILD_DIR SECONDS [TARGET...]: runs each fuzz target of BUILD_DIR/fuzz (built with
# HMAP_FUZZ=ON, seeds made by the fuzz_corpus target) for SECONDS, one after another, one process
# each (-jobs is not used: the machine's cores are shared). Inputs that grow coverage go to
# BUILD_DIR/fuzz/work/TARGET; a crash, a leak, a timeout or running out of memory stops the run,
# leaves the input in BUILD_DIR/fuzz/artifacts/TARGET/ and makes the script fail.
# Prints one line per target: time, executions, coverage, corpus size (for docs/RELIABILITY.md).
set -euo pipefail
if [ $# -lt 2 ]; then echo "usage: $0 BUILD_DIR SECONDS [TARGET...]" >&2; exit 2; fi
build=$(cd "$1" && pwd)
seconds=$2
shift 2
src=$(cd "$(dirname "$0")" && pwd)
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  for program in "$build"/fuzz/fuzz_*; do
    name=${program##*/fuzz_}
    [ "$name" = seeds ] || targets+=("$name")
  done
fi
status=0
for name in "${targets[@]}"; do
  work=$build/fuzz/work/$name
  artifacts=$build/fuzz/artifacts/$name
  log=$build/fuzz/logs/$name.log
  mkdir -p "$work" "$artifacts" "$(dirname "$log")"
  seeds=()
  for dir in "$build/fuzz/seeds/$name" "$src/corpus/$name" "$src/regressions/$name"; do
    [ -d "$dir" ] && seeds+=("$dir")
  done
  start=$(date +%s)
  if ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=0 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
     "$build/fuzz/fuzz_$name" "$work" "${seeds[@]}" -max_total_time="$seconds" -rss_limit_mb=2048 \
       -malloc_limit_mb=2048 -timeout=10 -max_len=65536 -print_final_stats=1 -artifact_prefix="$artifacts/" \
       >"$log" 2>&1; then
    result=ok
  else
    result=FAILED
    status=1
  fi
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo "?")
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*' || echo "?")
  printf '%-12s %-6s %4ss  %10s execs  cov %6s  corpus %5s files\n' "$name" "$result" "$(( $(date +%s) - start ))" \
    "$execs" "$cov" "$(ls "$work" | wc -l)"
  if [ $result = FAILED ]; then
    grep -E 'ERROR|SUMMARY|property violated|terminate|what\(\)|deadly signal|Test unit written' "$log" | head -20 | sed 's/^/    /'
  fi
done
exit $status
