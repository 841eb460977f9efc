#!/usr/bin/env bash
# `make demo`: the most complete end-to-end path that exists today.
# Runs the unchanged drive firmware against the simulated reference axis
# (every plant effect on) in lock-step, and summarises the logs.
set -euo pipefail
cd "$(dirname "$0")/.."
out=build/demo
mkdir -p "$out"
t0=$(date +%s)
for s in step slow_rate; do
  echo "demo: hdservo-sim run sim/scenarios/$s.toml -> $out/$s.csv"
  build/bin/hdservo-sim run "sim/scenarios/$s.toml" -o "$out/$s.csv"
done
.venv/bin/python tools/demo_summary.py "$out/step.csv" "$out/slow_rate.csv"
echo "demo: done in $(( $(date +%s) - t0 )) s; logs and sidecars in $out/"
