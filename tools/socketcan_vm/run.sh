#!/usr/bin/env bash
# tools/socketcan_vm/run.sh - `make test-socketcan` (docs/can.md, "SocketCAN in a VM").
#
# Boots Debian's standard amd64 kernel (CONFIG_CAN_VCAN=m) under QEMU TCG with an
# initramfs holding busybox, the CAN modules, can-utils and build/bin/hdservo-sim
# (with its shared libraries from ldd), runs the virtual drive on a real vcan0
# against a candump/cansend peer (tools/socketcan_vm/init.in) and turns the VM's
# RESULT lines into TAP.  Exit 0 only if every check passed.
#
#   tools/socketcan_vm/run.sh [--no-install]
#     --no-install   never apt-get: print "SKIP <reason>" and exit 77 if qemu,
#                    busybox-static, kmod, cpio or the kernel package is missing
#   env: SOCKETCAN_VM_KPKG (default: newest linux-image-6.1.0-N-amd64 apt knows),
#        SOCKETCAN_VM_DURATION (simulated seconds the drive runs, default 3),
#        SOCKETCAN_VM_TIMEOUT (qemu wall-clock limit, default 120)
# Everything goes to build/socketcan/ (the kernel .deb is cached in build/socketcan/deb/).
set -euo pipefail
cd "$(dirname "$0")/../.."
ROOT=$PWD
OUT=$ROOT/build/socketcan
SIM=$ROOT/build/bin/hdservo-sim
DURATION=${SOCKETCAN_VM_DURATION:-3}
TMO=${SOCKETCAN_VM_TIMEOUT:-120}
INSTALL=1
[ "${1:-}" = "--no-install" ] && INSTALL=0
mkdir -p "$OUT/deb"
skip() { echo "SKIP $*"; exit 77; }
die() { echo "test-socketcan: error: $*" >&2; exit 1; }

[ -x "$SIM" ] || die "$SIM not built (make build/bin/hdservo-sim)"

# ---- host tools (tools/setup.sh installs them for make test; installed here for a bare checkout)
need=()
command -v qemu-system-x86_64 >/dev/null || need+=(qemu-system-x86)
[ -x /bin/busybox ] && file -L /bin/busybox 2>/dev/null | grep -q static || \
  { dpkg-query -W -f='${Status}' busybox-static 2>/dev/null | grep -q "ok installed" || need+=(busybox-static); }
command -v depmod >/dev/null || [ -x /usr/sbin/depmod ] || need+=(kmod)
command -v cpio >/dev/null || need+=(cpio)
command -v candump >/dev/null || need+=(can-utils)
if [ ${#need[@]} -gt 0 ]; then
  [ $INSTALL = 1 ] || skip "missing Debian packages: ${need[*]}"
  echo "test-socketcan: installing Debian packages for the SocketCAN VM test: ${need[*]}"
  SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo -n"
  DEBIAN_FRONTEND=noninteractive timeout 600 $SUDO apt-get install -y -qq --no-install-recommends \
    -o DPkg::Lock::Timeout=300 "${need[@]}" > "$OUT/apt.log" 2>&1 \
    || die "apt-get install ${need[*]} failed (build/socketcan/apt.log); install them by hand"
fi
BUSYBOX=/bin/busybox
DEPMOD=$(command -v depmod || echo /usr/sbin/depmod)

# ---- kernel package (cached)
deb=$(ls "$OUT"/deb/linux-image-6.1.0-*-amd64_*.deb 2>/dev/null | sort -V | tail -n 1 || true)
if [ -z "$deb" ]; then
  KPKG=${SOCKETCAN_VM_KPKG:-$(apt-cache search --names-only '^linux-image-6\.1\.0-[0-9]+-amd64$' 2>/dev/null \
                               | cut -d' ' -f1 | sort -V | tail -n 1)}
  if [ -z "$KPKG" ]; then
    [ $INSTALL = 1 ] && die "apt knows no linux-image-6.1.0-N-amd64 package (apt-get update?)"
    skip "no linux-image-6.1.0-N-amd64 package known to apt"
  fi
  echo "test-socketcan: downloading $KPKG (cached in build/socketcan/deb/)"
  (cd "$OUT/deb" && timeout 300 apt-get download -q "$KPKG" >"$OUT/download.log" 2>&1) || {
    [ $INSTALL = 1 ] && die "apt-get download $KPKG failed (build/socketcan/download.log)"
    skip "apt-get download $KPKG failed"; }
  deb=$(ls "$OUT"/deb/linux-image-6.1.0-*-amd64_*.deb | sort -V | tail -n 1)
fi
KDIR=$OUT/kernel
if [ ! -f "$KDIR/.from" ] || [ "$(cat "$KDIR/.from")" != "$(basename "$deb")" ]; then
  rm -rf "$KDIR"; mkdir -p "$KDIR"
  dpkg -x "$deb" "$KDIR"
  basename "$deb" > "$KDIR/.from"
fi
KVER=$(ls "$KDIR/lib/modules" | head -n 1)
[ -n "$KVER" ] || die "no lib/modules/ in $deb"

# ---- uncompressed vmlinux from the bzImage (boots through PVH in ~3 s)
if [ ! -s "$OUT/vmlinux" ] || [ "$OUT/vmlinux" -ot "$KDIR/.from" ]; then
  python3 - "$KDIR/boot/vmlinuz-$KVER" "$OUT/vmlinux" <<'PY'
import lzma, sys
data = open(sys.argv[1], "rb").read()
off = data.find(b"\xfd7zXZ\x00")
if off < 0:
    sys.exit("no xz stream in " + sys.argv[1])
out = lzma.LZMADecompressor(format=lzma.FORMAT_XZ).decompress(data[off:])
if out[:4] != b"\x7fELF":
    sys.exit("decompressed kernel is not an ELF vmlinux")
open(sys.argv[2], "wb").write(out)
PY
fi

# ---- initramfs
R=$OUT/root
rm -rf "$R"; mkdir -p "$R"/{bin,sbin,usr/bin,usr/sbin,proc,sys,dev,tmp,lib/modules/$KVER}
cp "$BUSYBOX" "$R/bin/busybox"
for a in $("$BUSYBOX" --list-full | grep -vx bin/busybox); do ln -sf /bin/busybox "$R/$a" 2>/dev/null || true; done
MSRC=$KDIR/lib/modules/$KVER
for m in kernel/net/can/can.ko kernel/net/can/can-raw.ko kernel/drivers/net/can/vcan.ko \
         kernel/drivers/net/can/dev/can-dev.ko; do
  f=$(ls "$MSRC/$m"* 2>/dev/null | head -n 1) || true
  [ -n "$f" ] || die "$m not in $deb (need the standard, not the cloud, kernel)"
  mkdir -p "$R/lib/modules/$KVER/$(dirname "$m")"; cp "$f" "$R/lib/modules/$KVER/$(dirname "$m")/"
done
cp "$MSRC/modules.order" "$MSRC/modules.builtin" "$R/lib/modules/$KVER/"
"$DEPMOD" -b "$R" "$KVER" 2>&1 | grep -v "modules.builtin.modinfo" >&2 || true
copy_bin() {   # copy_bin SRC DEST: the binary and every shared library ldd names
  cp "$1" "$R/$2"
  for lib in $(ldd "$1" | grep -o '/[^ ]*'); do
    mkdir -p "$R$(dirname "$lib")"; cp -L "$lib" "$R$lib"
  done
}
copy_bin "$SIM" usr/bin/hdservo-sim
copy_bin "$(command -v candump)" usr/bin/candump
copy_bin "$(command -v cansend)" usr/bin/cansend
sed "s/@DURATION@/$DURATION/g" tools/socketcan_vm/init.in > "$R/init"
chmod +x "$R/init"
(cd "$R" && find . | cpio -o -H newc --quiet | gzip -1 > "$OUT/initrd.gz")

# ---- boot and check
echo "# SocketCAN VM: kernel $KVER ($(basename "$deb")), initramfs $(du -h "$OUT/initrd.gz" | cut -f1), drive --duration $DURATION"
t0=$(date +%s.%N)
set +e
timeout "$TMO" qemu-system-x86_64 -accel tcg -cpu max -m 512M -nographic -no-reboot -monitor none \
  -kernel "$OUT/vmlinux" -initrd "$OUT/initrd.gz" -append "console=ttyS0 panic=-1 loglevel=3" \
  < /dev/null > "$OUT/console.log" 2>&1
qrc=$?
set -e
t1=$(date +%s.%N)
tr -d '\r' < "$OUT/console.log" > "$OUT/console.txt"
n=0; fail=0
while IFS= read -r line; do
  case "$line" in
    "RESULT ok "*)   n=$((n + 1)); echo "ok $n - socketcan vm: ${line#RESULT ok }" ;;
    "RESULT fail "*) n=$((n + 1)); fail=1; echo "not ok $n - socketcan vm: ${line#RESULT fail }" ;;
    INFO*)           echo "# ${line#INFO }" ;;
  esac
done < <(grep -a -o -E '(RESULT (ok|fail) |INFO ).*' "$OUT/console.txt")
n=$((n + 1))
if grep -a -q 'RESULT end$' "$OUT/console.txt"; then
  echo "ok $n - socketcan vm: VM ran to the end (qemu rc $qrc, $(printf '%.1f' "$(echo "$t1 - $t0" | bc -l 2>/dev/null || python3 -c "print($t1-$t0)")") s)"
else
  fail=1
  echo "not ok $n - socketcan vm: VM did not finish (qemu rc $qrc, timeout ${TMO}s); console in build/socketcan/console.txt:"
  tail -n 15 "$OUT/console.txt" | sed 's/^/#   /'
fi
[ $n -ge 7 ] || { fail=1; echo "# expected 6 RESULT lines and the end marker, got $((n - 1))"; }
exit $fail
