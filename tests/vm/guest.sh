#!/bin/sh
# PID 1 inside the VM (tests/vm/init execs it on the host's read-only root). Brings up what the
# tests need (proc, sysfs, configfs, udev so libcamera finds and loses cameras as on a booth),
# runs every test $share/env names, one after the other, and leaves per test NAME.rc, NAME.log
# and NAME.ms in $share/results, then powers off. The host side (test_vm.sh) reports them.
share=${fsvm_share:?}
exec >/dev/ttyS0 2>&1
export PATH=/usr/sbin:/usr/bin:/sbin:/bin
now_ms() { awk '{ printf "%d\n", $1 * 1000 }' /proc/uptime; }
poweroff() {
	sync
	echo o >/proc/sysrq-trigger
	sleep 60
}
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t configfs configfs /sys/kernel/config
# shellcheck source=/dev/null # written by test_vm.sh: REPO, TESTS, FACESCAN_BIN, GUEST_TESTS
. "$share/env"
results=$share/results
mkdir -p "$results"
t0=$(now_ms)
/lib/systemd/systemd-udevd --daemon >/dev/null 2>&1
udevadm trigger --action=add >/dev/null 2>&1
udevadm settle -t 30
echo "$t0 $(now_ms)" >"$results/boot.ms" # uptime at the guest script, at udev settled

export FACESCAN_VM=1 FACESCAN_BIN FACESCAN_VM_SHARE=$share/work HOME=/tmp
# libcamera's errors (and the message of an abort inside it) into each test's log.
export LIBCAMERA_LOG_LEVELS='*:ERROR'
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=0 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
mkdir -p "$FACESCAN_VM_SHARE"
cd "$REPO" || poweroff
for t in $GUEST_TESTS; do
	name=$(basename "$t")
	start=$(now_ms)
	timeout -k 5 "${GUEST_TEST_TIMEOUT:-330}" "$t" >"$results/$name.log" 2>&1
	echo $? >"$results/$name.rc.tmp"
	echo $(($(now_ms) - start)) >"$results/$name.ms"
	mv "$results/$name.rc.tmp" "$results/$name.rc"
done
touch "$results/done"
poweroff
