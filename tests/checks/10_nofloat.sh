#!/usr/bin/env bash
# No floating point in the drive firmware (DESIGN.md section 3).
# Every firmware object built for the Cortex-M4 with the soft-float ABI must
# reference no soft-float helper (arm-none-eabi-nm -u); one TAP line per
# object.  Self-tests: the same check flags a deliberately float-using object,
# and hd_nofloat.h rejects float/double at compile time.
set -uo pipefail
cd "$(dirname "$0")/../.."
unset MAKEFLAGS MFLAGS MAKELEVEL
# soft-float helper names (toolchain.md section 5, plus the libgcc names)
RE='__aeabi_(c?[fd](add|sub|mul|div|cmp|rcmp|neg|rsub)|[a-z0-9]*2[fd]|[fd]2)|__(add|sub|mul|div|neg)[sd]f3|__(float|fix|extend|trunc)[a-z]*[sd]f|__(eq|ne|lt|le|gt|ge|unord|cmp)[sd]f2'

shopt -s nullglob
srcs=(firmware/core/*.c firmware/app/*.c firmware/canopen/*.c firmware/port/qemu-m4/*.c firmware/port/common/*.c)
objs=()
for s in "${srcs[@]}"; do objs+=("build/m4/obj/${s%.c}.o"); done
if [ ${#objs[@]} -gt 0 ] && ! make --no-print-directory -s "${objs[@]}" >build/nofloat-make.log 2>&1; then
  echo "not ok - building the firmware objects for Cortex-M4 failed (build/nofloat-make.log)"
  sed 's/^/# /' build/nofloat-make.log | tail -n 20
fi
for i in "${!srcs[@]}"; do
  o=${objs[$i]}
  if [ ! -f "$o" ]; then
    echo "not ok - no Cortex-M4 object for ${srcs[$i]}"
    continue
  fi
  bad=$(arm-none-eabi-nm -u "$o" | awk '{print $NF}' | grep -E "$RE" | tr '\n' ' ')
  if [ -z "$bad" ]; then
    echo "ok - no soft-float helper referenced by ${srcs[$i]} (Cortex-M4, -mfloat-abi=soft)"
  else
    echo "not ok - ${srcs[$i]} references soft-float helpers: $bad"
  fi
done

# ---- self-tests -------------------------------------------------------------
tmp=build/nofloat-selftest
rm -rf "$tmp"; mkdir -p "$tmp"
cat >"$tmp/uses_float.c" <<'C'
#include <stdint.h>
int32_t uses_float(int32_t a, int32_t b);
int32_t uses_float(int32_t a, int32_t b)
{
    double d = (double)a / (double)b + 0.5;
    float f = (float)a * 1.5f;
    return (int32_t)(d + (double)f);
}
C
M4="arm-none-eabi-gcc -mcpu=cortex-m4 -mthumb -mfloat-abi=soft -O2 -std=c99 -ffreestanding"
if $M4 -c "$tmp/uses_float.c" -o "$tmp/uses_float.o" 2>"$tmp/cc.log"; then
  found=$(arm-none-eabi-nm -u "$tmp/uses_float.o" | awk '{print $NF}' | grep -E "$RE" | tr '\n' ' ')
  if [ -n "$found" ]; then
    echo "ok - nofloat check catches a float-using object ($(echo $found | wc -w) helpers: $found)"
  else
    echo "not ok - nofloat check missed the float-using object ($(arm-none-eabi-nm -u "$tmp/uses_float.o" | tr '\n' ' '))"
  fi
else
  echo "not ok - could not build the float-using self-test object ($(head -n 1 "$tmp/cc.log"))"
fi
# integer helpers must not match (no false alarm on 64-bit division)
if printf '__aeabi_ldivmod\n__aeabi_uldivmod\n__aeabi_idiv\n__aeabi_uidiv\n__aeabi_llsl\n__aeabi_lmul\n' | grep -qE "$RE"; then
  echo "not ok - nofloat regex matches an integer helper"
else
  echo "ok - nofloat regex does not match the integer helpers (__aeabi_ldivmod, __aeabi_uldivmod, __aeabi_idiv, ...)"
fi
if $M4 -include firmware/core/hd_nofloat.h -c "$tmp/uses_float.c" -o "$tmp/poisoned.o" 2>"$tmp/poison.log"; then
  echo "not ok - hd_nofloat.h did not reject a float-using source"
elif grep -q 'poisoned' "$tmp/poison.log"; then
  echo "ok - hd_nofloat.h rejects float/double at compile time (attempt to use poisoned)"
else
  echo "not ok - poisoned build failed for another reason: $(head -n 1 "$tmp/poison.log")"
fi
