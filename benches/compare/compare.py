#!/usr/bin/env python3
"""Side-by-side: the same PMSM output-error identification with plain numpy/scipy and with fracid.

Both fit K/(a2 s^(zeta+theta) + a1 s^zeta + 1) to the same CSV (t,u,y), from the same start, with
the same parametrisation (log of K, a1, a2; logit of zeta/2, theta/2) and the same discrete model:
each s^nu is the Oustaloup approximation (band [1e-6/dt, 30 pi/dt] rad/s, N = 8, 2N+1 cells, integer
part split off as a bilinear differentiator), each cell discretised bilinear (Tustin) as a
first-order section, the input delayed by half a step (linear interpolation) to compensate the
bilinear map's treatment of a held input -- exactly fracid's default ApproxSpec.

The scipy side is written as a Python user would: each operator's cascade becomes a small state
space, the implicit combination of the operators is solved once into a closed-loop state space,
scipy.signal.dlsim simulates it, and scipy.optimize.least_squares (method 'lm', MINPACK) fits it
with a finite-difference Jacobian.

Usage: compare.py DATA.csv FIT_CSV_BINARY [--repeats R]
"""
import argparse
import json
import subprocess
import sys
import time

import numpy as np
import scipy
from scipy import optimize, signal

N_ORDER = 8
# The band's lower edge at a 1 ms step (rad/s); fracid's default scales it as 1/dt.
W_B_1MS = 1e-3


def oustaloup_sections(nu, dt):
    """Bilinear first-order sections (b0, b1, a1) and gain of fracid's Oustaloup s^nu."""
    c = 2.0 / dt
    w_h = 30.0 * np.pi / dt
    w_b = W_B_1MS * 1e-3 / dt
    n_int = int(np.floor(nu))
    f = nu - n_int
    cells = 2 * N_ORDER + 1
    step = np.log(w_h / w_b) / cells
    k = np.arange(cells) + 0.5
    z = np.exp((k - 0.5 * f) * step) * w_b
    p = np.exp((k + 0.5 * f) * step) * w_b
    gain = np.exp(f * np.log(w_h))
    den = p + c
    secs = [((zz + c) / d, -(c - zz) / d, -(c - pp) / d) for zz, pp, d in zip(z, p, den)]
    secs += [(c, -c, 1.0)] * n_int
    return secs, gain


def operator_ss(nu, dt):
    """State space (A, B, C, D) of the cascade of sections (transposed direct form II)."""
    secs, gain = oustaloup_sections(nu, dt)
    n = len(secs)
    A = np.zeros((n, n))
    B = np.zeros(n)
    vrow, vx = np.zeros(n), 1.0  # the signal entering section i, as vrow . s + vx x
    for i, (b0, b1, a1) in enumerate(secs):
        # y_i = b0 v_i + s_i ; s_i' = b1 v_i - a1 y_i = (b1 - a1 b0) v_i - a1 s_i
        e = b1 - a1 * b0
        A[i] = e * vrow
        A[i, i] -= a1
        B[i] = e * vx
        vrow = b0 * vrow
        vrow[i] += 1.0
        vx = b0 * vx
    return A, B, gain * vrow, gain * vx


def params_of(th):
    return np.array([np.exp(th[0]), np.exp(th[1]), np.exp(th[2]),
                     2.0 / (1.0 + np.exp(-th[3])), 2.0 / (1.0 + np.exp(-th[4]))])


def theta_of(p):
    s3, s4 = p[3] / 2.0, p[4] / 2.0
    return np.array([np.log(p[0]), np.log(p[1]), np.log(p[2]),
                     np.log(s3 / (1 - s3)), np.log(s4 / (1 - s4))])


def simulate(p, u_held, dt):
    """y of K/(a2 s^(zeta+theta) + a1 s^zeta + 1) on the (half-step delayed) input."""
    k, a1, a2, zeta, theta = p
    A1, B1, C1, D1 = operator_ss(zeta + theta, dt)
    A2, B2, C2, D2 = operator_ss(zeta, dt)
    df = a2 * D1 + a1 * D2 + 1.0
    n1, n2 = len(B1), len(B2)
    A = np.zeros((n1 + n2, n1 + n2))
    A[:n1, :n1], A[n1:, n1:] = A1, A2
    B = np.concatenate([B1, B2])
    C = -np.concatenate([a2 * C1, a1 * C2]) / df
    D = k / df
    Acl = A + np.outer(B, C)
    Bcl = (B * D)[:, None]
    _, y, _ = signal.dlsim((Acl, Bcl, C[None, :], np.array([[D]]), dt), u_held)
    return y[:, 0]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("data")
    ap.add_argument("fit_csv")
    ap.add_argument("--repeats", type=int, default=5, help="fracid fits to time (best of)")
    ap.add_argument("--rtol", type=float, default=1e-3, help="parameter agreement (relative)")
    ap.add_argument("--nrmse-tol", type=float, default=0.01, help="NRMSE agreement (points)")
    a = ap.parse_args()

    with open(a.data) as fh:
        lines = [ln for ln in fh if not ln.startswith("#")]
    cols = lines[0].strip().split(",")
    arr = np.loadtxt(lines[1:], delimiter=",")
    d = {c: arr[:, i] for i, c in enumerate(cols)}
    t, u, y = d["t"], d["u"], d["y"]
    dt = t[1] - t[0]
    u_held = 0.5 * (u + np.concatenate([[0.0], u[:-1]]))  # the half-step hold compensation

    truth = np.array([6.82, 0.0059, 2.655e-5, 0.92, 0.8252])
    if "y_clean" in d:
        dev = np.max(np.abs(simulate(truth, u_held, dt) - d["y_clean"]))
        print(f"same discrete model: max |y_scipy - y_fracid| at the true parameters = {dev:.2e}")

    start = np.array([5.0, 0.008, 2.0e-5, 0.8, 0.7])
    sims = [0]

    def residual(th):
        sims[0] += 1
        return simulate(params_of(th), u_held, dt) - y

    t0 = time.perf_counter()
    res = optimize.least_squares(residual, theta_of(start), method="lm", xtol=1e-10, ftol=1e-10)
    t_py = time.perf_counter() - t0
    p_py = params_of(res.x)
    e = simulate(p_py, u_held, dt) - y
    nrmse_py = 100.0 * (1.0 - np.linalg.norm(e) / np.linalg.norm(y - y.mean()))

    out = subprocess.run([a.fit_csv, a.data, str(a.repeats)], check=True, capture_output=True, text=True)
    fr = json.loads(out.stdout.strip().splitlines()[-1])
    p_rs = np.array([fr["params"][k] for k in ("K", "a1", "a2", "zeta", "theta")])
    t_rs = fr["time_s"]

    names = ("K", "a1", "a2", "zeta", "theta")
    print(f"data: {a.data}, {len(y)} samples, dt = {dt:g} s; numpy {np.__version__}, scipy {scipy.__version__}")
    print(f"{'param':>6} {'scipy':>14} {'fracid':>14} {'rel. diff':>10}")
    rel = np.abs(p_py - p_rs) / np.abs(p_rs)
    for n, x, z, r in zip(names, p_py, p_rs, rel):
        print(f"{n:>6} {x:14.6e} {z:14.6e} {r:10.2e}")
    print(f"{'NRMSE':>6} {nrmse_py:13.4f}% {fr['nrmse_percent']:13.4f}%")
    print(f"scipy : {t_py:8.3f} s  ({sims[0]} simulations, finite-difference Jacobian, one run)")
    print(f"fracid: {t_rs:8.4f} s  ({fr['iterations']} iterations, {fr['evaluations']} simulations, "
          f"dual-number Jacobian, best of {a.repeats})")
    print(f"speed-up: {t_py / t_rs:.1f}x")
    same = bool(np.all(rel < a.rtol)) and abs(nrmse_py - fr["nrmse_percent"]) < a.nrmse_tol
    print(f"same fit (params within {a.rtol:g} relative, NRMSE within {a.nrmse_tol:g} points): "
          f"{'yes' if same else 'NO'}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
