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
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
t0=$SECONDS

export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
export MATURIN_PEP517_ARGS="${MATURIN_PEP517_ARGS:---profile dev}"

VENV="${FRACID_VENV:-$(mktemp -d)/venv}"
rm -rf "$VENV"
python3 -m venv "$VENV"
echo "== python: venv $VENV ($("$VENV/bin/python" --version))"
"$VENV/bin/pip" install --quiet --disable-pip-version-check numpy pytest
# The optional extras (fracid[scipy], fracid[control], fracid[dask]): their tests skip only when
# these cannot be installed.
"$VENV/bin/pip" install --quiet --disable-pip-version-check scipy control "dask[distributed]" \
    || echo "warning: scipy/control/dask could not be installed: their tests will skip"

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
"$VENV/bin/pytest" -q
echo "== python: done in $((SECONDS - t0)) s"
