# mk/control.mk - shared library of the optimised firmware controllers for the
# Python double-precision reference tests (tests/python/test_control_*.py load
# it with ctypes).  Only the core controllers are pulled from the archive
# (no hal.h symbols needed).

CONTROL_SO := $(B)/lib/libhdcontrol.so
CONTROL_SYMS := hd_pid_step hd_pid_reset hd_velobs_step hd_velobs_reset hd_velobs_design \
  hd_velobs_vel_out hd_biquad_step hd_biquad_reset hd_biquad_chain_step hd_traj_reset \
  hd_traj_ptp hd_traj_rate hd_traj_sine hd_traj_step hd_traj_done hd_exc_start hd_exc_step

$(CONTROL_SO): $(B)/opt/libhdfw.a
	@mkdir -p $(@D)
	$(HOST_CC) -shared -o $@ $(addprefix -Wl$(comma)-u$(comma),$(CONTROL_SYMS)) $(B)/opt/libhdfw.a

comma := ,
BUILD_TESTS_EXTRA += $(CONTROL_SO)
