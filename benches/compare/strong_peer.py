#!/usr/bin/env python3
"""The strongest numpy/scipy peer of `fracid time` on the PMSM structure (issue 18).

Fits y = K/(a2 s^(zeta+theta) + a1 s^zeta + 1) u + c to a CSV record (columns t,u,y; `#` lines
are comments) the way a capable scipy user would, with no Python loop over samples:

- every s^nu is approximated by the refined Oustaloup filter (Xue, Zhao & Chen 2006; N = 8,
  band [1e-6/dt, 30 pi/dt] rad/s -- fracid's default ApproxSpec), its integer part kept exact;
- the whole model is one continuous state space (the denominator divided by s when an order is
  at least 1, so that it is proper, and solved for y around its feed-through);
- exact zero-order hold by the matrix exponential of [[A, B], [0, 0]] dt (scipy.linalg.expm),
  diagonalised (numpy.linalg.eig), and simulated with one vectorised scipy.signal.lfilter per mode
  (conjugate pairs run once, real part doubled);
- the output offset c projected out (the residual is centred: c = mean(y - yhat) in closed form);
- scipy.optimize.least_squares(method="lm") (MINPACK) with its finite-difference Jacobian, on
  log K, log a1, log a2 and logit(zeta/2), logit(theta/2).

The operating point is removed as `fracid time` does by default (the first sample's u and y), the
first 70% of the record is fitted (fracid's default holdout 0.3) and the RMSE is reported on that
estimation part, from rest (the record starts at rest).

The peer is started at the true parameters of the benchmark data (`--start` to change): from
a start 10-40% off it stalled far above the noise floor, so any start fracid would have to make
too is given to it for free. Its simulation agrees with fracid's (`gen_data`'s `y_clean`) to
4e-6 of the output swing at the true parameters.

Usage: strong_peer.py DATA.csv [--start K a1 a2 zeta theta]
Prints one JSON line: params, rmse (estimation part), simulations, fit and total times.
"""
import time

T_START = time.perf_counter()

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402

import numpy as np  # noqa: E402
from scipy import linalg, optimize, signal  # noqa: E402

N_ORDER = 8
# The band's lower edge at a 1 ms step (rad/s); fracid's default scales it as 1/dt.
W_B_1MS = 1e-3


def refined_oustaloup(nu, w_b, w_h, n=N_ORDER):
    """(int_order, gain, zeros, poles) of s^nu ~ s^int gain prod (s + z)/(s + p) (Xue 2006)."""
    n_int = int(np.floor(nu))
    f = nu - n_int
    b, d = 10.0, 9.0
    lo, hi = d * w_b / b, b * w_h / d
    cells = 2 * n + 1
    step = np.log(hi / lo) / cells
    base = np.arange(cells) + 0.5
    zeros = list(np.exp((base - 0.5 * f) * step) * lo)
    poles = list(np.exp((base + 0.5 * f) * step) * lo)
    gain = np.exp(f * np.log(hi))
    if f == 0.0:
        return n_int, gain, np.array(zeros), np.array(poles)
    # fracid's unit frequency for Xue's constant term: w_u^2 = w_b w_h / 100
    w_u2 = w_b * w_h / 100.0
    bw = b * w_h
    disc = np.sqrt(bw * bw - f * (1.0 - f) * 4.0 * d * d * w_u2)
    p_big = (bw + disc) / ((1.0 - f) * 2.0 * d)
    p_small = (f * w_u2 / (1.0 - f)) / p_big
    zeros += [0.0, b * w_h / d]
    poles += [p_big, p_small]
    zeros, poles = np.array(zeros), np.array(poles)
    w_c = np.sqrt(w_b * w_h)
    mag2 = np.prod((zeros**2 + w_c**2) / (poles**2 + w_c**2))
    gain = np.exp(f * np.log(w_c)) / np.sqrt(mag2)
    return n_int, gain, zeros, poles


def cascade_ss(gain, zeros, poles):
    """State space (A, B, C, D) of gain * prod (s + z)/(s + p) (len(zeros) <= len(poles)), one
    first-order cell per state: the cells without a zero (1/(s + p)) first."""
    n = len(poles)
    extra = n - len(zeros)
    zs = [None] * extra + list(zeros)
    A = np.zeros((n, n))
    B = np.zeros(n)
    # The signal entering cell i is vrow . x + vx * input; cell i: x_i' = -p_i x_i + v_i, output
    # v_(i+1) = v_i + (z_i - p_i) x_i, or x_i for a cell without a zero.
    vrow, vx = np.zeros(n), 1.0
    for i, (z, p) in enumerate(zip(zs, poles)):
        A[i] = vrow
        A[i, i] -= p
        B[i] = vx
        if z is None:
            vrow, vx = np.zeros(n), 0.0
            vrow[i] = 1.0
        else:
            vrow = vrow.copy()
            vrow[i] += z - p
    return A, B, gain * vrow, gain * vx


def model_ss(p, dt):
    """Continuous (A, B, C, D) of K/(a2 s^(zeta+theta) + a1 s^zeta + 1), approximated, minimal
    (no pole-zero cancellation at the origin, which would leave a spurious mode near 0)."""
    k, a1, a2, zeta, theta = p
    w_h = 30.0 * np.pi / dt
    parts = []
    for coef, nu in [(a2, zeta + theta), (a1, zeta)]:
        n_int, g, z, q = refined_oustaloup(nu, W_B_1MS * 1e-3 / dt, w_h)
        if n_int > 1:
            raise ValueError(f"order {nu} above 2")
        parts.append((coef, n_int, g, list(z), list(q)))
    # Divided by s^shift (0 or 1) so that H is proper: H y = w with
    # H = sum coef s^(n - shift) R + s^-shift and w = s^-shift K u.
    shift = max(n for _, n, _, _, _ in parts)
    blocks = []  # (A, B, C, D) of each term of H, input y
    for coef, n, g, z, q in parts:
        if n - shift == -1:  # R(s)/s: the zero at the origin cancels the 1/s
            if 0.0 in z:
                z.remove(0.0)
            else:
                q.append(0.0)
        A, B, C, D = cascade_ss(g, z, q)
        blocks.append((A, B, coef * C, coef * D))
    sizes = [len(b[1]) for b in blocks]
    n = sum(sizes) + shift
    Ax = np.zeros((n, n))
    By = np.zeros(n)
    Ch = np.zeros(n)
    Dh = 0.0
    o = 0
    for A, B, C, D in blocks:
        m = len(B)
        Ax[o:o + m, o:o + m] = A
        By[o:o + m] = B
        Ch[o:o + m] = C
        Dh += D
        o += m
    Bu = np.zeros(n)
    if shift == 0:
        # (sum terms + 1) y = K u:  y = (K u - Ch x)/(Dh + 1)
        Dh += 1.0
        Cy, Dy = -Ch / Dh, k / Dh
    else:
        # sum terms y = z with z = (K u - y)/s:  y = (z - Ch x)/Dh, z' = K u - y
        Ch[n - 1] = -1.0
        Cy, Dy = -Ch / Dh, 0.0
        By[n - 1] = -1.0
        Bu[n - 1] = k
    Acl = Ax + np.outer(By, Cy)
    Bcl = Bu + By * Dy
    return Acl, Bcl, Cy, Dy


def simulate(p, u, dt):
    """Exact ZOH response y_k (at t_k; u_k held on [t_k, t_(k+1))), from rest, modal lfilters.

    The discrete system is expm([[A, B], [0, 0]] dt) = [[Ad, Bd], [0, 1]] (scipy.linalg.expm),
    diagonalised, Ad = V diag(phi) V^-1, and each mode run by scipy.signal.lfilter. (Diagonalising
    the continuous A instead and discretising per mode is cheaper but loses the slowest poles,
    near -1e-6 rad/s beside poles at -1e6: its response drifts on long records.)
    """
    A, B, C, D = model_ss(p, dt)
    n = len(B)
    M = np.zeros((n + 1, n + 1))
    M[:n, :n] = A * dt
    M[:n, n] = B * dt
    E = linalg.expm(M)
    phi, V = np.linalg.eig(E[:n, :n])
    g = (C @ V) * np.linalg.solve(V, E[:n, n].astype(complex))
    y = D * u
    for i in np.flatnonzero(phi.imag >= 0):
        if phi[i].imag > 0:  # with its conjugate: run the pair once, real part doubled
            y = y + 2.0 * np.real(g[i] * signal.lfilter([0.0, 1.0], [1.0, -phi[i]], u))
        else:
            y = y + np.real(g[i]) * signal.lfilter([0.0, 1.0], [1.0, -phi[i].real], u)
    return y


def params_of(th):
    return np.array([np.exp(th[0]), np.exp(th[1]), np.exp(th[2]),
                     2.0 / (1.0 + np.exp(-th[3])), 2.0 / (1.0 + np.exp(-th[4]))])


def theta_of(p):
    s3, s4 = p[3] / 2.0, p[4] / 2.0
    return np.array([np.log(p[0]), np.log(p[1]), np.log(p[2]),
                     np.log(s3 / (1 - s3)), np.log(s4 / (1 - s4))])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("data")
    # The default start is the truth of the benchmark data: generous to the peer (fracid starts
    # from its own automatic start). From (5, 0.008, 2e-5, 0.8, 0.7) or (6, 0.005, 3e-5, 0.9,
    # 0.8) this LM stalled at RMSE 3.8 and 0.136 on the 3048-sample record.
    ap.add_argument("--start", type=float, nargs=5, default=[6.82, 0.0059, 2.655e-5, 0.92, 0.8252],
                    metavar=("K", "a1", "a2", "zeta", "theta"))
    ap.add_argument("--holdout", type=float, default=0.3)
    a = ap.parse_args()

    t_read = time.perf_counter()
    with open(a.data) as fh:
        while True:  # comments, then the header t,u,y
            line = fh.readline()
            if not line.startswith("#"):
                break
        arr = np.loadtxt(fh, delimiter=",", comments="#", usecols=(0, 1, 2))
    t, u, y = arr[:, 0], arr[:, 1], arr[:, 2]
    read_s = time.perf_counter() - t_read
    dt = t[1] - t[0]
    u = u - u[0]
    y = y - y[0]
    split = int(round(len(y) * (1.0 - a.holdout)))
    ue, ye = u[:split], y[:split]
    yc = ye - ye.mean()
    sims = [0]

    def residual(th):
        sims[0] += 1
        yh = simulate(params_of(th), ue, dt)
        return (yh - yh.mean()) - yc

    t0 = time.perf_counter()
    # diff_step 1e-6: the default (sqrt of machine epsilon) is below what the expm and eig
    # rounding of a simulation resolves, and the finite-difference Jacobian then misleads LM.
    res = optimize.least_squares(residual, theta_of(np.array(a.start)), method="lm", diff_step=1e-6,
                                 xtol=1e-12, ftol=1e-12)
    fit_s = time.perf_counter() - t0
    p = params_of(res.x)
    e = residual(res.x)
    rmse = float(np.sqrt(np.mean(e**2)))
    names = ("K", "a1", "a2", "zeta", "theta")
    print(json.dumps({
        "tool": "scipy-strong", "samples": len(y), "estimation_samples": split,
        "params": dict(zip(names, map(float, p))), "rmse": rmse, "simulations": sims[0],
        "status": int(res.status), "read_s": read_s, "fit_s": fit_s,
        "total_s": time.perf_counter() - T_START,
    }))
    return 0


if __name__ == "__main__":
    sys.exit(main())
