"""Shared fixtures. The tests import the *installed* ``fracid`` (run with ``--import-mode=importlib``
from python/tests, see pyproject.toml); the source tree is never on ``sys.path``."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent  # python/tests -> repo root
DATA = REPO / "data"  # the example data shipped with the repository


def repo_data(name: str) -> Path:
    """A file of the repository's example data (``data/``); missing is a failure, never a skip."""
    p = DATA / name
    if not p.is_file():
        pytest.fail(f"{p} is missing: the example data ships with the repository in data/")
    return p


@pytest.fixture(scope="session")
def table1() -> Path:
    """The paper's Table 1 Bode data (freq_hz, gain_db, phase_deg)."""
    return repo_data("paper_table1_bode.csv")


@pytest.fixture(scope="session")
def fracid_bin() -> Path:
    """The Rust CLI. With $FRACID_BIN set (as CI does) it must exist; otherwise
    target/release/fracid or target/debug/fracid, else `fracid` on PATH; missing is a failure
    (python/ci.sh builds it), never a skip."""
    env = os.environ.get("FRACID_BIN")
    if env:
        p = Path(env)
        if not (p.is_file() and os.access(p, os.X_OK)):
            pytest.fail(f"FRACID_BIN={env} is not an executable file")
        return p
    for cand in (REPO / "target" / "release" / "fracid", REPO / "target" / "debug" / "fracid"):
        if cand.is_file() and os.access(cand, os.X_OK):
            return cand
    which = shutil.which("fracid")
    if which:
        return Path(which)
    pytest.fail("the fracid CLI is not built (cargo build -p fracid, or set FRACID_BIN)")


def pytest_report_header(config):
    import fracid

    return f"fracid {fracid.__version__} from {Path(fracid.__file__).parent}"
