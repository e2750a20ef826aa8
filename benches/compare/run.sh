#!/usr/bin/env bash
# Side-by-side: the PMSM output-error fit with numpy/scipy and with fracid, on the same data.
# Usage: bash benches/compare/run.sh [samples (default 10000)] [noise sigma (default 0.05)]
# Creates a venv with numpy and scipy (VENV, default ~/.cache/fracid-compare-venv), builds the
# fracid side in release mode, writes the data with fracid's PRBS and seeded noise, and compares.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
samples="${1:-10000}"
sigma="${2:-0.05}"
venv="${VENV:-$HOME/.cache/fracid-compare-venv}"
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c "import numpy, scipy" 2>/dev/null; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet numpy scipy
fi
cd "$root"
cargo build --quiet --release -p fracid-benches --example gen_data --example fit_csv
target="$(cargo metadata --format-version 1 --no-deps | "$venv/bin/python" -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')"
data="$(mktemp -d)/pmsm_prbs_${samples}.csv"
"$target/release/examples/gen_data" "$data" "$samples" "$sigma" 1
echo "machine: $(nproc) cores, $(lscpu 2>/dev/null | sed -n 's/^Model name: *//p' | head -1)"
"$venv/bin/python" "$here/compare.py" "$data" "$target/release/examples/fit_csv"
