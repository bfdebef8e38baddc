#!/bin/sh
# Inside the VM tier (run by guest.sh, not by run-tests.sh on the host): facescand as a booth
# would run it — mode booth, libcamera cameras (the two vimc instances), the button, LED and MCU
# reset on a libgpiod chip (gpio-sim), the trigger MCU in-process (serial_device = fake: the VM
# has no MCU). A bouncing press on the simulated button starts a scan; vimc's colour bars carry
# no pattern, so the scan must reach reconstruction and fail there with "no pattern found", and
# the clinic share must hold nothing afterwards (no mesh, no temp file).
set -u
: "${FACESCAN_BIN:?}" "${FACESCAN_VM_SHARE:?}"
say() { echo "guest_scan: $*"; }
die() {
	say "FAIL: $*"
	[ -f "$logs/facescand.log" ] && sed 's/^/  facescand: /' "$logs/facescand.log" | tail -30
	exit 1
}
tmp=$(mktemp -d)
logs=$FACESCAN_VM_SHARE/scan-logs # on the share: they survive a guest that is killed
mkdir -p "$logs"
share=$FACESCAN_VM_SHARE/clinic-share
mkdir -p "$share"
sock=$tmp/facescand.sock
W=1920 H=1080 # libcamera's default still-capture size for vimc; the daemon configures no size

# Both cameras, whatever a test before this one left unbound.
[ -e /sys/bus/platform/drivers/vimc/vimc.1 ] || echo vimc.1 >/sys/bus/platform/drivers/vimc/bind
[ -e /sys/bus/platform/drivers/vimc/vimc.0 ] || echo vimc.0 >/sys/bus/platform/drivers/vimc/bind

# The booth's GPIO chip: line 0 button (active low, pulled up = released), 1 LED, 2 MCU reset.
sim=/sys/kernel/config/gpio-sim/facescand
mkdir -p "$sim/bank0" || die "no gpio-sim in configfs"
echo 4 >"$sim/bank0/num_lines"
echo 1 >"$sim/live"
chip=$(cat "$sim/bank0/chip_name")
lines=/sys/devices/platform/$(cat "$sim/dev_name")/$chip
echo pull-up >"$lines/sim_gpio0/pull"
cleanup() {
	echo 0 >"$sim/live" 2>/dev/null
	rmdir "$sim/bank0" "$sim" 2>/dev/null
}
trap cleanup EXIT

# A nominal calibration of the two vimc cameras (vimc has no optics: any plausible one serves).
{
	echo '%YAML:1.0'
	echo '---'
	echo 'camera_count: 2'
	echo 'units: mm'
	echo 'id: "vimc x2, nominal"'
	for i in 0 1; do
		cat <<EOF
cam${i}_K: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 1600., 0., $((W / 2)).5, 0., 1600., $((H / 2)).5, 0., 0., 1. ]
cam${i}_dist: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ 0., 0., 0., 0., 0. ]
cam${i}_R: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 1., 0., 0., 0., 1., 0., 0., 0., 1. ]
cam${i}_T: !!opencv-matrix
   rows: 3
   cols: 1
   dt: d
   data: [ $((-120 * i)).0, 0., 0. ]
cam${i}_size: [ $W, $H ]
EOF
	done
} >"$tmp/calibration.yaml"

cat >"$tmp/facescand.conf" <<EOF
mode = booth
share_dir = $share
spool_dir = $tmp/spool
socket_path = $sock
serial_device = fake
button_source = gpio
gpio_chip = $chip
gpio_button_line = 0
gpio_led_line = 1
gpio_mcu_reset_line = 2
camera_backend = libcamera
camera_count = 2
# vimc free-runs (no external trigger): the two cameras' frames of one shot lie up to a frame apart
max_frame_skew_us = 1000000
capture_timeout_ms = 20000
recon_backend = pipeline
# The test binaries are AddressSanitizer builds: ASan reserves ~16 TB of address space for its
# shadow, so any RLIMIT_AS on the worker aborts it at start (ReserveShadowMemoryRange failed).
recon_memory_mb = 0
calibration_file = $tmp/calibration.yaml
EOF
mkdir -p "$tmp/spool"
"$FACESCAN_BIN/facescand" --config "$tmp/facescand.conf" --check || die "config refused"
start=$(date +%s)
"$FACESCAN_BIN/facescand" --config "$tmp/facescand.conf" >"$logs/facescand.log" 2>&1 &
pid=$!
until timeout 10 "$FACESCAN_BIN/facescan" status --socket "$sock" >"$tmp/status" 2>&1 && grep -q idle "$tmp/status"; do
	[ $(($(date +%s) - start)) -lt 45 ] || die "facescand not idle after 45 s: $(cat "$tmp/status")"
	kill -0 $pid 2>/dev/null || die "facescand exited"
	sleep 0.5
done
say "facescand idle after $(($(date +%s) - start)) s: $(tr '\n' ' ' <"$tmp/status")"

# Press with bounces (the debouncer must see one press), hold, release.
for p in pull-down pull-up pull-down pull-up pull-down; do echo $p >"$lines/sim_gpio0/pull"; done
sleep 0.3
echo pull-up >"$lines/sim_gpio0/pull"
pressed=$(date +%s)
while :; do
	timeout 10 "$FACESCAN_BIN/facescan" last --json --socket "$sock" >"$tmp/last" 2>&1
	grep -q '"state": *"\(failed\|delivered\|spooled\)"' "$tmp/last" && break
	# The worker is the ASan build of facescan, started and run under TCG: a minute or more.
	[ $(($(date +%s) - pressed)) -lt 240 ] || die "no finished scan 240 s after the press: $(cat "$tmp/last")"
	sleep 0.5
done
say "scan finished $(($(date +%s) - pressed)) s after the press"
say "last: $(cat "$tmp/last")"
grep -q '"state": *"failed"' "$tmp/last" || die "the scan did not fail (vimc frames hold no pattern)"
grep -q '"failed_stage": *"reconstructing"' "$tmp/last" || die "the scan failed before reconstruction"
grep -q 'no pattern found' "$tmp/last" || die "the error does not say 'no pattern found'"
grep -q '"patient_id": *"walk-in"' "$tmp/last" || die "the press did not start the booth's walk-in scan"
# One press, one scan: the bounces started nothing else.
[ "$(grep -c 'scan .*started\|starting scan' "$logs/facescand.log")" -le 1 ] || die "more than one scan started"
left=$(find "$share" -mindepth 1 | head -5)
[ -z "$left" ] || die "the clinic share is not empty after a failed scan: $left"
kill -TERM $pid
i=0
while kill -0 $pid 2>/dev/null; do
	i=$((i + 1))
	[ $i -lt 40 ] || { kill -KILL $pid; die "facescand still running 20 s after SIGTERM"; }
	sleep 0.5
done
wait $pid
rc=$?
[ $rc -eq 0 ] || die "facescand exited $rc on SIGTERM"
sed 's/^/  facescand: /' "$logs/facescand.log" | tail -15
say "PASS"
