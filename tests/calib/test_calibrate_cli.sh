#!/bin/sh
# facescan calibrate never writes its calibration over what it reads: a board image or the pair
# list (exit 2, before any image is decoded; the files unchanged).
set -u
bin=${FACESCAN_BIN:?}/facescan
tmp=$(mktemp -d /tmp/facescan-calibrate-cli.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
fail=0
for f in pose0_cam0.png pose0_cam1.png; do printf 'an image' >"$tmp/$f"; done
printf 'pose0_cam0.png pose0_cam1.png\n' >"$tmp/pairs.yaml"
ln -s "$tmp/pose0_cam1.png" "$tmp/link.yaml"
sums=$(md5sum "$tmp"/*.png "$tmp/pairs.yaml")
refused() { # name expected-substring args...
	name=$1 want=$2; shift 2
	"$bin" calibrate "$@" --board 9x6 --square-mm 20 >"$tmp/log" 2>&1; rc=$?
	if [ $rc -ne 2 ] || ! grep -q -- "$want" "$tmp/log" || [ "$(md5sum "$tmp"/*.png "$tmp/pairs.yaml")" != "$sums" ]; then
		echo "FAIL: $name: exit $rc (want 2), inputs kept?"; cat "$tmp/log"; fail=1
	else echo "ok: $name: $(cat "$tmp/log")"; fi
}
refused over-image "ending in .yaml" --dir "$tmp" -o "$tmp/pose0_cam0.png"
refused over-pair-list "the pair list" --pairs "$tmp/pairs.yaml" -o "$tmp/pairs.yaml"
refused over-image-by-symlink "a board image" --dir "$tmp" -o "$tmp/link.yaml"
# A FIFO among the board images is skipped with its reason, never waited on.
mkdir "$tmp/fifo" && mkfifo "$tmp/fifo/pose0_cam0.png" && printf 'an image' >"$tmp/fifo/pose0_cam1.png"
timeout 20 "$bin" calibrate --dir "$tmp/fifo" -o "$tmp/c.yaml" --board 9x6 --square-mm 20 >"$tmp/log" 2>&1; rc=$?
if [ $rc -eq 1 ] && grep -q "not a regular file" "$tmp/log"; then echo "ok: fifo image skipped, exit 1"
else echo "FAIL: fifo image: exit $rc (124 = hung), want 1"; cat "$tmp/log"; fail=1; fi
exit $fail
