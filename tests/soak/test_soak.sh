#!/bin/sh
# The short soak in `make test`: 10 scans, each of the 9 fault kinds striking one of them (share
# removed, read-only, full; MCU link killed, MCU reset; camera frames delayed, dropped; recon
# worker killed; facescand kill -9), on the binaries under test (the ASan build). `make soak`
# runs 200 (docs/daemon.md, "Soak"). Fails on a lost, duplicated or half-written scan, a
# failure without its capture or without a fault behind it, no scan delivered, or facescand's
# fds/RSS growing. Skips (77) without root.
set -u
bin=${FACESCAN_BIN:?}
command -v python3 >/dev/null || { echo "SKIP: no python3" >&2; exit 77; }
# The booth at 25 % of the rig's resolution (the least the pattern decodes at), slack for the
# sanitizer build's pace, and no RLIMIT_AS on its worker (the sanitizer's shadow needs
# terabytes of address space).
exec python3 tests/soak/soak.py --bin "$bin" --scans 10 --seed "${SOAK_SEED:-5}" --scale 25 \
	--scan-s 20 --capture-timeout-ms 4000 --scan-timeout-s 240 --fault-rate 0 --recon-memory-mb 0
