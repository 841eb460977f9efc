# mk/sim.mk - closed-loop harness, `hdservo-sim`, the Python binding's shared
# library, and the harness unit tests.  See docs/sim.md.  Included by the
# top-level Makefile.
#
#   sim/harness/*.c (not *_main.c)   harness, scenario, TOML reader, log writer, simlib
#   firmware/port/host/*.c           hal.h on the PC (firmware flags: integer only)
#   build/bin/hdservo-sim            the scenario runner (optimised objects)
#   build/lib/libhdsim.so            ctypes library for host/hdservo/sim.py (optimised)
#   build/host/libhdharness.a        sanitized harness + port, linked into tests/c/test_harness*

HARNESS_SRC   := $(filter-out %_main.c,$(wildcard sim/harness/*.c))
HARNESS_MAIN  := sim/harness/hdservo_sim_main.c
PORT_HOST_SRC := $(wildcard firmware/port/host/*.c)

HARNESS_HOST_OBJ := $(patsubst %.c,$(B)/host/obj/%.o,$(HARNESS_SRC))
HARNESS_OPT_OBJ  := $(patsubst %.c,$(B)/opt/obj/%.o,$(HARNESS_SRC))
PORT_HOST_OBJ    := $(patsubst %.c,$(B)/host/obj/%.o,$(PORT_HOST_SRC))
PORT_OPT_OBJ     := $(patsubst %.c,$(B)/opt/obj/%.o,$(PORT_HOST_SRC))
HARNESS_MAIN_OBJ := $(patsubst %.c,$(B)/opt/obj/%.o,$(HARNESS_MAIN))

HDSIM_BIN := $(B)/bin/hdservo-sim
HDSIM_SO  := $(B)/lib/libhdsim.so
HARNESS_HOST_LIB := $(B)/host/libhdharness.a

SIM_FW_INC := $(FW_INC) -Ifirmware/port/host

# libsocketcan (bitrate, restart-ms, controller state of the SocketCAN transport)
# when pkg-config finds it (libsocketcan-dev, tools/setup.sh); without it the
# transport still opens raw CAN sockets, it only cannot configure the controller.
SOCKETCAN_LIBS   := $(shell pkg-config --libs libsocketcan 2>/dev/null)
SOCKETCAN_CFLAGS := $(if $(SOCKETCAN_LIBS),-DHD_HAVE_LIBSOCKETCAN $(shell pkg-config --cflags libsocketcan 2>/dev/null))
PORT_LIBS        := $(SOCKETCAN_LIBS) -lm

# The harness (sim side, double precision) sees the firmware headers it drives.
$(HARNESS_HOST_OBJ): HOST_SIM_CFLAGS += $(SIM_FW_INC)
$(HARNESS_OPT_OBJ) $(HARNESS_MAIN_OBJ): OPT_SIM_CFLAGS += $(SIM_FW_INC)
# The host port is firmware/ (integer only, -Werror -Wconversion, nofloat) but
# uses stdio for the NVM file, so it gets POSIX declarations.
$(PORT_HOST_OBJ): HOST_FW_CFLAGS += -D_POSIX_C_SOURCE=200809L $(SOCKETCAN_CFLAGS)
$(PORT_OPT_OBJ): OPT_FW_CFLAGS += -D_POSIX_C_SOURCE=200809L $(SOCKETCAN_CFLAGS)

$(HDSIM_BIN): $(HARNESS_MAIN_OBJ) $(HARNESS_OPT_OBJ) $(PORT_OPT_OBJ) $(B)/opt/libhdfw.a $(B)/opt/libhdplant.a
	@mkdir -p $(@D)
	$(HOST_CC) -O2 -o $@ $(HARNESS_MAIN_OBJ) $(HARNESS_OPT_OBJ) $(PORT_OPT_OBJ) $(B)/opt/libhdfw.a $(B)/opt/libhdplant.a $(PORT_LIBS)

$(HDSIM_SO): $(HARNESS_OPT_OBJ) $(PORT_OPT_OBJ) $(B)/opt/libhdfw.a $(B)/opt/libhdplant.a
	@mkdir -p $(@D)
	$(HOST_CC) -shared -O2 -Wl,-Bsymbolic -o $@ $(HARNESS_OPT_OBJ) $(PORT_OPT_OBJ) $(B)/opt/libhdfw.a $(B)/opt/libhdplant.a $(PORT_LIBS)

$(HARNESS_HOST_LIB): $(HARNESS_HOST_OBJ) $(PORT_HOST_OBJ)
	@mkdir -p $(@D); rm -f $@; ar rcs $@ $^

# Harness unit tests link the sanitized harness + port before the firmware
# and plant libraries (static pattern rule: wins over the generic test rule).
HARNESS_TESTS := $(patsubst tests/c/%.c,$(B)/host/tests/%,$(wildcard tests/c/test_harness*.c))
$(HARNESS_TESTS): $(B)/host/tests/%: tests/c/%.c $(CTEST_HELPERS) $(HARNESS_HOST_LIB) $(B)/host/libhdfw.a $(B)/host/libhdplant.a
	@mkdir -p $(@D)
	$(HOST_CC) -std=c99 -D_POSIX_C_SOURCE=200809L -Wall -Wextra -Werror -O1 -g $(SAN) $(SIM_FW_INC) $(SIM_INC) -Itests/c \
	  -o $@ $< $(CTEST_HELPERS) $(HARNESS_HOST_LIB) $(B)/host/libhdfw.a $(B)/host/libhdplant.a -lcmocka $(PORT_LIBS)

.PHONY: sim
sim: $(HDSIM_BIN) $(HDSIM_SO)
# `make all` builds the simulator too, so the binding never loads a stale library
all: sim

BUILD_TESTS_EXTRA += $(HDSIM_BIN) $(HDSIM_SO)
