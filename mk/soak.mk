# mk/soak.mk - long runs (tests/soak/soak.c, optimised build like hdservo-sim).
#
#   make soak                  SOAK_PERIODS (default 10^8) control periods, JSON in
#                              build/results/soak.json
# `make test` runs tests/checks/80_soak.sh: the same program with 10^7 periods.

SOAK_PERIODS ?= 100000000
SOAK_BIN := $(B)/bin/hdservo-soak
# harness pieces the soak needs (not the virtual-drive server or the ctypes API)
SOAK_HARNESS_OBJ = $(filter-out %/serve.o %/simlib.o,$(HARNESS_OPT_OBJ))

$(SOAK_BIN): tests/soak/soak.c $(SOAK_HARNESS_OBJ) $(PORT_OPT_OBJ) $(B)/opt/libhdfw.a $(B)/opt/libhdplant.a
	@mkdir -p $(@D)
	$(HOST_CC) -std=gnu99 -D_POSIX_C_SOURCE=200809L -Wall -Wextra -Werror -O2 -g $(SIM_FW_INC) $(SIM_INC) \
	  -o $@ $< $(SOAK_HARNESS_OBJ) $(PORT_OPT_OBJ) $(B)/opt/libhdfw.a $(B)/opt/libhdplant.a $(PORT_LIBS)

.PHONY: soak
soak: $(SOAK_BIN)
	@mkdir -p $(B)/results
	$(SOAK_BIN) $(SOAK_PERIODS) $(B)/results/soak.json

BUILD_TESTS_EXTRA += $(SOAK_BIN)

# Fault-injection runner for host/hdservo/faults.py (`make results`).
FAULTS_BIN := $(B)/bin/hdservo-faults
$(FAULTS_BIN): tests/soak/faults.c $(SOAK_HARNESS_OBJ) $(PORT_OPT_OBJ) $(B)/opt/libhdfw.a $(B)/opt/libhdplant.a
	@mkdir -p $(@D)
	$(HOST_CC) -std=gnu99 -D_POSIX_C_SOURCE=200809L -Wall -Wextra -Werror -O2 -g $(SIM_FW_INC) $(SIM_INC) \
	  -o $@ $< $(SOAK_HARNESS_OBJ) $(PORT_OPT_OBJ) $(B)/opt/libhdfw.a $(B)/opt/libhdplant.a $(PORT_LIBS)
BUILD_TESTS_EXTRA += $(FAULTS_BIN)
