#!/usr/bin/env bash
# Run every *.sh and *.py in a directory (sorted), as `make bench` / `make results` do.
# A script that fails is reported and makes the whole run fail at the end.
set -uo pipefail
cd "$(dirname "$0")/.."
dir=$1
rc=0
shopt -s nullglob
for f in "$dir"/*.sh "$dir"/*.py; do
  echo "== $f"
  case "$f" in
    *.sh) bash "$f" || { echo "FAILED: $f"; rc=1; } ;;
    *.py) .venv/bin/python "$f" || { echo "FAILED: $f"; rc=1; } ;;
  esac
done
exit $rc
