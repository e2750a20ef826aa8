#!/usr/bin/env bash
# Whole process, fracid time against the strongest scipy peer (issue 18): the paper's PMSM on the
# paper's PRBS (10 +- 3 V, dt 0.5 ms, noise sigma 0.13), at 1e4, 1e5 and 1e6 samples by default.
# Usage: bash benches/compare/strong.sh [samples ...]
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
venv="${VENV:-$HOME/.cache/fracid-compare-venv}"
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c "import numpy, scipy" 2>/dev/null; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet numpy scipy
fi
cd "$root"
cargo build --quiet --release -p fracid -p fracid-benches --example gen_data
target="$(cargo metadata --format-version 1 --no-deps | "$venv/bin/python" -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')"
dir="$(mktemp -d)"
files=()
for n in "${@:-10000 100000 1000000}"; do
    for m in $n; do
        f="$dir/pmsm_prbs_$m.csv"
        "$target/release/examples/gen_data" "$f" "$m" 0.13 1 5e-4 3 10
        files+=("$f")
    done
done
# The files just written are flushed first: their writeback would otherwise run beside the first
# timed runs (fracid's), not the peer's.
sync
echo "machine: $(nproc) cores, $(lscpu 2>/dev/null | sed -n 's/^Model name: *//p' | head -1), load $(cut -d' ' -f1-3 /proc/loadavg)"
"$venv/bin/python" -c 'import numpy, scipy, sys; print(f"numpy {numpy.__version__}, scipy {scipy.__version__}, Python {sys.version.split()[0]}")'
"$venv/bin/python" "$here/strong_compare.py" "$target/release/fracid" "$venv/bin/python" "${files[@]}"
