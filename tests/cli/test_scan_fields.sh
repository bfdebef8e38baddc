#!/bin/sh
# facescan scan's DICOM fields: each is checked before anything is sent (exit 2, a reason that
# does not repeat the value, no daemon contacted), and good ones pass the check.
set -u
bin=${FACESCAN_BIN:?}/facescan
sock=/tmp/facescan-scan-fields.$$.sock # nothing listens here
fail=0
refuse() { # description args...
	what=$1; shift
	out=$("$bin" scan --socket "$sock" --patient P-1 "$@" 2>&1); rc=$?
	if [ $rc -eq 2 ] && ! echo "$out" | grep -q "$sock"; then echo "ok: refused $what: $out"
	else echo "FAIL: $what: exit $rc: $out"; fail=1; fi
}
refuse "a name over 64 bytes" --name "$(printf 'x%.0s' $(seq 65))"
refuse "a name with '\\'" --name 'Doe\Jane'
refuse "a name with '='" --name 'Doe=Jane'
refuse "a name with a control character" --name "$(printf 'Doe\tJane')"
refuse "a name with 6 components" --name 'a^b^c^d^e^f'
refuse "a name that is not UTF-8" --name "$(printf 'M\374ller')"
refuse "an accession over 16 characters" --accession 12345678901234567
refuse "an accession with '\\'" --accession 'A\1'
refuse "an accession with non-ASCII" --accession 'Zürich'
refuse "a study UID with a letter" --study-uid 1.2.a
refuse "a study UID with a leading zero" --study-uid 1.02.3
refuse "a study UID with an empty component" --study-uid 1..2
refuse "a study UID over 64 characters" --study-uid "1.$(printf '2%.0s' $(seq 64))"
refuse "a study UID given empty" --study-uid ''
refuse "a bad patient id with good fields" --patient '../x' --name 'Doe^Jane'
# Good values get past the checks and fail only at the (absent) daemon: exit 1, not 2.
"$bin" scan --socket "$sock" --patient P-1 --name 'Müller^Anna' --accession A-2026/1 \
	--study-uid 1.2.826.0.1.3680043.2.1125.7 --no-wait >/dev/null 2>&1; rc=$?
[ $rc -eq 1 ] && echo "ok: good fields pass the checks (exit 1: no daemon)" || { echo "FAIL: good fields: exit $rc"; fail=1; }
exit $fail
