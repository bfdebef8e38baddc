#!/bin/sh
# Installs the Debian 12 packages facescan builds and tests with. Idempotent:
# does nothing when every package is already present. Needs root (or sudo).
set -eu

PKGS="build-essential pkg-config cmake
libopencv-dev libopencv-contrib-dev libeigen3-dev libcamera-dev libgpiod-dev
libdraco-dev libcmocka-dev libembree-dev nlohmann-json3-dev libsystemd-dev
gcc-arm-none-eabi libnewlib-arm-none-eabi binutils-arm-none-eabi qemu-system-arm
clang libclang-rt-14-dev python3 strace
draco libtinygltf-dev libassimp-dev libdcmtk-dev libcpp-httplib-dev libssl-dev zlib1g-dev libbrotli-dev
orthanc chromium
qemu-system-x86 linux-headers-amd64 linux-source-6.1 busybox-static cpio kmod patch udev libcamera-ipa"
# strace slows the share and the spool of a running facescand in tests/e2e/test_daemon_e2e.sh
# (delay injection); the daemon has no test pauses of its own.
# The last line is the VM tier (tests/vm/README.md): QEMU, the kernel headers and sources vimc
# and gpio-sim are built from, the initramfs's tools, udev and the vimc IPA so libcamera finds
# its cameras inside the VM. The kernel image itself is fetched into build/vm, not installed.

missing=""
for p in $PKGS; do
	dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" ||
		missing="$missing $p"
done
[ -z "$missing" ] && exit 0

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
	command -v sudo >/dev/null 2>&1 || {
		echo "install-deps: missing packages:$missing (run as root or install sudo)" >&2
		exit 1
	}
	SUDO=sudo
fi
echo "install-deps: installing$missing"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
# shellcheck disable=SC2086
$SUDO apt-get install -y -qq --no-install-recommends $missing
