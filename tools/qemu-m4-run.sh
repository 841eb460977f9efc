#!/usr/bin/env bash
# Run a Cortex-M4 test image on QEMU mps2-an386 with semihosting on stdout,
# always under a timeout (a hung image must not hang the test run).
#   tools/qemu-m4-run.sh IMAGE.elf [extra qemu args...]
# Exit status: the image's own (SYS_EXIT_EXTENDED), 124 on timeout.
set -uo pipefail
elf=$1; shift
exec timeout "${HD_QEMU_TIMEOUT:-60}" qemu-system-arm -M mps2-an386 -nographic -monitor none -serial none \
  -chardev stdio,id=sh0 -semihosting-config enable=on,target=native,chardev=sh0 "$@" -kernel "$elf"
