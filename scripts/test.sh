#!/usr/bin/env bash
# The whole test suite: Rust unit, integration, doc and end-to-end tests, then the Python package
# built as a wheel, installed into a fresh virtual environment and tested with pytest.
#
# What waits on the network or runs on one core goes on beside the Rust build: the Python venv's
# PyPI packages are installed and the C firmware's tests run while `cargo test` compiles; their
# output is printed (and their exit status checked) when the build's own is done.
set -euo pipefail
cd "$(dirname "$0")/.."
logs=$(mktemp -d)
# A failure stops the script: what still runs beside it stops too.
trap 'kill $(jobs -p) 2>/dev/null || true' EXIT

python_side=0
if [ -f python/pyproject.toml ] && [ -x python/ci.sh ]; then
    python_side=1
    export FRACID_VENV="${FRACID_VENV:-$logs/venv}"
    bash python/ci.sh --venv-only "$FRACID_VENV" >"$logs/venv.log" 2>&1 &
    venv_pid=$!
fi

bash firmware/test.sh >"$logs/firmware.log" 2>&1 &
firmware_pid=$!

echo "== cargo test (workspace)"
# The default members: every crate but the pyo3 extension (the drive's end-to-end tests run there
# on both firmwares behind the pty: NAME::rust, NAME::c). Every test target (unit tests of each lib
# and bin, integration tests), then the doc tests; the examples, which no test runs, are not
# linked here (`cargo clippy --all-targets` compiles and lints them; they took 26 s of CPU here).
# cargo-nextest, when the machine has it, runs every binary's tests in one pool of processes (one
# per test): `cargo test` runs the binaries one after the other, and a binary whose slowest test
# outlasts the rest of its tests leaves a core idle until it ends. Doc tests are cargo's alone.
rc=0
if cargo nextest --version >/dev/null 2>&1; then
    cargo nextest run --no-fail-fast --tests || rc=$?
else
    cargo test --no-fail-fast --tests || rc=$?
fi
cargo test --no-fail-fast --doc || rc=$?

echo "== firmware (C): unit tests and shared vectors, 8-bit and 16-bit octets, ASan/UBSan"
fw_rc=0
wait "$firmware_pid" || fw_rc=$?
cat "$logs/firmware.log"
if [ "$fw_rc" != 0 ]; then
    echo "firmware tests failed (exit $fw_rc)" >&2
    rc=1
fi
[ "$rc" = 0 ] || exit "$rc"

if [ "$python_side" = 1 ]; then
    echo "== python: build the wheel, install it in a fresh venv, pytest"
    venv_rc=0
    wait "$venv_pid" || venv_rc=$?
    cat "$logs/venv.log"
    [ "$venv_rc" = 0 ] || { echo "the venv could not be made (exit $venv_rc)" >&2; exit 1; }
    # The CLI the agreement tests compare with: the one `cargo test` built above (python/ci.sh
    # would otherwise build `-p fracid` alone, whose features differ: the whole stack again).
    # The wheel shares the target directory and profile, and its features match the test build's
    # (python/Cargo.toml, "feature unification"; check: python3 scripts/feature_drift.py).
    export FRACID_BIN="${FRACID_BIN:-${CARGO_TARGET_DIR:-$PWD/target}/debug/fracid}"
    FRACID_VENV_READY=1 bash python/ci.sh
fi
