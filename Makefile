# hdservo top-level build.  `make test` and `make demo` set the machine up
# first (tools/setup.sh, idempotent).  See README.md.
#
# Sources are found by wildcard so that adding a file needs no Makefile edit:
#   firmware/{core,app,canopen}/*.c  -> libhdfw.a   (integer-only, no-float poisoned)
#   sim/plant/*.c                    -> libhdplant.a (double precision)
#   tests/c/test_*.c                 -> one cmocka binary each, sanitized
#   tests/checks/*.sh                -> shell checks that print TAP (ok / not ok)
#   tests/python/                    -> pytest
#   tests/bench/*.sh|*.py            -> `make bench`, JSON under build/bench/
#   tests/results/*.sh|*.py          -> `make results`, JSON under build/results/

SHELL := /bin/bash
.SUFFIXES:
.DELETE_ON_ERROR:

B        := build
VENV     := .venv
PY       := $(VENV)/bin/python

# ---- firmware sources --------------------------------------------------------
FW_DIRS  := firmware/core firmware/app firmware/canopen
FW_SRC   := $(foreach d,$(FW_DIRS),$(wildcard $(d)/*.c))
FW_INC   := $(addprefix -I,$(FW_DIRS) firmware/hal)
FW_WARN  := -Wall -Wextra -Wconversion -Wshadow -Wstrict-prototypes -Wmissing-prototypes -Werror
FW_STD   := -std=c99 -include firmware/core/hd_nofloat.h

# Host, sanitized (unit tests): UB and memory errors abort the test.
SAN      := -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer
HOST_CC  := gcc
HOST_FW_CFLAGS := $(FW_STD) $(FW_WARN) -O1 -g $(SAN) $(FW_INC)
# Host, optimised (simulator, virtual drive, Python binding): same code, no sanitizer.
# On x86-64 these target x86-64-v2 where the compiler knows it (SSE4.1 rounding: floor and
# nearbyint in one instruction, no libm call): the same results bit for bit (no FMA in v2,
# and -std=c99 forbids contraction), about 5 % faster simulation (docs/sim.md "Speed").
OPT_ARCH := $(if $(filter x86_64,$(shell uname -m)),$(shell $(HOST_CC) -march=x86-64-v2 -E -x c /dev/null >/dev/null 2>&1 && echo -march=x86-64-v2))
OPT_FW_CFLAGS  := $(FW_STD) $(FW_WARN) -O2 $(OPT_ARCH) -g -fPIC -fno-semantic-interposition $(FW_INC)

# Cortex-M4 (emulated for bit-exactness and instruction counts; STM32G474 ABI is hard-float
# but the core is integer-only, so soft-float objects prove no FP helper is called).
M4_CC    := arm-none-eabi-gcc
M4_NM    := arm-none-eabi-nm
M4_ARCH  := -mcpu=cortex-m4 -mthumb -mfloat-abi=soft
M4_CFLAGS := $(M4_ARCH) $(FW_STD) $(FW_WARN) -O2 -g -ffunction-sections -fdata-sections -ffreestanding $(FW_INC)

HOST_FW_OBJ := $(patsubst %.c,$(B)/host/obj/%.o,$(FW_SRC))
OPT_FW_OBJ  := $(patsubst %.c,$(B)/opt/obj/%.o,$(FW_SRC))
M4_FW_OBJ   := $(patsubst %.c,$(B)/m4/obj/%.o,$(FW_SRC))

# ---- simulator sources (double precision, not firmware) ------------------------
SIM_SRC     := $(wildcard sim/plant/*.c)
SIM_INC     := -Isim/plant -Isim/harness
SIM_WARN    := -Wall -Wextra -Wshadow -Werror
HOST_SIM_CFLAGS := -std=c99 -D_POSIX_C_SOURCE=200809L $(SIM_WARN) -O1 -g $(SAN) $(SIM_INC)
OPT_SIM_CFLAGS  := -std=c99 -D_POSIX_C_SOURCE=200809L $(SIM_WARN) -O2 $(OPT_ARCH) -g -fPIC -fno-semantic-interposition $(SIM_INC)
HOST_SIM_OBJ := $(patsubst %.c,$(B)/host/obj/%.o,$(SIM_SRC))
OPT_SIM_OBJ  := $(patsubst %.c,$(B)/opt/obj/%.o,$(SIM_SRC))

# ---- tests ---------------------------------------------------------------------
CTEST_SRC := $(wildcard tests/c/test_*.c)
CTEST_BIN := $(patsubst tests/c/%.c,$(B)/host/tests/%,$(CTEST_SRC))
CTEST_HELPERS := $(wildcard tests/c/support/*.c)

.PHONY: all setup test build-tests bench results demo clean firmware-objs m4-objs help docs-figures
all: build-tests

help:
	@echo "make setup    install missing Debian packages and the Python venv (.venv)"
	@echo "make test     build and run every test; last line 'N passed, N failed'"
	@echo "make bench    measure (never fails on time); JSON under build/bench/"
	@echo "make docs-figures  rewrite docs/firmware.md's bench figures from build/bench/ (after make bench)"
	@echo "make results  closed-loop figures; JSON under build/results/"
	@echo "make demo     the end-to-end demo on the simulated reference axis"

setup:
	@bash tools/setup.sh

# ---- compile rules ---------------------------------------------------------------
$(B)/host/obj/firmware/%.o: firmware/%.c
	@mkdir -p $(@D)
	$(HOST_CC) $(HOST_FW_CFLAGS) -MMD -MP -c $< -o $@
$(B)/opt/obj/firmware/%.o: firmware/%.c
	@mkdir -p $(@D)
	$(HOST_CC) $(OPT_FW_CFLAGS) -MMD -MP -c $< -o $@
$(B)/m4/obj/firmware/%.o: firmware/%.c
	@mkdir -p $(@D)
	$(M4_CC) $(M4_CFLAGS) -MMD -MP -c $< -o $@
$(B)/host/obj/sim/%.o: sim/%.c
	@mkdir -p $(@D)
	$(HOST_CC) $(HOST_SIM_CFLAGS) -MMD -MP -c $< -o $@
$(B)/opt/obj/sim/%.o: sim/%.c
	@mkdir -p $(@D)
	$(HOST_CC) $(OPT_SIM_CFLAGS) -MMD -MP -c $< -o $@


$(B)/host/libhdfw.a: $(HOST_FW_OBJ)
	@mkdir -p $(@D); rm -f $@; ar rcs $@ $^
$(B)/opt/libhdfw.a: $(OPT_FW_OBJ)
	@mkdir -p $(@D); rm -f $@; ar rcs $@ $^
$(B)/host/libhdplant.a: $(HOST_SIM_OBJ)
	@mkdir -p $(@D); rm -f $@; ar rcs $@ $(if $^,$^,)
$(B)/opt/libhdplant.a: $(OPT_SIM_OBJ)
	@mkdir -p $(@D); rm -f $@; ar rcs $@ $(if $^,$^,)

m4-objs: $(M4_FW_OBJ)

# Unit tests: each tests/c/test_X.c is one cmocka program, linked with the
# firmware library and the plant library (sanitized).
$(B)/host/tests/%: tests/c/%.c $(CTEST_HELPERS) $(B)/host/libhdfw.a $(B)/host/libhdplant.a
	@mkdir -p $(@D)
	$(HOST_CC) -std=c99 -D_POSIX_C_SOURCE=200809L -Wall -Wextra -Werror -O1 -g $(SAN) $(FW_INC) $(SIM_INC) -Itests/c \
	  -o $@ $< $(CTEST_HELPERS) $(B)/host/libhdfw.a $(B)/host/libhdplant.a -lcmocka -lm

build-tests: $(CTEST_BIN) m4-objs

# Extra make fragments contributed by subsystems (golden vectors, simulator,
# firmware image, ...).  Each defines its own targets and may append to
# BUILD_TESTS_EXTRA (built before the test run) and BENCH_DEPS.
-include $(sort $(wildcard mk/*.mk))

test: setup
	@$(MAKE) --no-print-directory build-tests $(BUILD_TESTS_EXTRA)
	@$(PY) tools/run_tests.py

bench: setup
	@$(MAKE) --no-print-directory build-tests $(BUILD_TESTS_EXTRA)
	@mkdir -p $(B)/bench
	@bash tools/run_dir.sh tests/bench

# The figures docs/firmware.md quotes from build/bench/ (cm4_cost, phase_cost, isr_load,
# profile), rewritten in place; `tools/firmware_doc_figures.py` alone only checks them.
docs-figures: setup
	@$(PY) tools/firmware_doc_figures.py --fix

results: setup
	@$(MAKE) --no-print-directory build-tests $(BUILD_TESTS_EXTRA)
	@mkdir -p $(B)/results
	@bash tools/run_dir.sh tests/results

demo: setup
	@$(MAKE) --no-print-directory build-tests $(BUILD_TESTS_EXTRA)
	@bash tools/demo.sh

clean:
	rm -rf $(B)

-include $(shell find $(B) -type f -name '*.d' 2>/dev/null)
