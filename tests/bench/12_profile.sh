#!/usr/bin/env bash
# Per-function Cortex-M4 instruction profile of the worst control period
# (isr_worst_case in its worst tick, as cm4_cost.json names it) -> build/bench/profile.json
# (docs/firmware.md "Where the worst period goes").  The cost image runs once more under
# the QEMU TCG plugin tools/qemu-insncount with window=K,pcs=FILE: every instruction
# executed between the kernel's two marks by address; tools/cm4_profile.py sums them per
# function of the image (inlined helpers in their caller) and checks the sum against the
# kernel's count.  Needs 10_cm4_cost.sh first.  Never fails on "too slow".
set -uo pipefail
cd "$(dirname "$0")/../.."
unset MAKEFLAGS MFLAGS MAKELEVEL
elf=build/golden/cost_m4.elf
so=build/tools/libinsncount.so
kernel=isr_worst_case
make --no-print-directory -s "$elf" "$so" || { echo "profile: building $elf / $so failed"; exit 1; }
cm4=build/bench/cm4_cost.json
out1=build/bench/cm4_cost.d/stdout1.txt
[ -f "$cm4" ] && [ -f "$out1" ] || { echo "profile: $cm4 missing (tests/bench/10_cm4_cost.sh first)"; exit 1; }
mark=$(arm-none-eabi-nm "$elf" | awk '$3=="hd_gv_cost_mark"{print "0x"$1}')
[ -n "$mark" ] || { echo "profile: hd_gv_cost_mark not found in $elf"; exit 1; }
PY=.venv/bin/python; [ -x "$PY" ] || PY=python3
d=build/bench/profile.d
mkdir -p "$d"
win=$("$PY" tools/cm4_profile.py window "$cm4" "$out1" "$kernel") || { echo "profile: no window for $kernel"; exit 1; }
tools/qemu-m4-run.sh "$elf" -plugin "$so,mark=$mark,out=$d/marks.txt,window=$win,pcs=$d/pcs.txt" >"$d/stdout.txt" 2>&1 \
  || { echo "profile: cost image run failed (rc $?)"; cat "$d/stdout.txt"; exit 1; }
arm-none-eabi-nm -n -S --defined-only "$elf" >"$d/nm.txt"
"$PY" tools/cm4_profile.py profile build/bench/profile.json "$cm4" "$d/stdout.txt" "$kernel" "$d/pcs.txt" "$d/marks.txt" "$d/nm.txt"
