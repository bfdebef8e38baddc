#!/bin/sh
# Installs the pinned pieces that do not come from Debian, cached under the build directory:
#   web  build/web/page: the viewer page (copied from host/viewer/page on every run), and
#        build/web/node_modules: three.js (GLTFLoader, DRACOLoader, Draco decoder wasm) that the
#        viewer serves, and the Khronos glTF validator the tests run (npm ci from
#        host/viewer/package-lock.json: exact versions, checked integrity)
#   py   build/pyenv: Python trimesh (+ numpy, pillow, rtree for its ray queries), the independent
#        mesh reader of the tests
#   scan build/cache/scan-head: a real head for `facescan simulate --head scan`: the CT of a
#        patient's head ("ProMED CT 0051", 256 x 256 x 108 voxels, 0.96 x 0.96 x 1.5 mm, crown
#        to upper lip) that Debian's invesalius-examples ships (GPL-2, its copyright file is
#        kept beside it), as volume.raw (int16) + volume.txt (nx ny nz sx sy sz). Never
#        committed; fetched with apt-get download, which needs no root and installs nothing.
# Idempotent: a piece whose pinned set is already there is not fetched again.
# usage: install-web-deps.sh web|py|scan [BUILD_DIR]     exit 0 ready, 1 could not be installed
set -eu
what=${1:?usage: install-web-deps.sh web|py|scan [BUILD_DIR]}
build=${2:-${FACESCAN_BUILD:-build}}
root=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$build"
build=$(cd "$build" && pwd)

case $what in
web)
	dir=$build/web
	stamp=$dir/.installed
	# The page is the project's own: refreshed every time (cheap), atomically by rename.
	sync_page() {
		rm -rf "$dir/page.tmp" && cp -R "$root/host/viewer/page" "$dir/page.tmp" &&
			rm -rf "$dir/page" && mv "$dir/page.tmp" "$dir/page"
	}
	if [ -f "$stamp" ] && cmp -s "$stamp" "$root/host/viewer/package-lock.json"; then
		sync_page
		exit 0
	fi
	command -v npm >/dev/null 2>&1 || { echo "install-web-deps: npm not found" >&2; exit 1; }
	rm -rf "$dir.tmp"
	mkdir -p "$dir.tmp"
	cp "$root/host/viewer/package.json" "$root/host/viewer/package-lock.json" "$dir.tmp/"
	(cd "$dir.tmp" && npm ci --no-audit --no-fund --loglevel=error >/dev/null) || {
		rm -rf "$dir.tmp"
		echo "install-web-deps: npm ci failed" >&2
		exit 1
	}
	cp "$root/host/viewer/package-lock.json" "$dir.tmp/.installed"
	rm -rf "$dir"
	mv "$dir.tmp" "$dir"
	sync_page
	;;
py)
	dir=$build/pyenv
	want="trimesh==4.5.3 numpy==2.4.6 pillow==13.0.0 rtree==1.3.0"
	stamp=$dir/.installed
	if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then
		exit 0
	fi
	rm -rf "$dir"
	python3 -m venv "$dir" || { echo "install-web-deps: python3 -m venv failed" >&2; exit 1; }
	# shellcheck disable=SC2086
	"$dir/bin/pip" install -q --disable-pip-version-check $want || {
		rm -rf "$dir"
		echo "install-web-deps: pip install failed" >&2
		exit 1
	}
	echo "$want" >"$stamp"
	;;
scan)
	dir=$build/cache/scan-head
	want="invesalius-examples=3.1.99998-4 Cranium.inv3"
	stamp=$dir/.installed
	if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then
		exit 0
	fi
	rm -rf "$dir.tmp"
	mkdir -p "$dir.tmp/deb"
	(cd "$dir.tmp/deb" && apt-get download -q=2 invesalius-examples=3.1.99998-4 >/dev/null 2>&1) || {
		rm -rf "$dir.tmp"
		echo "install-web-deps: apt-get download invesalius-examples failed (apt-get update first?)" >&2
		exit 1
	}
	doc=$dir.tmp/x/usr/share/doc/invesalius-examples
	dpkg-deb -x "$dir.tmp"/deb/invesalius-examples_*.deb "$dir.tmp/x" &&
		mkdir -p "$dir.tmp/inv3" && tar -xzf "$doc/examples/Cranium.inv3" -C "$dir.tmp/inv3" &&
		python3 - "$dir.tmp" <<'PY' || {
import glob, os, plistlib, shutil, sys
tmp = sys.argv[1]
main = glob.glob(tmp + "/inv3/*/main.plist")[0]
with open(main, "rb") as f:
    p = plistlib.load(f)
m = p["matrix"]
nz, ny, nx = m["shape"]
sx, sy, sz = p["spacing"]
src = os.path.join(os.path.dirname(main), m["filename"])
if m["dtype"] != "int16" or os.path.getsize(src) != nx * ny * nz * 2:
    sys.exit("Cranium.inv3: expected an int16 %dx%dx%d matrix" % (nx, ny, nz))
shutil.copyfile(src, tmp + "/volume.raw")  # numpy C order, x fastest, little-endian
with open(tmp + "/volume.txt", "w") as f:
    f.write("%d %d %d %.7g %.7g %.7g\n" % (nx, ny, nz, sx, sy, sz))
PY
		rm -rf "$dir.tmp"
		echo "install-web-deps: could not convert Cranium.inv3" >&2
		exit 1
	}
	cp "$doc/copyright" "$dir.tmp/copyright"
	rm -rf "$dir.tmp/deb" "$dir.tmp/x" "$dir.tmp/inv3"
	echo "$want" >"$dir.tmp/.installed"
	rm -rf "$dir"
	mv "$dir.tmp" "$dir"
	;;
*)
	echo "install-web-deps: unknown piece '$what' (web|py|scan)" >&2
	exit 2
	;;
esac
