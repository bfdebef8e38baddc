#!/bin/sh
# `make fuzz`'s capture-set targets in every test run: fuzz_calibration (calibration.yaml) and
# fuzz_capture_json (capture.json) over their seeds (tests/host/*_seeds: valid files, the
# malformed ones, every input a fuzz run found) + 3000 generated inputs each.
set -u
rc=0
./tests/fuzz-replay.sh fuzz_calibration tests/host/fuzz_calibration_seeds 3000 16384 || rc=1
./tests/fuzz-replay.sh fuzz_capture_json tests/host/fuzz_capture_json_seeds 3000 16384 || rc=1
exit $rc
