#!/bin/sh
# The install path (packaging/install.mk): `make install DESTDIR=scratch` and `make deb`, both
# into scratch directories only (nothing is installed on this machine). Checks that the files
# are where the unit and the config name them, that `systemd-analyze verify` passes on the
# installed unit (in a scratch root that also holds this machine's own units, so its targets
# resolve), that the installed binaries run from there (facescan --help, facescand --check on
# the installed config, the viewer serving its page and three.js from PREFIX/share), that the
# package's control, conffiles, maintainer scripts and contents are right, that its sysusers and
# tmpfiles files create the user and the spool in the scratch root, and that the unit's
# `systemd-analyze security` exposure stays at or below MAX_EXPOSURE (docs/daemon.md "Hardening").
# Uses the release build (build/bin) when it has both binaries, else $FACESCAN_BIN (the runner's
# ASan build), as they are (never rebuilt here). Skips (77) only without dpkg-deb or
# systemd-analyze, or when the viewer's three.js cannot be had from npm.
set -u
# The exposure `systemd-analyze security --offline=yes` gives the unit (systemd 252, Debian 12),
# alone and with the network drop-in viewer_port / the PACS need (was 1.3 before the hardening
# pass); a change that loosens the unit fails here. Lower them when the unit gets tighter.
MAX_EXPOSURE=0.6
MAX_EXPOSURE_NETWORK=1.3
root=$(cd "$(dirname "$0")/../.." && pwd)
build=${FACESCAN_BUILD:-build}
case $build in /*) ;; *) build=$root/$build ;; esac
for tool in dpkg-deb systemd-analyze; do
	command -v $tool >/dev/null 2>&1 || { echo "SKIP: $tool is not installed"; exit 77; }
done
if [ -x "$build/bin/facescan" ] && [ -x "$build/bin/facescand" ]; then
	from=$build/bin
else
	from=${FACESCAN_BIN:?}
	case $from in /*) ;; *) from=$root/$from ;; esac
fi
echo "installing the binaries of $from"
# The binaries are tested as built: -o keeps make from rebuilding a stale release build here.
keep="-o $from/facescan -o $from/facescand"
# The package as shipped (xz) from the release build; gzip for the 90 MB of a sanitizer build.
compress=xz
[ "$from" = "$build/bin" ] || compress=gzip
"$root/tools/install-web-deps.sh" web "$build" >/dev/null ||
	{ echo "SKIP: the viewer's three.js could not be installed from npm (tools/install-web-deps.sh web)"; exit 77; }
T=$(mktemp -d /tmp/facescan-install-XXXXXX)
vpid=
trap '[ -n "$vpid" ] && kill "$vpid" 2>/dev/null; rm -rf "$T"' EXIT
fails=0
ok() { echo "ok: $*"; }
bad() { echo "FAIL: $*"; fails=$((fails + 1)); }
check() { what=$1; shift; if "$@"; then ok "$what"; else bad "$what"; fi; }
t0=$(date +%s)

# ---- make install ---------------------------------------------------------------------------
I=$T/inst
if ! make -C "$root" --no-print-directory $keep install DESTDIR="$I" BUILD="$build" INSTALL_FROM="$from" \
	>"$T/install.log" 2>&1; then
	bad "make install DESTDIR=$I"; cat "$T/install.log"; exit 1
fi
ok "make install DESTDIR=scratch"
THREE=usr/share/facescan/web/node_modules/three
want="usr/bin/facescan usr/bin/facescand usr/lib/systemd/system/facescand.service
usr/lib/sysusers.d/facescan.conf usr/lib/tmpfiles.d/facescan.conf etc/facescan/facescand.conf
usr/share/doc/facescan/README.md usr/share/doc/facescan/daemon.md usr/share/doc/facescan/clinic.md
usr/share/facescan/web/page/view.html usr/share/facescan/web/page/index.html
$THREE/build/three.module.js $THREE/LICENSE $THREE/examples/jsm/libs/draco/gltf/draco_decoder.wasm
usr/share/doc/facescan/examples/facescand.service.d/network.conf"
missing=
for f in $want; do [ -f "$I/$f" ] || missing="$missing $f"; done
check "installed files are in place${missing:+ (missing:$missing)}" [ -z "$missing" ]
check "binaries are executable" [ -x "$I/usr/bin/facescan" ] && [ -x "$I/usr/bin/facescand" ]
# Nothing that is not ours: no test, bench or firmware binary.
extra=$(ls "$I/usr/bin" | grep -vx -e facescan -e facescand)
check "only facescan and facescand in bin${extra:+ (also: $extra)}" [ -z "$extra" ]

# Every file the unit names exists in the installed tree: ExecStart*/ExecStartPre binaries,
# --config, Documentation=file://, sysusers' user = User=, tmpfiles' spool in ReadWritePaths=.
unit=$I/usr/lib/systemd/system/facescand.service
for exe in $(sed -n 's/^ExecStart[A-Za-z]*=[-@:+!]*\([^ ]*\).*/\1/p' "$unit"); do
	check "unit runs $exe, installed" [ -x "$I$exe" ]
done
for conf in $(sed -n 's/^ExecStart[A-Za-z]*=.*--config \([^ ]*\).*/\1/p' "$unit" | sort -u); do
	check "unit's --config $conf is installed" [ -f "$I$conf" ]
done
doc=$(sed -n 's|^Documentation=file://||p' "$unit")
check "unit's Documentation $doc is installed" [ -f "$I$doc" ]
user=$(sed -n 's/^User=//p' "$unit")
check "sysusers creates the unit's User=$user" grep -q "^u $user " "$I/usr/lib/sysusers.d/facescan.conf"
spool=$(awk '$1 == "d" { print $2 }' "$I/usr/lib/tmpfiles.d/facescan.conf")
check "tmpfiles' $spool is in ReadWritePaths" grep -q "^ReadWritePaths=.*$spool" "$unit"
check "config's spool_dir is tmpfiles' $spool" grep -qx "spool_dir = $spool" "$I/etc/facescan/facescand.conf"

# The installed config: valid, and every key of this build is in it (set or commented with its doc).
check "installed facescand --check accepts the installed config" \
	"$I/usr/bin/facescand" --config "$I/etc/facescan/facescand.conf" --check
undoc=
for k in $("$I/usr/bin/facescand" --print-config | sed -n 's/^\([a-z_]*\) = .*/\1/p'); do
	grep -Eq "^#?$k = " "$I/etc/facescan/facescand.conf" || undoc="$undoc $k"
done
check "installed config names every key${undoc:+ (missing:$undoc)}" [ -z "$undoc" ]
check "installed facescan --help" sh -c "'$I/usr/bin/facescan' --help | grep -q '^  recon '"
check "installed facescan version" sh -c "'$I/usr/bin/facescan' version | grep -q '^facescan '"
# make install never overwrites a site's config: a second run puts the new one beside it.
echo "# site" >>"$I/etc/facescan/facescand.conf"
make -C "$root" --no-print-directory $keep install DESTDIR="$I" BUILD="$build" INSTALL_FROM="$from" >"$T/install2.log" 2>&1
check "a second make install keeps the site's config (new one as .conf.new)" \
	sh -c "tail -1 '$I/etc/facescan/facescand.conf' | grep -qx '# site' && [ -f '$I/etc/facescan/facescand.conf.new' ]"

# The viewer from the installed location (FACESCAN_WEB unset: found as bin/../share/facescan/web):
# the page, and every module the page's import map and imports load, served.
mkdir -p "$T/share"
(unset FACESCAN_WEB; exec "$I/usr/bin/facescan" view "$T/share" --port 0) >"$T/view.log" 2>&1 &
vpid=$!
i=0; while ! grep -q http "$T/view.log" && [ $i -lt 100 ]; do sleep 0.1; i=$((i + 1)); done
url=$(sed -n 's/.*\(http[^ ]*\/\).*/\1/p' "$T/view.log" | head -1)
if [ -z "$url" ]; then
	bad "installed facescan view serves"; cat "$T/view.log"
elif command -v curl >/dev/null 2>&1; then
	# three/addons/... relative to examples/jsm, '../x.js' imports relative to the importer.
	mods="build/three.module.js examples/jsm/libs/draco/gltf/draco_decoder.wasm
	examples/jsm/libs/draco/gltf/draco_wasm_wrapper.js examples/jsm/libs/draco/gltf/draco_decoder.js"
	for m in $(sed -n "s|.*from 'three/addons/\([^']*\)'.*|\1|p" "$root/host/viewer/page/"*.js); do
		mods="$mods examples/jsm/$m"
		for r in $(sed -n "s|.*from '\.\./\([^']*\)'.*|\1|p" "$I/$THREE/examples/jsm/$m" 2>/dev/null); do
			mods="$mods examples/jsm/$(dirname "$(dirname "$m")")/$r"
		done
	done
	unserved=
	for p in view.html viewer.js; do curl -fsS -o /dev/null "$url$p" || unserved="$unserved $p"; done
	for m in $mods; do curl -fsS -o /dev/null "${url}vendor/three/$m" 2>/dev/null || unserved="$unserved $m"; done
	check "installed viewer serves its page and $(echo $mods | wc -w) three.js files${unserved:+ (not:$unserved)}" [ -z "$unserved" ]
else
	ok "installed facescan view serves $url (curl missing: files not fetched)"
fi
kill "$vpid" 2>/dev/null; wait "$vpid" 2>/dev/null; vpid=

# ---- systemd-analyze verify, in a scratch root ------------------------------------------------
# The root is the installed tree plus this machine's units (the unit's targets must resolve);
# /lib -> usr/lib as on Debian 12. Any message fails (an unknown key is only a warning).
V=$T/verify
cp -a "$I" "$V" && cp -an /lib/systemd/system/. "$V/usr/lib/systemd/system/" && ln -s usr/lib "$V/lib"
systemd-analyze verify --root="$V" --man=no --recursive-errors=no facescand.service >"$T/verify.log" 2>&1
rc=$?
check "systemd-analyze verify --root passes (exit $rc, $(wc -l <"$T/verify.log") messages)" \
	[ $rc -eq 0 ] && [ ! -s "$T/verify.log" ]
cat "$T/verify.log"

# ---- systemd-analyze security, the unit alone ------------------------------------------------
exposure() { # root max what
	systemd-analyze security --offline=yes --root="$1" facescand.service >"$T/security.log" 2>&1
	score=$(sed -n 's/.*Overall exposure level for facescand.service: \([0-9.]*\).*/\1/p' "$T/security.log")
	if [ -z "$score" ]; then
		bad "systemd-analyze security printed no exposure level"; cat "$T/security.log"; return
	fi
	check "security exposure, $3: $score <= $2" awk -v s="$score" -v m="$2" 'BEGIN { exit !(s <= m) }'
	grep '✗' "$T/security.log" | sed 's/  */ /g'
}
exposure "$I" "$MAX_EXPOSURE" "the unit"

# ---- ... and with the network drop-in (viewer_port, PACS), as docs/daemon.md installs it ------
D=$V/etc/systemd/system/facescand.service.d
mkdir -p "$D" && cp "$I/usr/share/doc/facescan/examples/facescand.service.d/network.conf" "$D/"
systemd-analyze verify --root="$V" --man=no --recursive-errors=no facescand.service >"$T/verify.log" 2>&1
rc=$?
check "systemd-analyze verify passes with the network drop-in (exit $rc)" [ $rc -eq 0 ] && [ ! -s "$T/verify.log" ]
cat "$T/verify.log"
exposure "$V" "$MAX_EXPOSURE_NETWORK" "with network.conf"
check "the drop-in opens the network (PrivateNetwork flagged)" grep -q '✗ PrivateNetwork=' "$T/security.log"

# ... and verify can fail: the same root without the binary.
rm "$V/usr/bin/facescand"
systemd-analyze verify --root="$V" --man=no --recursive-errors=no facescand.service >/dev/null 2>&1
check "systemd-analyze verify fails when ExecStart's binary is missing" [ $? -ne 0 ]

# ---- make deb --------------------------------------------------------------------------------
if ! make -C "$root" --no-print-directory $keep deb BUILD="$build" INSTALL_FROM="$from" DEB_COMPRESS=$compress >"$T/deb.log" 2>&1; then
	bad "make deb"; cat "$T/deb.log"; exit 1
fi
deb=$(sed -n 's/^deb: //p' "$T/deb.log")
rebuilt=$(cat "$T/install.log" "$T/install2.log" "$T/deb.log" | grep -E '^  (CC|CXX|LD|AR) ' | head -3)
check "make install / make deb rebuilt nothing${rebuilt:+ (did: $rebuilt)}" [ -z "$rebuilt" ]
check "make deb built $deb" [ -f "$deb" ]
dpkg-deb -I "$deb" >"$T/info" 2>&1
field() { sed -n "s/^ $1: //p" "$T/info"; }
check "package is facescan $(field Version) for $(dpkg --print-architecture)" \
	[ "$(field Package)" = facescan ] && [ "$(field Architecture)" = "$(dpkg --print-architecture)" ]
dep=$(field Depends)
echo "Depends: $dep"
for lib in libopencv-core libdraco libdcmtk libcamera libsystemd0 libstdc++6 libc6 systemd; do
	check "Depends names $lib" sh -c "echo '$dep' | grep -q '$lib'"
done
dpkg-deb --ctrl-tarfile "$deb" | tar -t >"$T/ctrl" 2>&1
for s in postinst prerm postrm conffiles; do check "control has $s" grep -qx "./$s" "$T/ctrl"; done
mkdir -p "$T/ctl" && dpkg-deb -e "$deb" "$T/ctl"
check "conffiles is the config" grep -qx /etc/facescan/facescand.conf "$T/ctl/conffiles"
check "postinst runs systemd-sysusers and systemd-tmpfiles on the package's files" sh -c \
	"grep -q 'systemd-sysusers /usr/lib/sysusers.d/facescan.conf' '$T/ctl/postinst' &&
	 grep -q 'systemd-tmpfiles --create /usr/lib/tmpfiles.d/facescan.conf' '$T/ctl/postinst'"
check "postinst enables and starts nothing" \
	sh -c "! grep -Eq 'systemctl.*[[:space:]](enable|start|reenable|preset|unmask)[[:space:]]' '$T/ctl/postinst'"
for s in postinst prerm postrm; do
	check "$s is executable and parses" sh -c "[ -x '$T/ctl/$s' ] && sh -n '$T/ctl/$s'"
done
dpkg-deb -c "$deb" >"$T/contents"
check "package files belong to root:root" sh -c "! awk '\$2 != \"root/root\"' '$T/contents' | grep -q ."
# The package holds exactly what make install puts there (+ its copyright file).
(cd "$I" && find . -type f ! -name '*.conf.new' | sort) >"$T/inst.list"
awk '$1 !~ /^d/ { print $6 }' "$T/contents" | grep -v '^./usr/share/doc/facescan/copyright$' | sort >"$T/deb.list"
check "package contents = make install's files ($(wc -l <"$T/deb.list") files)" cmp -s "$T/inst.list" "$T/deb.list"
cmp -s "$T/inst.list" "$T/deb.list" || diff "$T/inst.list" "$T/deb.list" | head
X=$T/deb
dpkg-deb -x "$deb" "$X"
check "packaged facescan --help runs" sh -c "'$X/usr/bin/facescan' --help >/dev/null"
check "packaged facescand --check accepts the packaged config" \
	"$X/usr/bin/facescand" --config "$X/etc/facescan/facescand.conf" --check
check "packaged binaries are stripped" sh -c "! file -b '$X/usr/bin/facescand' | grep -q 'not stripped'"
echo "package: $(du -k "$deb" | cut -f1) KiB, installed $(field Installed-Size) KiB"
# What postinst does, in the extracted root: the user and the spool appear there (root only:
# tmpfiles chowns to the new user).
if [ "$(id -u)" -eq 0 ]; then
	systemd-sysusers --root="$X" "$X/usr/lib/sysusers.d/facescan.conf" >"$T/sysusers.log" 2>&1
	check "sysusers creates the user facescan in the root" grep -q '^facescan:' "$X/etc/passwd"
	systemd-tmpfiles --root="$X" --create "$X/usr/lib/tmpfiles.d/facescan.conf" >"$T/tmpfiles.log" 2>&1
	check "tmpfiles creates $spool 0750" sh -c "[ \"\$(stat -c %a '$X$spool')\" = 750 ]"
else
	echo "note: not root, sysusers/tmpfiles in the root not tried"
fi

echo "test_install: $(( $(date +%s) - t0 )) s"
[ $fails -eq 0 ] || { echo "$fails check(s) failed"; exit 1; }
