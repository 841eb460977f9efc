#!/usr/bin/env bash
# The STM32G474 drive image (issue 11): `make firmware` builds without any
# warning, meets the flash/RAM budget, and links no floating-point code.
# TAP lines.
set -uo pipefail
cd "$(dirname "$0")/../.."
unset MAKEFLAGS MFLAGS MAKELEVEL
log=build/firmware-check.log
mkdir -p build
ELF=build/firmware/hdservo-g474.elf

# a clean image build, so every warning is seen
rm -rf build/firmware
if make --no-print-directory firmware >"$log" 2>&1; then
  echo "ok - make firmware builds build/firmware/hdservo-g474.{elf,bin,hex,map}"
  built=1
else
  if grep -q "budget exceeded" "$log"; then
    echo "ok - make firmware compiles and links (budget checked below)"; built=1
  else
    echo "not ok - make firmware failed (build/firmware-check.log)"; sed 's/^/# /' "$log" | tail -n 20; built=0
  fi
fi
if grep -Eiq '(^|[^a-z])warning:' "$log"; then
  echo "not ok - the firmware build printed warnings"; grep -Ei 'warning:' "$log" | head -5 | sed 's/^/# /'
else
  echo "ok - no compiler or linker warning"
fi
for f in hdservo-g474.elf hdservo-g474.bin hdservo-g474.hex hdservo-g474.map; do
  if [ -s "build/firmware/$f" ]; then echo "ok - build/firmware/$f exists"; else echo "not ok - build/firmware/$f missing"; fi
done
if [ "$built" = 1 ] && grep -q "^hdservo-g474: flash" "$log" && ! grep -q "budget exceeded" "$log"; then
  echo "ok - size budget met: $(grep '^hdservo-g474: flash' "$log")"
else
  echo "not ok - size budget: $(grep -E '^hdservo-g474: flash|budget exceeded' "$log" | tr '\n' ' ')"
fi
# no float: no soft-float helper referenced or defined, no VFP arithmetic in the image
RE='__aeabi_(c?[fd](add|sub|mul|div|cmp|rcmp|neg|rsub)|[a-z0-9]*2[fd]|[fd]2)|__(add|sub|mul|div|neg)[sd]f3|__(float|fix|extend|trunc)[a-z]*[sd]f|__(eq|ne|lt|le|gt|ge|unord|cmp)[sd]f2'
if [ -f "$ELF" ]; then
  bad=$(for o in $(find build/firmware/obj -name '*.o'); do arm-none-eabi-nm "$o"; done | awk '{print $NF}' | grep -E "$RE" | sort -u | tr '\n' ' ')
  badelf=$(arm-none-eabi-nm "$ELF" | awk '{print $NF}' | grep -E "$RE" | sort -u | tr '\n' ' ')
  if [ -z "$bad$badelf" ]; then
    echo "ok - no floating-point helper in the linked objects or the image"
  else
    echo "not ok - floating-point helpers: $bad $badelf"
  fi
  # VFP arithmetic / conversions must not appear; gcc may use the FPU register
  # file for plain 64-bit moves under the hard-float ABI (vldr/vstr/vmov),
  # which is data movement, not floating point (the FPU is enabled at reset).
  dis=$(arm-none-eabi-objdump -d "$ELF")
  nv=$(grep -cE $'\tv(add|sub|mul|div|cvt|sqrt|fma|fms|fnm|nmul|neg|abs|cmp|mla|mls|rint|sel|max|min)' <<<"$dis" || true)
  nm=$(grep -cE $'\tv(ldr|str|mov|push|pop|ldm|stm)' <<<"$dis" || true)
  if [ "$nv" = 0 ]; then
    echo "ok - no VFP arithmetic or conversion in the image ($nm VFP register moves used for 64-bit data)"
  else
    echo "not ok - $nv VFP arithmetic/conversion instructions in the image"
  fi
  # the vector table sits at the start of flash; the reset vector points into flash (Thumb bit set)
  rv=$(arm-none-eabi-objdump -s -j .isr_vector "$ELF" | awk '/^ 8000000/{print $3}')
  if [[ "$rv" =~ ^[0-9a-f]{6}08$ ]] && [ $((16#${rv:0:2} & 1)) = 1 ]; then
    echo "ok - reset vector in flash, Thumb ($rv)"
  else
    echo "not ok - reset vector word '$rv'"
  fi
else
  echo "not ok - no image to inspect"
fi
