#!/usr/bin/env bash
# The whole test suite: Rust unit, integration, doc and end-to-end tests, then the Python package
# built as a wheel, installed into a fresh virtual environment and tested with pytest.
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== firmware (C): unit tests and shared vectors, 8-bit and 16-bit octets, ASan/UBSan"
bash firmware/test.sh

echo "== cargo test (workspace)"
cargo test --no-fail-fast   # the default members: every crate but the pyo3 extension

echo "== drive end-to-end tests again, against the C firmware (firmware/) behind the pty"
FRACID_SIM_FIRMWARE=c cargo test -p drive --test integration e2e

if [ -f python/pyproject.toml ] && [ -x python/ci.sh ]; then
    echo "== python: build the wheel, install it in a fresh venv, pytest"
    bash python/ci.sh
fi
