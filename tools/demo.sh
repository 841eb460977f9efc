#!/usr/bin/env bash
# `make demo`: the most complete end-to-end path that exists (grows with the project).
set -euo pipefail
cd "$(dirname "$0")/.."
echo "hdservo demo: nothing to run yet"
