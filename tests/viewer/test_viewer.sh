#!/bin/sh
# The web viewer in a real browser, on a real scan (the simulated booth reconstructed by
# host/recon, made by the binaries under test). `facescan view` serves the share on
# localhost; headless Chromium (Debian's chromium, driven by puppeteer-core from npm) opens the
# scan, waits until it is drawn and screenshots it. The face must be where the project's ray
# caster puts it from the same viewpoint (silhouette IoU >= 0.9), and a measurement clicked
# between two known vertices must read their distance within 0.5 mm. Paths out of the share are
# refused. Skips (77) only when chromium or the npm/PyPI pieces cannot be installed.
set -u
bin=${FACESCAN_BIN:?}/facescan
build=${FACESCAN_BUILD:-build}
here=$(cd "$(dirname "$0")/../.." && pwd)
command -v chromium >/dev/null 2>&1 || { echo "SKIP: chromium is not installed (tools/install-deps.sh)"; exit 77; }
"$here/tools/install-web-deps.sh" web "$build" || { echo "SKIP: three.js / puppeteer-core could not be installed from npm"; exit 77; }
"$here/tools/install-web-deps.sh" py "$build" || { echo "SKIP: trimesh could not be installed from PyPI"; exit 77; }
build=$(cd "$build" && pwd)
py=$build/pyenv/bin/python
W=960 H=720
tmp=$(mktemp -d /tmp/facescan-viewer.XXXXXX)
vpid=""
trap '[ -n "$vpid" ] && kill "$vpid" 2>/dev/null; rm -rf "$tmp"' EXIT
fail=0
t_start=$(date +%s)

# The scan: simulated capture (half resolution) → facescan recon, made afresh by the binary under
# test (a scan kept from an older recon once hid a failure that only a clean clone showed).
"$bin" simulate --scale 0.5 --out "$tmp/set" >"$tmp/log" 2>&1 &&
	"$bin" recon "$tmp/set" -o "$tmp/scan.drc" >>"$tmp/log" 2>&1 ||
	{ echo "FAIL: could not make the scan"; cat "$tmp/log"; exit 1; }
echo "ok: made the scan in $(( $(date +%s) - t_start )) s"
share=$tmp/share
mkdir -p "$share/P-TEST" "$tmp/outside"
"$bin" convert "$tmp/scan.drc" "$share/P-TEST/scan.glb" >"$tmp/log" 2>&1 || { echo "FAIL: convert"; cat "$tmp/log"; exit 1; }
echo "ok: $(cat "$tmp/log")"
echo "secret-outside-the-share" >"$tmp/outside/secret.json"
ln -s "$tmp/outside/secret.json" "$share/P-TEST/link.json"
ln -s "$tmp/outside" "$share/P-OUT"

"$bin" view "$share" --port 0 >"$tmp/view.log" 2>&1 &
vpid=$!
i=0; while ! grep -q http "$tmp/view.log" && [ $i -lt 100 ]; do sleep 0.1; i=$((i + 1)); done
url=$(sed -n 's/.*\(http[^ ]*\).*/\1/p' "$tmp/view.log" | head -1)
case $url in http://127.0.0.1:*/) echo "ok: serving on $url (localhost)" ;; *) echo "FAIL: no URL"; cat "$tmp/view.log"; exit 1 ;; esac
base=${url%/}

# What it serves and what it refuses.
get() { curl -s --path-as-is -o "$tmp/body" -w '%{http_code} %{content_type}' "$base$1"; }
for case in "/share/P-TEST/scan.glb=200 model/gltf-binary" \
	"/vendor/three/examples/jsm/libs/draco/gltf/draco_decoder.wasm=200 application/wasm" \
	"/vendor/three/build/three.module.js=200 text/javascript; charset=utf-8" \
	"/api/scans=200 application/json" \
	"/share/../secret.json=40" "/share/P-TEST/../../outside/secret.json=40" \
	"/share/%2e%2e/outside/secret.json=40" "/share/P-TEST/%2e%2e%2f%2e%2e%2foutside%2fsecret.json=40" \
	"/share/P-TEST/link.json=403" "/share/P-OUT/secret.json=403" "/share/P-TEST/.hidden.glb=403" \
	"/vendor/three/../../package.json=40" "/vendor/three/package.json=403" "/share//etc/passwd=40" \
	"/share/P-TEST/scan.glb%00.png=40" "/../../../../etc/passwd=40"; do
	path=${case%%=*} want=${case#*=}
	got=$(get "$path")
	case $got in
	"$want"*) if grep -q -e secret-outside -e root: "$tmp/body"; then echo "FAIL: $path leaked a file"; fail=1
		else echo "ok: GET $path -> $got"; fi ;;
	*) echo "FAIL: GET $path -> $got, want $want"; fail=1 ;;
	esac
done
grep -q '"P-TEST"' "$tmp/body" 2>/dev/null || true
get /api/scans >/dev/null; grep -q '"/share/P-TEST/scan.glb"' "$tmp/body" && echo "ok: the listing names P-TEST/scan.glb" ||
	{ echo "FAIL: listing"; cat "$tmp/body"; fail=1; }

# Two known vertices: front-facing, unoccluded, away from holes, on either cheek.
"$bin" convert "$share/P-TEST/scan.glb" "$tmp/scan.ply" >/dev/null 2>&1
pts=$("$py" - "$tmp/scan.ply" <<'PY'
import sys
import numpy as np
import trimesh
m = trimesh.load(sys.argv[1], force="mesh", process=False)
v, n = m.vertices, m.vertex_normals
lo, hi = v.min(0), v.max(0)
c, size = (lo + hi) / 2, hi - lo
facing = np.abs(n[:, 2]) > 0.7
# Not on or next to a hole's rim: a click through a rim vertex can pass beside the surface.
edges, count = np.unique(np.sort(m.edges, axis=1), axis=0, return_counts=True)
rim = np.zeros(len(v), bool)
rim[edges[count == 1].ravel()] = True
for _ in range(2):
    rim[m.edges[rim[m.edges[:, 0]], 1]] = True
facing &= ~rim
top = v[:, 2].max() + 10
# Nothing in front of it: the front view's ray through it meets the mesh first at it, and the
# rays 1 mm around it meet it within 1.5 mm of its depth (the same surface at up to 45 degrees,
# not a nose or a fold in front). Checking by neighbouring vertices instead (none within 3 mm
# across and 0.5 mm nearer) refused every vertex of a slanted cheek on a mesh as fine as 0.35 mm.
def visible(i):
    x, y, z = v[i]
    xy = np.array([[x, y], [x + 1, y], [x - 1, y], [x, y + 1], [x, y - 1]])
    origins = np.column_stack([xy, np.full(len(xy), top)])
    hit, ray, _ = m.ray.intersects_location(origins, np.tile([0.0, 0.0, -1.0], (len(xy), 1)),
                                            multiple_hits=False)
    if len(set(ray.tolist())) < len(xy):
        return False
    first = dict(zip(ray.tolist(), hit[:, 2]))
    return first[0] <= z + 0.5 and max(first[k] for k in range(1, len(xy))) <= z + 1.5
def pick(tx, ty):
    cost = np.hypot(v[:, 0] - tx, v[:, 1] - ty) + np.where(facing, 0, 1e9)
    for i in np.argsort(cost)[:3000]:
        if cost[i] > 1e8:
            break
        if visible(i):
            return v[i]
    return None
a = pick(c[0] - 0.25 * size[0], c[1])
b = None
for dy in (-0.15, 0.0, 0.1, -0.25):  # the other cheek, wherever the scan has it
    b = b if b is not None else pick(c[0] + 0.25 * size[0], c[1] + dy * size[1])
if a is None or b is None:
    sys.exit("no visible front-facing vertex on a cheek")
print(" ".join("%.4f" % x for x in list(a) + list(b)), "%.4f" % np.linalg.norm(a - b))
PY
) || { echo "FAIL: picking vertices"; exit 1; }
set -- $pts
truth=$7
t0=$(date +%s)
node "$here/tests/viewer/viewer_check.cjs" "$build/web/node_modules/puppeteer-core" \
	"$base/view.html?mesh=/share/P-TEST/scan.glb" $W $H "$tmp/shot.png" "$tmp/ui.png" $1 $2 $3 $4 $5 $6 >"$tmp/page.json" 2>"$tmp/node.log"
echo "ok: chromium ran the page in $(( $(date +%s) - t0 )) s"
"$bin" thumbnail "$share/P-TEST/scan.glb" "$tmp/ref.png" --azimuth 0 --size ${W}x$H --mask ||
	{ echo "FAIL: reference render"; fail=1; }
"$py" - "$tmp/page.json" "$tmp/shot.png" "$tmp/ref.png" "$truth" <<'PY' || fail=1
import json, sys
import numpy as np
from PIL import Image
page = json.load(open(sys.argv[1]))
bad = 0
def check(cond, what):
    global bad
    print(("ok: " if cond else "FAIL: ") + what)
    bad += not cond
if page.get("error"):
    print("FAIL: the page reported: %s\n%s" % (page["error"], "\n".join(page.get("console", []))))
    sys.exit(1)
shot = np.asarray(Image.open(sys.argv[2]).convert("RGB")).astype(int)
ref = np.asarray(Image.open(sys.argv[3])) > 127
face = np.abs(shot - np.array([0x20, 0x24, 0x28])).max(axis=2) > 6
iou = (face & ref).sum() / max(1, (face | ref).sum())
check(ref.sum() > 0.05 * ref.size, "the reference render shows the face on %.0f %% of the view" % (100 * ref.mean()))
check(iou >= 0.9, "silhouette IoU %.4f >= 0.9 (browser %d px, ray caster %d px; loaded in %d ms)" %
      (iou, face.sum(), ref.sum(), page["load_ms"]))
truth = float(sys.argv[4])
got = page.get("measurement_mm")
check(got is not None and abs(got - truth) <= 0.5,
      "measured %s mm between the vertices, true %.3f mm (readout '%s', clicks %s)" %
      (None if got is None else "%.3f" % got, truth, page.get("readout"), page.get("clicks")))
sys.exit(1 if bad else 0)
PY
[ -n "${FACESCAN_VIEWER_SHOT:-}" ] && cp "$tmp/ui.png" "$FACESCAN_VIEWER_SHOT"
echo "viewer test: $(( $(date +%s) - t_start )) s"
exit $fail
