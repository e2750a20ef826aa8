#!/usr/bin/env python3
"""Whole-process side by side: `fracid time FILE --json` against the strongest scipy peer
(`strong_peer.py`), both run as fresh processes on the same CSV (reading the file, the fit and
the report included; the Python process's interpreter start and imports included too).

Usage: strong_compare.py FRACID_BINARY PYTHON DATA.csv [DATA.csv ...] [--fracid-runs R] [--peer-runs R]
Prints one line per file and a markdown table; exits 1 when the estimation RMSEs differ by more
than 1%.
"""
import argparse
import json
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))


def timed(cmd, runs):
    best, out = float("inf"), None
    for _ in range(runs):
        t0 = time.perf_counter()
        p = subprocess.run(cmd, check=True, capture_output=True, text=True)
        el = time.perf_counter() - t0
        if el < best:
            best, out = el, p.stdout
    return best, out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("fracid")
    ap.add_argument("python")
    ap.add_argument("data", nargs="+")
    ap.add_argument("--fracid-runs", type=int, default=3)
    ap.add_argument("--peer-runs", type=int, default=1)
    a = ap.parse_args()
    rows, ok = [], True
    for path in a.data:
        t_rs, out = timed([a.fracid, "time", path, "--json"], a.fracid_runs)
        fr = json.loads(out)
        rmse_rs = fr["fit"]["estimation"]["rmse"]
        params = {p["name"]: p["value"] for p in fr["params"]}
        t_py, out = timed([a.python, os.path.join(HERE, "strong_peer.py"), path], a.peer_runs)
        py = json.loads(out.strip().splitlines()[-1])
        rel = abs(rmse_rs - py["rmse"]) / py["rmse"]
        ok &= rel <= 0.01
        n = py["samples"]
        print(f"{path}: {n} samples")
        print(f"  fracid time : {t_rs:8.3f} s whole process (best of {a.fracid_runs}), "
              f"fit {fr['seconds']:.3f} s, {fr['iterations']} iterations, RMSE {rmse_rs:.5f}, "
              f"K {params['K']:.4f} zeta {params['zeta']:.4f} theta {params['theta']:.4f}")
        print(f"  scipy strong: {t_py:8.3f} s whole process (best of {a.peer_runs}), "
              f"read {py['read_s']:.3f} s, fit {py['fit_s']:.3f} s, {py['simulations']} simulations, "
              f"RMSE {py['rmse']:.5f}, K {py['params']['K']:.4f} zeta {py['params']['zeta']:.4f} "
              f"theta {py['params']['theta']:.4f}")
        print(f"  speed-up {t_py / t_rs:.1f}x, RMSE difference {100 * rel:.2f}%")
        rows.append((n, t_py, py["rmse"], t_rs, rmse_rs, t_py / t_rs, rel))
    print()
    print("| samples | scipy strong peer | RMSE | fracid time | RMSE | speed-up |")
    print("|---|---|---|---|---|---|")
    for n, tp, rp, tr, rr, x, _ in rows:
        print(f"| {n:.0e} | {tp:.3f} s | {rp:.5f} | {tr:.3f} s | {rr:.5f} | {x:.1f}x |")
    print(f"same fit (estimation RMSE within 1%): {'yes' if ok else 'NO'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
