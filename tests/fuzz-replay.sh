#!/bin/sh
# The fast replay of a libFuzzer target in `make test` (the long run is `make fuzz`): its seeds
# plus RUNS generated inputs from a fixed seed, under ASan/UBSan, the target's invariants, 2 GB
# RSS and 10 s per input. Exit 0, or 1 (never libFuzzer's 77, which run-tests.sh would count
# as a skip) with the crash's report. The seeds are copied: libFuzzer adds to its corpus dir.
#   usage: fuzz-replay.sh TARGET SEED_DIR RUNS MAX_LEN
set -u
name=${1:?usage: fuzz-replay.sh TARGET SEED_DIR RUNS MAX_LEN}
seeds=${2:?} runs=${3:?} len=${4:?}
f=${FACESCAN_BUILD:-build}/fuzz/$name
[ -x "$f" ] || { echo "$name: $f not built (make test builds it: fuzz-bins)" >&2; exit 1; }
d=$(mktemp -d "${TMPDIR:-/tmp}/facescan-$name-XXXXXX") || exit 1
trap 'rm -rf "$d"' EXIT
mkdir "$d/corpus" && cp "$seeds"/* "$d/corpus/" || exit 1
# libFuzzer skips empty files.
n=$(find "$d/corpus" -type f -size +0 | wc -l)
start=$(date +%s.%N)
if ! "$f" -runs="$runs" -seed=1 -max_len="$len" -rss_limit_mb=2048 -timeout=10 \
	-artifact_prefix="$d/" "$d/corpus" >"$d/log" 2>&1; then
	tail -n 60 "$d/log" >&2
	for a in "$d"/crash-* "$d"/timeout-* "$d"/oom-* "$d"/leak-*; do
		[ -f "$a" ] && { echo "$name: failing input (base64):" >&2; base64 "$a" >&2; }
	done
	echo "$name: FAILED on its seeds + $runs generated inputs" >&2
	exit 1
fi
grep -q "seed corpus: files: $n " "$d/log" || {
	grep 'seed corpus' "$d/log" >&2
	echo "$name: did not read its $n non-empty seeds" >&2
	exit 1
}
secs=$(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN { print b - a }')
printf '%s: ok, %d seeds + %d generated inputs, no crash, %.1f s\n' "$name" "$n" "$runs" "$secs"
