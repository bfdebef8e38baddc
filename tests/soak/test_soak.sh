#!/bin/sh
# The short soak in `make test`: 12 scans under every fault kind at least once (share removed,
# read-only, full; MCU link killed, MCU reset; camera frames delayed, dropped; recon worker
# killed; facescand kill -9), on the binaries under test (the ASan build). `make soak` runs
# 200 (docs/daemon.md, "Soak"). Fails on a lost, duplicated or half-written scan, a failure
# without its capture, or facescand's fds/RSS growing. Skips (77) without root.
set -u
bin=${FACESCAN_BIN:?}
command -v python3 >/dev/null || { echo "SKIP: no python3" >&2; exit 77; }
# A small booth (15 % of the rig's resolution) and slack for the sanitizer build's pace.
exec python3 tests/soak/soak.py --bin "$bin" --scans 12 --seed "${SOAK_SEED:-5}" --scale 15 \
	--scan-s 20 --capture-timeout-ms 4000 --scan-timeout-s 240 --fault-rate 0.3
