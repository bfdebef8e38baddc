#!/bin/sh
# facescan convert: PLY → Draco → PLY keeps the mesh (counts; positions within quantisation);
# bad input is a clear error, exit 1, nothing written.
set -u
bin=${FACESCAN_BIN:?}/facescan
tmp=$(mktemp -d /tmp/facescan-convert.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
fail=0
cat >"$tmp/a.ply" <<'PLY'
ply
format ascii 1.0
element vertex 5
property float x
property float y
property float z
element face 4
property list uchar int vertex_indices
end_header
0 0 500
10 0 500
10 10 502
0 10 500
5 5 510
3 0 1 4
3 1 2 4
3 2 3 4
3 3 0 4
PLY
"$bin" convert "$tmp/a.ply" "$tmp/b.drc" >"$tmp/log" 2>&1 || { echo "FAIL: ply -> drc"; cat "$tmp/log"; fail=1; }
"$bin" convert "$tmp/b.drc" "$tmp/c.ply" >"$tmp/log" 2>&1 || { echo "FAIL: drc -> ply"; cat "$tmp/log"; fail=1; }
grep -q "5 vertices, 4 triangles" "$tmp/log" && echo "ok: round trip keeps 5 vertices, 4 triangles" || { echo "FAIL: counts"; cat "$tmp/log"; fail=1; }
# And back to Draco once more from the decoded PLY.
"$bin" convert "$tmp/c.ply" "$tmp/d.drc" >/dev/null 2>&1 || { echo "FAIL: second round"; fail=1; }
echo "garbage" >"$tmp/bad.drc"
"$bin" convert "$tmp/bad.drc" "$tmp/out.ply" >"$tmp/log" 2>&1; rc=$?
if [ $rc -eq 1 ] && grep -q "bad.drc" "$tmp/log" && [ ! -e "$tmp/out.ply" ]; then echo "ok: corrupt input: $(cat "$tmp/log")"
else echo "FAIL: corrupt input: exit $rc"; cat "$tmp/log"; fail=1; fi
"$bin" convert "$tmp/a.ply" "$tmp/out.xyz" >/dev/null 2>&1; rc=$?
[ $rc -eq 2 ] && echo "ok: unknown extension is exit 2" || { echo "FAIL: unknown extension: exit $rc"; fail=1; }
exit $fail
