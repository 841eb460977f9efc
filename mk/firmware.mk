# mk/firmware.mk - the flashable STM32G474 drive image (issue 11).
#
#   make firmware   -> build/firmware/hdservo-g474.{elf,bin,hex,map}, prints the
#                      flash / RAM use and fails if the budget is exceeded.
#
# Objects: firmware/{core,app,canopen}/*.c + firmware/port/stm32g474/*.c, built
# for the G474 ABI (hard float, FPv4-SP; the code is integer-only) with the
# firmware warning flags and -Werror; linked with --gc-sections, no C library
# (firmware/port/common/mini_libc.c has memcpy & co.), libgcc for the 64-bit division helpers.
# Budget (issue 11): flash (text + data) <= 128 KiB, RAM (data + bss + CCM bss
# + stack) <= 48 KiB.

G4_DIR    := firmware/port/stm32g474
G4_OUT    := $(B)/firmware
G4_ELF    := $(G4_OUT)/hdservo-g474.elf
G4_LD     := $(G4_DIR)/stm32g474.ld
G4_ARCH   := -mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16
# Capture buffer of the MCU image: 4096 words = 16 KiB (RAM budget; hd_capture.h).
G4_CAPTURE_WORDS := 4096u
G4_CFLAGS := $(G4_ARCH) $(FW_STD) $(FW_WARN) -O2 -g -ffunction-sections -fdata-sections -ffreestanding -fstack-usage \
             -DHD_CAPTURE_WORDS=$(G4_CAPTURE_WORDS) $(FW_INC) -I$(G4_DIR)
G4_SRC    := $(FW_SRC) $(wildcard $(G4_DIR)/*.c) firmware/port/common/mini_libc.c
G4_OBJ    := $(patsubst %.c,$(G4_OUT)/obj/%.o,$(G4_SRC))
G4_FLASH_MAX := 131072
G4_RAM_MAX   := 49152
G4_STACK     := 2560

.PHONY: firmware
firmware: $(G4_ELF) $(G4_OUT)/hdservo-g474.bin $(G4_OUT)/hdservo-g474.hex
	@set -e; \
	eval $$(arm-none-eabi-size -A $(G4_ELF) | awk '\
	  $$1==".isr_vector"||$$1==".text"||$$1==".ARM.exidx"||$$1==".ARM.extab"{t+=$$2} \
	  $$1==".data"{d=$$2} $$1==".bss"{b=$$2} $$1==".ccmbss"{c=$$2} \
	  END{printf "T=%d D=%d BSS=%d CCM=%d\n", t, d, b, c}'); \
	FL=$$((T + D)); RAM=$$((D + BSS + CCM + $(G4_STACK))); \
	arm-none-eabi-size $(G4_ELF); \
	printf 'hdservo-g474: flash %d B (%.1f KiB of %d KiB budget), RAM %d B (%.1f KiB of %d KiB budget; data %d, bss %d, ccm %d, stack %d)\n' \
	  $$FL $$(echo "$$FL/1024" | bc -l) $$(($(G4_FLASH_MAX)/1024)) $$RAM $$(echo "$$RAM/1024" | bc -l) $$(($(G4_RAM_MAX)/1024)) $$D $$BSS $$CCM $(G4_STACK) \
	  | tee $(G4_OUT)/size.txt; \
	if [ $$FL -gt $(G4_FLASH_MAX) ]; then echo "FAIL: flash budget exceeded" >&2; exit 1; fi; \
	if [ $$RAM -gt $(G4_RAM_MAX) ]; then echo "FAIL: RAM budget exceeded" >&2; exit 1; fi

$(G4_OUT)/obj/%.o: %.c
	@mkdir -p $(@D)
	$(M4_CC) $(G4_CFLAGS) -MMD -MP -c $< -o $@
$(G4_OUT)/obj/firmware/port/common/mini_libc.o: G4_CFLAGS += -fno-tree-loop-distribute-patterns

$(G4_ELF): $(G4_OBJ) $(G4_LD)
	@mkdir -p $(@D)
	$(M4_CC) $(G4_ARCH) -nostdlib -nostartfiles -T $(G4_LD) -Wl,--gc-sections -Wl,--fatal-warnings \
	  -Wl,-Map=$(G4_OUT)/hdservo-g474.map -o $@ $(G4_OBJ) -lgcc
$(G4_OUT)/hdservo-g474.bin: $(G4_ELF)
	arm-none-eabi-objcopy -O binary $< $@
$(G4_OUT)/hdservo-g474.hex: $(G4_ELF)
	arm-none-eabi-objcopy -O ihex $< $@
