#!/usr/bin/env bash
# Cortex-M4 instruction cost of every golden-vector kernel with a cost()
# function -> build/bench/cm4_cost.json {"kernels": {name: {"instructions": N}}}.
# Counted by the QEMU TCG plugin tools/qemu-insncount on mps2-an386, two runs
# (must agree to the instruction).  Never fails on "too slow".
set -uo pipefail
cd "$(dirname "$0")/../.."
unset MAKEFLAGS MFLAGS MAKELEVEL
elf=build/golden/cost_m4.elf
so=build/tools/libinsncount.so
make --no-print-directory -s "$elf" "$so" || { echo "cm4_cost: building $elf / $so failed"; exit 1; }
mark=$(arm-none-eabi-nm "$elf" | awk '$3=="hd_gv_cost_mark"{print "0x"$1}')
[ -n "$mark" ] || { echo "cm4_cost: hd_gv_cost_mark not found in $elf"; exit 1; }
d=build/bench/cm4_cost.d
mkdir -p "$d"
for r in 1 2; do
  tools/qemu-m4-run.sh "$elf" -plugin "$so,mark=$mark,out=$d/marks$r.txt" >"$d/stdout$r.txt" 2>&1 \
    || { echo "cm4_cost: cost image run $r failed (rc $?)"; cat "$d/stdout$r.txt"; exit 1; }
done
PY=.venv/bin/python; [ -x "$PY" ] || PY=python3
"$PY" tools/cm4_cost.py build/bench/cm4_cost.json "$d/stdout1.txt" "$d/marks1.txt" "$d/stdout2.txt" "$d/marks2.txt"
