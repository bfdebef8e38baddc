#!/bin/sh
# facescan simulate end to end at a small scale: writes a complete capture set that the
# capture-set reader accepts (checked through the files it must contain and their sizes).
set -u
bin=${FACESCAN_BIN:?}/facescan
out=$(mktemp -d /tmp/facescan-sim.XXXXXX)
trap 'rm -rf "$out"' EXIT
fail=0
"$bin" simulate --scene turned --seed 3 --scale 0.2 --out "$out/set" --contact-sheet "$out/sheet.png" || {
	echo "FAIL: simulate exited $?"; exit 1; }
for f in calibration.yaml capture.json ground_truth.ply ground_truth_face.ply ground_truth_projectors.yaml cam0.png cam1.png cam2.png cam3.png \
	cam0_texture.png cam1_texture.png cam2_texture.png cam3_texture.png; do
	[ -s "$out/set/$f" ] || { echo "FAIL: $f missing or empty"; fail=1; }
done
[ -s "$out/sheet.png" ] || { echo "FAIL: no contact sheet"; fail=1; }
grep -q '"pattern"' "$out/set/capture.json" || { echo "FAIL: capture.json has no pattern"; fail=1; }
grep -q 'cam3_K' "$out/set/calibration.yaml" || { echo "FAIL: calibration.yaml has no cam3_K"; fail=1; }
grep -q '^cam3_size' "$out/set/calibration.yaml" && grep -A1 -E '^cam3_size' "$out/set/calibration.yaml" | grep -q 320 ||
	{ echo "FAIL: cam3_size is not the scaled 320x240"; grep -A2 cam3_size "$out/set/calibration.yaml"; fail=1; }
head -c 3 "$out/set/ground_truth.ply" | grep -q ply || { echo "FAIL: ground_truth.ply is not a PLY"; fail=1; }
# The set records its projectors, so completeness counts the points this rig lit without being
# told the rig: the same count as naming the rig file, not the built-in default rig's.
rigs=tools/sim/rigs
"$bin" simulate --config $rigs/landscape.yaml --seed 3 --scale 0.2 --no-texture --out "$out/land" >/dev/null || {
	echo "FAIL: simulate --config landscape exited $?"; exit 1; }
counted() { "$bin" evaluate "$out/land/ground_truth.ply" "$out/land" "$@" | sed -n 's/.* of \([0-9]*\) truth points.*/\1/p'; }
recorded=$(counted) named=$(counted --rig $rigs/landscape.yaml) default=$(counted --rig $rigs/default.yaml)
echo "truth points counted: recorded projectors $recorded, landscape rig named $named, default rig $default"
[ -n "$recorded" ] && [ "$recorded" = "$named" ] && [ "$recorded" != "$default" ] ||
	{ echo "FAIL: evaluate did not use the projectors recorded in the set"; fail=1; }
# Errors: unknown scene → 2, unreadable rig file → 1.
"$bin" simulate --scene nosuch --out "$out/x" 2>/dev/null; rc=$?
[ $rc -eq 2 ] || { echo "FAIL: unknown scene exited $rc, want 2"; fail=1; }
"$bin" simulate --config /nonexistent.yaml --out "$out/x" 2>/dev/null; rc=$?
[ $rc -eq 1 ] || { echo "FAIL: missing rig exited $rc, want 1"; fail=1; }
"$bin" simulate --scale 9 --out "$out/x" 2>/dev/null; rc=$?
[ $rc -eq 2 ] || { echo "FAIL: --scale 9 exited $rc, want 2"; fail=1; }
"$bin" simulate --head-seed round --out "$out/x" 2>/dev/null; rc=$?
[ $rc -eq 2 ] || { echo "FAIL: --head-seed round exited $rc, want 2"; fail=1; }
# A random booth: its extra files, the same seed twice gives the same set, the written
# calibration differs from the true one, and evaluate scores the truth against itself fully.
# (The canonical head keeps it short: a random head with shoulders has twice the triangles;
# tests/sim/test_sim_booth covers the head family.)
for run in r1 r2; do
	"$bin" simulate --booth random --seed 4 --head canonical --scale 0.2 --no-texture --out "$out/$run" >"$out/$run.txt" || {
		echo "FAIL: simulate --booth random exited $?"; exit 1; }
done
cat "$out/r1.txt"
for f in booth.yaml ground_truth_calibration.yaml ground_truth_projectors.yaml calibration.yaml cam3.png; do
	[ -s "$out/r1/$f" ] || { echo "FAIL: random booth: $f missing or empty"; fail=1; }
	cmp -s "$out/r1/$f" "$out/r2/$f" || { echo "FAIL: random booth seed 4 twice: $f differs"; fail=1; }
done
cmp -s "$out/r1/calibration.yaml" "$out/r1/ground_truth_calibration.yaml" &&
	{ echo "FAIL: the written calibration carries no error"; fail=1; }
grep -q '^booth:' "$out/r1/booth.yaml" && grep -q 'calibration_error_px' "$out/r1/booth.yaml" ||
	{ echo "FAIL: booth.yaml does not record the draw"; fail=1; }
"$bin" simulate --config "$out/r1/booth.yaml" --head canonical --scale 0.1 --no-texture --out "$out/again" >/dev/null ||
	{ echo "FAIL: booth.yaml is not a rig file simulate reads"; fail=1; }
"$bin" evaluate "$out/r1/ground_truth.ply" "$out/r1" >"$out/r1-eval.txt"
self=$(sed -n 's/^completeness: \([0-9.]*\) %.*/\1/p' "$out/r1-eval.txt")
face=$(sed -n 's/^face completeness: \([0-9.]*\) % of \([0-9]*\) counted face points.* the face.s \([0-9]*\) .*/\1 \2 \3/p' "$out/r1-eval.txt")
echo "random booth: the truth against itself is $self % complete; face: $face (%, counted, all)"
[ "$self" = "100.0" ] || { echo "FAIL: evaluate on a random booth set"; fail=1; }
# The face (ground_truth_face.ply) is found in the truth: 100 %, some of the head's points.
set -- $face
[ "${1:-}" = "100.0" ] && [ "${2:-0}" -gt 0 ] && [ "${3:-0}" -ge "${2:-0}" ] ||
	{ echo "FAIL: evaluate's face figures on a random booth set"; cat "$out/r1-eval.txt"; fail=1; }
for args in "--booth random --config $rigs/default.yaml" "--booth random --scene dark" "--booth nosuch" "--head nosuch" \
	"--head random --head-seed canonical"; do
	# shellcheck disable=SC2086
	"$bin" simulate $args --out "$out/x" 2>/dev/null; rc=$?
	[ $rc -eq 2 ] || { echo "FAIL: simulate $args exited $rc, want 2"; fail=1; }
done
[ $fail -eq 0 ] && echo "ok: facescan simulate wrote a complete capture set"
exit $fail
