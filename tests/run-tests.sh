#!/bin/bash
# Runs every built test program under $1 and every tests/*/test_*.sh script.
# Exit 0 = pass, 77 = skipped (needs hardware this machine lacks), anything else = fail.
# Scripts get FACESCAN_BIN (the binaries under test) in their environment.
#
# TEST_JOBS (default 2: CI's two cores) tests run at a time; TEST_JOBS=1 runs them one after
# another. A test's output is printed whole when it ends (never interleaved with another's),
# framed by "=== name" and "=== name: PASS (Ns)"; "--- name: started" says when it began (a test
# that hangs shows there). The tests named in `alone` below run with nothing beside them.
# Bash, not sh: `wait -n`.
set -u
dir=${1:?usage: run-tests.sh TEST_BIN_DIR}
jobs=${TEST_JOBS:-2}
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
# Each test's output is kept, so the end of a failed one is printed again last: a CI log that
# shows only its tail still says why.
logs=$(mktemp -d "${TMPDIR:-/tmp}/facescan-test-logs-XXXXXX") || exit 1
# What several tests render alike is made once per run and kept here for the others
# (tests/simulated_scan.hpp): a directory made afresh for this run and removed after it.
mkdir -p "${FACESCAN_BUILD:-build}/test-cache" &&
	FACESCAN_TEST_CACHE=$(mktemp -d "$(cd "${FACESCAN_BUILD:-build}/test-cache" && pwd)/run-XXXXXX") || exit 1
export FACESCAN_TEST_CACHE
trap 'rm -rf "$logs" "$FACESCAN_TEST_CACHE"' EXIT

# Run alone (nothing else on the machine while they run; first, one after another), each for
# its reason:
#   timing: deadlines, delays or rates measured against the wall clock, which a neighbour
#   on a 2-core machine stretches; the VM: QEMU's guest takes both cores; ports: two Orthancs
#   would race for the free ports they draw.
alone="
tests/vm/test_vm.sh
tests/soak/test_soak.sh
tests/e2e/test_daemon_e2e.sh
tests/viewer/test_viewer.sh
tests/dicom/test_orthanc.sh
tests/dicom/test_daemon_pacs.sh
firmware/test_qemu
firmware/test_fw_native
daemon/test_daemon
daemon/test_worker_recon
e2e/test_sd_notify
drivers/test_camera
drivers/test_camera_isolated
drivers/test_camera_replay
drivers/test_gpio
drivers/test_serial
drivers/test_serial_firmware
"
# Of the others, started first (the longest, measured under ASan), so that the short ones fill
# in beside them at the end instead of a long one running on its own last.
first="
calib/test_calib
recon/test_e2e
tests/recon/test_dense_e2e.sh
tests/sim/test_simulate.sh
daemon/test_pipeline_recon
sim/test_sim_render
recon/test_dense
recon/test_image_stages
"
tests=$(find "$dir" -type f -name 'test_*' -perm -u+x 2>/dev/null | sort)
scripts=$(ls tests/*/test_*.sh 2>/dev/null | sort)
name_of() { printf '%s' "${1#"$dir"/}"; }
log_of() { printf '%s/%s.log' "$logs" "$(printf '%s' "$1" | tr '/' '_')"; } # by test name
listed() { case "$2" in *"
$1
"*) return 0 ;; esac; return 1; }
serial="" ordered=""
for t in $tests $scripts; do listed "$(name_of "$t")" "$alone" && serial="$serial $t"; done
for f in $first; do
	for t in $tests $scripts; do [ "$(name_of "$t")" = "$f" ] && ordered="$ordered $t"; done
done
for t in $tests $scripts; do
	listed "$(name_of "$t")" "$first" || listed "$(name_of "$t")" "$alone" || ordered="$ordered $t"
done

# Runs test $1 (its log, exit code and seconds into $logs), then prints it whole.
run_one() {
	local t=$1 name log start rc secs
	name=$(name_of "$t")
	log=$(log_of "$name")
	start=$(date +%s)
	{ flock 9; printf -- '--- %s: started\n' "$name"; } 9>>"$logs/print.lock"
	# To a file, not through a pipe: a helper a test leaves running must not hold the run open.
	"$t" >"$log" 2>&1 </dev/null
	rc=$?
	secs=$(($(date +%s) - start))
	{
		flock 9
		printf '=== %s\n' "$name"
		cat "$log"
		case $rc in
		0) printf '=== %s: PASS (%ss)\n' "$name" "$secs" ;;
		77) printf '=== %s: SKIP (needs hardware, see above)\n' "$name" ;;
		*) printf '=== %s: FAIL (exit %s, %ss)\n' "$name" "$rc" "$secs" ;;
		esac
		printf '%s %s\n' "$rc" "$name" >>"$logs/results"
	} 9>>"$logs/print.lock"
}

run_start=$(date +%s)
for t in $serial; do
	run_one "$t"
done
for t in $ordered; do
	if [ "$jobs" -le 1 ]; then
		run_one "$t"
	else
		while [ "$(jobs -pr | wc -l)" -ge "$jobs" ]; do wait -n; done
		run_one "$t" &
	fi
done
wait

pass=0 fail=0 skip=0 failed=""
while read -r rc name; do
	case $rc in
	0) pass=$((pass + 1)) ;;
	77) skip=$((skip + 1)) ;;
	*) fail=$((fail + 1)); failed="$failed $name" ;;
	esac
done <"$logs/results"
printf '\n%d passed, %d skipped, %d failed (%d tests at a time, %ss)\n' "$pass" "$skip" "$fail" "$jobs" \
	"$(($(date +%s) - run_start))"
k=1
for name in $failed; do
	printf '\n--- the last 40 lines of failed test %d of %d (%s):\n' "$k" "$fail" "$name"
	tail -n 40 "$(log_of "$name")"
	k=$((k + 1))
done
[ "$fail" -eq 0 ] || { printf '\n%d passed, %d skipped, %d failed\nfailed:%s\n' "$pass" "$skip" "$fail" "$failed"; exit 1; }
