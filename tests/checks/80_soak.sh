#!/usr/bin/env bash
# 80_soak.sh - 10^7 control periods on the simulator (optimised build) plus the
# trajectory-exactness and adaptive-bound runs of tests/soak/soak.c (about 10 s).
# `make soak` runs 10^8.  Prints TAP lines itself.
cd "$(dirname "$0")/../.." || exit 1
bin=build/bin/hdservo-soak
[ -x "$bin" ] || { echo "not ok - soak: $bin not built"; exit 0; }
mkdir -p build/results
exec "$bin" "${SOAK_TEST_PERIODS:-10000000}" build/results/soak_test.json
