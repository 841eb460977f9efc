#!/usr/bin/env bash
# Bite check: the golden-vector comparison must FAIL, and name the kernel,
# when the Cortex-M4 build differs from the host build.  Each mutant is a
# sed-altered copy of firmware/core/hd_fixed.c under build/bite/<mutant>/,
# linked into the M4 image only (the expected outputs stay the host's).
set -uo pipefail
cd "$(dirname "$0")/../.."
unset MAKEFLAGS MFLAGS MAKELEVEL
src=firmware/core/hd_fixed.c

# mutant | sed expression | kernel that must be named | description
mutants=(
  'mul_trunc|/HD_MUL_Q_ROUNDING/c\    return hd_sat32(hd_asr64_floor(p, q)); /* MUTANT: truncation */|hd_mul_q|truncated rounding in hd_mul_q'
  'div_trunc|s@if (rem >= ud - rem) { /\* HD_DIV_Q_ROUNDING@if (rem > ud) { /* MUTANT@|hd_div_q|truncated rounding in hd_div_q'
  'add_wrap|s@return hd_sat32((int64_t)a + (int64_t)b); /\* HD_ADD_SAT_SATURATION@return (int32_t)((int64_t)a + (int64_t)b); /* MUTANT@|hd_add_sat|wrap-around instead of saturation in hd_add_sat'
)
for m in "${mutants[@]}"; do
  IFS='|' read -r name expr kernel desc <<<"$m"
  dir=build/bite/$name
  mkdir -p "$dir"
  sed "$expr" "$src" >"$dir/hd_fixed.c.new"
  if ! grep -q 'MUTANT' "$dir/hd_fixed.c.new"; then
    echo "not ok - bite $name: the sed pattern no longer matches $src (marker comment moved?)"
    continue
  fi
  # keep the timestamp when the mutant is unchanged, so make does not rebuild
  if cmp -s "$dir/hd_fixed.c.new" "$dir/hd_fixed.c"; then rm -f "$dir/hd_fixed.c.new"; else mv -f "$dir/hd_fixed.c.new" "$dir/hd_fixed.c"; fi
  if ! make --no-print-directory -s "$dir/gv_m4.elf" >"$dir/make.log" 2>&1; then
    echo "not ok - bite $name: the mutant image did not build ($dir/make.log)"
    sed 's/^/# /' "$dir/make.log" | tail -n 5
    continue
  fi
  out=$(tools/qemu-m4-run.sh "$dir/gv_m4.elf" 2>&1); rc=$?
  hit=$(grep -E "^FAIL $kernel vector " <<<"$out" | head -n 1)
  others=$(grep -cE '^PASS ' <<<"$out")
  if [ "$rc" != 0 ] && [ -n "$hit" ]; then
    echo "ok - golden check catches $desc (rc $rc; $hit; $others other kernels still pass)"
  else
    echo "not ok - golden check missed $desc (rc $rc, no 'FAIL $kernel' line)"
  fi
done
exit 0
