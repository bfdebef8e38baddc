# make soak: facescand with the native firmware, simulated cameras and the real recon worker,
# 200 scans under a seeded fault injector (docs/daemon.md, "Soak"). Not in `make test`; its
# short version is (tests/soak/test_soak.sh). Release build; needs root (tmpfs share).
#   make soak SOAK_SCANS=200 SOAK_SEED=12
SOAK_SCANS ?= 200
SOAK_SEED ?= 12
SOAK_ARGS ?=

.PHONY: soak
soak: deps
	@$(MAKE) --no-print-directory MODE=release bins $(BUILD)/bin/facescan-fw-native
	@python3 tests/soak/soak.py --bin $(BUILD)/bin --scans $(SOAK_SCANS) --seed $(SOAK_SEED) \
		--table $(BUILD)/soak-table.md $(SOAK_ARGS)
