"""Timing of the time-domain fit from Python: one fit (to compare with `fracid time` on the same
file), and four fits in four threads against four in a row (the GIL is released during fits).

Usage: python bench_fits.py OUT_DIR   (writes OUT_DIR/record.csv for the CLI, prints timings)
"""

from __future__ import annotations

import os
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

import fracid

DT = 5e-5
BAND = (0.1, 1e5)
ORDER = 6
TRUTH = fracid.FracTf.pmsm(6.82, 0.0059, 2.655e-5, 0.92, 0.8252)


def record(seed: int):
    u = np.concatenate([np.zeros(200), fracid.prbs(dt=DT, order=7, clock=0.003, periods=4)])
    y = TRUTH.simulate(u, DT)
    return u, y + 0.01 * y.std() * np.random.default_rng(seed).standard_normal(y.size)


def fit(data):
    u, y = data
    return fracid.fit_time(u, y, DT, "pmsm", method="oustaloup", band=BAND, order=ORDER)


def main() -> None:
    out = sys.argv[1] if len(sys.argv) > 1 else "."
    datasets = [record(s) for s in range(4)]
    u, y = datasets[0]
    path = os.path.join(out, "record.csv")
    with open(path, "w") as f:
        f.write("t,u,y\n")
        for k in range(u.size):
            f.write(f"{k * DT!r},{float(u[k])!r},{float(y[k])!r}\n")
    print(f"{u.size} samples, dt {DT} s, written to {path}")
    fit(datasets[0])  # warm-up
    times = []
    for _ in range(10):
        t0 = time.perf_counter()
        r = fit(datasets[0])
        times.append(time.perf_counter() - t0)
    print(f"one fit (Python, best of 10): {min(times):.3f} s  [{r.iterations} iterations, "
          f"{r.evaluations} simulations, val {r.validation.nrmse_percent:.2f}%]")
    print("  ", {k: round(v, 6) for k, v in r.values.items()})
    for rep in range(3):
        c0, t0 = time.process_time(), time.perf_counter()
        serial = [fit(d) for d in datasets]
        t_serial, c_serial = time.perf_counter() - t0, time.process_time() - c0
        c0, t0 = time.process_time(), time.perf_counter()
        with ThreadPoolExecutor(max_workers=4) as ex:
            threaded = list(ex.map(fit, datasets))
        t_threads, c_threads = time.perf_counter() - t0, time.process_time() - c0
        same = all(a.values == b.values for a, b in zip(serial, threaded))
        print(f"[{rep}] four fits in a row: {t_serial:.3f} s wall ({c_serial:.3f} s CPU); "
              f"four threads: {t_threads:.3f} s wall ({c_threads:.3f} s CPU); "
              f"speed-up {t_serial / t_threads:.2f}x on {os.cpu_count()} cores, "
              f"load average {os.getloadavg()[0]:.1f}; identical results: {same}")


if __name__ == "__main__":
    main()
