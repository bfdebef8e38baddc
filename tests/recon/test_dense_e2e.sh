#!/bin/sh
# End to end on two random booths no tuning looked at (facescan simulate --booth random --seed 7
# and 8: other lenses, pitches, rolls, masks, head pose and look, and a ~0.3 px calibration error):
# the dense surface must beat the paper's sparse mesh on completeness, and meet the floors
# over the face with a margin — RMS <= 0.27 mm (floor 0.30), face completeness >= 88 % (85),
# >= 110k face vertices (100k).
# Measured (release, 2026-12-07, after the guided second match, DenseParams::guided_pass):
# seed 7 RMS 0.177 mm (0.165 before it), face completeness 97.1 % (95.3; head 95.2 %, sparse
# 80.2 %), 181k face vertices; seed 8 RMS 0.235 mm (0.283 before it, when it was held to the floor
# itself, 0.30), 97.2 % (95.2; head 84.2 %, sparse 36.6 %), 161k. The floors are not met on every
# random booth yet: docs/benchmarks.md has the whole matrix.
set -u
bin=${FACESCAN_BIN:?}/facescan
tmp=$(mktemp -d /tmp/facescan-dense-e2e.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
fail=0
num() { # json-file key
	python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))[sys.argv[2]])' "$1" "$2"
}
check() { # description python-condition
	if python3 -c "import sys; sys.exit(0 if ($2) else 1)"; then
		echo "ok: $1"
	else
		echo "FAIL: $1 ($2)"
		fail=1
	fi
}
for seed in 7 8; do
	set_dir="$tmp/b$seed"
	"$bin" simulate --booth random --seed "$seed" --head random --no-texture --out "$set_dir" >/dev/null ||
		{ echo "FAIL: simulate --booth random --seed $seed"; exit 1; }
	"$bin" recon "$set_dir" -o "$tmp/d$seed.drc" --report "$tmp/d$seed.json" ||
		{ echo "FAIL: recon (dense) on booth $seed"; fail=1; continue; }
	"$bin" recon --sparse "$set_dir" -o "$tmp/s$seed.drc" >/dev/null ||
		{ echo "FAIL: recon --sparse on booth $seed"; fail=1; continue; }
	"$bin" evaluate "$tmp/d$seed.drc" "$set_dir" --json "$tmp/d$seed-eval.json" >/dev/null &&
		"$bin" evaluate "$tmp/s$seed.drc" "$set_dir" --json "$tmp/s$seed-eval.json" >/dev/null ||
		{ echo "FAIL: evaluate on booth $seed"; fail=1; continue; }
	rms=$(num "$tmp/d$seed-eval.json" rms_mm)
	comp=$(num "$tmp/d$seed-eval.json" completeness)
	face_comp=$(num "$tmp/d$seed-eval.json" face_completeness)
	face=$(num "$tmp/d$seed-eval.json" face_vertices)
	sparse=$(num "$tmp/s$seed-eval.json" completeness)
	dense=$(num "$tmp/d$seed.json" dense)
	echo "booth $seed: dense RMS $rms mm, face completeness $face_comp, completeness $comp (sparse $sparse)," \
		"$face vertices on the face"
	max_rms=0.27
	check "booth $seed: the output is the dense surface" "'$dense' == 'True'"
	check "booth $seed: RMS <= $max_rms mm" "$rms <= $max_rms"
	check "booth $seed: face completeness >= 0.88" "$face_comp >= 0.88"
	check "booth $seed: dense completeness beats sparse by 5 points" "$comp > $sparse + 0.05"
	check "booth $seed: >= 110k vertices on the face" "$face >= 110000"
done
exit $fail
