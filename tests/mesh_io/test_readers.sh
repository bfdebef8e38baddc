#!/bin/sh
# Independent readers open what `facescan convert` writes: Python trimesh (PyPI) reads the .obj
# (with its .mtl and texture), .stl and .ply; the Khronos glTF validator (npm) checks the .glb
# (KHR_draco_mesh_compression, embedded texture). The pieces are installed on first use under
# build/ (tools/install-web-deps.sh); without them the test skips (exit 77) saying why.
set -u
bin=${FACESCAN_BIN:?}/facescan
build=${FACESCAN_BUILD:-build}
here=$(cd "$(dirname "$0")/../.." && pwd)
"$here/tools/install-web-deps.sh" py "$build" || { echo "SKIP: trimesh could not be installed from PyPI"; exit 77; }
"$here/tools/install-web-deps.sh" web "$build" || { echo "SKIP: gltf-validator could not be installed from npm"; exit 77; }
build=$(cd "$build" && pwd)
py=$build/pyenv/bin/python
tmp=$(mktemp -d /tmp/facescan-readers.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
fail=0

# A textured, bumpy 40x30-vertex sheet (mm, z ~ 500) and a 96x64 texture.
"$py" - "$tmp" <<'PY' || exit 1
import sys, math
import numpy as np
from PIL import Image
d = sys.argv[1]
nx, ny = 40, 30
v, f = [], []
for j in range(ny):
    for i in range(nx):
        x, y = i * 2.0 - 39, j * 2.0 - 29
        v.append((x, y, 500 + 5 * math.sin(x * .1) * math.cos(y * .1), i / (nx - 1), j / (ny - 1)))
for j in range(ny - 1):
    for i in range(nx - 1):
        a = j * nx + i
        f += [(a, a + 1, a + nx + 1), (a, a + nx + 1, a + nx)]
with open(d + "/sheet.ply", "w") as o:
    o.write("ply\nformat ascii 1.0\nelement vertex %d\nproperty float x\nproperty float y\nproperty float z\n"
            "property float texture_u\nproperty float texture_v\nelement face %d\n"
            "property list uchar int vertex_indices\nend_header\n" % (len(v), len(f)))
    for p in v: o.write("%g %g %g %g %g\n" % p)
    for t in f: o.write("3 %d %d %d\n" % t)
img = np.zeros((64, 96, 3), np.uint8)
img[..., 0] = np.arange(96)[None, :] * 2; img[..., 1] = np.arange(64)[:, None] * 3; img[..., 2] = 90
Image.fromarray(img).save(d + "/tex.png")
PY

for out in sheet.glb sheet.obj sheet.stl sheet_m.stl sheet.drc out.ply back_m.stl; do
	units=mm; case $out in *_m.*) units=m ;; esac
	"$bin" convert --units $units --texture "$tmp/tex.png" "$tmp/sheet.ply" "$tmp/$out" >"$tmp/log" 2>&1 ||
		{ echo "FAIL: convert -> $out"; cat "$tmp/log"; fail=1; }
	[ $out = sheet_m.stl ] && "$bin" convert --in-units m "$tmp/sheet_m.stl" "$tmp/back.ply" >/dev/null 2>&1 &&
		"$bin" convert --units m "$tmp/back.ply" "$tmp/back_m.stl" >/dev/null 2>&1
done

"$py" - "$tmp" <<'PY' || fail=1
import sys
import numpy as np
import trimesh
d = sys.argv[1]
bad = 0
def check(name, cond, what):
    global bad
    print(("ok: " if cond else "FAIL: ") + name + ": " + what)
    bad += not cond
for name, scale in (("sheet.obj", 1), ("sheet.stl", 1), ("sheet_m.stl", 1e-3), ("out.ply", 1), ("back.ply", 1),
                    ("back_m.stl", 1e-3)):
    m = trimesh.load(d + "/" + name, force="mesh", process=True)
    lo, hi = m.bounds
    check(name, len(m.faces) == 2 * 39 * 29, "%d triangles" % len(m.faces))
    check(name, len(m.vertices) == 40 * 30, "%d vertices" % len(m.vertices))
    check(name, np.allclose(lo, np.array([-39, -29, 495]) * scale, atol=0.6 * scale) and
          np.allclose(hi[:2], np.array([39, 29]) * scale, atol=1e-3 * scale),
          "bounds %s .. %s" % (np.round(lo, 4), np.round(hi, 4)))
m = trimesh.load(d + "/sheet.obj", force="mesh", process=False)
img = getattr(m.visual.material, "image", None)
check("sheet.obj", img is not None and img.size == (96, 64), "texture %s via its .mtl" % ((None if img is None else img.size),))
uv = getattr(m.visual, "uv", None)
check("sheet.obj", uv is not None and len(uv) == len(m.vertices) and uv.min() >= 0 and uv.max() <= 1, "UVs per vertex")
# OBJ's v runs up: the vertex with the smallest y (recon/PLY v = 0, image top) has OBJ v = 1.
i = int(np.argmin(m.vertices[:, 1] + 1e-3 * m.vertices[:, 0]))
check("sheet.obj", abs(uv[i][1] - 1) < 1e-4 and abs(uv[i][0]) < 1e-4, "corner UV %s" % (uv[i],))
sys.exit(1 if bad else 0)
PY

cat >"$tmp/validate.cjs" <<'JS'
const fs = require('fs');
const validator = require(process.argv[2]);
const data = new Uint8Array(fs.readFileSync(process.argv[3]));
validator.validateBytes(data).then((r) => {
	const i = r.issues;
	const used = (r.info && r.info.extensionsUsed) || [];
	const images = ((r.info && r.info.resources) || []).filter((x) => x.image);
	const size = images.length ? `${images[0].image.width}x${images[0].image.height} ${images[0].mimeType}` : 'none';
	console.log(`errors ${i.numErrors} warnings ${i.numWarnings} extensions ${used.join(',')} image ${size}`);
	for (const m of i.messages.filter((m) => m.severity <= 1)) console.log(`  ${m.code} ${m.pointer || ''} ${m.message}`);
	process.exit(i.numErrors === 0 && used.includes('KHR_draco_mesh_compression') && size.startsWith('96x64') ? 0 : 1);
}, (e) => { console.log('validator failed: ' + e); process.exit(1); });
JS
if node "$tmp/validate.cjs" "$build/web/node_modules/gltf-validator" "$tmp/sheet.glb" >"$tmp/vlog" 2>&1; then
	echo "ok: sheet.glb passes the Khronos glTF validator: $(head -1 "$tmp/vlog")"
else
	echo "FAIL: glTF validator on sheet.glb:"; cat "$tmp/vlog"; fail=1
fi
# Draco's own decoder (Debian's `draco` CLI, tools/install-deps.sh) opens the .drc.
if ! command -v draco_decoder >/dev/null 2>&1; then
	echo "FAIL: draco_decoder missing (Debian package 'draco')"; fail=1
else
	if draco_decoder -i "$tmp/sheet.drc" -o "$tmp/drc.ply" >"$tmp/dlog" 2>&1 &&
		grep -a -q "element face 2262" "$tmp/drc.ply"; then
		echo "ok: sheet.drc opens in draco_decoder: 2262 faces"
	else
		echo "FAIL: draco_decoder on sheet.drc"; cat "$tmp/dlog"; fail=1
	fi
fi
ls -l "$tmp" | awk '/sheet|out/ {print "  " $5 " bytes  " $9}'
exit $fail
