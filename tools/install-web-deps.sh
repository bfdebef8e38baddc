#!/bin/sh
# Installs the pinned pieces that do not come from Debian, cached under the build directory:
#   web  build/web/page: the viewer page (copied from host/viewer/page on every run), and
#        build/web/node_modules: three.js (GLTFLoader, DRACOLoader, Draco decoder wasm) that the
#        viewer serves, and the Khronos glTF validator the tests run (npm ci from
#        host/viewer/package-lock.json: exact versions, checked integrity)
#   py   build/pyenv: Python trimesh (+ numpy, pillow), the independent mesh reader of the tests
# Idempotent: a piece whose pinned set is already there is not fetched again.
# usage: install-web-deps.sh web|py [BUILD_DIR]     exit 0 ready, 1 could not be installed
set -eu
what=${1:?usage: install-web-deps.sh web|py [BUILD_DIR]}
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
	want="trimesh==4.5.3 numpy==2.4.6 pillow==13.0.0"
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
*)
	echo "install-web-deps: unknown piece '$what' (web|py)" >&2
	exit 2
	;;
esac
