# libFuzzer targets over the host's readers of untrusted bytes, and `make fuzz` (all targets).
#
#   $(FUZZ_DIR)/fuzz_calibration    calibration.yaml   tests/host/fuzz_calibration.cpp
#   $(FUZZ_DIR)/fuzz_capture_json   capture.json       tests/host/fuzz_capture_json.cpp
#   $(FUZZ_DIR)/fuzz_control        control socket     tests/daemon/fuzz_control.cpp
#   (and fuzz_protocol, the firmware protocol + command handler: firmware/firmware.mk)
#
#   make fuzz                          every target for FUZZ_SECONDS (default 60) each, one
#                                      after the other; prints the executions per target
#   make fuzz FUZZ_TARGETS=fuzz_control   a subset
#
# Each target is its harness plus only the sources it needs, built with clang++ and
# -fsanitize=fuzzer,address,undefined, linked against the system libraries (OpenCV is built
# with gcc; linking it with clang++ works). Corpus, crash artifacts and the log of the last run
# live in $(FUZZ_DIR)/<target>/; the corpus starts from tests/<area>/<target>_seeds/ and grows
# from run to run. tests/*/test_fuzz_replay*.sh replay the seeds + a few thousand generated
# inputs in every `make test` (the binaries are built by `make test`, not by `make`).

FUZZ_CXX := clang++
FUZZ_SAN := -fsanitize=address,undefined -fno-sanitize-recover=undefined
FUZZ_CXXFLAGS := -std=gnu++17 -g -O1 -fno-omit-frame-pointer $(FUZZ_SAN) $(WARN) \
	-Ihost -Itests $(PKG_CFLAGS)
FUZZ_OBJ := $(FUZZ_DIR)/obj

# Per target: the sources beside the harness, the libraries, and -max_len (bytes).
FUZZ_HOST := tests/host/fuzz_calibration tests/host/fuzz_capture_json tests/daemon/fuzz_control
FUZZ_SRC_fuzz_calibration  := host/capture/capture_set.cpp
FUZZ_LIBS_fuzz_calibration := -lopencv_imgcodecs -lopencv_core
FUZZ_LEN_fuzz_calibration  := 16384
FUZZ_SRC_fuzz_capture_json  := host/capture/capture_set.cpp
FUZZ_LIBS_fuzz_capture_json := -lopencv_imgcodecs -lopencv_core
FUZZ_LEN_fuzz_capture_json  := 16384
# Past kMaxRequest (4096), so that oversize lines and several lines per stream are reached.
FUZZ_SRC_fuzz_control  := host/daemon/control.cpp host/daemon/patient_id.cpp host/dicom/instance.cpp
FUZZ_LIBS_fuzz_control := -ldcmdata -loflog -lofstd
FUZZ_LEN_fuzz_control  := 16384
FUZZ_LEN_fuzz_protocol := 4096

FUZZ_HOST_BINS := $(foreach t,$(FUZZ_HOST),$(FUZZ_DIR)/$(notdir $(t)))
FUZZ_TARGETS ?= fuzz_protocol $(notdir $(FUZZ_HOST))

# Objects: coverage-instrumented (fuzzer-no-link); the harness's link adds libFuzzer's main.
$(FUZZ_OBJ)/%.cpp.o: %.cpp
	@mkdir -p $(dir $@)
	@$(if $(V),,echo "  FUZZCXX $<")
	$(Q)$(FUZZ_CXX) $(FUZZ_CXXFLAGS) -fsanitize=fuzzer-no-link -MMD -MP -c $< -o $@

define FUZZ_HOST_RULE
$(FUZZ_DIR)/$(notdir $(1)): $(FUZZ_OBJ)/$(1).cpp.o $$(patsubst %,$(FUZZ_OBJ)/%.o,$$(FUZZ_SRC_$(notdir $(1))))
	@$$(if $$(V),,echo "  FUZZ  $$@")
	$$(Q)$(FUZZ_CXX) -fsanitize=fuzzer $(FUZZ_SAN) -o $$@ $$^ $$(FUZZ_LIBS_$(notdir $(1)))
endef
$(foreach t,$(FUZZ_HOST),$(eval $(call FUZZ_HOST_RULE,$(t))))

# `make test` builds these (EXTRA_TEST: in MODE=asan, beside the test programs) so the replay
# tests find them; a release `make` does not.
.PHONY: fuzz-bins
fuzz-bins: $(FUZZ_DIR)/fuzz_protocol $(FUZZ_HOST_BINS)
EXTRA_TEST += fuzz-bins

FUZZ_SEEDS_fuzz_protocol := $(FUZZ_DIR)/fuzz_protocol.seeds
$(foreach t,$(FUZZ_HOST),$(eval FUZZ_SEEDS_$(notdir $(t)) := $(t)_seeds))

.PHONY: fuzz
fuzz: $(FUZZ_DIR)/fuzz_protocol $(FUZZ_HOST_BINS)
	@rm -rf $(FUZZ_SEEDS_fuzz_protocol) && mkdir -p $(FUZZ_SEEDS_fuzz_protocol)
	@FS_FUZZ_SEEDS=$(FUZZ_SEEDS_fuzz_protocol) $(FUZZ_DIR)/fuzz_protocol -runs=0 >/dev/null 2>&1
	@rc=0; $(foreach t,$(FUZZ_TARGETS),./tests/run-fuzz.sh $(FUZZ_DIR)/$(t) $(FUZZ_SEEDS_$(t)) \
		$(FUZZ_DIR)/$(t).run $(FUZZ_SECONDS) $(FUZZ_LEN_$(t)) || rc=1;) \
	echo "== make fuzz: $(FUZZ_SECONDS) s per target"; \
	cat $(foreach t,$(FUZZ_TARGETS),$(FUZZ_DIR)/$(t).run/summary); exit $$rc

-include $(shell find $(FUZZ_OBJ) -name '*.d' 2>/dev/null)
