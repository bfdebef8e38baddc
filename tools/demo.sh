#!/bin/sh
# make demo: runs the chain that exists on the simulated booth and says what it did.
set -eu
bin=${1:-build/bin}
out=out
mkdir -p "$out"
echo "facescan demo: $("$bin"/facescan version)"
