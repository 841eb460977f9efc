#!/usr/bin/env bash
# 60_fuzz.sh - libFuzzer targets (tests/fuzz/, built by mk/fuzz.mk): every
# committed corpus input replayed under ASan+UBSan, then a short fuzzing run
# per target (FUZZ_TEST_SECONDS, default 12 s each).  Every tests/fuzz/fuzz_*.c is
# a target (run.sh finds them; mk/fuzz.mk builds each one).  Prints executions and
# coverage (libFuzzer cov:/ft:).  `make fuzz` fuzzes longer.
cd "$(dirname "$0")/../.." || exit 1
exec bash tests/fuzz/run.sh test
