# mk/fuzz.mk - libFuzzer targets (tests/fuzz/fuzz_*.c), clang with
# -fsanitize=fuzzer,address,undefined.  See docs/reliability.md.
#
#   make fuzz                    run every target for FUZZ_SECONDS (default 60) each,
#                                starting from the committed corpus tests/fuzz/corpus/<t>/;
#                                new inputs go to build/fuzz/corpus/<t>/, crashes to
#                                build/fuzz/artifacts/<t>/; prints execs and coverage
#   make fuzz FUZZ_TARGETS=toml  only some targets (names without fuzz_)
#   make fuzz-merge              minimise build/fuzz/corpus into the committed corpus
#   make fuzz-build              just build
# `make test` runs tests/checks/60_fuzz.sh: every committed input replayed,
# then FUZZ_TEST_SECONDS (default 12) of fuzzing per target.

FUZZ_CC       ?= clang
FUZZ_SECONDS  ?= 60
FUZZ_DIR      := $(B)/fuzz
FUZZ_ALL      := $(patsubst tests/fuzz/fuzz_%.c,%,$(wildcard tests/fuzz/fuzz_*.c))
FUZZ_TARGETS  ?= $(FUZZ_ALL)
FUZZ_SAN      := -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer
FUZZ_FW_CFLAGS  := -std=c99 -include firmware/core/hd_nofloat.h -Wall -Wextra -g -O1 $(FUZZ_SAN) \
                   -fsanitize=fuzzer-no-link $(FW_INC) -Ifirmware/port/host -D_POSIX_C_SOURCE=200809L
# The targets themselves are test code (stdlib, no poisoning).
FUZZ_TGT_CFLAGS := $(filter-out -include firmware/core/hd_nofloat.h,$(FUZZ_FW_CFLAGS))
FUZZ_SIM_CFLAGS := -std=c99 -D_POSIX_C_SOURCE=200809L -Wall -Wextra -g -O1 $(FUZZ_SAN) \
                   -fsanitize=fuzzer-no-link -Isim/harness

FUZZ_FW_SRC  := $(FW_SRC) firmware/port/host/hal_host.c
FUZZ_FW_OBJ  := $(patsubst %.c,$(FUZZ_DIR)/obj/%.o,$(FUZZ_FW_SRC))
FUZZ_BINS    := $(addprefix $(FUZZ_DIR)/fuzz_,$(FUZZ_ALL))

$(FUZZ_DIR)/obj/firmware/%.o: firmware/%.c
	@mkdir -p $(@D)
	$(FUZZ_CC) $(FUZZ_FW_CFLAGS) -MMD -MP -c $< -o $@
$(FUZZ_DIR)/obj/sim/%.o: sim/%.c
	@mkdir -p $(@D)
	$(FUZZ_CC) $(FUZZ_SIM_CFLAGS) -MMD -MP -c $< -o $@

# clang (unlike gcc) applies `#pragma GCC poison` inside system headers, and the
# host port includes stdio.h: compile it without the no-float include (the
# gcc builds of mk/sim.mk keep checking it).
$(FUZZ_DIR)/obj/firmware/port/host/hal_host.o: FUZZ_FW_CFLAGS := $(FUZZ_TGT_CFLAGS)

# Firmware without the host port (targets that bring their own hal functions).
$(FUZZ_DIR)/libfw.a: $(patsubst %.c,$(FUZZ_DIR)/obj/%.o,$(FW_SRC))
	@mkdir -p $(@D); rm -f $@; ar rcs $@ $^

$(FUZZ_DIR)/fuzz_toml: tests/fuzz/fuzz_toml.c tests/fuzz/fuzz_common.h $(FUZZ_DIR)/obj/sim/harness/toml_lite.o $(FUZZ_DIR)/obj/sim/harness/sim_err.o
	$(FUZZ_CC) $(FUZZ_SIM_CFLAGS) -fsanitize=fuzzer -o $@ $< $(FUZZ_DIR)/obj/sim/harness/toml_lite.o $(FUZZ_DIR)/obj/sim/harness/sim_err.o -lm
$(FUZZ_DIR)/fuzz_preisach $(FUZZ_DIR)/fuzz_pstore $(FUZZ_DIR)/fuzz_tstore $(FUZZ_DIR)/fuzz_canopen: $(FUZZ_DIR)/fuzz_%: tests/fuzz/fuzz_%.c tests/fuzz/fuzz_common.h tests/fuzz/fuzz_nvm.h $(FUZZ_DIR)/libfw.a
	$(FUZZ_CC) $(FUZZ_TGT_CFLAGS) -fsanitize=fuzzer -o $@ $< $(FUZZ_DIR)/libfw.a
# Simulator targets: the plant + closed-loop harness (fuzz_plant), the socketcand
# server of the host port and the serve --rig channel (fuzz_socketcand).  The sim
# objects see the plant, the firmware headers and the host port; the host port's
# socketcand server uses system headers, so it is built like hal_host.o.
FUZZ_SIMX_CFLAGS := $(FUZZ_SIM_CFLAGS) -Isim/plant $(FW_INC) -Ifirmware/port/host
FUZZ_PLANT_SIM := $(addprefix $(FUZZ_DIR)/obj/sim/,plant/hd_plant.o plant/hd_plant_params.o plant/hd_plant_preisach.o \
                    harness/harness.o harness/scenario.o harness/toml_lite.o harness/sim_err.o harness/logwrite.o)
$(FUZZ_PLANT_SIM) $(FUZZ_DIR)/obj/sim/harness/rig.o: FUZZ_SIM_CFLAGS := $(FUZZ_SIMX_CFLAGS)
$(FUZZ_DIR)/obj/firmware/port/host/can_socketcand.o: FUZZ_FW_CFLAGS := $(FUZZ_TGT_CFLAGS)
$(FUZZ_DIR)/fuzz_plant: tests/fuzz/fuzz_plant.c tests/fuzz/fuzz_common.h $(FUZZ_PLANT_SIM) $(FUZZ_DIR)/obj/firmware/port/host/hal_host.o $(FUZZ_DIR)/libfw.a
	$(FUZZ_CC) $(FUZZ_SIMX_CFLAGS) -fsanitize=fuzzer -o $@ $< $(FUZZ_PLANT_SIM) $(FUZZ_DIR)/obj/firmware/port/host/hal_host.o $(FUZZ_DIR)/libfw.a -lm
$(FUZZ_DIR)/fuzz_socketcand: tests/fuzz/fuzz_socketcand.c tests/fuzz/fuzz_common.h $(FUZZ_DIR)/obj/sim/harness/rig.o $(FUZZ_DIR)/obj/firmware/port/host/can_socketcand.o
	$(FUZZ_CC) $(FUZZ_SIMX_CFLAGS) -fsanitize=fuzzer -o $@ $< $(FUZZ_DIR)/obj/sim/harness/rig.o $(FUZZ_DIR)/obj/firmware/port/host/can_socketcand.o -lm

$(FUZZ_DIR)/fuzz_params: tests/fuzz/fuzz_params.c tests/fuzz/fuzz_common.h $(FUZZ_DIR)/libfw.a $(FUZZ_DIR)/obj/firmware/port/host/hal_host.o
	$(FUZZ_CC) $(FUZZ_TGT_CFLAGS) -fsanitize=fuzzer -o $@ $< $(FUZZ_DIR)/obj/firmware/port/host/hal_host.o $(FUZZ_DIR)/libfw.a
# fuzz_appco: device + adapter + app on the host port.  FUZZ_APPCO_DEFS leaves single
# invariants out of a build (to fuzz the rest past a known violation), e.g.
#   make fuzz FUZZ_TARGETS=appco FUZZ_APPCO_DEFS=-DFUZZ_CHECK_NMT_REACTION=0
# (the value is kept in appco.defs, so changing it rebuilds the target).
FUZZ_APPCO_DEFS ?=
$(FUZZ_DIR)/appco.defs: fuzz-appco-defs
	@mkdir -p $(@D); echo '$(FUZZ_APPCO_DEFS)' | cmp -s - $@ || echo '$(FUZZ_APPCO_DEFS)' >$@
$(FUZZ_DIR)/fuzz_appco: tests/fuzz/fuzz_appco.c tests/fuzz/fuzz_common.h $(FUZZ_DIR)/libfw.a $(FUZZ_DIR)/obj/firmware/port/host/hal_host.o $(FUZZ_DIR)/appco.defs
	$(FUZZ_CC) $(FUZZ_TGT_CFLAGS) $(FUZZ_APPCO_DEFS) -fsanitize=fuzzer -o $@ $< $(FUZZ_DIR)/obj/firmware/port/host/hal_host.o $(FUZZ_DIR)/libfw.a

.PHONY: fuzz fuzz-build fuzz-merge fuzz-appco-defs
fuzz-build: $(FUZZ_BINS)

fuzz: fuzz-build
	@FUZZ_SECONDS=$(FUZZ_SECONDS) bash tests/fuzz/run.sh run $(FUZZ_TARGETS)

fuzz-merge: fuzz-build
	@bash tests/fuzz/run.sh merge $(FUZZ_TARGETS)

BUILD_TESTS_EXTRA += $(FUZZ_BINS)
