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

# The Cortex-M4 bodies of hd_fixed.h: a mutated copy of the header is compiled
# into the hdf_* kernels of the M4 image (mk/golden.mk, gv_m4_h.elf); the host
# side runs the portable bodies, so the comparison must name the kernel.
hsrc=firmware/core/hd_fixed.h
hmutants=(
  'h_qadd|s@"qadd %0, %1, %2"@"add %0, %1, %2" /* MUTANT */@|hdf_add_sat|wrap-around instead of QADD in the M4 hdf_add_sat'
  'h_rnd_shift|s@"asrvc %\[yh\], %\[yh\], %\[s\]"@"lsrvc %[yh], %[yh], %[s]" /* MUTANT */@|hdf_asr64_rnd|logical instead of arithmetic shift in the M4 hdf_asr64_rnd'
  'h_mul96_sign|s@"and %\[n\], %\[al\], %\[b\], asr #31\\n\\t"@"mov %[n], #0\\n\\t" /* MUTANT */@|hdf_mul64x32_q|missing negative-b correction in the M4 96-bit product'
)
for m in "${hmutants[@]}"; do
  IFS='|' read -r name expr kernel desc <<<"$m"
  dir=build/bite/$name
  mkdir -p "$dir"
  sed "$expr" "$hsrc" >"$dir/hd_fixed.h.new"
  if ! grep -q 'MUTANT' "$dir/hd_fixed.h.new"; then
    echo "not ok - bite $name: the sed pattern no longer matches $hsrc"
    continue
  fi
  if cmp -s "$dir/hd_fixed.h.new" "$dir/hd_fixed.h"; then rm -f "$dir/hd_fixed.h.new"; else mv -f "$dir/hd_fixed.h.new" "$dir/hd_fixed.h"; fi
  if ! make --no-print-directory -s "$dir/gv_m4_h.elf" >"$dir/make.log" 2>&1; then
    echo "not ok - bite $name: the mutant image did not build ($dir/make.log)"
    sed 's/^/# /' "$dir/make.log" | tail -n 5
    continue
  fi
  out=$(tools/qemu-m4-run.sh "$dir/gv_m4_h.elf" 2>&1); rc=$?
  hit=$(grep -E "^FAIL $kernel vector " <<<"$out" | head -n 1)
  others=$(grep -cE '^PASS ' <<<"$out")
  if [ "$rc" != 0 ] && [ -n "$hit" ]; then
    echo "ok - golden check catches $desc (rc $rc; $hit; $others other kernels still pass)"
  else
    echo "not ok - golden check missed $desc (rc $rc, no 'FAIL $kernel' line)"
  fi
done
exit 0
