"""Make ``robot_arm.csv`` from the SLICOT System Identification Toolbox's ``robot_arm_dat.mat``.

Usage: ``python3 data/slicot_robot_arm/convert.py PATH/TO/robot_arm_dat.mat [OUT.csv]``

The source file (one variable ``robot_arm_dat``, 1024 x 2: column 1 the input u, column 2 the
output y, as the toolbox's own demo reads it) is written unchanged as ``t,u,y``: ``t`` is the
sample index (the source states no sampling period), ``u`` and ``y`` the source's double values
printed with ``repr`` (17 significant digits: the round trip through the text is exact). Nothing
is filtered, cut, decimated or rescaled. The script checks the shape and that the text reads back
to the same bits.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.io import loadmat


def convert(src: Path, out: Path) -> None:
    data = loadmat(src)["robot_arm_dat"]
    if data.shape != (1024, 2) or not np.all(np.isfinite(data)):
        raise SystemExit(f"{src}: expected 1024 x 2 finite values, found {data.shape}")
    lines = ["t,u,y"]
    lines += [f"{k},{u!r},{y!r}" for k, (u, y) in enumerate(data.tolist())]
    out.write_text("\n".join(lines) + "\n")
    back = np.genfromtxt(out, delimiter=",", names=True)
    if not (np.array_equal(back["u"], data[:, 0]) and np.array_equal(back["y"], data[:, 1])):
        raise SystemExit(f"{out}: the text does not read back to the source values")


if __name__ == "__main__":
    if len(sys.argv) not in (2, 3):
        raise SystemExit(__doc__)
    here = Path(__file__).resolve().parent
    convert(Path(sys.argv[1]), Path(sys.argv[2]) if len(sys.argv) == 3 else here / "robot_arm.csv")
