#!/bin/sh
# facescan dicom on the files it is given: an output never replaces its input (exit 2, the
# input unchanged); without a PACS (test_orthanc.sh sends to a real one).
set -u
bin=${FACESCAN_BIN:?}/facescan
tmp=$(mktemp -d /tmp/facescan-dicom-cli.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
fail=0
printf 'ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 500\n10 0 500\n0 10 500\n3 0 1 2\n' >"$tmp/face.ply"
"$bin" dicom export "$tmp/face.ply" "$tmp/a.dcm" --patient P-1 >/dev/null 2>&1 || { echo "FAIL: export"; exit 1; }
sums=$(md5sum "$tmp/face.ply" "$tmp/a.dcm")
refused() { # name expected-substring args...
	name=$1 want=$2; shift 2
	"$bin" dicom "$@" >"$tmp/log" 2>&1; rc=$?
	if [ $rc -ne 2 ] || ! grep -q -- "$want" "$tmp/log" || [ "$(md5sum "$tmp/face.ply" "$tmp/a.dcm")" != "$sums" ]; then
		echo "FAIL: $name: exit $rc (want 2), inputs kept?"; cat "$tmp/log"; fail=1
	else echo "ok: $name: $(cat "$tmp/log")"; fi
}
ln -s "$tmp/face.ply" "$tmp/face.dcm"
refused export-over-mesh "the mesh being exported" export "$tmp/face.dcm" "$tmp/face.dcm" --patient P-1
refused export-over-mesh-target "the mesh being exported" export "$tmp/face.dcm" "$tmp/../$(basename "$tmp")/face.dcm" --patient P-1
refused export-not-dcm "ending in .dcm" export "$tmp/face.ply" "$tmp/out.ply" --patient P-1
refused show-document-over-instance "the instance being shown" show "$tmp/a.dcm" --document "$tmp/a.dcm"
"$bin" dicom show "$tmp/a.dcm" --document "$tmp/a.stl" >/dev/null && [ -s "$tmp/a.stl" ] &&
	echo "ok: show --document writes the STL beside it" || { echo "FAIL: show --document"; fail=1; }
# A FIFO as the mesh or the instance is refused, never waited on.
mkfifo "$tmp/fifo.ply" "$tmp/fifo.dcm"
for args in "export $tmp/fifo.ply $tmp/f.dcm --patient P-1" "show $tmp/fifo.dcm"; do
	# shellcheck disable=SC2086
	timeout 20 "$bin" dicom $args >"$tmp/log" 2>&1; rc=$?
	if [ $rc -eq 1 ] && grep -q "not a regular file" "$tmp/log"; then echo "ok: fifo: $(cat "$tmp/log")"
	else echo "FAIL: fifo ($args): exit $rc (124 = hung), want 1"; cat "$tmp/log"; fail=1; fi
done
exit $fail
