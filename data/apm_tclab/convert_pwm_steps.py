"""Make ``tclab_pwm_steps.csv`` from APMonitor/arduino's
``2_Regression/1st_order_SISO/APM_Python_with_stats/data.csv``.

Usage: ``python3 data/apm_tclab/convert_pwm_steps.py PATH/TO/data.csv [OUT.csv]``

The source's header ``time,voltage,temperature`` is renamed to ``t,u,y`` (fracid's defaults);
the lines after it are copied unchanged, with the source's CR LF line ends (the script checks the values read back). The times are
already whole seconds, 0 to 850, uniform.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np


def convert(src: Path, out: Path) -> None:
    head, rest = src.read_bytes().decode().split("\n", 1)
    if head.rstrip("\r") != "time,voltage,temperature":
        raise SystemExit(f"{src}: expected the header time,voltage,temperature, found {head!r}")
    eol = "\r\n" if head.endswith("\r") else "\n"  # the source's line ends (CR LF), kept
    out.write_bytes(("t,u,y" + eol + rest).encode())
    a = np.genfromtxt(src, delimiter=",", names=True)
    b = np.genfromtxt(out, delimiter=",", names=True)
    for old, new in (("time", "t"), ("voltage", "u"), ("temperature", "y")):
        if not np.array_equal(a[old], b[new]):
            raise SystemExit(f"{out}: column {new} differs from the source's {old}")
    if not np.all(np.diff(b["t"]) == 1.0):
        raise SystemExit(f"{out}: the times are not a uniform 1 s grid")


if __name__ == "__main__":
    if len(sys.argv) not in (2, 3):
        raise SystemExit(__doc__)
    here = Path(__file__).resolve().parent
    convert(
        Path(sys.argv[1]), Path(sys.argv[2]) if len(sys.argv) == 3 else here / "tclab_pwm_steps.csv"
    )
