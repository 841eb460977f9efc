#!/usr/bin/env bash
# The constant tables of hd_fixed.c are generated: fail if they are stale.
cd "$(dirname "$0")/../.."
if python3 tools/gen_math_tables.py --check; then
  echo "ok - firmware/core/hd_math_tables.h and hd_foc_tables.h match tools/gen_math_tables.py"
else
  echo "not ok - firmware/core/hd_math_tables.h or hd_foc_tables.h is stale: run python3 tools/gen_math_tables.py"
fi
