"""Make ``cd_player_arm.csv`` from the SLICOT System Identification Toolbox's ``CD_player_arm_dat.mat``.

Usage: ``python3 data/slicot_cd_player_arm/convert.py PATH/TO/CD_player_arm_dat.mat [OUT.csv]``

The source file (one variable ``CD_player_arm_dat``, 2048 x 4: columns 1-2 the inputs u1, u2,
columns 3-4 the outputs y1, y2, as the toolbox's ``cmp_ident.m`` reads them) is written unchanged
as ``t,u,y,u2,y2``: ``u`` = u1, ``y`` = y1 (the pair fracid fits by default), ``u2`` and ``y2``
the other input and output, kept beside them. ``t`` is the sample index (the source states no
sampling period). Values are printed with ``repr`` (17 significant digits: the text reads back to
the same doubles; the script checks). Nothing is filtered, cut, decimated or rescaled.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.io import loadmat


def convert(src: Path, out: Path) -> None:
    data = loadmat(src)["CD_player_arm_dat"]
    if data.shape != (2048, 4) or not np.all(np.isfinite(data)):
        raise SystemExit(f"{src}: expected 2048 x 4 finite values, found {data.shape}")
    lines = ["t,u,y,u2,y2"]
    lines += [
        f"{k},{u1!r},{y1!r},{u2!r},{y2!r}" for k, (u1, u2, y1, y2) in enumerate(data.tolist())
    ]
    out.write_text("\n".join(lines) + "\n")
    back = np.genfromtxt(out, delimiter=",", names=True)
    for name, col in (("u", 0), ("u2", 1), ("y", 2), ("y2", 3)):
        if not np.array_equal(back[name], data[:, col]):
            raise SystemExit(f"{out}: column {name} does not read back to the source values")


if __name__ == "__main__":
    if len(sys.argv) not in (2, 3):
        raise SystemExit(__doc__)
    here = Path(__file__).resolve().parent
    convert(
        Path(sys.argv[1]), Path(sys.argv[2]) if len(sys.argv) == 3 else here / "cd_player_arm.csv"
    )
