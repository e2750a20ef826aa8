"""Make ``hppc_25c_pulse4.csv`` from ``data/NissanLeaf-cell-Low-Current-HPPC-25C-2.csv`` of the
public repository batterysim/nissan-leaf-data.

Usage: ``python3 data/ornl_nissan_leaf_cell/convert.py PATH/TO/NissanLeaf-cell-Low-Current-HPPC-25C-2.csv [OUT.csv]``

The source (a battery tester's log: ``Time(s)``, ``Step``, ``Current(A)``, ``Voltage(V)``, ...)
logs each test step at its own rate: 60 s while resting between pulses, 0.5 s during the 30 s
discharge pulse, 1 s during the rest after it, 0.1 s during the 10 s charge (regen) pulse, 1 s
during the constant-current discharge to the next state of charge. This script cuts one block of
the test, the fourth pulse: from the last rest sample before it (source time 29724.9 s) to the
last sample of the discharge that follows (30884.9 s), and keeps the logged samples whose time
falls on the 1 s grid ``29724.9 + k`` (every one of the 1161 grid times has a logged sample
there, within 1e-6 s): the faster-logged samples in between are dropped, no value is
interpolated or changed. Columns ``t,u,y,step``: ``t`` = source time - 29724.9 [s] (0 to 1160),
``u`` = current [A] (negative discharging, as logged), ``y`` = voltage [V], ``step`` = the
tester's step number (10 rest, 6 discharge pulse, 7 rest, 8 charge pulse, 9 discharge).
The script checks the grid, the values and that the text reads back to them.
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np

T_FIRST, T_LAST = 29724.9, 30884.9


def convert(src: Path, out: Path) -> None:
    with src.open(newline="") as f:
        rows = list(csv.reader(f))
    head = rows[0]
    i_t, i_step, i_cur, i_volt = (
        head.index(k) for k in ("Time(s)", "Step", "Current(A)", "Voltage(V)")
    )
    t = np.array([float(r[i_t]) for r in rows[1:]])
    step = np.array([int(r[i_step]) for r in rows[1:]])
    cur = np.array([float(r[i_cur]) for r in rows[1:]])
    volt = np.array([float(r[i_volt]) for r in rows[1:]])
    grid = T_FIRST + np.arange(round(T_LAST - T_FIRST) + 1)
    pick = np.searchsorted(t, grid - 1e-6)
    if np.max(np.abs(t[pick] - grid)) > 1e-6:
        raise SystemExit(f"{src}: a grid time has no logged sample")
    if list(np.unique(step[pick])) != [6, 7, 8, 9, 10] or step[pick][0] != 10:
        raise SystemExit(f"{src}: the cut is not the expected rest, pulse, rest, pulse, discharge")
    rel = [f"{k}" for k in range(len(grid))]
    lines = ["t,u,y,step"]
    lines += [
        f"{k},{rows[1 + j][i_cur]},{rows[1 + j][i_volt]},{step[j]}" for k, j in zip(rel, pick)
    ]
    out.write_text("\n".join(lines) + "\n")
    back = np.genfromtxt(out, delimiter=",", names=True)
    if not (np.array_equal(back["u"], cur[pick]) and np.array_equal(back["y"], volt[pick])):
        raise SystemExit(f"{out}: the text does not read back to the source values")


if __name__ == "__main__":
    if len(sys.argv) not in (2, 3):
        raise SystemExit(__doc__)
    here = Path(__file__).resolve().parent
    convert(
        Path(sys.argv[1]), Path(sys.argv[2]) if len(sys.argv) == 3 else here / "hppc_25c_pulse4.csv"
    )
