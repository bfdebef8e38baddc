# Sourced by the DICOM tests and tools/demo.sh: a real Orthanc (Debian's `orthanc`) on loopback ports the kernel
# picks, with its own temporary configuration and storage under $1 (the test's temp dir).
#   orthanc_setup DIR   config + free ports (sets ORTHANC_HTTP, ORTHANC_DIMSE, ORTHANC_AE)
#   orthanc_start       starts it and waits until its REST API answers (exit 1 if it does not)
#   orthanc_stop        stops the one we started (TERM, then KILL after 10 s)
#   orthanc_rest PATH   GET on its REST API, body to stdout
#   orthanc_count       how many instances it holds
# A test without Orthanc installed skips: orthanc_setup exits 77 with the reason.
ORTHANC_PID=""
orthanc_setup() {
	ORTHANC_BIN=$(command -v Orthanc || echo /usr/sbin/Orthanc)
	[ -x "$ORTHANC_BIN" ] || { echo "SKIP: Orthanc is not installed (Debian package 'orthanc', tools/install-deps.sh)"; exit 77; }
	ORTHANC_DIR=$1
	set -- $(python3 -c 'import socket
s=[socket.socket() for _ in range(2)]
[x.bind(("127.0.0.1",0)) for x in s]
print(*[x.getsockname()[1] for x in s])')
	ORTHANC_HTTP=$1 ORTHANC_DIMSE=$2 ORTHANC_AE=TESTPACS
	mkdir -p "$ORTHANC_DIR/db"
	cat >"$ORTHANC_DIR/orthanc.json" <<JSON
{ "Name": "facescan-test", "StorageDirectory": "$ORTHANC_DIR/db", "IndexDirectory": "$ORTHANC_DIR/db",
  "HttpPort": $ORTHANC_HTTP, "DicomPort": $ORTHANC_DIMSE, "DicomAet": "$ORTHANC_AE", "DicomCheckCalledAet": true,
  "RemoteAccessAllowed": false, "AuthenticationEnabled": false, "HttpServerEnabled": true,
  "Plugins": [], "DicomModalities": {}, "ConcurrentJobs": 1 }
JSON
}
orthanc_rest() { python3 -c 'import sys,urllib.request
sys.stdout.buffer.write(urllib.request.urlopen("http://127.0.0.1:'"$ORTHANC_HTTP"'"+sys.argv[1], timeout=10).read())' "$1"; }
orthanc_count() { orthanc_rest /instances | python3 -c 'import sys,json; print(len(json.load(sys.stdin)))'; }
orthanc_start() {
	"$ORTHANC_BIN" "$ORTHANC_DIR/orthanc.json" >>"$ORTHANC_DIR/orthanc.log" 2>&1 &
	ORTHANC_PID=$!
	_i=0
	until orthanc_rest /system >/dev/null 2>&1; do
		_i=$((_i + 1))
		if [ $_i -gt 300 ] || ! kill -0 "$ORTHANC_PID" 2>/dev/null; then
			echo "FAIL: Orthanc did not come up"; tail -20 "$ORTHANC_DIR/orthanc.log"; exit 1
		fi
		sleep 0.1
	done
}
orthanc_stop() {
	[ -n "$ORTHANC_PID" ] || return 0
	kill "$ORTHANC_PID" 2>/dev/null
	_i=0; while kill -0 "$ORTHANC_PID" 2>/dev/null && [ $_i -lt 100 ]; do sleep 0.1; _i=$((_i + 1)); done
	kill -9 "$ORTHANC_PID" 2>/dev/null
	wait "$ORTHANC_PID" 2>/dev/null
	ORTHANC_PID=""
}
