#!/bin/sh
# facescand to the PACS: a scan requested with patient, name, accession and study UID lands in a
# real Orthanc as Encapsulated STL with those fields, its metadata on the share says so, and the
# .dcm/.stl/.obj copies are on the share with the manifest's sizes and sha256. With Orthanc
# stopped the next scan is delivered to the share and its instance waits in the DICOM spool
# (metadata: "spooled"); Orthanc back, the daemon's retry sends it once and rewrites the metadata.
set -u
bin=${FACESCAN_BIN:?}
tmp=$(mktemp -d /tmp/facescan-dpacs.XXXXXX)
. "$(dirname "$0")/../../tools/orthanc.sh"
DPID=""
trap 'orthanc_stop; [ -n "$DPID" ] && kill "$DPID" 2>/dev/null && wait "$DPID" 2>/dev/null; rm -rf "$tmp"' EXIT
fail=0
ok() { echo "ok: $*"; }
bad() { echo "FAIL: $*"; fail=1; }
orthanc_setup "$tmp"
orthanc_start
mkdir -p "$tmp/share"
cat >"$tmp/facescand.conf" <<CONF
share_dir = $tmp/share
spool_dir = $tmp/spool
socket_path = $tmp/sock
serial_device = fake
camera_backend = fake
recon_backend = fake
min_free_mb = 0
spool_retry_ms = 300
output_stl = true
output_obj = true
output_dicom = true
pacs_called_ae = $ORTHANC_AE
pacs_host = 127.0.0.1
pacs_port = $ORTHANC_DIMSE
pacs_timeout_s = 2
CONF
"$bin/facescand" --config "$tmp/facescand.conf" 2>>"$tmp/daemon.log" &
DPID=$!
export FACESCAN_SOCKET=$tmp/sock
for _ in $(seq 100); do "$bin/facescan" status >/dev/null 2>&1 && break; sleep 0.1; done

meta_of() { ls "$tmp/share/$1"/*.json 2>/dev/null | head -1; }
jq_py() { python3 -c 'import sys,json; d=json.load(open(sys.argv[1])); print(eval(sys.argv[2]))' "$@"; }

"$bin/facescan" scan --patient PACS-1 --name 'Doe^Jane' --accession ACC-9 --study-uid 1.2.826.0.1.3680043.2.1125.99 \
	>"$tmp/log" 2>&1 || { bad "scan PACS-1"; cat "$tmp/log"; tail "$tmp/daemon.log"; }
meta=$(meta_of PACS-1)
[ -n "$meta" ] && ok "PACS-1 delivered: $(ls "$tmp/share/PACS-1" | sed 's/^[^.]*_[0-9a-f]*//' | tr '\n' ' ')" || bad "no metadata for PACS-1"
state=$(jq_py "$meta" 'd["dicom"]["pacs"]["state"]')
[ "$state" = sent ] && ok "metadata: PACS copy sent" || bad "metadata pacs state '$state'"
uid=$(jq_py "$meta" 'd["dicom"]["sop_instance_uid"]')
found=$(python3 -c 'import json,sys,urllib.request
q=json.dumps({"Level":"Instance","Expand":True,"Query":{"SOPInstanceUID":sys.argv[2]}}).encode()
r=json.load(urllib.request.urlopen("http://127.0.0.1:"+sys.argv[1]+"/tools/find", q, timeout=10))
t=r[0]["MainDicomTags"] if r else {}
print(len(r))' "$ORTHANC_HTTP" "$uid")
[ "$found" = 1 ] && ok "Orthanc holds the scan's instance" || bad "Orthanc holds $found instances of $uid"
id=$(orthanc_rest /instances | python3 -c 'import sys,json; print(json.load(sys.stdin)[0])')
orthanc_rest "/instances/$id/simplified-tags" >"$tmp/tags.json"
for check in "SOPClassUID=1.2.840.10008.5.1.4.1.1.104.3" "PatientID=PACS-1" "PatientName=Doe^Jane" \
	"AccessionNumber=ACC-9" "StudyInstanceUID=1.2.826.0.1.3680043.2.1125.99"; do
	key=${check%%=*} want=${check#*=}
	got=$(jq_py "$tmp/tags.json" "d.get('$key')")
	[ "$got" = "$want" ] && ok "PACS: $key = $got" || bad "PACS: $key = '$got', want '$want'"
done
python3 - "$meta" <<'PY' || fail=1
import hashlib, json, os, sys
meta = json.load(open(sys.argv[1]))
d = os.path.dirname(sys.argv[1])
names = sorted(m["file"] for m in meta["manifest"])
files = sorted(f for f in os.listdir(d) if not f.endswith(".json"))
ok = names == files
for m in meta["manifest"]:
    body = open(os.path.join(d, m["file"]), "rb").read()
    ok = ok and len(body) == m["bytes"] and hashlib.sha256(body).hexdigest() == m["sha256"]
print(("ok: " if ok else "FAIL: ") + "the manifest lists every file with its size and sha256: " +
      ", ".join("%s %d B" % (m["role"], m["bytes"]) for m in meta["manifest"]))
sys.exit(0 if ok else 1)
PY
obj=$(ls "$tmp/share/PACS-1"/*.obj); mtl=$(basename "${obj%.obj}.mtl")
grep -q "^mtllib $mtl" "$obj" && ok "the .obj names its material file $mtl" || bad ".obj: $(head -5 "$obj")"

# A bad field over the socket is refused by the daemon too.
python3 - "$tmp/sock" <<'PY' && ok "the daemon refuses a bad accession over the socket" || bad "bad accession accepted"
import json, socket, sys
s = socket.socket(socket.AF_UNIX); s.connect(sys.argv[1])
s.sendall(b'{"cmd":"scan","patient":"X-1","accession":"A\\\\B"}\n')
r = json.loads(s.makefile().readline())
sys.exit(0 if not r.get("ok") and "accession" in r.get("message", "") else 1)
PY

# PACS down: the scan is delivered, its instance waits; back up: sent once, metadata rewritten.
orthanc_stop
"$bin/facescan" scan --patient PACS-2 >"$tmp/log" 2>&1 || { bad "scan PACS-2"; cat "$tmp/log"; }
meta=$(meta_of PACS-2)
state=$(jq_py "$meta" 'd["dicom"]["pacs"]["state"]')
[ "$state" = spooled ] && ok "PACS down: scan delivered, metadata says the instance waits in $(jq_py "$meta" 'd["dicom"]["pacs"]["spool"]' | sed "s|$tmp/||")" ||
	bad "PACS down: state '$state'"
uid2=$(jq_py "$meta" 'd["dicom"]["sop_instance_uid"]')
orthanc_start
for _ in $(seq 100); do
	[ "$(jq_py "$meta" 'd["dicom"]["pacs"]["state"]')" = sent ] && break
	sleep 0.1
done
[ "$(jq_py "$meta" 'd["dicom"]["pacs"]["state"]')" = sent ] && ok "PACS back: metadata rewritten to sent" || bad "metadata not updated"
sleep 1 # another retry round must not send it again
n=$(orthanc_count)
[ "$n" = 2 ] && [ -z "$(ls "$tmp/spool/dicom" | grep '\.dcm$')" ] && [ "$(grep -c "$uid2" "$tmp/spool/dicom/sent.log")" = 1 ] &&
	ok "delivered once: Orthanc holds $n instances, the DICOM spool is empty" || bad "Orthanc holds $n"
grep -q -e PACS-1 -e Doe -e ACC-9 "$tmp/daemon.log" && bad "patient data in the daemon's log" || ok "no patient data in the daemon's log"
exit $fail
