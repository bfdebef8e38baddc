#!/bin/sh
# Prepares the VM tier (tests/vm/README.md): Debian 12's kernel, the virtual drivers it does not
# ship (vimc, gpio-sim, and irq_sim under them) built out of tree from linux-source-6.1, and an
# initramfs that loads them, mounts this machine's root read-only over 9p and runs the guest
# script. Idempotent: everything is cached under $VM_DIR (default build/vm) and rebuilt only
# when the kernel version or the files it is made from change. Prints nothing on a cache hit.
#
# Exit 0: ready ($VM_DIR/vmlinuz, $VM_DIR/initramfs.cpio.gz). Exit 77 with the reason: a package
# this needs cannot be had (not installed, and the kernel image not downloadable). Else: failed.
set -eu

here=$(cd "$(dirname "$0")" && pwd)
VM_DIR=${VM_DIR:-build/vm}
mkdir -p "$VM_DIR"
VM_DIR=$(cd "$VM_DIR" && pwd)

skip() { echo "vm setup: skipped: $*" >&2; exit 77; }
fail() { echo "vm setup: $*" >&2; exit 1; }

for tool in qemu-system-x86_64 busybox cpio depmod modprobe make gcc patch; do
	command -v "$tool" >/dev/null 2>&1 ||
		skip "$tool not found (tools/install-deps.sh installs qemu-system-x86, busybox-static, cpio, kmod)"
done
# busybox must be static: it runs in the initramfs before any library is reachable.
busybox=$(command -v busybox)
if ! busybox --list 2>/dev/null | grep -qx switch_root; then
	skip "busybox lacks switch_root (install busybox-static)"
fi
# The kernel version is the one the installed headers are for, so modules and image match.
hdr_dep=$(dpkg-query -W -f='${Depends}' linux-headers-amd64 2>/dev/null) ||
	skip "linux-headers-amd64 is not installed (tools/install-deps.sh installs it)"
kver=$(echo "$hdr_dep" | sed -n 's/^linux-headers-\([^ ]*\) (= \([^)]*\)).*/\1/p')
pver=$(echo "$hdr_dep" | sed -n 's/^linux-headers-\([^ ]*\) (= \([^)]*\)).*/\2/p')
[ -n "$kver" ] && [ -n "$pver" ] || fail "cannot read the kernel version from linux-headers-amd64 ($hdr_dep)"
headers=/usr/src/linux-headers-$kver
[ -f "$headers/Makefile" ] || skip "$headers missing (reinstall linux-headers-$kver)"
src_tar=/usr/src/linux-source-6.1.tar.xz
[ -f "$src_tar" ] || skip "$src_tar missing (tools/install-deps.sh installs linux-source-6.1)"

# Everything the cache depends on: kernel version, the kernel source package, these files.
key=$(
	{
		echo "$kver $pver"
		dpkg-query -W -f='${Version}' linux-source-6.1
		cat "$here/setup.sh" "$here/Kbuild" "$here/init" "$here/vimc-instances.patch" "$busybox"
	} | sha256sum | cut -d' ' -f1
)
if [ -f "$VM_DIR/ready" ] && [ "$(cat "$VM_DIR/ready")" = "$key" ] &&
	[ -f "$VM_DIR/vmlinuz" ] && [ -f "$VM_DIR/initramfs.cpio.gz" ]; then
	exit 0
fi
rm -f "$VM_DIR/ready"
echo "vm setup: preparing kernel $kver in $VM_DIR" >&2
start=$(date +%s)

# 1. The kernel image package, fetched (not installed: this machine boots nothing from it).
deb=$VM_DIR/dl/linux-image-${kver}_${pver}_amd64.deb
if [ ! -s "$deb" ]; then
	mkdir -p "$VM_DIR/dl"
	(cd "$VM_DIR/dl" && apt-get download -q "linux-image-$kver=$pver" >/dev/null 2>&1) ||
		skip "apt-get download linux-image-$kver=$pver failed (offline, or the archive moved on: run apt-get update and tools/install-deps.sh)"
fi
rm -rf "$VM_DIR/kroot"
dpkg-deb -x "$deb" "$VM_DIR/kroot"
moddir=$VM_DIR/kroot/lib/modules/$kver
[ -f "$VM_DIR/kroot/boot/vmlinuz-$kver" ] || fail "$deb holds no boot/vmlinuz-$kver"

# 2. The missing drivers, out of tree. Only their sources are unpacked from the 138 MB tarball.
src=$VM_DIR/src
rm -rf "$src" "$VM_DIR/mod"
mkdir -p "$src" "$VM_DIR/mod"
tar -xJf "$src_tar" -C "$src" --strip-components=1 \
	linux-source-6.1/drivers/media/test-drivers/vimc \
	linux-source-6.1/drivers/gpio/gpio-sim.c linux-source-6.1/drivers/gpio/gpiolib.h \
	linux-source-6.1/kernel/irq/irq_sim.c
cp "$src"/drivers/media/test-drivers/vimc/*.[ch] "$src"/drivers/gpio/gpio-sim.c \
	"$src"/drivers/gpio/gpiolib.h "$src"/kernel/irq/irq_sim.c "$here/Kbuild" "$VM_DIR/mod/"
# irq_sim is built-in code in the kernel tree: as a module it needs a licence, and irq_to_desc()
# is not exported to modules; generic_handle_irq() runs the same flow handler (handle_simple_irq,
# which irq_sim_domain_map installs).
sed -i 's/handle_simple_irq(irq_to_desc(irqnum));/generic_handle_irq(irqnum);/' "$VM_DIR/mod/irq_sim.c"
grep -q 'generic_handle_irq(irqnum)' "$VM_DIR/mod/irq_sim.c" || fail "irq_sim.c changed upstream: patch no longer applies"
printf '\n#include <linux/module.h>\nMODULE_LICENSE("GPL");\n' >>"$VM_DIR/mod/irq_sim.c"
# vimc registers one device; the booth has several cameras, so a module parameter asks for more.
patch -s -d "$VM_DIR/mod" -p1 <"$here/vimc-instances.patch" || fail "vimc-instances.patch no longer applies"
make -s -C "$headers" M="$VM_DIR/mod" -j2 modules >"$VM_DIR/mod/build.log" 2>&1 ||
	{ tail -20 "$VM_DIR/mod/build.log" >&2; fail "module build failed (log: $VM_DIR/mod/build.log)"; }
mkdir -p "$moddir/updates"
cp "$VM_DIR"/mod/*.ko "$moddir/updates/"
depmod -b "$VM_DIR/kroot" "$kver"

# 3. The initramfs: static busybox, the init script, and exactly the modules it loads, in the
#    order modprobe resolves (virtio transport, 9p for the root, the two virtual drivers).
ird=$VM_DIR/initramfs
rm -rf "$ird"
mkdir -p "$ird/bin" "$ird/lib/modules" "$ird/proc" "$ird/sys" "$ird/dev" "$ird/newroot"
cp "$busybox" "$ird/bin/busybox"
ln -s busybox "$ird/bin/sh"
cp "$here/init" "$ird/init"
chmod 755 "$ird/init"
: >"$ird/lib/modules/order"
for m in virtio_pci 9pnet_virtio 9p vimc gpio-sim; do
	modprobe -d "$VM_DIR/kroot" -S "$kver" --show-depends "$m" | awk '$1 == "insmod" { print $2 }'
done | awk '!seen[$0]++' | while read -r ko; do
	cp "$ko" "$ird/lib/modules/"
	name=$(basename "$ko")
	# Two cameras: the smallest rig that has a stereo pair, so a scan can reach reconstruction.
	[ "$name" = vimc.ko ] && name="$name instances=2"
	echo "$name" >>"$ird/lib/modules/order"
done
(cd "$ird" && find . | LC_ALL=C sort | cpio -o -H newc --quiet | gzip -1) >"$VM_DIR/initramfs.cpio.gz.tmp"
mv "$VM_DIR/initramfs.cpio.gz.tmp" "$VM_DIR/initramfs.cpio.gz"
cp "$VM_DIR/kroot/boot/vmlinuz-$kver" "$VM_DIR/vmlinuz"
echo "$kver" >"$VM_DIR/kernel-version"
# Only the image, the initramfs and the download are needed from here on.
rm -rf "$VM_DIR/kroot" "$src" "$ird"
echo "$key" >"$VM_DIR/ready"
echo "vm setup: ready in $(($(date +%s) - start)) s" >&2
