# mk/socketcan.mk - `make test-socketcan`: the virtual drive on a real Linux
# SocketCAN vcan0 inside a QEMU TCG VM running Debian's standard amd64 kernel,
# against a candump/cansend peer in the VM (boot-up, SDO upload of 0x1018:1,
# heartbeat and TPDO after NMT start).  About 7 s; also run by `make test`
# through tests/checks/90_socketcan_vm.sh.  See docs/can.md, tools/socketcan_vm/.
# Work files and the cached kernel .deb live in build/socketcan/.

.PHONY: test-socketcan
test-socketcan: $(HDSIM_BIN)
	@bash tools/socketcan_vm/run.sh
