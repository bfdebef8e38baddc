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
# Everything else under firmware/protocol, drivers, host and tools is one static library.

BUILD ?= build
MODE  ?= release
JOBS  ?= $(shell nproc 2>/dev/null || echo 2)
MAKEFLAGS += --no-builtin-rules -j$(JOBS)

ifeq ($(MODE),asan)
OUT      := $(BUILD)/asan
OPTFLAGS := -O1 -g -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined
else
OUT      := $(BUILD)
OPTFLAGS := -O2 -g -DNDEBUG
endif

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
# host/preview also gets -Itools for the one listed exception (it renders with tools/sim's tracer).
includes_for = $(strip \
	$(if $(filter tests/%,$(1)),$(INCLUDES), \
	$(if $(filter tools/% host/facescand/%,$(1)),$(INC_APPS), \
	$(if $(filter host/daemon/%,$(1)),$(INC_DRIVERS), \
	$(if $(filter host/preview/%,$(1)),$(INC_HOST) -Itools, \
	$(if $(filter host/%,$(1)),$(INC_HOST), \
	$(if $(filter drivers/%,$(1)),$(INC_DRIVERS), \
	$(if $(filter firmware/%,$(1)),$(INC_FIRMWARE), \
	$(INCLUDES)))))))))
DEPFLAGS = -MMD -MP
CFLAGS   := -std=gnu11 $(WARN) $(OPTFLAGS) $(PKG_CFLAGS)
CXXFLAGS := -std=gnu++17 $(WARN) $(OPTFLAGS) $(PKG_CFLAGS)
OPENCV_LIBS := -lopencv_calib3d -lopencv_features2d -lopencv_flann -lopencv_aruco \
	-lopencv_imgcodecs -lopencv_imgproc -lopencv_core
LDLIBS := $(OPENCV_LIBS) -ldraco -lassimp -ldcmnet -ldcmdata -loflog -lofstd -lcpp-httplib -lcrypto -lembree3 -lcamera -lcamera-base -lgpiod -lsystemd -lpthread -lm
LDFLAGS := $(OPTFLAGS)

# ---- sources -------------------------------------------------------------------------
# Directories whose sources form libfacescan.a (host-side code, incl. the shared protocol).
LIB_DIRS := firmware/protocol $(wildcard drivers/*) $(wildcard host/*) $(wildcard tools/*)
ALL_SRC  := $(foreach d,$(LIB_DIRS),$(wildcard $(d)/*.c $(d)/*.cpp))
MAIN_SRC := $(filter %/main.c %/main.cpp,$(ALL_SRC))
LIB_SRC  := $(filter-out $(MAIN_SRC),$(ALL_SRC))
LIB_OBJ  := $(patsubst %,$(OUT)/obj/%.o,$(LIB_SRC))
LIB      := $(OUT)/lib/libfacescan.a
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

# Quiet by default; V=1 shows whole command lines.
Q := $(if $(V),,@)
$(OUT)/obj/%.c.o: %.c
	@mkdir -p $(dir $@)
	@$(if $(V),,echo "  CC    $<")
	$(Q)$(CC) $(CFLAGS) $(call includes_for,$<) $(DEPFLAGS) -c $< -o $@
$(OUT)/obj/%.cpp.o: %.cpp
	@mkdir -p $(dir $@)
	@$(if $(V),,echo "  CXX   $<")
	$(Q)$(CXX) $(CXXFLAGS) $(call includes_for,$<) $(DEPFLAGS) -c $< -o $@

$(LIB): $(LIB_OBJ)
	@mkdir -p $(dir $@)
	@rm -f $@
	@$(if $(V),,echo "  AR    $@")
	$(Q)ar rcs $@ $^

define BIN_RULE
$(OUT)/bin/$(notdir $(patsubst %/,%,$(dir $(1)))): $(OUT)/obj/$(1).o $(LIB) $(FW_NATIVE_LIB)
	@mkdir -p $$(dir $$@)
	@$$(if $$(V),,echo "  LD    $$@")
	$$(Q)$$(CXX) $$(LDFLAGS) -o $$@ $$< -Wl,--start-group $$(LIB) $$(FW_NATIVE_LIB) -Wl,--end-group $$(LDLIBS)
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
test: deps
	@$(MAKE) --no-print-directory MODE=asan tests $(EXTRA_ALL) $(EXTRA_TEST)
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
