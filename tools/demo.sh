#!/usr/bin/env bash
# `make demo`: the end-to-end demo on the virtual reference axis (docs/demo.md; --axis FILE: another axis).
# Simulated by design (no real drive is touched; `hdservo demo` says so on stderr).
# Starts the virtual drive, identifies the axis over CAN, downloads the compensator
# parameters, runs the test procedures with the PID baseline and with compensation,
# writes build/demo/report.html and build/demo/summary.json, prints a summary table
# and the run time, and stops the virtual drive.  Options are passed to `hdservo demo`
# (e.g. tools/demo.sh --quick, --controllers pid,best).
set -euo pipefail
cd "$(dirname "$0")/.."
exec .venv/bin/hdservo demo "$@"
