"""The suite runs against the installed wheel, not the source tree."""

from __future__ import annotations

from pathlib import Path

import fracid


def test_imported_from_the_installed_package():
    pkg = Path(fracid.__file__).resolve().parent
    src = (Path(__file__).resolve().parent.parent / "fracid").resolve()
    assert pkg != src, f"fracid imported from the source tree {src}; install the wheel"
    assert (pkg / "py.typed").is_file()
    assert any(pkg.glob("_fracid*.so")) or any(pkg.glob("_fracid*.pyd"))
    assert (pkg / "_fracid.pyi").is_file()
