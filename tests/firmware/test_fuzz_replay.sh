#!/bin/sh
# The `make fuzz` target in every test run: its seeds (one frame per command, framed and raw)
# plus 3000 generated inputs from a fixed seed, under ASan/UBSan and the target's invariants
# (valid replies only, no light on outside a scan, dark after ABORT). The long run is
# `make fuzz` (60 s); this only keeps the target building and passing.
set -u
f=${FACESCAN_BUILD:-build}/fuzz/fuzz_protocol
[ -x "$f" ] || { echo "test_fuzz_replay: $f not built (make firmware)" >&2; exit 1; }
d=$(mktemp -d)
trap 'rm -rf "$d"' EXIT
mkdir "$d/corpus"
FS_FUZZ_SEEDS=$d/corpus "$f" -runs=0 >/dev/null 2>&1
n=$(ls "$d/corpus" | wc -l)
[ "$n" -ge 10 ] || { echo "test_fuzz_replay: only $n seeds written" >&2; exit 1; }
if ! "$f" -runs=3000 -seed=1 -artifact_prefix="$d/" "$d/corpus" >"$d/log" 2>&1; then
	cat "$d/log" >&2
	exit 1
fi
grep -E '^Done' "$d/log"
echo "ok: $n seeds + 3000 generated inputs, no crash"
