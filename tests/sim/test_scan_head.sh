#!/bin/sh
# facescan simulate --head scan: the real head's CT (tools/install-web-deps.sh scan) rendered
# at a small scale, placed as docs/simulator.md says (nose tip on the canonical head's), and
# refused with exit 1 where it was not fetched. Skips (77) when the scan is not there.
set -u
bin=${FACESCAN_BIN:?}/facescan
data=${FACESCAN_SCAN_HEAD:-${FACESCAN_BUILD:-build}/cache/scan-head}
out=$(mktemp -d /tmp/facescan-scan.XXXXXX)
trap 'rm -rf "$out"' EXIT
fail=0
FACESCAN_SCAN_HEAD=/nonexistent "$bin" simulate --head scan --scale 0.2 --out "$out/none" 2>"$out/err"; rc=$?
[ $rc -eq 1 ] && grep -q 'install-web-deps.sh scan' "$out/err" ||
	{ echo "FAIL: --head scan without the scan exited $rc, want 1 naming the fetch"; cat "$out/err"; fail=1; }
# A FIFO where the volume should be is refused, not waited on (no writer ever comes).
mkdir "$out/fifo" && echo "8 8 8 1 1 1" >"$out/fifo/volume.txt" && mkfifo "$out/fifo/volume.raw"
FACESCAN_SCAN_HEAD=$out/fifo timeout 20 "$bin" simulate --head scan --scale 0.2 --out "$out/f" 2>"$out/err"; rc=$?
[ $rc -eq 1 ] && grep -q 'not a regular file' "$out/err" ||
	{ echo "FAIL: --head scan with a FIFO for volume.raw exited $rc, want 1 (124: it waited)"; cat "$out/err"; fail=1; }
if [ ! -s "$data/volume.raw" ]; then
	echo "SKIP: no scanned head in $data (tools/install-web-deps.sh scan)"
	[ $fail -eq 0 ] && exit 77
	exit 1
fi
FACESCAN_SCAN_HEAD=$data "$bin" simulate --head scan --seed 2 --scale 0.2 --no-texture --out "$out/set" || {
	echo "FAIL: simulate --head scan exited $?"; exit 1; }
for f in calibration.yaml capture.json ground_truth.ply ground_truth_projectors.yaml cam0.png cam3.png; do
	[ -s "$out/set/$f" ] || { echo "FAIL: $f missing or empty"; fail=1; }
done
# The truth mesh in the head frame (default scene: no pose): its front-most point is the nose tip
# at (0, -30, 119.5) mm, crown to the CT's lowest slice 150-170 mm, one closed piece.
python3 - "$out/set/ground_truth.ply" <<'PY' || fail=1
import struct, sys
d = open(sys.argv[1], "rb").read()
end = d.index(b"end_header\n") + len(b"end_header\n")
head = d[:end].decode().split("\n")
nv = int([l for l in head if l.startswith("element vertex")][0].split()[2])
nf = int([l for l in head if l.startswith("element face")][0].split()[2])
v = [struct.unpack_from("<6f", d, end + 24 * i) for i in range(nv)]
tip = max(v, key=lambda p: p[2])
ys = [p[1] for p in v]
edges = {}
o = end + 24 * nv
for t in range(nf):
    a, b, c = struct.unpack_from("<3i", d, o + 13 * t + 1)
    for e in ((a, b), (b, c), (c, a)):
        k = (min(e), max(e))
        edges[k] = edges.get(k, 0) + 1
boundary = sum(1 for n in edges.values() if n == 1)
print("scan head: %d vertices, %d triangles, nose tip (%.1f, %.1f, %.1f) mm, height %.1f mm, %d boundary edges"
      % (nv, nf, tip[0], tip[1], tip[2], max(ys) - min(ys), boundary))
ok = abs(tip[0]) < 3 and abs(tip[1] + 30) < 3 and abs(tip[2] - 119.5) < 1.5
ok = ok and 150 < max(ys) - min(ys) < 170 and nv > 50000 and boundary == 0
if not ok:
    print("FAIL: the scan head is not where docs/simulator.md puts it, or not closed")
    sys.exit(1)
PY
# evaluate scores the truth against itself 100 %.
self=$("$bin" evaluate "$out/set/ground_truth.ply" "$out/set" | sed -n 's/^completeness: \([0-9.]*\) %.*/\1/p')
echo "scan head: the truth against itself is $self % complete"
[ "$self" = "100.0" ] || { echo "FAIL: evaluate on the scan head's set"; fail=1; }
[ $fail -eq 0 ] && echo "test_scan_head: ok"
exit $fail
