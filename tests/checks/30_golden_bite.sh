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
  'sin_fast_trunc|s@(int32_t)((s31 + 1u) >> 1); /\* HD_SIN_FAST_ROUNDING@(int32_t)(s31 >> 1); /* MUTANT@|hd_sin_turn_fast|truncated rounding in hd_sin_turn_fast'
  'add_wrap|s@return hd_sat32((int64_t)a + (int64_t)b); /\* HD_ADD_SAT_SATURATION@return (int32_t)((int64_t)a + (int64_t)b); /* MUTANT@|hd_add_sat|wrap-around instead of saturation in hd_add_sat'
)
# bite SOURCE IMAGE MUTANT...: each mutant is a sed-altered copy of SOURCE under
# build/bite/<name>/, built into build/bite/<name>/IMAGE; the M4 replay must fail and name
# the kernel.
bite() {
  local src=$1 image=$2; shift 2
  local base m name expr kernel desc dir out rc hit others
  base=$(basename "$src")
  for m in "$@"; do
    IFS='|' read -r name expr kernel desc <<<"$m"
    dir=build/bite/$name
    mkdir -p "$dir"
    sed "$expr" "$src" >"$dir/$base.new"
    if ! grep -q 'MUTANT' "$dir/$base.new"; then
      echo "not ok - bite $name: the sed pattern no longer matches $src (marker comment moved?)"
      continue
    fi
    # keep the timestamp when the mutant is unchanged, so make does not rebuild
    if cmp -s "$dir/$base.new" "$dir/$base"; then rm -f "$dir/$base.new"; else mv -f "$dir/$base.new" "$dir/$base"; fi
    if ! make --no-print-directory -s "$dir/$image" >"$dir/make.log" 2>&1; then
      echo "not ok - bite $name: the mutant image did not build ($dir/make.log)"
      sed 's/^/# /' "$dir/make.log" | tail -n 5
      continue
    fi
    out=$(tools/qemu-m4-run.sh "$dir/$image" 2>&1); rc=$?
    hit=$(grep -E "^FAIL $kernel vector " <<<"$out" | head -n 1)
    others=$(grep -cE '^PASS ' <<<"$out")
    if [ "$rc" != 0 ] && [ -n "$hit" ]; then
      echo "ok - golden check catches $desc (rc $rc; $hit; $others other kernels still pass)"
    else
      echo "not ok - golden check missed $desc (rc $rc, no 'FAIL $kernel' line)"
    fi
  done
}

bite "$src" gv_m4.elf "${mutants[@]}"

# The Cortex-M4 bodies of hd_fixed.h: a mutated copy of the header is compiled
# into the hdf_* kernels of the M4 image (mk/golden.mk, gv_m4_h.elf); the host
# side runs the portable bodies, so the comparison must name the kernel.
hmutants=(
  'h_qadd|s@"qadd %0, %1, %2"@"add %0, %1, %2" /* MUTANT */@|hdf_add_sat|wrap-around instead of QADD in the M4 hdf_add_sat'
  'h_rnd_shift|s@"asrvc %\[yh\], %\[yh\], %\[s\]"@"lsrvc %[yh], %[yh], %[s]" /* MUTANT */@|hdf_asr64_rnd|logical instead of arithmetic shift in the M4 hdf_asr64_rnd'
  'h_rnd_fit_carry|s@"adc %\[yh\], %\[hi\], #0"@"mov %[yh], %[hi]" /* MUTANT */@|hdf_asr32_rnd_fit|rounding carry dropped in the M4 hdf_asr32_rnd_fit'
  'h_smmulr|s@"smmulr %0, %1, %2"@"smmul %0, %1, %2" /* MUTANT */@|hdf_smmulr|rounding dropped in the M4 hdf_smmulr (SMMUL for SMMULR)'
  'h_smmlar|s@"smmlar %0, %1, %2, %3"@"smmla %0, %1, %2, %3" /* MUTANT */@|hdf_smmlar|rounding dropped in the M4 hdf_smmlar (SMMLA for SMMLAR)'
  'h_dot2|s@"smlal %\[lo\], %\[hi\], %\[c\], %\[d\]"@"smull %[lo], %[hi], %[c], %[d]" /* MUTANT */@|hdf_dot2_rnd32|first product and rounding dropped in the M4 hdf_dot2_rnd32'
  'h_dot2_64|s@"smull %\[lo\], %\[hi\], %\[a\], %\[b\]\\n\\t"@"mov %[lo], #0\\n\\tmov %[hi], #0\\n\\t" /* MUTANT */@|hdf_dot2_64|first product dropped in the M4 hdf_dot2_64'
  'h_ssat|s@"ssat %0, %1, %2"@"mov %0, %2" /* MUTANT */@|hdf_ssat|saturation dropped in the M4 hdf_ssat'
  'h_mac64|s@"smull %\[pl\], %\[ph\], %\[x\], %\[y\]"@"umull %[pl], %[ph], %[x], %[y]" /* MUTANT */@|hdf_mac64|unsigned instead of signed product in the M4 hdf_mac64'
  'h_mul96_sign|s@"and %\[n\], %\[al\], %\[b\], asr #31\\n\\t"@"mov %[n], #0\\n\\t" /* MUTANT */@|hdf_mul64x32_q|missing negative-b correction in the M4 96-bit product'
)
bite firmware/core/hd_fixed.h gv_m4_h.elf "${hmutants[@]}"
exit 0
