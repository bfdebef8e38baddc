#!/bin/sh
# facescand end to end: the native firmware build on a pty (the real protocol and trigger
# sequence), facescand as its own process with the fake cameras and reconstruction, the CLI.
# Scans by socket request and by button press; faults: a bad config, the MCU unplugged
# mid-scan, the share missing then back, a slow delivery (the loop keeps answering), kill -9
# while spooling and while delivering.
# The slow share and the slow spool are made from outside the daemon, which has no pause of its
# own: strace attaches to the running facescand and delays its renames into a named place
# (slow(), below; strace is in tools/install-deps.sh).
set -u
bin=${FACESCAN_BIN:?}
fw=$bin/facescan-fw-native
[ -x "$fw" ] || { echo "SKIP: $fw not built" >&2; exit 77; }
T=$(mktemp -d /tmp/facescan-e2e-XXXXXX)
T=$(cd "$T" && pwd -P) # strace matches the paths the kernel reports for the daemon's fds
FWPID= DPID= SPID=
cleanup() {
	[ -n "$SPID" ] && kill "$SPID" 2>/dev/null
	[ -n "$DPID" ] && kill -9 "$DPID" 2>/dev/null
	[ -n "$FWPID" ] && kill "$FWPID" 2>/dev/null
	wait 2>/dev/null
	rm -rf "$T"
}
trap cleanup EXIT
fails=0
ok() { echo "ok: $*"; }
bad() { echo "FAIL: $*"; fails=$((fails + 1)); }
check() { what=$1; shift; if "$@"; then ok "$what"; else bad "$what"; fi; }
export FACESCAN_SOCKET=$T/sock
fs() { "$bin/facescan" "$@"; }
state_now() { fs status --json 2>/dev/null | sed -n 's/^ *"state": "\([a-z]*\)".*/\1/p'; }

start_fw() {
	"$fw" --link "$T/tty" >"$T/fw.out" 2>"$T/fw.err" &
	FWPID=$!
	for _ in $(seq 50); do [ -e "$T/tty" ] && return 0; sleep 0.1; done
	return 1
}
start_daemon() { # extra config lines on stdin
	{ cat <<-CONF
	share_dir = $T/share
	spool_dir = $T/spool
	socket_path = $T/sock
	serial_device = $T/tty
	camera_backend = fake
	recon_backend = fake
	mode = booth
	min_free_mb = 0
	spool_retry_ms = 200
	mcu_timeout_ms = 1500
	CONF
	cat; } >"$T/facescand.conf"
	"$bin/facescand" --config "$T/facescand.conf" 2>>"$T/daemon.log" &
	DPID=$!
	for _ in $(seq 100); do fs status >/dev/null 2>&1 && return 0; sleep 0.1; done
	return 1
}
stop_daemon() { unslow; kill "$DPID"; wait "$DPID"; DPID=; }
# slow WHEN DELAY PLACE...: from now on every rename the running facescand makes into PLACE (a
# directory: any file renamed into place there; a bare name: a file of that name in any directory)
# is held DELAY (strace units: 1500ms) before (WHEN = delay_enter) or after (delay_exit) it
# happens. Returns once every thread of the daemon is traced; threads it starts later are too.
slow() {
	when=$1 delay=$2
	shift 2
	command -v strace >/dev/null || { echo "strace is missing (tools/install-deps.sh)" >&2; return 1; }
	paths=
	for p; do paths="$paths -P $p"; done
	# shellcheck disable=SC2086
	strace -qq -f -p "$DPID" -o /dev/null $paths -e trace=renameat,renameat2 \
		-e inject=renameat,renameat2:"$when=$delay" 2>>"$T/strace.err" &
	SPID=$!
	for _ in $(seq 50); do
		traced=yes
		for s in /proc/"$DPID"/task/*/status; do
			grep -q "^TracerPid:[[:space:]]*$SPID\$" "$s" 2>/dev/null || traced=no
		done
		[ "$traced" = yes ] && return 0
		sleep 0.1
	done
	return 1
}
# Detaches strace (the daemon runs on at full speed; LeakSanitizer cannot work under ptrace).
unslow() { [ -n "$SPID" ] && { kill "$SPID" 2>/dev/null; wait "$SPID" 2>/dev/null; SPID=; }; return 0; }
wait_state() { # state, tenths of a second
	for _ in $(seq "$2"); do
		[ "$(state_now)" = "$1" ] && return 0
		sleep 0.1
	done
	return 1
}
visible_files() { find "$T/share/$1" -type f ! -name '.*' 2>/dev/null | wc -l; }
hidden_files() { find "$T/share" -name '.*' -type f 2>/dev/null | wc -l; }

# ---- the shipped config parses; the unit is Type=notify with a watchdog and sandboxing ----
check "shipped facescand.conf is valid" "$bin/facescand" --check --config host/facescand/facescand.conf
for key in Type=notify WatchdogSec= User=facescan ProtectSystem=strict ReadWritePaths=/srv/facescan/share; do
	check "unit has $key" grep -q "^$key" host/facescand/facescand.service
done

# ---- a bad config is refused, naming the line ----
printf 'mode = booth\nshare_dir = relative\n' >"$T/bad.conf"
"$bin/facescand" --config "$T/bad.conf" 2>"$T/bad.err"; rc=$?
check "bad config refused (exit 1)" [ "$rc" -eq 1 ]
check "bad config error names the line" grep -q "bad.conf:2: share_dir" "$T/bad.err"

mkdir -p "$T/share"
check "native firmware on a pty" start_fw
check "facescand starts" start_daemon </dev/null
check "socket is mode 0660" [ "$(stat -c %a "$T/sock")" = 660 ]
check "status over the socket" sh -c "\"$bin/facescan\" status | grep -q 'firmware .* on native'"

# ---- booth: a request arms, the firmware's button fires it ----
fs scan --patient E2E-1 --json >"$T/scan1.json" &
SCAN=$!
check "armed" wait_state armed 30
kill -USR1 "$FWPID"   # the firmware's booth button (debounced in the firmware)
wait "$SCAN"; rc=$?
check "scan by request + button exits 0" [ "$rc" -eq 0 ]
check "five files for E2E-1 (.drc .png .glb _thumb.png .json)" [ "$(visible_files E2E-1)" -eq 5 ]
drc=$(ls "$T"/share/E2E-1/*.drc 2>/dev/null | head -1)
check "mesh is named <UTC>_<scan-id>.drc" sh -c "basename '$drc' | grep -Eq '^[0-9]{8}T[0-9]{6}Z_[0-9a-f]{12}\.drc$'"
check "mesh is Draco" sh -c "head -c 5 '$drc' | grep -q DRACO"
meta=${drc%.drc}.json
check "metadata has the firmware's trigger report" sh -c "grep -q '\"trigger\": \"button\"' '$meta' && grep -q '\"shutters_in_lockstep\": true' '$meta'"

# ---- booth: a press with nothing armed is a walk-in scan ----
kill -USR1 "$FWPID"
sleep 0.3
check "walk-in scan done" wait_state idle 50
sleep 0.3
check "walk-in scan delivered" [ "$(visible_files walk-in)" -eq 5 ]

# ---- MCU unplugged mid-scan ----
stop_daemon
start_daemon <<CONF
projector_settle_us = 500000
CONF
fs scan --patient UNPLUG --no-wait >/dev/null
check "armed before the unplug" wait_state armed 30
kill -USR1 "$FWPID"
sleep 0.2             # the sequence runs >= 500 ms: the cable goes in the middle of it
kill -9 "$FWPID"; wait "$FWPID" 2>/dev/null; FWPID=
check "error after the MCU vanished mid-scan" wait_state error 40
check "last reports the failure" sh -c "\"$bin/facescan\" last --json | grep -q '\"failed_stage\": \"capturing\"'"
check "the failure in words, not errno's" sh -c "\"$bin/facescan\" last --json | grep -q 'MCU.*link lost' && ! grep -q 'Transport endpoint' '$T/daemon.log'"
check "nothing on the share for UNPLUG" [ "$(visible_files UNPLUG)" -eq 0 ]
start_fw
check "recovered when the MCU is back" wait_state idle 60
stop_daemon

# ---- share missing, then back: spooled, delivered once ----
start_daemon </dev/null
mv "$T/share" "$T/share.away"
fs scan --patient SPOOL-1 --press >"$T/spool.out"; rc=$?
check "spooled scan exits 0" [ "$rc" -eq 0 ]
check "scan reported spooled" grep -q ": spooled" "$T/spool.out"
check "share root not recreated" [ ! -e "$T/share" ]
check "status counts it" sh -c "\"$bin/facescan\" status --json | grep -q '\"spool_pending\": 1'"
mv "$T/share.away" "$T/share"
for _ in $(seq 50); do [ "$(visible_files SPOOL-1)" -eq 5 ] && break; sleep 0.1; done
check "spooled scan delivered when the share is back" [ "$(visible_files SPOOL-1)" -eq 5 ]
sleep 0.6
check "delivered once" [ "$(visible_files SPOOL-1)" -eq 5 ]
check "last says delivered" sh -c "\"$bin/facescan\" last | grep -q ': delivered'"
check "spool empty" [ -z "$(ls "$T/spool/queue")" ]
stop_daemon

# ---- a slow delivery never blocks the loop: status answers, a scan request is taken at once,
# the delivery stops after the scan it delivers and the new scan's capture follows it ----
ms_of() { s=$(date +%s%N); "$@" >/dev/null 2>&1; echo $(( ($(date +%s%N) - s) / 1000000 )); }
start_daemon </dev/null
mv "$T/share" "$T/share.away"
fs scan --patient SLOW-1 --press >/dev/null
check "strace slows the share (1 s after each file of SLOW-1)" slow delay_exit 1s "$T/share/SLOW-1"
mv "$T/share.away" "$T/share"
for _ in $(seq 50); do [ "$(visible_files SLOW-1)" -ge 1 ] && break; sleep 0.05; done
check "a spooled scan is being delivered (slowly)" [ "$(visible_files SLOW-1)" -ge 1 ] && [ "$(visible_files SLOW-1)" -lt 5 ]
t=$(ms_of fs status)
check "status answers during the delivery (${t} ms)" [ "$t" -lt 1500 ]
t=$(ms_of fs scan --patient SLOW-2 --press --no-wait)
check "a scan request is answered during the delivery (${t} ms)" [ "$t" -lt 1500 ]
t=$(ms_of fs status)
check "status answers while the capture waits for the delivery (${t} ms)" [ "$t" -lt 1500 ]
check "both scans done" wait_state idle 250
for _ in $(seq 50); do [ "$(visible_files SLOW-2)" -eq 5 ] && break; sleep 0.1; done
check "SLOW-1 delivered whole" [ "$(visible_files SLOW-1)" -eq 5 ]
check "SLOW-2 delivered whole" [ "$(visible_files SLOW-2)" -eq 5 ]
check "spool empty after both" [ -z "$(ls "$T/spool/queue")" ]
stop_daemon

# ---- kill -9 before the files exist (armed): reported failed on restart ----
start_daemon </dev/null
fs scan --patient KILL-0 --no-wait >/dev/null
check "armed before the kill" wait_state armed 30
kill -9 "$DPID"; wait "$DPID" 2>/dev/null; DPID=
start_daemon </dev/null
check "scan killed while armed reported failed after restart" sh -c "\"$bin/facescan\" last --json | grep -q 'interrupted while armed'"
check "idle after the restart" wait_state idle 30
stop_daemon

# ---- kill -9 while spooling: nothing visible, reported failed on restart ----
# The spool's commit point (its manifest, renamed into place after every file) is held 3 s: the
# kill comes with the scan's files in the spool and the scan not yet committed.
start_daemon </dev/null
check "strace slows the spool's commit" slow delay_enter 3s manifest
fs scan --patient KILL-1 --press --no-wait >/dev/null
check "writing" wait_state writing 50
spooled_json() { ls "$T"/spool/queue/*/*.json >/dev/null 2>&1; }
for _ in $(seq 30); do spooled_json && break; sleep 0.1; done
check "the files are in the spool, the manifest is not" sh -c "ls '$T'/spool/queue/*/*.json >/dev/null 2>&1 && ! ls '$T'/spool/queue/*/manifest >/dev/null 2>&1"
kill -9 "$DPID"; wait "$DPID" 2>/dev/null; DPID=
unslow
check "no file of the killed scan on the share" [ "$(visible_files KILL-1)" -eq 0 ]
start_daemon </dev/null
check "killed scan reported failed after restart" sh -c "\"$bin/facescan\" last --json | grep -q 'interrupted while writing'"
check "last names the killed scan's patient and start" sh -c "\"$bin/facescan\" last | grep -q 'patient: *KILL-1' && \"$bin/facescan\" last | grep -q 'started: '"
check "spool cleared" [ -z "$(ls "$T/spool/queue")" ]
stop_daemon

# ---- kill -9 while delivering: recovered on restart, no partial or duplicate file ----
start_daemon </dev/null
check "strace slows the share (1.5 s after each file of KILL-2)" slow delay_exit 1500ms "$T/share/KILL-2"
fs scan --patient KILL-2 --press --no-wait >/dev/null
sleep 0.5
for _ in $(seq 50); do [ "$(visible_files KILL-2)" -ge 1 ] && break; sleep 0.1; done
kill -9 "$DPID"; wait "$DPID" 2>/dev/null; DPID=
unslow
n=$(visible_files KILL-2)
check "mid-delivery: some but not all files (got $n)" [ "$n" -ge 1 ] && [ "$n" -lt 5 ]
check "no metadata before the mesh is complete" [ -z "$(ls "$T"/share/KILL-2/*.json 2>/dev/null)" ]
start_daemon </dev/null
for _ in $(seq 50); do [ "$(visible_files KILL-2)" -eq 5 ] && break; sleep 0.1; done
check "delivery completed after restart" [ "$(visible_files KILL-2)" -eq 5 ]
for _ in $(seq 30); do fs last | grep -q 'patient: *KILL-2' && break; sleep 0.1; done
check "last shows the redelivered scan, delivered" sh -c "\"$bin/facescan\" last | grep -q 'patient: *KILL-2' && \"$bin/facescan\" last | grep -q ': delivered'"
check "no temp file left on the share" [ "$(hidden_files)" -eq 0 ]
check "no patient id in the daemon's log" sh -c "! grep -E 'E2E-1|UNPLUG|SPOOL-1|KILL-0|KILL-1|KILL-2' '$T/daemon.log'"
check "a progress line per stage" sh -c "grep -c '\[[123]/3\]' '$T/daemon.log' | awk '{exit !(\$1 >= 9)}'"
stop_daemon

# ---- a second facescand on the same config is refused and touches nothing ----
start_daemon </dev/null
check "strace slows the spool's commit" slow delay_enter 1500ms manifest
fs scan --patient LIVE-1 --press --no-wait >/dev/null
check "writing before the second start" wait_state writing 50
"$bin/facescand" --config "$T/facescand.conf" 2>"$T/second.err"; rc=$?
check "second facescand refused (exit 1)" [ "$rc" -eq 1 ]
check "it says another is running" grep -q "another facescand (pid $DPID) is running" "$T/second.err"
check "the running scan is delivered" wait_state idle 80
check "LIVE-1 on the share" [ "$(visible_files LIVE-1)" -eq 5 ]
check "last says LIVE-1 delivered" sh -c "\"$bin/facescan\" last | grep -q ': delivered' && \"$bin/facescan\" last | grep -q LIVE-1"
stop_daemon

# ---- socket_path naming a regular file: refused, the file kept ----
echo "keep me" >"$T/notasocket"
sed "s|^socket_path = .*|socket_path = $T/notasocket|" "$T/facescand.conf" >"$T/file.conf"
"$bin/facescand" --config "$T/file.conf" 2>"$T/file.err"; rc=$?
check "socket_path on a regular file refused (exit 1)" [ "$rc" -eq 1 ]
check "it says not a socket" grep -q "not a socket" "$T/file.err"
check "the file is kept" [ "$(cat "$T/notasocket")" = "keep me" ]

[ "$fails" -eq 0 ] || { echo "--- daemon log"; cat "$T/daemon.log"; }
exit "$fails"
