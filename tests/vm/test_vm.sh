#!/bin/sh
# The VM tier (tests/vm/README.md): boots Debian 12's kernel in QEMU (TCG) with vimc and gpio-sim,
# on this machine's root shared read-only, runs the real-backend tests inside in one boot and
# reports each one. Exit 0 all passed, 77 QEMU or the kernel packages cannot be had, 1 failed.
# Environment: FACESCAN_BUILD (build/), FACESCAN_BIN (the binaries under test; make test sets
# both), VM_TIMEOUT (whole run, s; default 480: ~130 s on an idle 2-core host, over 300 s when
# other builds load it), VM_TESTS (override the list, absolute paths).
set -u
repo=$(cd "$(dirname "$0")/../.." && pwd)
build=${FACESCAN_BUILD:-build}
case $build in /*) ;; *) build=$repo/$build ;; esac
bin=${FACESCAN_BIN:-$build/asan/bin}
case $bin in /*) ;; *) bin=$repo/$bin ;; esac
tests=$(dirname "$bin")/tests
vm=$build/vm

VM_DIR=$vm "$repo/tests/vm/setup.sh"
rc=$?
[ $rc -eq 0 ] || exit $rc
for t in "$tests/vm/test_vm_camera" "$bin/facescand" "$bin/facescan"; do
	[ -x "$t" ] || { echo "test_vm: $t not built (make MODE=asan tests)" >&2; exit 1; }
done

# The share is the VM's only writable view of this machine; it is ours alone, made afresh.
share=$vm/share
rm -rf "$share"
mkdir -p "$share/results"
default_tests="$tests/vm/test_vm_gpio $tests/vm/test_vm_camera $tests/vm/test_vm_capture
$tests/drivers/test_camera_libcamera_enum $repo/tests/vm/guest_scan.sh"
{
	echo "REPO='$repo'"
	echo "FACESCAN_BIN='$bin'"
	echo "GUEST_TESTS='$(echo ${VM_TESTS:-$default_tests})'"
} >"$share/env"

start=$(date +%s)
# -smp 2: MTTCG runs the guest's two CPUs on two host threads (the machine's two cores).
timeout -k 5 "${VM_TIMEOUT:-480}" qemu-system-x86_64 \
	-machine q35,accel=tcg -cpu max -smp 2 -m 2048 \
	-nographic -no-reboot -net none -serial "file:$vm/console.log" -monitor none \
	-kernel "$vm/vmlinuz" -initrd "$vm/initramfs.cpio.gz" \
	-append "console=ttyS0 quiet panic=-1 fsvm_share=$share fsvm_script=$repo/tests/vm/guest.sh" \
	-virtfs local,path=/,mount_tag=hostroot,security_model=none,readonly=on,multidevs=remap \
	-virtfs "local,path=$share,mount_tag=share,security_model=none,multidevs=remap" \
	>"$vm/qemu.log" 2>&1
qrc=$?
wall=$(($(date +%s) - start))

fail=0
if [ -f "$share/results/boot.ms" ]; then
	read -r at_script at_udev <"$share/results/boot.ms"
	echo "vm: kernel + initramfs to guest script ${at_script} ms, udev settled at ${at_udev} ms (guest uptime)"
fi
for t in $(cat "$share/env" | sed -n "s/^GUEST_TESTS='\(.*\)'/\1/p"); do
	name=$(basename "$t")
	r=$share/results/$name
	if [ ! -f "$r.rc" ]; then
		echo "=== vm/$name: FAIL (did not finish)"
		fail=1
		continue
	fi
	code=$(cat "$r.rc")
	ms=$(cat "$r.ms")
	case $code in
	0) echo "=== vm/$name: PASS (${ms} ms)" ;;
	77) echo "=== vm/$name: SKIP (${ms} ms): $(grep -i skip "$r.log" | head -1)" ;;
	*)
		echo "=== vm/$name: FAIL (exit $code, ${ms} ms)"
		sed 's/^/    /' "$r.log" | tail -40
		fail=1
		;;
	esac
done
echo "vm: whole run ${wall} s (qemu exit $qrc)"
if [ ! -f "$share/results/done" ]; then
	echo "vm: the guest did not finish; console:" >&2
	tail -40 "$vm/console.log" >&2
	fail=1
fi
exit $fail
