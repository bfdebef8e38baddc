#!/bin/sh
# make demo: one scan through the whole booth on this machine, with whatever of the chain exists.
#
#   trigger firmware   QEMU (lm3s6965evb image, UART on a pty), else the native build on a pty
#   cameras            the booth simulator through the camera driver's simulated backend, else
#                      the daemon's fake cameras
#   facescand          booth mode; the simulated button press goes through the firmware
#   reconstruction     host/recon's pipeline when facescand accepts it, else the fake mesh
#   output             ./out/share/<patient>/<UTC time>_<scan-id>.{drc,png,glb,_thumb.png,stl,dcm,json}
#   PACS               a local Orthanc this script starts (when installed) receives the DICOM instance
#   viewer             `facescan view` is checked on the share and its URL printed
#
# Prints what ran, what stood in for a missing part, and a summary. Exits 0 when the parts that
# exist work; non-zero only when one of them fails.
set -u
bin=${1:-build/bin}
out=$(pwd)/out
patient=DEMO-0001
FWPID= DPID= VPID=
. "$(dirname "$0")/orthanc.sh"
cleanup() {
	orthanc_stop
	[ -n "$DPID" ] && kill "$DPID" 2>/dev/null
	[ -n "$FWPID" ] && kill "$FWPID" 2>/dev/null
	wait 2>/dev/null
}
trap cleanup EXIT INT TERM
say() { printf '%s\n' "$*"; }
die() { say "demo: $*"; [ -f "$out/facescand.log" ] && tail -20 "$out/facescand.log"; exit 1; }
fs() { "$bin/facescan" "$@"; }
ms_since() { echo $(( ($(date +%s%N) - $1) / 1000000 )); }

[ -x "$bin/facescand" ] && [ -x "$bin/facescan" ] || die "$bin/facescand or $bin/facescan missing (make bins)"
rm -rf "$out/share" "$out/spool" "$out/run" "$out/capture" "$out/facescand.log" "$out/firmware.log"
mkdir -p "$out/share" "$out/run"
export FACESCAN_SOCKET=$out/run/facescand.sock
say "facescan demo: $(fs version)"
ran="" stood_in=""

# ---- 1. the trigger firmware on a pty --------------------------------------------------------
fw_kind=""
elf=build/firmware/lm3s6965evb/facescan-fw.elf
if command -v qemu-system-arm >/dev/null 2>&1 && [ -f "$elf" ]; then
	qemu-system-arm -M lm3s6965evb -nographic -monitor none -icount shift=5,sleep=off -serial pty -kernel "$elf" \
		>"$out/firmware.log" 2>&1 &
	FWPID=$!
	for _ in $(seq 50); do
		pty=$(sed -n 's/.*redirected to \(\/dev\/pts\/[0-9]*\).*/\1/p' "$out/firmware.log" | head -1)
		[ -n "$pty" ] && break
		sleep 0.1
	done
	if [ -n "${pty:-}" ]; then
		ln -sf "$pty" "$out/run/mcu"
		fw_kind="QEMU lm3s6965evb ($elf, UART on $pty)"
	else
		kill "$FWPID" 2>/dev/null; FWPID=
	fi
fi
if [ -z "$fw_kind" ] && [ -x "$bin/facescan-fw-native" ]; then
	"$bin/facescan-fw-native" --link "$out/run/mcu" >"$out/firmware.log" 2>&1 &
	FWPID=$!
	for _ in $(seq 50); do [ -e "$out/run/mcu" ] && break; sleep 0.1; done
	fw_kind="native firmware build on $(head -1 "$out/firmware.log")"
fi
if [ -n "$fw_kind" ]; then
	serial="$out/run/mcu"
	ran="$ran\n  firmware:        $fw_kind"
else
	serial=fake
	stood_in="$stood_in\n  firmware:        in-process fake MCU (no QEMU image and no native firmware build)"
fi

# ---- 2. the cameras: facescand renders through the camera driver's simulated backend ------------
# (tools/sim's sim/booth_camera.h, which facescand injects), or uses its fake cameras when that is missing.

# ---- 3. a PACS: a local Orthanc on loopback, its storage under out/ ----------------------------
pacs_conf=""
if command -v Orthanc >/dev/null 2>&1 || [ -x /usr/sbin/Orthanc ]; then
	rm -rf "$out/orthanc" && mkdir -p "$out/orthanc"
	orthanc_setup "$out/orthanc" && orthanc_start
	pacs_conf="pacs_called_ae = $ORTHANC_AE
pacs_host = 127.0.0.1
pacs_port = $ORTHANC_DIMSE"
	ran="$ran\n  PACS:            Orthanc $(orthanc_rest /system | sed -n 's/.*"Version" : "\([^"]*\)".*/\1/p') on 127.0.0.1:$ORTHANC_DIMSE (AE $ORTHANC_AE, REST $ORTHANC_HTTP)"
else
	stood_in="$stood_in\n  PACS:            none (Debian's orthanc is not installed): the instance stays on the share"
fi

# ---- 4. facescand -----------------------------------------------------------------------------
write_conf() { # cameras recon
	cat >"$out/run/facescand.conf" <<-CONF
	mode = booth
	share_dir = $out/share
	spool_dir = $out/spool
	socket_path = $FACESCAN_SOCKET
	serial_device = $serial
	camera_backend = $1
	recon_backend = $2
	sim_scene = default
	min_free_mb = 0
	mcu_timeout_ms = 5000
	output_stl = true
	output_dicom = true
	$pacs_conf
	CONF
}
start_daemon() {
	"$bin/facescand" --config "$out/run/facescand.conf" 2>>"$out/facescand.log" &
	DPID=$!
	for _ in $(seq 100); do
		fs status >/dev/null 2>&1 && return 0
		kill -0 "$DPID" 2>/dev/null || { DPID=; return 1; }
		sleep 0.1
	done
	return 1
}
refusal() { sed -n 's/.*refusing to start: //p' "$out/facescand.log" | tail -1; }
cameras=simulated recon=pipeline
write_conf simulated pipeline
if ! start_daemon; then
	why=$(refusal)
	cameras=fake recon=fake
	write_conf fake fake
	start_daemon || die "facescand did not start"
	stood_in="$stood_in\n  cameras:         fake synthetic frames (simulated cameras refused: $why)"
	stood_in="$stood_in\n  reconstruction:  fake mesh, a fixed hemisphere (the pipeline needs real or simulated frames)"
else
	ran="$ran\n  cameras:         booth simulator (tools/sim, scene 'default') through drivers/camera's simulated backend"
	ran="$ran\n  reconstruction:  host/recon pipeline (recon::reconstruct), Draco by host/mesh_io, accuracy by host/eval"
fi
mcu=$(fs status | sed -n 's/^MCU: *//p')
case $mcu in
connected*) ;;
*) die "facescand has no MCU link: $mcu" ;;
esac
ran="$ran\n  facescand:       booth mode, MCU $mcu, cameras $cameras, reconstruction $recon"

# ---- 5. a button press -------------------------------------------------------------------------
say ""
say "scan of $patient: arming, then pressing the booth button"
case $fw_kind in
native*)
	fs scan --patient "$patient" --no-wait >/dev/null || die "facescand refused the scan"
	kill -USR1 "$FWPID" # the native board's button input, debounced by the firmware
	how="SIGUSR1 to the native firmware (its button input, debounced by the firmware)" ;;
*)
	# QEMU and the fake MCU take a simulated press over the link (FS_CMD_DEBUG_BUTTON).
	fs scan --patient "$patient" --press --no-wait >/dev/null || die "facescand refused the scan"
	how="simulated press over the MCU link (FS_CMD_DEBUG_BUTTON)" ;;
esac
for _ in $(seq 1800); do
	kill -0 "$DPID" 2>/dev/null || { DPID=; die "facescand died during the scan (its last lines above)"; }
	st=$(fs status --json 2>/dev/null | sed -n 's/^ *"state": "\([a-z]*\)".*/\1/p')
	if [ "$st" = idle ] || [ "$st" = error ]; then
		fs last --json | grep -q '^  "state": "\(delivered\|spooled\|failed\)"' && break
	fi
	sleep 0.1
done
say "  button:        $how"
fs last | sed 's/^/  /'
state=$(fs last --json | sed -n 's/^  "state": "\([a-z]*\)".*/\1/p')
[ "$state" = delivered ] || die "the scan did not reach the share (state: $state)"
sed -n 's/^.*scan [0-9a-f]*: \(\[[1-3]\/3\].*\)$/  progress:      \1/p' "$out/facescand.log"

# ---- 6. the viewer on the share ----------------------------------------------------------------
glb=$(ls "$out"/share/"$patient"/*.glb 2>/dev/null | head -1)
view_url=""
if [ -n "$glb" ] && ./tools/install-web-deps.sh web "$(dirname "$bin")" >/dev/null 2>&1; then
	"$bin/facescan" view "$out/share" --port 0 >"$out/run/view.log" 2>&1 &
	VPID=$!
	for _ in $(seq 50); do grep -q http "$out/run/view.log" && break; sleep 0.1; done
	base_url=$(sed -n 's/.*\(http[^ ]*\)\/$/\1/p' "$out/run/view.log")
	rel="/share/$patient/$(basename "$glb")"
	code=$(curl -s -o /dev/null -w '%{http_code}' "$base_url$rel" 2>/dev/null)
	kill "$VPID" 2>/dev/null; wait "$VPID" 2>/dev/null
	[ "$code" = 200 ] && view_url="view.html?mesh=$rel" &&
		ran="$ran\n  viewer:          facescan view served the scan's .glb (HTTP $code)"
fi
[ -z "$view_url" ] && stood_in="$stood_in\n  viewer:          not checked (no .glb, or three.js could not be installed from npm)"

# ---- 7. summary -------------------------------------------------------------------------------
meta=$(ls "$out"/share/"$patient"/*.json | head -1)
num() { sed -n "s/^ *\"$1\": \([0-9.]*\),\{0,1\}$/\1/p" "$meta" | head -1; }
top() { sed -n "s/^ \"$1\": \([0-9.]*\),\{0,1\}$/\1/p" "$meta" | head -1; } # top-level key
mm() { printf '%.3f' "$(num "$1")"; }
say ""
say "summary"
say "  mesh:          $(ls "$out"/share/"$patient"/*.drc) ($(wc -c <"$(ls "$out"/share/"$patient"/*.drc)") bytes)"
say "  vertices:      $(top vertices), faces: $(top faces)"
say "  ms per stage:  capture $(num capture | cut -d. -f1), reconstruct $(num reconstruct | cut -d. -f1), write $(fs last --json | sed -n 's/^ *"write": \([0-9]*\).*/\1/p')"
ticks=$(tr -d ' \n' <"$meta" | sed -n 's/.*"step_ticks":\[\([0-9,]*\)\].*/\1/p')
[ -n "$ticks" ] && say "  trigger:       firmware step ticks $ticks (at $(num tick_hz) Hz); 4 shutters in one port write: $(grep -q '"shutters_in_lockstep": true' "$meta" && echo yes || echo no)"
acc=$(sed -n 's/^ *"\(rms_mm\|accuracy_rms_mm\|mean_error_mm\)": \([0-9.]*\).*/\1 \2/p' "$meta" | head -1)
if [ -n "$acc" ]; then
	say "  accuracy:      RMS $(mm rms_mm) mm, median $(mm median_mm) mm, p95 $(mm p95_mm) mm, completeness $(mm completeness) (reconstructed vertices vs the simulator's ground-truth head)"
else
	say "  accuracy:      not measured (needs simulated cameras, for the ground truth, and the real reconstruction)"
fi
python3 - "$meta" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
ms = m.get("output_ms", {})
role_ms = {"gltf": "glb", "thumbnail": "thumbnail", "stl": "stl", "obj": "obj", "obj-material": "obj", "dicom": "dicom"}
print("  files:")
for f in m.get("manifest", []):
    t = ms.get(role_ms.get(f["role"], ""), None)
    print("    %-12s %9d bytes  %s  %s" % (f["role"], f["bytes"], f["sha256"][:16] + "...",
                                          "written in %.0f ms" % t if t is not None else "from the reconstruction"))
d = m.get("dicom", {})
if d:
    p = d.get("pacs", {})
    print("  DICOM:         %s (SOP class %s)%s" % (d.get("share", "-"), d.get("sop_class_uid"),
          ", PACS %s: %s" % (p.get("ae"), p.get("state")) if p else ""))
for k, v in m.get("output_errors", {}).items():
    print("  output error:  %s: %s" % (k, v))
PY
[ -n "$ORTHANC_PID" ] && say "  Orthanc holds: $(orthanc_count) instance(s)"
[ -n "$view_url" ] && say "  viewer:        facescan view $out/share --port 8080  ->  http://127.0.0.1:8080/$view_url"
say ""
printf "what ran:$ran\n"
[ -n "$stood_in" ] && printf "stand-ins for parts not on main yet:$stood_in\n"
exit 0
