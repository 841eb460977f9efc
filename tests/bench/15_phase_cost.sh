#!/usr/bin/env bash
# Per-phase Cortex-M4 instruction cost of one control period (hd_app_step) in
# the kernels control_step_baseline, control_step_full / semi / dual,
# isr_worst_case and isr_worst_case_semi_t2 (these at every tick of the bank's schedule, folded to the worst)
# -> build/bench/phase_cost.json.  Same counter as 10_cm4_cost.sh (QEMU TCG
# plugin tools/qemu-insncount on mps2-an386); the probe image is the cost image
# with hd_app.c compiled with HD_APP_PHASE_PROBE (a mark between the phases of
# hd_app_step) and tests/bench/phase/phase_main.c running one kernel's cost().
# Each probe mark costs the 2-instruction mark baseline (subtracted) and a call's
# register spills around it, so the phases add up to a little more than the
# kernel's count in cm4_cost.json.  Never fails on "too slow".
set -uo pipefail
cd "$(dirname "$0")/../.."
unset MAKEFLAGS MFLAGS MAKELEVEL
so=build/tools/libinsncount.so
d=build/bench/phase_cost.d
make --no-print-directory -s build/golden/cost_m4.elf "$so" || { echo "phase_cost: building the cost image failed"; exit 1; }
mkdir -p "$d"
CC=arm-none-eabi-gcc
ARCH="-mcpu=cortex-m4 -mthumb -mfloat-abi=soft"
CFLAGS="$ARCH -std=c99 -include firmware/core/hd_nofloat.h -Wall -Wextra -Werror -O2 -g -ffunction-sections -fdata-sections -ffreestanding"
INC="-Ifirmware/core -Ifirmware/app -Ifirmware/canopen -Ifirmware/hal -Ifirmware/port/qemu-m4 -Itests/golden -Ibuild/golden"
$CC $CFLAGS $INC -DHD_APP_PHASE_PROBE -Dhd_app_phase_mark=hd_gv_cost_mark -c firmware/app/hd_app.c -o "$d/hd_app_probe.o" \
  || { echo "phase_cost: probe build of hd_app.c failed"; exit 1; }
q=build/m4/obj/firmware/port/qemu-m4
objs=("$q/startup.o" "$q/semihost.o" build/m4/obj/firmware/port/common/mini_libc.o build/m4/obj/tests/golden/*.o build/golden/m4/gv_registry.o)
PY=.venv/bin/python; [ -x "$PY" ] || PY=python3
args=()
# the kernels with the bank on are measured at every tick of its schedule (hd_sched.h)
cycle=$(awk '$1=="#define" && $2=="HD_SCHED_CYCLE"{gsub("u","",$3); print $3}' firmware/app/hd_sched.h)
[ -n "$cycle" ] || { echo "phase_cost: no HD_SCHED_CYCLE in firmware/app/hd_sched.h"; exit 1; }
kernels=(control_step_baseline)
for b in control_step_full control_step_semi control_step_dual isr_worst_case isr_worst_case_semi_t2; do
  for ((t = 0; t < cycle; t++)); do kernels+=("$b.s$t"); done
done
for k in "${kernels[@]}"; do
  $CC $CFLAGS $INC "-DHD_PHASE_KERNEL=\"$k\"" -c tests/bench/phase/phase_main.c -o "$d/main_$k.o" || exit 1
  $CC $ARCH -nostdlib -nostartfiles -T firmware/port/qemu-m4/mps2-an386.ld -Wl,--gc-sections -o "$d/$k.elf" \
    "$d/main_$k.o" "$d/hd_app_probe.o" "${objs[@]}" build/m4/libhdfw.a -lgcc || { echo "phase_cost: linking $k failed"; exit 1; }
  mark=$(arm-none-eabi-nm "$d/$k.elf" | awk '$3=="hd_gv_cost_mark"{print "0x"$1}')
  tools/qemu-m4-run.sh "$d/$k.elf" -plugin "$so,mark=$mark,out=$d/marks_$k.txt" >"$d/stdout_$k.txt" 2>&1 \
    || { echo "phase_cost: $k probe run failed"; cat "$d/stdout_$k.txt"; exit 1; }
  args+=("$k" "$d/marks_$k.txt")
done
"$PY" tests/bench/phase/phase_cost.py build/bench/phase_cost.json build/bench/cm4_cost.json "${args[@]}"
