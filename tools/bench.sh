#!/bin/sh
# make bench: the random booth x head matrix, facescan recon beside the stock OpenCV SGBM
# baseline, scored against the simulator's truth → docs/benchmarks.md (tools/bench.py); then
# 12 booths no one tuned on, one head each → docs/benchmarks-heldout.md. Move
# BENCH_HELDOUT_SEED to a fresh range once a session has looked at the held-out booths: a booth
# that has been tuned on is no longer held out.
# Usage: tools/bench.sh BIN_DIR; BENCH_BOOTHS / BENCH_HEADS / BENCH_DIR shrink or move it.
set -eu
here=$(dirname "$0")
python3 "$here/bench.py" "$@"
BENCH_DIR=${BENCH_HELDOUT_DIR:-build/bench-heldout} BENCH_BOOTHS=12 BENCH_HEADS=1 \
	python3 "$here/bench.py" "$@" --first-seed "${BENCH_HELDOUT_SEED:-9200}" \
	--out docs/benchmarks-heldout.md
