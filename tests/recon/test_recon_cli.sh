#!/bin/sh
# facescan recon on bad input: a clear error naming the cause, exit 1, and no output file left.
set -u
bin=${FACESCAN_BIN:?}/facescan
tmp=$(mktemp -d /tmp/facescan-recon-cli.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
fail=0

# A well-formed 2-camera set whose frames are the bare slide (1024x768).
"$bin" pattern --width 1024 --height 768 --out "$tmp/pat" >/dev/null || { echo "FAIL: facescan pattern"; exit 1; }
id=$(sed -n 's/.*"id": *"\([^"]*\)".*/\1/p' "$tmp/pat/pattern.json" | head -1)
make_set() { # dir
	mkdir -p "$1"
	cp "$tmp/pat/slide.png" "$1/cam0.png"
	cp "$tmp/pat/slide.png" "$1/cam1.png"
	printf '{"scan_id": "cli-test", "pattern": "%s"}\n' "$id" >"$1/capture.json"
	{
		printf '%%YAML:1.0\n---\ncamera_count: 2\nunits: mm\n'
		for i in 0 1; do
			printf 'cam%d_K: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1000., 0., 512., 0., 1000., 384., 0., 0., 1. ]\n' $i
			printf 'cam%d_dist: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   data: [ 0., 0., 0., 0., 0. ]\n' $i
			printf 'cam%d_R: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1., 0., 0., 0., 1., 0., 0., 0., 1. ]\n' $i
			printf 'cam%d_T: !!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n   data: [ %d., 0., 500. ]\n' $i $((i * -100))
			printf 'cam%d_size: [ 1024, 768 ]\n' $i
		done
	} >"$1/calibration.yaml"
}

expect_failure() { # name dir expected-substring
	name=$1 dir=$2 want=$3
	out="$tmp/out-$name"
	"$bin" recon "$dir" -o "$out.drc" --ply "$out.ply" --report "$out.json" >"$tmp/log" 2>&1
	rc=$?
	if [ $rc -ne 1 ]; then
		echo "FAIL: $name: exit $rc, want 1"; cat "$tmp/log"; fail=1; return
	fi
	if ! grep -q -- "$want" "$tmp/log"; then
		echo "FAIL: $name: message does not name '$want':"; cat "$tmp/log"; fail=1; return
	fi
	for f in "$out.drc" "$out.png" "$out.ply" "$out.json"; do
		if [ -e "$f" ]; then echo "FAIL: $name: $f left behind"; fail=1; fi
	done
	ls "$tmp" | grep -q '\.tmp' && { echo "FAIL: $name: temp file left behind"; fail=1; }
	echo "ok: $name: $(head -1 "$tmp/log")"
}

expect_failure missing-dir "$tmp/no-such-dir" "no-such-dir"

make_set "$tmp/nocam"; rm "$tmp/nocam/cam1.png"
expect_failure missing-frame "$tmp/nocam" "cam1.png"

make_set "$tmp/corrupt"; echo "not a png" >"$tmp/corrupt/cam0.png"
expect_failure unreadable-frame "$tmp/corrupt" "cam0.png"

make_set "$tmp/size"; sed -i 's/cam1_size: \[ 1024, 768 \]/cam1_size: [ 1600, 1200 ]/' "$tmp/size/calibration.yaml"
expect_failure calibration-size "$tmp/size" "cam1"

make_set "$tmp/badid"; printf '{"scan_id": "cli-test", "pattern": "fs-l9-99x99-s7"}\n' >"$tmp/badid/capture.json"
expect_failure unknown-pattern "$tmp/badid" "fs-l9-99x99-s7"

make_set "$tmp/nocal"; rm "$tmp/nocal/calibration.yaml"
expect_failure missing-calibration "$tmp/nocal" "calibration.yaml"

# Outputs that would replace an input or another output are refused (exit 2) before anything
# is read, and every file of the set is left as it was.
make_set "$tmp/own"
cp "$tmp/own/calibration.yaml" "$tmp/own/ground_truth.ply"
ln -s "$tmp/own/cam1.png" "$tmp/cam1link.png"
(cd "$tmp/own" && md5sum * >"$tmp/own.md5")
expect_refused() { # name expected-substring args...
	name=$1 want=$2; shift 2
	"$bin" recon "$tmp/own" "$@" >"$tmp/log" 2>&1
	rc=$?
	if [ $rc -ne 2 ]; then echo "FAIL: $name: exit $rc, want 2"; cat "$tmp/log"; fail=1; return; fi
	if ! grep -q -- "$want" "$tmp/log"; then echo "FAIL: $name: message does not say '$want':"; cat "$tmp/log"; fail=1; return; fi
	if ! (cd "$tmp/own" && md5sum --quiet -c "$tmp/own.md5") || [ "$(ls "$tmp/own" | wc -l)" -ne 5 ]; then
		echo "FAIL: $name: the capture set changed"; ls -la "$tmp/own"; fail=1; return
	fi
	echo "ok: $name: $(head -1 "$tmp/log")"
}
expect_refused texture-over-frame "input of the capture set" -o "$tmp/own/cam0.drc"
expect_refused over-calibration ".drc" -o "$tmp/own/calibration.yaml"
expect_refused ply-over-truth "input of the capture set" -o "$tmp/m.drc" --ply "$tmp/own/ground_truth.ply"
expect_refused report-over-meta "input of the capture set" -o "$tmp/m.drc" --report "$tmp/own/capture.json"
expect_refused ply-named-drc ".ply" -o "$tmp/d.drc" --ply "$tmp/d.drc"
expect_refused mesh-named-png "ending in .drc" -o "$tmp/m.png"
expect_refused via-dotdot "input of the capture set" -o "$tmp/own/../own/cam1.drc" --no-texture --ply "$tmp/x.ply" --report "$tmp/own/./capture.json"
expect_refused via-symlink "input of the capture set" -o "$tmp/cam1link.drc"
expect_refused no-such-dir "does not exist" -o "$tmp/nowhere/m.drc"
ln "$tmp/own/capture.json" "$tmp/hard.json"
expect_refused via-hardlink "input of the capture set" -o "$tmp/m.drc" --report "$tmp/hard.json"

# Bad arguments are exit 2.
"$bin" recon "$tmp/nocal" >/dev/null 2>&1; rc=$?
[ $rc -eq 2 ] && echo "ok: missing -o is exit 2" || { echo "FAIL: missing -o: exit $rc, want 2"; fail=1; }
exit $fail
