# facescan — the one entry point.
#
#   make demo     a complete scan on the simulated booth (the main job)
#   make test     every test, built with AddressSanitizer + UBSan
#   make bench    accuracy / speed / memory benchmarks → docs/benchmarks.md
#   make soak     200 scans under injected faults, nothing lost (root; docs/daemon.md, "Soak")
#   make          release build: build/bin/facescan, build/bin/facescand, firmware images
#
# Layout of the build: release objects and binaries in build/, the sanitizer build in
# build/asan/. Every directory <area>/<name>/main.c(pp) is a program: build/bin/<name>.
# Everything else under firmware/protocol, drivers, host and tools is a static library per layer.

BUILD ?= build
MODE  ?= release
JOBS  ?= $(shell nproc 2>/dev/null || echo 2)
MAKEFLAGS += --no-builtin-rules -j$(JOBS)

ifeq ($(MODE),asan)
OUT      := $(BUILD)/asan
# -g1: line tables and function names, so every frame of a sanitizer report (inlined ones too)
# keeps its file:line; no local-variable info (rebuild with OPTFLAGS for a debugger session).
# Compiles in about 3/4 of -g's time. gold links a test in about half of ld.bfd's.
OPTFLAGS := -O1 -g1 -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined
LDFLAGS_LD := -fuse-ld=gold
# The simulator renders the scenes of most tests (heads, booths, boards), in its own small
# functions that -O1 does not inline: at -O2 (as in release), still under both sanitizers, it
# renders the same bytes in 2/3 of the CPU time (default scene 25 -> 17 CPU-s) and compiles in
# 25 CPU-s more (61 for tools/sim).
ASAN_O2_DIRS := tools/sim
else
OUT      := $(BUILD)
OPTFLAGS := -O2 -g -DNDEBUG
LDFLAGS_LD :=
ASAN_O2_DIRS :=
endif
# Extra flags of source $(1): -O2 after OPTFLAGS' -O1 (the last -O wins) in ASAN_O2_DIRS.
opt_for = $(if $(filter $(addsuffix /%,$(ASAN_O2_DIRS)),$(1)),-O2)

CC  := gcc
CXX := g++
WARN := -Wall -Wextra -Werror
# System headers (OpenCV, Eigen, libcamera) go in with -isystem so that -Werror judges our code only.
PKGS := opencv4 eigen3 libcamera libgpiod cmocka
PKG_CFLAGS := $(patsubst -I%,-isystem %,$(shell pkg-config --cflags $(PKGS) 2>/dev/null))
# Include roots per layer (tools/layers.txt): a directory compiles with only the roots of the
# layers it may include, so most upward includes fail to compile. The roots are coarser than the
# map (-Ihost is every host library and the daemon), so tests/build/test_layers.sh, which
# checks the map itself, stays the authority.
INC_FIRMWARE := -Ifirmware
INC_HOST     := -Ihost
INC_DRIVERS  := -Ifirmware -Idrivers/include -Ihost
INC_APPS     := -Ifirmware -Idrivers/include -Ihost -Itools
INCLUDES     := $(INC_APPS) -Itests
# The roots of source $(1): the longest matching directory wins, as in the map.
includes_for = $(strip \
	$(if $(filter tests/%,$(1)),$(INCLUDES), \
	$(if $(filter tools/% host/facescand/%,$(1)),$(INC_APPS), \
	$(if $(filter host/daemon/%,$(1)),$(INC_DRIVERS), \
	$(if $(filter host/%,$(1)),$(INC_HOST), \
	$(if $(filter drivers/%,$(1)),$(INC_DRIVERS), \
	$(if $(filter firmware/%,$(1)),$(INC_FIRMWARE), \
	$(INCLUDES))))))))
DEPFLAGS = -MMD -MP
CFLAGS   := -std=gnu11 $(WARN) $(OPTFLAGS) $(PKG_CFLAGS)
CXXFLAGS := -std=gnu++17 $(WARN) $(OPTFLAGS) $(PKG_CFLAGS)
OPENCV_LIBS := -lopencv_calib3d -lopencv_features2d -lopencv_flann -lopencv_aruco \
	-lopencv_imgcodecs -lopencv_imgproc -lopencv_core
LDLIBS := $(OPENCV_LIBS) -ldraco -lassimp -ldcmnet -ldcmdata -loflog -lofstd -lcpp-httplib -lcrypto -lembree3 -lcamera -lcamera-base -lgpiod -lsystemd -lpthread -lm
LDFLAGS := $(OPTFLAGS) $(LDFLAGS_LD)

# ---- sources -------------------------------------------------------------------------
# The library side is one static archive per layer (tools/layers.txt), in link order: each layer
# may use only the layers after it. Programs link them in that order without a group, so a call
# into a higher layer that nothing above pulled in fails to link; the include roots
# (includes_for) and tests/build/test_layers.sh catch the includes.
LAYERS := apps daemon host drivers format protocol
LAYER_DIRS_protocol := firmware/protocol
LAYER_DIRS_format   := host/common host/capture
LAYER_DIRS_drivers  := $(wildcard drivers/*)
LAYER_DIRS_daemon   := host/daemon
LAYER_DIRS_apps     := $(wildcard tools/*) host/facescand
LAYER_DIRS_host     := $(filter-out $(LAYER_DIRS_format) $(LAYER_DIRS_daemon) $(LAYER_DIRS_apps),$(wildcard host/*))
layer_src = $(filter-out %/main.c %/main.cpp,$(foreach d,$(LAYER_DIRS_$(1)),$(wildcard $(d)/*.c $(d)/*.cpp)))
layer_lib = $(OUT)/lib/libfacescan-$(1).a
LIB_DIRS := $(foreach l,$(LAYERS),$(LAYER_DIRS_$(l)))
ALL_SRC  := $(foreach d,$(LIB_DIRS),$(wildcard $(d)/*.c $(d)/*.cpp))
MAIN_SRC := $(filter %/main.c %/main.cpp,$(ALL_SRC))
# Every layer's archive, in link order (the firmware core on the native board, which the serial
# fake's MCU pulls in, goes between the drivers and the layers below them: firmware/firmware.mk).
LIB      := $(foreach l,$(LAYERS),$(call layer_lib,$(l)))
BINS     := $(foreach m,$(MAIN_SRC),$(OUT)/bin/$(notdir $(patsubst %/,%,$(dir $(m)))))

# Tests: tests/<area>/test_<name>.c(pp) → $(OUT)/tests/<area>/test_<name>.
# Extra link flags (e.g. -Wl,--wrap=SYM for mocks) go in tests/<area>/test_<name>.ldflags.
TEST_SRC  := $(wildcard tests/*/test_*.c tests/*/test_*.cpp)
TEST_BINS := $(patsubst tests/%,$(OUT)/tests/%,$(basename $(TEST_SRC)))

# `make` alone is the release build, whatever target an included fragment defines first.
.DEFAULT_GOAL := all
EXTRA_ALL :=
# What `make test` builds besides the test programs (e.g. the fuzz targets its replays run).
EXTRA_TEST :=
# Firmware (arm-none-eabi images, native build) and other fragments add their own rules.
-include $(wildcard firmware/*.mk tools/*.mk tests/*.mk packaging/*.mk)

.PHONY: all bins tests test demo bench deps clean format
# Targets that need the packages re-enter make after deps, so pkg-config is read once they exist.
all: deps
	@$(MAKE) --no-print-directory bins $(EXTRA_ALL)
bins: $(BINS)
tests: $(TEST_BINS) $(BINS)

deps:
	@./tools/install-deps.sh
	@./tools/install-web-deps.sh scan $(BUILD) || echo "deps: no scanned head fetched (facescan simulate --head scan exits 1)"

# Quiet by default; V=1 shows whole command lines.
Q := $(if $(V),,@)
$(OUT)/obj/%.c.o: %.c
	@mkdir -p $(dir $@)
	@$(if $(V),,echo "  CC    $<")
	$(Q)$(CC) $(CFLAGS) $(call opt_for,$<) $(call includes_for,$<) $(DEPFLAGS) -c $< -o $@
$(OUT)/obj/%.cpp.o: %.cpp
	@mkdir -p $(dir $@)
	@$(if $(V),,echo "  CXX   $<")
	$(Q)$(CXX) $(CXXFLAGS) $(call opt_for,$<) $(call includes_for,$<) $(DEPFLAGS) -c $< -o $@

define LAYER_LIB_RULE
$(call layer_lib,$(1)): $(patsubst %,$(OUT)/obj/%.o,$(call layer_src,$(1)))
	@mkdir -p $$(dir $$@)
	@rm -f $$@
	@$$(if $$(V),,echo "  AR    $$@")
	$$(Q)ar rcs $$@ $$^
endef
$(foreach l,$(LAYERS),$(eval $(call LAYER_LIB_RULE,$(l))))
# Programs: the layers in order, no group (see LAYERS).
PROGRAM_LIBS = $(call layer_lib,apps) $(call layer_lib,daemon) $(call layer_lib,host) \
	$(call layer_lib,drivers) $(FW_NATIVE_LIB) $(call layer_lib,format) $(call layer_lib,protocol)

define BIN_RULE
$(OUT)/bin/$(notdir $(patsubst %/,%,$(dir $(1)))): $(OUT)/obj/$(1).o $(LIB) $(FW_NATIVE_LIB)
	@mkdir -p $$(dir $$@)
	@$$(if $$(V),,echo "  LD    $$@")
	$$(Q)$$(CXX) $$(LDFLAGS) -o $$@ $$< $$(PROGRAM_LIBS) $$(LDLIBS)
endef
$(foreach m,$(MAIN_SRC),$(eval $(call BIN_RULE,$(m))))

.SECONDEXPANSION:
# The test objects are intermediates of the pattern rule below; keep them, or every `make test`
# recompiles all the tests (minutes under ASan).
.SECONDARY:
$(OUT)/tests/%: $(OUT)/obj/tests/%.$$(if $$(wildcard tests/$$*.cpp),cpp,c).o $(LIB) $(FW_NATIVE_LIB)
	@mkdir -p $(dir $@)
	@$(if $(V),,echo "  LD    $@")
	$(Q)$(CXX) $(LDFLAGS) -o $@ $< $(shell cat tests/$*.ldflags 2>/dev/null) \
		-Wl,--start-group $(LIB) $(FW_NATIVE_LIB) -Wl,--end-group $(LDLIBS) -lcmocka

# ---- the two commands the README names -----------------------------------------------
# The npm and PyPI pieces some tests use (tools/install-web-deps.sh web, py) are fetched while
# the build compiles (they wait on the network, the build on the CPU), not by the first test that
# needs them, which runs alone. A test still calls the script itself: a cache hit, or on a failed
# fetch here its own attempt and its skip.
test: deps
	@./tools/install-web-deps.sh web $(BUILD) >/dev/null 2>&1 & ./tools/install-web-deps.sh py $(BUILD) >/dev/null 2>&1 & \
		$(MAKE) --no-print-directory MODE=asan tests $(EXTRA_ALL) $(EXTRA_TEST); rc=$$?; wait; exit $$rc
	@FACESCAN_BIN=$(BUILD)/asan/bin FACESCAN_BUILD=$(BUILD) ./tests/run-tests.sh $(BUILD)/asan/tests

demo: deps
	@$(MAKE) --no-print-directory MODE=release bins $(EXTRA_ALL)
	@./tools/demo.sh $(BUILD)/bin

bench: deps
	@$(MAKE) --no-print-directory MODE=release bins
	@./tools/bench.sh $(BUILD)/bin

format:
	clang-format -i $(ALL_SRC) $(TEST_SRC)

clean:
	rm -rf $(BUILD)

-include $(shell find $(OUT)/obj -name '*.d' 2>/dev/null)
