#!/usr/bin/env bash
# 90_socketcan_vm.sh - hdservo-sim serve on a real SocketCAN vcan0 inside a
# QEMU TCG VM (tools/socketcan_vm/run.sh, also `make test-socketcan`); ~7 s.
# Skips (TAP "# SKIP") when qemu-system-x86, busybox-static, kmod, cpio or the
# kernel package cannot be had; never installs anything itself.
cd "$(dirname "$0")/../.." || exit 1
[ -x build/bin/hdservo-sim ] || { echo "not ok - socketcan vm: build/bin/hdservo-sim not built"; exit 0; }
out=$(bash tools/socketcan_vm/run.sh --no-install 2>&1)
rc=$?
if [ $rc = 77 ]; then
  echo "ok - socketcan vm # SKIP ${out#SKIP }"
  exit 0
fi
printf '%s\n' "$out"
exit $rc
