#!/bin/sh
# The layer check (tools/layers.txt, tools/check_layers.py): no source includes a layer above
# its own or a backend folder's private header. First proves on a copy of the tree that the
# check fails on an injected upward include and an injected private one, then checks the tree.
set -u
cd "$(dirname "$0")/../.." || exit 1
command -v python3 >/dev/null || { echo "python3 missing (tools/install-deps.sh)"; exit 77; }
tmp=$(mktemp -d "${TMPDIR:-/tmp}/facescan-layers-XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT
fail=0

# A copy of the sources (only what the check reads) and the map.
find firmware drivers host tools tests -type f \( -name '*.[ch]' -o -name '*.[ch]pp' -o -name '*.cc' \) \
	| tar -cf - -T - | tar -xf - -C "$tmp" || exit 1
mkdir -p "$tmp/map" && cp tools/layers.txt "$tmp/map/" || exit 1

# expect_fail FILE LINE-TEXT WANT: with LINE-TEXT appended to FILE the check must fail and name WANT.
expect_fail() {
	cp "$tmp/$1" "$tmp/saved" || exit 1
	printf '%s\n' "$2" >>"$tmp/$1"
	n=$(wc -l <"$tmp/$1" | tr -d ' ')
	python3 tools/check_layers.py --map "$tmp/map/layers.txt" "$tmp" >"$tmp/out" 2>&1
	rc=$?
	if [ "$rc" -ne 1 ] || ! grep -qF "$1:$n: $3" "$tmp/out"; then
		echo "FAIL: the check missed $1:$n ($2): exit $rc, output:"; cat "$tmp/out"; fail=1
	else
		echo "ok: an injected bad include is found: $(grep -F "$1:$n:" "$tmp/out")"
	fi
	mv "$tmp/saved" "$tmp/$1"
}
# Upward: a driver reaching into the daemon; the simulator from a driver (issue 12's case).
expect_fail drivers/gpio/gpio.c '#include "daemon/config.hpp"' '"daemon/config.hpp" -> daemon'
expect_fail drivers/camera/camera_sim.c '#include "sim/sim.hpp"' '"sim/sim.hpp" -> apps'
# Sideways: the daemon including a backend's private header.
expect_fail host/daemon/driver_cameras.cpp '#include "../../drivers/camera/camera_internal.h"' \
	'"../../drivers/camera/camera_internal.h" -> drivers (drivers/camera/camera_internal.h): private'

# The tree itself.
if python3 tools/check_layers.py; then
	echo "ok: the tree keeps its layers (tools/layers.txt)"
else
	echo "FAIL: forbidden includes above (map and reasons: tools/layers.txt)"; fail=1
fi
exit "$fail"
