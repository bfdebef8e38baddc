#!/bin/sh
# DICOM to a real PACS: Orthanc (Debian's `orthanc`) started here on localhost with its own
# temporary configuration. A scan mesh goes out as Encapsulated STL by C-STORE; Orthanc must
# hold it with the right SOP class and patient, and the STL fetched back over its REST API must
# equal the one written. Then Orthanc is stopped while a second instance is sent (it waits in the
# DICOM spool, exit 3), started again, and the next send delivers it exactly once.
set -u
bin=${FACESCAN_BIN:?}/facescan
tmp=$(mktemp -d /tmp/facescan-orthanc.XXXXXX)
. "$(dirname "$0")/../../tools/orthanc.sh"
trap 'orthanc_stop; rm -rf "$tmp"' EXIT
fail=0
orthanc_setup "$tmp"
http=$ORTHANC_HTTP dimse=$ORTHANC_DIMSE
rest() { orthanc_rest "$1"; }
json_get() { python3 -c 'import sys,json; d=json.load(sys.stdin); print(eval(sys.argv[1]))' "$1"; }
start_orthanc() { orthanc_start; }
stop_orthanc() { orthanc_stop; }

t0=$(date +%s.%N)
start_orthanc
echo "ok: Orthanc up on 127.0.0.1:$dimse (REST $http) in $(python3 -c "print(round($(date +%s.%N)-$t0,2))") s"

# A mesh: a 20x20 bumpy sheet (ASCII PLY).
awk 'BEGIN { n=20; print "ply\nformat ascii 1.0\nelement vertex " n*n "\nproperty float x\nproperty float y\nproperty float z";
	print "element face " 2*(n-1)*(n-1) "\nproperty list uchar int vertex_indices\nend_header";
	for (j=0;j<n;j++) for (i=0;i<n;i++) print i*3, j*3, 500+4*sin(i*.4)*cos(j*.3);
	for (j=0;j<n-1;j++) for (i=0;i<n-1;i++) { a=j*n+i; print 3, a, a+1, a+n+1; print 3, a, a+n+1, a+n } }' >"$tmp/face.ply"
pacs="TESTPACS@127.0.0.1:$dimse"

"$bin" dicom export "$tmp/face.ply" "$tmp/a.dcm" --patient P-0042 --name "Doe^Jane" --accession A123 \
	--study-uid 1.2.826.0.1.3680043.2.1125.42 >"$tmp/log" 2>&1 || { echo "FAIL: export"; cat "$tmp/log"; exit 1; }
uid_a=$("$bin" dicom show "$tmp/a.dcm" | awk '$1=="sop_instance_uid" {print $2}')
"$bin" dicom send --pacs "$pacs" --spool "$tmp/spool" "$tmp/a.dcm" >"$tmp/log" 2>&1; rc=$?
[ $rc -eq 0 ] && echo "ok: C-STORE: $(cat "$tmp/log")" || { echo "FAIL: send exit $rc"; cat "$tmp/log"; fail=1; }
ids=$(rest /instances)
n=$(echo "$ids" | json_get 'len(d)')
[ "$n" = 1 ] && echo "ok: Orthanc holds 1 instance" || { echo "FAIL: Orthanc holds $n instances"; fail=1; }
id=$(echo "$ids" | json_get 'd[0]')
tags=$(rest "/instances/$id/simplified-tags")
for check in "SOPClassUID=1.2.840.10008.5.1.4.1.1.104.3" "PatientID=P-0042" "PatientName=Doe^Jane" \
	"AccessionNumber=A123" "StudyInstanceUID=1.2.826.0.1.3680043.2.1125.42" "SOPInstanceUID=$uid_a" \
	"Modality=M3D" "MIMETypeOfEncapsulatedDocument=model/stl"; do
	key=${check%%=*} want=${check#*=}
	got=$(echo "$tags" | json_get "d.get('$key')")
	[ "$got" = "$want" ] && echo "ok: $key = $got" || { echo "FAIL: $key = '$got', want '$want'"; fail=1; }
done
rest "/instances/$id/file" >"$tmp/back.dcm"
"$bin" dicom show "$tmp/back.dcm" --document "$tmp/back.stl" >/dev/null &&
	"$bin" dicom show "$tmp/a.dcm" --document "$tmp/a.stl" >/dev/null &&
	cmp -s "$tmp/a.stl" "$tmp/back.stl" &&
	"$bin" convert "$tmp/back.stl" "$tmp/back.ply" >"$tmp/log" 2>&1 && grep -q "400 vertices, 722 triangles" "$tmp/log" &&
	echo "ok: the STL fetched back from Orthanc equals the one written ($(wc -c <"$tmp/a.stl") bytes; $(sed 's/.*: //' "$tmp/log"))" ||
	{ echo "FAIL: STL fetched back differs"; cat "$tmp/log"; fail=1; }

# PACS down: the instance waits in the spool, in order; back up: delivered once.
stop_orthanc
"$bin" dicom export "$tmp/face.ply" "$tmp/b.dcm" --patient P-0042 >/dev/null 2>&1
uid_b=$("$bin" dicom show "$tmp/b.dcm" | awk '$1=="sop_instance_uid" {print $2}')
"$bin" dicom send --pacs "$pacs" --spool "$tmp/spool" --timeout 2 "$tmp/b.dcm" >"$tmp/log" 2>&1; rc=$?
waiting=$(ls "$tmp/spool" | grep -c '\.dcm$')
[ $rc -eq 3 ] && [ "$waiting" = 1 ] && echo "ok: PACS down: exit 3, 1 instance spooled ($(tail -1 "$tmp/log"))" ||
	{ echo "FAIL: PACS down: exit $rc, $waiting spooled"; cat "$tmp/log"; fail=1; }
"$bin" dicom send --pacs "$pacs" --spool "$tmp/spool" --timeout 2 >/dev/null 2>&1; rc=$?
[ $rc -eq 3 ] && echo "ok: still down: exit 3, still spooled" || { echo "FAIL: still down: exit $rc"; fail=1; }
start_orthanc
"$bin" dicom send --pacs "$pacs" --spool "$tmp/spool" >"$tmp/log" 2>&1; rc=$?
"$bin" dicom send --pacs "$pacs" --spool "$tmp/spool" >>"$tmp/log" 2>&1 || rc=1
n=$(rest /instances | json_get 'len(d)')
sent_b=$(grep -c "sent $uid_b" "$tmp/log")
found=$(python3 -c 'import json,sys,urllib.request
q=json.dumps({"Level":"Instance","Query":{"SOPInstanceUID":sys.argv[2]}}).encode()
print(len(json.load(urllib.request.urlopen("http://127.0.0.1:"+sys.argv[1]+"/tools/find", q, timeout=10))))' "$http" "$uid_b")
if [ $rc -eq 0 ] && [ "$n" = 2 ] && [ "$sent_b" = 1 ] && [ "$found" = 1 ] && [ -z "$(ls "$tmp/spool" | grep '\.dcm$')" ] &&
	[ "$(grep -c . "$tmp/spool/sent.log")" = 2 ]; then
	echo "ok: PACS back: the spooled instance delivered once (Orthanc holds $n, spool empty)"
else
	echo "FAIL: after restart: exit $rc, Orthanc holds $n, sent $sent_b times, found $found"; cat "$tmp/log"; fail=1
fi
exit $fail
