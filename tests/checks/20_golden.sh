#!/usr/bin/env bash
# Golden vectors: the Cortex-M4 image (build/golden/gv_m4.elf, QEMU
# mps2-an386) replays the host-generated inputs and compares every output
# word with the host x86-64 result.  One TAP line per registered kernel.
set -uo pipefail
cd "$(dirname "$0")/../.."
elf=build/golden/gv_m4.elf
list=build/golden/kernels.txt
if [ ! -f "$elf" ] || [ ! -f "$list" ]; then
  echo "not ok - golden vectors: $elf or $list missing (run make build-tests golden)"
  exit 0
fi
out=$(tools/qemu-m4-run.sh "$elf" 2>&1); rc=$?
nfail=0
while read -r name nin nout count hascost; do
  [ -n "$name" ] || continue
  line=$(grep -E "^(PASS|FAIL) $name( |$)" <<<"$out" | head -n 1)
  case "$line" in
    "PASS $name "*) echo "ok - golden $name: $count vectors bit-exact, host x86-64 vs Cortex-M4 (QEMU mps2-an386)";;
    "FAIL $name "*) echo "not ok - golden $name: ${line#FAIL $name }"; nfail=$((nfail + 1));;
    *) echo "not ok - golden $name: no result from the Cortex-M4 image"; nfail=$((nfail + 1));;
  esac
done <"$list"
# anything the image reports that is not a listed kernel (stale build)
while read -r l; do
  echo "not ok - golden image: $l"; nfail=$((nfail + 1))
done < <(grep -E '^FAIL ' <<<"$out" | while read -r _ n rest; do grep -q "^$n " "$list" || echo "$n $rest"; done)
if ! grep -q '^DONE ' <<<"$out"; then
  echo "not ok - golden image did not finish (rc $rc)"; nfail=$((nfail + 1))
  sed 's/^/# /' <<<"$out" | tail -n 5
elif [ "$rc" != 0 ] && [ "$nfail" = 0 ]; then
  echo "not ok - golden image exited with rc $rc without naming a failing kernel"
fi
exit 0
