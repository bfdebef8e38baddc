# Firmware build (included by the root Makefile).
#
#   build/firmware/<board>/facescan-fw.elf   arm-none-eabi images (+ .bin, .map, size.txt),
#                                            whatever MODE is, for every board in FW_ARM_BOARDS
#   $(OUT)/bin/facescan-fw-native            the core on the native board behind a pty
#   $(OUT)/lib/libfacescan-fw-native.a       core + native board, linked into tests/firmware/*
#   $(BUILD)/fuzz/fuzz_protocol              libFuzzer on the protocol decoder and the command
#                                            handler; `make fuzz` (tests/fuzz.mk) runs it and the
#                                            host targets (FUZZ_SECONDS, default 60, each)
#
# firmware/core is deliberately not in the host's libraries: it defines the firmware's main-loop
# task and needs a board, which a host program must not get by accident. The root Makefile
# links $(FW_NATIVE_LIB) after the drivers' library into every program and test, so that only the one
# object that asks for it (the serial fake's MCU, drivers/serial/serial_mcu_model.c) pulls the
# core in: a program that never starts the fake MCU links none of it.

FW_CORE_SRC   := $(wildcard firmware/core/*.c)
FW_NATIVE_SRC := firmware/boards/native/hal_native.c
FW_NATIVE_LIB := $(OUT)/lib/libfacescan-fw-native.a
FW_NATIVE_BIN := $(OUT)/bin/facescan-fw-native

$(FW_NATIVE_LIB): $(patsubst %,$(OUT)/obj/%.o,$(FW_CORE_SRC) $(FW_NATIVE_SRC))
	@mkdir -p $(dir $@)
	@rm -f $@
	@$(if $(V),,echo "  AR    $@")
	$(Q)ar rcs $@ $^

$(FW_NATIVE_BIN): $(OUT)/obj/firmware/boards/native/main.c.o $(FW_NATIVE_LIB) $(LIB)
	@mkdir -p $(dir $@)
	@$(if $(V),,echo "  LD    $@")
	$(Q)$(CC) $(LDFLAGS) -o $@ $< $(FW_NATIVE_LIB) $(LIB)

# Firmware tests link the core and the native board (before the host's libraries, which have the
# protocol they use).
FW_TESTS := $(filter $(OUT)/tests/firmware/%,$(TEST_BINS))
$(FW_TESTS): $(FW_NATIVE_LIB)
$(FW_TESTS): LDLIBS := $(FW_NATIVE_LIB) $(LIB) $(LDLIBS)

# `firmware` is what EXTRA_ALL names: the root Makefile expands EXTRA_ALL in the outer make
# (release paths) and builds it in the inner one (any MODE), so the name must not hold $(OUT).
.PHONY: firmware
firmware: $(FW_NATIVE_BIN)
EXTRA_ALL += firmware

# ---- arm-none-eabi images ----------------------------------------------------------------
ARM_CC   := arm-none-eabi-gcc
ARM_SIZE := arm-none-eabi-size
ARM_OBJCOPY := arm-none-eabi-objcopy
# Every board folder with a linker script is an arm-none-eabi target.
FW_ARM_BOARDS := $(patsubst firmware/boards/%/link.ld,%,$(wildcard firmware/boards/*/link.ld))
FW_ARM_CFLAGS := -std=c11 -Wall -Wextra -Werror -Wpedantic -Os -g -mthumb \
	-ffunction-sections -fdata-sections -ffreestanding -Ifirmware
FW_ARM_LDFLAGS := -Lfirmware/boards -nostartfiles --specs=nano.specs --specs=nosys.specs -Wl,--gc-sections
FW_CPU_lm3s6965evb := -mcpu=cortex-m3
FW_CPU_stm32f103   := -mcpu=cortex-m3
FW_ARM_COMMON := $(FW_CORE_SRC) firmware/protocol/protocol.c

ifneq ($(shell command -v $(ARM_CC) 2>/dev/null),)
define FW_ARM_BOARD_RULES
FW_$(1)_DIR := $(BUILD)/firmware/$(1)
FW_$(1)_SRC := $(FW_ARM_COMMON) $(wildcard firmware/boards/$(1)/*.c)
FW_$(1)_OBJ := $$(patsubst %,$(BUILD)/firmware/$(1)/obj/%.o,$$(FW_$(1)_SRC))

$(BUILD)/firmware/$(1)/obj/%.c.o: %.c
	@mkdir -p $$(dir $$@)
	@$$(if $$(V),,echo "  ARMCC $$<")
	$$(Q)$(ARM_CC) $(FW_ARM_CFLAGS) $(FW_CPU_$(1)) -MMD -MP -c $$< -o $$@

$(BUILD)/firmware/$(1)/facescan-fw.elf: $$(FW_$(1)_OBJ) firmware/boards/$(1)/link.ld firmware/boards/cortex-m.ld
	@$$(if $$(V),,echo "  ARMLD $$@")
	$$(Q)$(ARM_CC) $(FW_ARM_CFLAGS) $(FW_CPU_$(1)) $(FW_ARM_LDFLAGS) \
		-T firmware/boards/$(1)/link.ld -Wl,-Map=$$(basename $$@).map -o $$@ $$(FW_$(1)_OBJ)
	$$(Q)$(ARM_OBJCOPY) -O binary $$@ $$(basename $$@).bin
	@$(ARM_SIZE) $$@ | tee $$(dir $$@)size.txt | \
		awk 'NR==2 { printf "firmware $(1): flash %d bytes, RAM %d bytes (incl. stack)\n", $$$$1+$$$$2, $$$$2+$$$$3 }'

-include $$(patsubst %.o,%.d,$$(FW_$(1)_OBJ))
firmware: $(BUILD)/firmware/$(1)/facescan-fw.elf
endef
$(foreach b,$(FW_ARM_BOARDS),$(eval $(call FW_ARM_BOARD_RULES,$(b))))
endif

# ---- fuzzing -----------------------------------------------------------------------------
FUZZ_SECONDS ?= 60
FUZZ_DIR := $(BUILD)/fuzz
FUZZ_CFLAGS := -std=gnu11 -g -O1 -fsanitize=fuzzer,address,undefined \
	-fno-sanitize-recover=undefined -Wall -Wextra -Werror -Ifirmware
FUZZ_SRC := tests/firmware/fuzz_protocol.c firmware/protocol/protocol.c $(FW_CORE_SRC) \
	$(FW_NATIVE_SRC)

$(FUZZ_DIR)/fuzz_protocol: $(FUZZ_SRC) $(wildcard firmware/*.h firmware/*/*.h firmware/boards/native/*.h)
	@mkdir -p $(dir $@)
	@$(if $(V),,echo "  FUZZ  $@")
	$(Q)clang $(FUZZ_CFLAGS) -o $@ $(FUZZ_SRC)

# Built with the firmware so tests/firmware/test_fuzz_replay.sh keeps it compiling and sane.
firmware: $(FUZZ_DIR)/fuzz_protocol

# `make fuzz` runs it with the host targets: tests/fuzz.mk.
