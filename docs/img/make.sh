#!/usr/bin/env bash
# The README's pictures: `fracid demo` (the drive simulator in virtual time, a PRBS record, a sine
# sweep, both fits, the diagnosis, the tuned loop on the drive).
# Run from the repository root: bash docs/img/make.sh
set -euo pipefail
out=$(mktemp -d)
cargo run --release -q -p fracid -- demo --out "$out/demo"
for f in time time_diagnosis bode compare loop; do
    cp "$out/demo/$f.png" "docs/img/$f.png"
done
rm -rf "$out"
