#!/usr/bin/env bash
# tests/fuzz/run.sh - run the libFuzzer targets built by mk/fuzz.mk.
#
#   run.sh run   T...   fuzz each target for $FUZZ_SECONDS (default 60) from the
#                       committed corpus; new inputs in build/fuzz/corpus/T,
#                       crashes in build/fuzz/artifacts/T; summary JSON in
#                       build/fuzz/summary.json
#   run.sh test  [T...] for `make test` (TAP): replay every committed input
#                       (must not crash), then $FUZZ_TEST_SECONDS (default 12)
#                       of fuzzing from a scratch copy of the corpus
#   run.sh merge T...   minimise build/fuzz/corpus/T into tests/fuzz/corpus/T
#
# Execution counts and coverage come from libFuzzer's -print_final_stats=1
# (stat::number_of_executed_units) and its last status line (cov: = covered
# edges / PCs, ft: = features).  Time limits are wall-clock budgets, never
# pass/fail criteria: a slow machine just executes fewer inputs.
set -uo pipefail
cd "$(dirname "$0")/../.."
B=build/fuzz
mode=${1:-test}; shift || true
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  for f in tests/fuzz/fuzz_*.c; do t=${f#tests/fuzz/fuzz_}; targets+=("${t%.c}"); done
fi
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
COMMON=(-timeout=10 -rss_limit_mb=1536 -print_final_stats=1)

stat() {  # stat LOG -> "execs cov ft corpus"
  local log=$1 execs cov ft
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n1)
  cov=$(grep -oE 'cov: [0-9]+' "$log" | tail -n1 | awk '{print $2}')
  ft=$(grep -oE 'ft: [0-9]+' "$log" | tail -n1 | awk '{print $2}')
  echo "${execs:-0} ${cov:-0} ${ft:-0}"
}

case $mode in
run)
  secs=${FUZZ_SECONDS:-60}
  json="$B/summary.json"; echo "{" >"$json.tmp"; first=1
  for t in "${targets[@]}"; do
    mkdir -p "$B/corpus/$t" "$B/artifacts/$t"
    log="$B/$t.log"
    "$B/fuzz_$t" "${COMMON[@]}" -max_total_time="$secs" -artifact_prefix="$B/artifacts/$t/" \
      "$B/corpus/$t" "tests/fuzz/corpus/$t" >"$log" 2>&1
    rc=$?
    read -r execs cov ft <<<"$(stat "$log")"
    ncorp=$(ls "$B/corpus/$t" "tests/fuzz/corpus/$t" | wc -l)
    printf 'fuzz %-9s %4ss  execs %-9s cov %-5s ft %-6s corpus %-5s %s\n' "$t" "$secs" "$execs" "$cov" "$ft" "$ncorp" \
      "$([ $rc = 0 ] && echo ok || echo "CRASH (see $log, $B/artifacts/$t/)")"
    [ $first = 1 ] || echo "," >>"$json.tmp"; first=0
    printf '  "%s": {"seconds": %s, "executions": %s, "cov": %s, "ft": %s, "exit": %s}' "$t" "$secs" "$execs" "$cov" "$ft" "$rc" >>"$json.tmp"
  done
  printf '\n}\n' >>"$json.tmp"; mv "$json.tmp" "$json"
  ;;
test)
  secs=${FUZZ_TEST_SECONDS:-12}
  total=0
  for t in "${targets[@]}"; do
    bin="$B/fuzz_$t"
    if [ ! -x "$bin" ]; then echo "not ok - fuzz $t: $bin not built (make fuzz-build)"; continue; fi
    log="$B/$t.test.log"
    n=$(ls "tests/fuzz/corpus/$t" | wc -l)
    mkdir -p "$B/artifacts/$t"
    if "$bin" "${COMMON[@]}" -runs=0 -artifact_prefix="$B/artifacts/$t/" "tests/fuzz/corpus/$t" >"$log" 2>&1; then
      read -r execs cov ft <<<"$(stat "$log")"
      echo "ok - fuzz $t: $n committed inputs replayed clean (cov $cov, ft $ft)"
    else
      echo "not ok - fuzz $t: a committed input fails (see $log)"; tail -n 20 "$log" | sed 's/^/# /'
      continue
    fi
    scratch="$B/test-corpus/$t"; rm -rf "$scratch"; mkdir -p "$scratch" "$B/artifacts/$t"
    cp "tests/fuzz/corpus/$t"/* "$scratch/"
    "$bin" "${COMMON[@]}" -max_total_time="$secs" -artifact_prefix="$B/artifacts/$t/" "$scratch" >"$log" 2>&1
    rc=$?
    read -r execs cov ft <<<"$(stat "$log")"
    total=$((total + execs))
    if [ $rc = 0 ]; then
      echo "ok - fuzz $t: ${secs}s, $execs executions, cov $cov, ft $ft, no crash"
    else
      echo "not ok - fuzz $t: crash after $execs executions (input saved in $B/artifacts/$t/, log $log)"
      grep -E 'ERROR|invariant failed|runtime error' "$log" | head -n 5 | sed 's/^/# /'
    fi
  done
  echo "# fuzz: $total executions in total"
  ;;
merge)
  for t in "${targets[@]}"; do
    mkdir -p "$B/corpus/$t"
    "$B/fuzz_$t" -merge=1 "tests/fuzz/corpus/$t" "$B/corpus/$t" >"$B/$t.merge.log" 2>&1 &&
      echo "merged $t: $(ls "tests/fuzz/corpus/$t" | wc -l) inputs" || echo "merge $t failed (see $B/$t.merge.log)"
  done
  ;;
*) echo "usage: $0 run|test|merge [target...]" >&2; exit 2 ;;
esac
