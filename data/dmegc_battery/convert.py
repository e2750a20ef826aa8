"""Make this folder's two records from ``Exp25_R1.mat`` of the DMEGC 18650 electro-thermal dataset.

Usage: ``python3 data/dmegc_battery/convert.py PATH/TO/Exp25_R1.mat [OUT_DIR]``

The source file holds MATLAB structs with fields ``t`` [s], ``I`` [A], ``V`` [V], ``T`` [degC]
and ``Q``. Two of them are written as ``t,u,y,temp_c`` text (``u`` the current ``I``, positive
when discharging, ``y`` the terminal voltage ``V``, ``temp_c`` the surface temperature ``T``):

- ``random_current_cycle26.csv``: ``rw_data(26)`` (MATLAB's 1-based index; Python's ``[25]``),
  the random-current discharge cycle with the most samples (447). Its last sample is logged 7 s
  after the one before it (the discharge stops at the 2.5 V cut-off between two 10 s ticks), not
  on the 10 s grid: it is dropped. Nothing else changes.
- ``pulse_discharge.csv``: ``pulse_data``, the whole pulse test (1981 samples on a 10 s grid),
  unchanged.

Values are printed with ``repr`` (the text reads back to the same doubles; the script checks).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.io import loadmat

DT = 10.0


def columns(rec):
    return [np.asarray(getattr(rec, k), float).ravel() for k in ("t", "I", "V", "T")]


def write(out: Path, cols) -> None:
    t, i, v, temp = cols
    if not (len(t) == len(i) == len(v) == len(temp)) or not np.all(
        np.isfinite(np.c_[t, i, v, temp])
    ):
        raise SystemExit(f"{out}: columns of unequal length or not finite")
    if not np.allclose(np.diff(t), DT, rtol=0, atol=1e-9):
        raise SystemExit(f"{out}: not on the {DT} s grid")
    lines = ["t,u,y,temp_c"] + [
        f"{a!r},{b!r},{c!r},{d!r}"
        for a, b, c, d in zip(t.tolist(), i.tolist(), v.tolist(), temp.tolist())
    ]
    out.write_text("\n".join(lines) + "\n")
    back = np.genfromtxt(out, delimiter=",", names=True)
    for name, col in zip(("t", "u", "y", "temp_c"), cols):
        if not np.array_equal(back[name], col):
            raise SystemExit(f"{out}: column {name} does not read back to the source values")


def convert(src: Path, out_dir: Path) -> None:
    d = loadmat(src, squeeze_me=True, struct_as_record=False)
    cols = columns(d["rw_data"][25])
    if len(cols[0]) != 447 or abs(cols[0][-1] - cols[0][-2] - DT) < 1e-9:
        raise SystemExit(f"{src}: rw_data(26) is not the expected 447 samples ending off the grid")
    write(out_dir / "random_current_cycle26.csv", [c[:-1] for c in cols])
    write(out_dir / "pulse_discharge.csv", columns(d["pulse_data"]))


if __name__ == "__main__":
    if len(sys.argv) not in (2, 3):
        raise SystemExit(__doc__)
    here = Path(__file__).resolve().parent
    convert(Path(sys.argv[1]), Path(sys.argv[2]) if len(sys.argv) == 3 else here)
