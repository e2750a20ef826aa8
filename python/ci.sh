#!/usr/bin/env bash
# CI for the Python package: build the wheel (maturin through PEP 517, `pip install ./python`),
# install it into a fresh virtual environment, and run the pytest suite against the installed
# package (from python/tests, so the source tree is never importable). Exits non-zero on failure.
#
# Network: PyPI only (numpy, pytest, maturin for the isolated build environment, and the optional
# extras the export and fleet tests use: scipy, control, dask[distributed]); crates come from the
# cargo registry/cache as for the rest of the workspace.
#
# Environment:
#   CARGO_TARGET_DIR      shared with the workspace build (default: <repo>/target), so the
#                         library crates are not compiled twice
#   MATURIN_PEP517_ARGS   default "--profile dev": the workspace's dev profile (opt-level 2, our
#                         dependencies at 3), the artefacts `cargo test` already built
#   FRACID_BIN            the CLI the agreement tests run (default: built here, target/debug/fracid)
#   FRACID_VENV           where to make the venv (default: a fresh temporary directory)
#   FRACID_VENV_READY     1: FRACID_VENV was already made by `python/ci.sh --venv-only DIR` (as
#                         scripts/test.sh does while the Rust side builds): use it as it is
#
# `python/ci.sh --venv-only DIR` makes the venv with the PyPI packages and stops (no wheel, no test).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
t0=$SECONDS

export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
export MATURIN_PEP517_ARGS="${MATURIN_PEP517_ARGS:---profile dev}"

# A fresh venv with the test dependencies from PyPI.
make_venv() {
    rm -rf "$1"
    python3 -m venv "$1"
    echo "== python: venv $1 ($("$1/bin/python" --version))"
    # pytest-xdist: the tests run on every core (each module on one worker: `--dist loadscope`
    # keeps a module's fixtures, such as the drive simulator, to one process).
    "$1/bin/pip" install --quiet --disable-pip-version-check numpy pytest pytest-xdist
    # The optional extras (fracid[scipy], fracid[control], fracid[dask]): their tests skip only
    # when these cannot be installed.
    "$1/bin/pip" install --quiet --disable-pip-version-check scipy control "dask[distributed]" \
        || echo "warning: scipy/control/dask could not be installed: their tests will skip"
}

if [ "${1:-}" = "--venv-only" ]; then
    make_venv "${2:?usage: python/ci.sh --venv-only DIR}"
    echo "   venv ready in $((SECONDS - t0)) s"
    exit 0
fi

VENV="${FRACID_VENV:-$(mktemp -d)/venv}"
if [ "${FRACID_VENV_READY:-}" = 1 ]; then
    echo "== python: venv $VENV (made while the Rust side built)"
else
    make_venv "$VENV"
fi

echo "== python: pip install ./python (maturin wheel, $MATURIN_PEP517_ARGS)"
"$VENV/bin/pip" install --disable-pip-version-check ./python
echo "   built and installed in $((SECONDS - t0)) s"

if [ -z "${FRACID_BIN:-}" ]; then
    echo "== python: cargo build -p fracid (the CLI the agreement tests compare with)"
    cargo build --quiet -p fracid
    export FRACID_BIN="$CARGO_TARGET_DIR/debug/fracid"
fi

echo "== python: pytest (installed package)"
cd python/tests
"$VENV/bin/python" -c 'import fracid, sys; print("fracid", fracid.__version__, "from", fracid.__file__)'
# The slowest tests named at the end (what to look at when CI nears its budget). On the 2-core CI
# machine the modules on two workers took 70 s where one process took 97 s.
"$VENV/bin/pytest" -q --durations=8 -n auto --dist loadscope
echo "== python: done in $((SECONDS - t0)) s"
