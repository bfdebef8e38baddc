#!/bin/sh
# Runs every built test program under $1 and every tests/*/test_*.sh script.
# Exit 0 = pass, 77 = skipped (needs hardware this machine lacks), anything else = fail.
# Scripts get FACESCAN_BIN (the binaries under test) in their environment.
set -u
dir=${1:?usage: run-tests.sh TEST_BIN_DIR}
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
pass=0 fail=0 skip=0 failed=""
# Each test's output is kept, so the end of a failed one is printed again last: a CI log that
# shows only its tail still says why.
logs=$(mktemp -d "${TMPDIR:-/tmp}/facescan-test-logs-XXXXXX") || exit 1
# What several tests render alike is made once per run and kept here for the others
# (tests/simulated_scan.hpp): a directory made afresh for this run and removed after it.
mkdir -p "${FACESCAN_BUILD:-build}/test-cache" &&
	FACESCAN_TEST_CACHE=$(mktemp -d "$(cd "${FACESCAN_BUILD:-build}/test-cache" && pwd)/run-XXXXXX") || exit 1
export FACESCAN_TEST_CACHE
trap 'rm -rf "$logs" "$FACESCAN_TEST_CACHE"' EXIT
tests=$(find "$dir" -type f -name 'test_*' -perm -u+x 2>/dev/null | sort)
scripts=$(ls tests/*/test_*.sh 2>/dev/null | sort)
for t in $tests $scripts; do
	name=${t#"$dir"/}
	printf '=== %s\n' "$name"
	start=$(date +%s)
	log="$logs/$(printf '%s' "$name" | tr '/' '_')"
	# To a file, not through a pipe: a helper a test leaves running must not hold the run open.
	"$t" >"$log" 2>&1 </dev/null
	rc=$?
	cat "$log"
	secs=$(( $(date +%s) - start ))
	case $rc in
	0) pass=$((pass + 1)); printf '=== %s: PASS (%ss)\n' "$name" "$secs" ;;
	77) skip=$((skip + 1)); printf '=== %s: SKIP (needs hardware, see above)\n' "$name" ;;
	*) fail=$((fail + 1)); failed="$failed $name"; printf '=== %s: FAIL (exit %s)\n' "$name" "$rc"
	   cp "$log" "$logs/failed.$fail" ;;
	esac
done
printf '\n%d passed, %d skipped, %d failed\n' "$pass" "$skip" "$fail"
k=1
while [ "$k" -le "$fail" ]; do
	printf '\n--- the last 40 lines of failed test %d of %d:\n' "$k" "$fail"
	tail -n 40 "$logs/failed.$k"
	k=$((k + 1))
done
[ "$fail" -eq 0 ] || { printf '\n%d passed, %d skipped, %d failed\nfailed:%s\n' "$pass" "$skip" "$fail" "$failed"; exit 1; }
