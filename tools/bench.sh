#!/bin/sh
# make bench: the random booth x head matrix, facescan recon beside the stock OpenCV SGBM
# baseline, scored against the simulator's truth → docs/benchmarks.md (tools/bench.py).
# Usage: tools/bench.sh BIN_DIR; BENCH_BOOTHS / BENCH_HEADS / BENCH_DIR shrink or move it.
set -eu
exec python3 "$(dirname "$0")/bench.py" "$@"
