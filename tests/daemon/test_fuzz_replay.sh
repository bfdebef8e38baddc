#!/bin/sh
# `make fuzz`'s control-socket target in every test run: fuzz_control (LineReader +
# parse_request + the reply) over its seeds (tests/daemon/fuzz_control_seeds) + 3000 generated
# inputs.
set -u
exec ./tests/fuzz-replay.sh fuzz_control tests/daemon/fuzz_control_seeds 3000 16384
