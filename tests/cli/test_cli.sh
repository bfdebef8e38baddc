#!/bin/sh
# The CLI's contract: --help succeeds, an unknown verb or bad argument fails with exit 2 and a message.
set -u
bin=${FACESCAN_BIN:?}/facescan
fail=0
check() { # expected-exit description command...
	want=$1; what=$2; shift 2
	"$@" >/tmp/facescan-cli.$$ 2>&1; got=$?
	if [ "$got" -ne "$want" ]; then echo "FAIL: $what: exit $got, want $want"; cat /tmp/facescan-cli.$$; fail=1
	else echo "ok: $what"; fi
}
check 0 "facescan --help" "$bin" --help
check 2 "no verb" "$bin"
check 2 "unknown verb" "$bin" frobnicate
check 0 "version" "$bin" version
for verb in $("$bin" --help | awk '/^  [a-z]/ {print $1}'); do
	[ "$verb" = version ] && continue
	check 0 "$verb --help" "$bin" "$verb" --help
	check 2 "$verb with a bad option" "$bin" "$verb" --no-such-option
done
rm -f /tmp/facescan-cli.$$
exit $fail
