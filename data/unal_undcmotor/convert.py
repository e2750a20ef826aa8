"""Make this folder's two records from the UNDCMotor repository's ``unmotor/datafiles``.

Usage: ``python3 data/unal_undcmotor/convert.py SRC_DIR [OUT_DIR]`` with ``SRC_DIR`` the source's
``code/python_code/unmotor/datafiles`` folder.

- ``DCmotor_prbs_open_low.csv``: the source's ``DCmotor_prbs_open_exp.csv``, copied byte for byte
  (columns ``t,u,y`` already).
- ``DCmotor_profile_closed_exp.csv``: the source's file of that name (columns ``t,r,y,u``) with
  its columns renamed to ``t,u,y,v`` (``u`` = the reference r, ``y`` = the speed, ``v`` = the
  controller output u), so that fracid's defaults fit the closed loop from reference to speed.
  The lines after the header are copied unchanged (the script checks the values read back).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np


def convert(src_dir: Path, out_dir: Path) -> None:
    prbs = (src_dir / "DCmotor_prbs_open_exp.csv").read_bytes()
    if not prbs.startswith(b"t,u,y\n"):
        raise SystemExit("DCmotor_prbs_open_exp.csv: expected the header t,u,y")
    (out_dir / "DCmotor_prbs_open_low.csv").write_bytes(prbs)

    src = src_dir / "DCmotor_profile_closed_exp.csv"
    head, rest = src.read_text().split("\n", 1)
    if head != "t,r,y,u":
        raise SystemExit(f"{src}: expected the header t,r,y,u, found {head!r}")
    out = out_dir / "DCmotor_profile_closed_exp.csv"
    out.write_text("t,u,y,v\n" + rest)
    a = np.genfromtxt(src, delimiter=",", names=True)
    b = np.genfromtxt(out, delimiter=",", names=True)
    for old, new in (("t", "t"), ("r", "u"), ("y", "y"), ("u", "v")):
        if not np.array_equal(a[old], b[new]):
            raise SystemExit(f"{out}: column {new} differs from the source's {old}")


if __name__ == "__main__":
    if len(sys.argv) not in (2, 3):
        raise SystemExit(__doc__)
    here = Path(__file__).resolve().parent
    convert(Path(sys.argv[1]), Path(sys.argv[2]) if len(sys.argv) == 3 else here)
