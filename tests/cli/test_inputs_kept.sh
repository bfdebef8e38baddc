#!/bin/sh
# What the verbs read stays as it was (tools/facescan/outputs.cpp, mesh_io / capture readers):
# an output that names an input or another output is refused with exit 2 before anything is
# read, the inputs unchanged; a FIFO given as an input is refused with exit 1, never waited on.
# (recon's own cases: tests/recon/test_recon_cli.sh.)
set -u
bin=${FACESCAN_BIN:?}/facescan
tmp=$(mktemp -d /tmp/facescan-inputs-kept.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
fail=0

# Inputs: a mesh (and its Draco copy), a DICOM of it, a capture set's files, recon debug files,
# board images and a pair list. Refusals come before anything is parsed, so most are stand-ins.
printf 'ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 500\n10 0 500\n0 10 500\n3 0 1 2\n' >"$tmp/face.ply"
"$bin" convert "$tmp/face.ply" "$tmp/face.drc" >/dev/null 2>&1 || { echo "FAIL: convert"; exit 1; }
"$bin" dicom export "$tmp/face.ply" "$tmp/face.dcm" --patient P-1 >/dev/null 2>&1 || { echo "FAIL: dicom export"; exit 1; }
printf 'a texture' >"$tmp/face_texture.png"
mkdir "$tmp/set" "$tmp/dbg" "$tmp/board"
for f in calibration.yaml capture.json ground_truth.ply ground_truth_face.ply cam0.png; do printf '%s' "$f" >"$tmp/set/$f"; done
printf 'a cloud' >"$tmp/dbg/pair0_dense.ply"
for f in pose0_cam0.png pose0_cam1.png; do printf 'an image' >"$tmp/board/$f"; done
printf 'pose0_cam0.png pose0_cam1.png\n' >"$tmp/board/pairs.yaml"
ln -s "$tmp/face.drc" "$tmp/link.drc"
ln -s "$tmp/board/pose0_cam1.png" "$tmp/board/link.yaml"
sums() { find "$tmp/face.ply" "$tmp/face.drc" "$tmp/face.dcm" "$tmp/face_texture.png" "$tmp/set" "$tmp/dbg" "$tmp/board" -type f -exec md5sum {} + | sort; }
before=$(sums)

refused() { # name expected-substring verb args...
	name=$1 want=$2; shift 2
	"$bin" "$@" >"$tmp/log" 2>&1; rc=$?
	if [ $rc -ne 2 ] || ! grep -q -- "$want" "$tmp/log" || [ "$(sums)" != "$before" ]; then
		echo "FAIL: $name: exit $rc (want 2, saying '$want'), inputs kept?"; cat "$tmp/log"; fail=1
	else echo "ok: $name: $(head -1 "$tmp/log")"; fi
}
refused "evaluate: errors over the mesh" "the mesh being evaluated" evaluate "$tmp/face.ply" "$tmp/set" --errors "$tmp/face.ply"
refused "evaluate: coverage over the truth" "input of the capture set" evaluate "$tmp/face.ply" "$tmp/set" --coverage "$tmp/set/ground_truth.ply"
refused "evaluate: errors over the face truth" "input of the capture set" evaluate "$tmp/face.ply" "$tmp/set" --errors "$tmp/set/ground_truth_face.ply"
refused "evaluate: json over capture.json" "input of the capture set" evaluate "$tmp/face.ply" "$tmp/set" --json "$tmp/set/capture.json"
refused "evaluate: two outputs, one file" "another output" evaluate "$tmp/face.ply" "$tmp/set" --errors "$tmp/e.ply" --coverage "$tmp/e.ply"
refused "evaluate: missing over a debug file" "recon debug directory" evaluate "$tmp/face.ply" "$tmp/set" --missing "$tmp/dbg/pair0_dense.ply" --recon-debug "$tmp/dbg"
refused "evaluate: json named .ply" "ending in .json" evaluate "$tmp/face.ply" "$tmp/set" --json "$tmp/e.ply"
refused "convert: out is in, by ../" "the input mesh" convert "$tmp/face.drc" "$tmp/../$(basename "$tmp")/face.drc"
refused "convert: out is in, through a symlink" "the input mesh" convert "$tmp/link.drc" "$tmp/face.drc"
refused "convert: OBJ texture over the input's" "the input's texture" convert --texture "$tmp/face_texture.png" "$tmp/face.drc" "$tmp/face.obj"
refused "dicom export: over the mesh" "ending in .dcm" dicom export "$tmp/face.drc" "$tmp/face.drc" --patient P-1
refused "dicom export: over the mesh, by ../" "the mesh being exported" dicom export "$tmp/face.dcm" "$tmp/../$(basename "$tmp")/face.dcm" --patient P-1
refused "dicom show: document over the instance" "the instance being shown" dicom show "$tmp/face.dcm" --document "$tmp/face.dcm"
refused "calibrate: over a board image" "ending in .yaml" calibrate --dir "$tmp/board" -o "$tmp/board/pose0_cam0.png" --board 9x6 --square-mm 20
refused "calibrate: over the pair list" "the pair list" calibrate --pairs "$tmp/board/pairs.yaml" -o "$tmp/board/pairs.yaml" --board 9x6 --square-mm 20
refused "calibrate: over an image through a symlink" "a board image" calibrate --dir "$tmp/board" -o "$tmp/board/link.yaml" --board 9x6 --square-mm 20

# FIFOs as inputs.
mkfifo "$tmp/fifo.drc" "$tmp/fifo.ply" "$tmp/fifo.dcm" "$tmp/fifo_texture.png"
mkdir "$tmp/fifoboard" && mkfifo "$tmp/fifoboard/pose0_cam0.png" && printf 'an image' >"$tmp/fifoboard/pose0_cam1.png"
fifo_refused() { # verb args...
	timeout 20 "$bin" "$@" >"$tmp/log" 2>&1; rc=$?
	if [ $rc -eq 1 ] && grep -q "not a regular file" "$tmp/log"; then echo "ok: fifo: $1: $(head -1 "$tmp/log")"
	else echo "FAIL: fifo ($*): exit $rc (124 = hung), want 1"; cat "$tmp/log"; fail=1; fi
}
fifo_refused convert "$tmp/fifo.drc" "$tmp/f.ply"
fifo_refused convert --texture "$tmp/fifo_texture.png" "$tmp/face.drc" "$tmp/f.obj"
fifo_refused evaluate "$tmp/fifo.drc" "$tmp/set"
fifo_refused dicom export "$tmp/fifo.ply" "$tmp/f.dcm" --patient P-1
fifo_refused dicom show "$tmp/fifo.dcm"
fifo_refused calibrate --dir "$tmp/fifoboard" -o "$tmp/c.yaml" --board 9x6 --square-mm 20
exit $fail
