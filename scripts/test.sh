#!/usr/bin/env bash
# The whole test suite: Rust unit, integration, doc and end-to-end tests, then the Python package
# built as a wheel, installed into a fresh virtual environment and tested with pytest.
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== firmware (C): unit tests and shared vectors, 8-bit and 16-bit octets, ASan/UBSan"
bash firmware/test.sh

echo "== cargo test (workspace)"
cargo test --no-fail-fast   # the default members: every crate but the pyo3 extension
# (the drive's end-to-end tests run there on both firmwares behind the pty: NAME::rust, NAME::c)

if [ -f python/pyproject.toml ] && [ -x python/ci.sh ]; then
    echo "== python: build the wheel, install it in a fresh venv, pytest"
    # The CLI the agreement tests compare with: the one `cargo test` built above (python/ci.sh
    # would otherwise build `-p fracid` alone, whose features differ: the whole stack again).
    # The wheel shares the target directory and profile, and its features match the test build's
    # (python/Cargo.toml, "feature unification"; check: python3 scripts/feature_drift.py).
    export FRACID_BIN="${FRACID_BIN:-${CARGO_TARGET_DIR:-$PWD/target}/debug/fracid}"
    bash python/ci.sh
fi
