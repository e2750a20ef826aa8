"""Long computations release the GIL: fits in threads give the serial results, and Python code
keeps running while a simulation runs in another thread."""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

import fracid

DT = 1e-4


def _data(seed: int):
    truth = fracid.FracTf.parse("6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)")
    u = fracid.prbs(dt=DT, periods=2)
    y = truth.simulate(u, DT)
    return u, y + 0.01 * y.std() * np.random.default_rng(seed).standard_normal(y.size)


def _fit(data):
    u, y = data
    return fracid.fit_time(u, y, DT, "commensurate", offsets="none", fit_offset=False).values


def test_threaded_fits_equal_serial_fits():
    datasets = [_data(s) for s in range(4)]
    serial = [_fit(d) for d in datasets]
    with ThreadPoolExecutor(max_workers=4) as ex:
        threaded = list(ex.map(_fit, datasets))
    assert threaded == serial  # bit-for-bit: no shared state between fits


def test_gil_is_released_during_simulation():
    g = fracid.FracTf.parse("6.77/(0.0064 s^0.89 + 1)")
    u = np.ones(200_000)  # the most Grunwald-Letnikov takes (its whole memory): > 0.1 s
    done = threading.Event()
    box = {}

    def work():
        t0 = time.perf_counter()
        box["y"] = fracid.gl_simulate(g, u, 1e-5)
        box["elapsed"] = time.perf_counter() - t0
        done.set()

    th = threading.Thread(target=work)
    th.start()
    ticks, last, max_gap = 0, time.perf_counter(), 0.0
    while not done.is_set():
        now = time.perf_counter()
        max_gap = max(max_gap, now - last)
        last = now
        ticks += 1
    th.join()
    # With the GIL held the main thread would stall for the whole simulation (one gap about as
    # long as it); released, it keeps ticking (gaps of a switch interval, 5 ms, plus scheduling).
    assert box["elapsed"] > 0.05
    assert ticks > 100
    assert max_gap < 0.5 * box["elapsed"], (max_gap, box["elapsed"])
