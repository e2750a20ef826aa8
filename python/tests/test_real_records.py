"""Real measured records shipped in ``data/`` (each with its source and licence beside it): fracid's
held-out fit with defaults against an integer-order baseline fitted here, independently, with scipy.

The baseline (``integer_baseline``) owes nothing to fracid's code: an all-pole continuous transfer
function of order 1, 2 or 3 (``K / (1 + T s)``, ``K / (s^2/w^2 + 2 z s/w + 1)``, the latter times
``1 / (1 + T s)``; stable by construction), a whole-sample input delay, an output offset and an
initial state (the equilibrium a past held input ``u_past`` left, fitted), discretised exactly for a
held input (zero-order hold, from the poles and residues; checked against scipy's
``cont2discrete`` in ``test_zoh_matches_scipy``) and fitted by ``scipy.optimize.least_squares``
on the estimation part that fracid reports (``split``). The delay is chosen on the estimation part
only; the baseline's figure is the best held-out fit of the three orders (the strongest of them, so
the comparison does not flatter fracid). Both are scored on the same held-out samples with the state
carried over from the estimation part, by the same formula as fracid's
(``100 (1 - ||y - yhat|| / ||y - mean(y)||)``, ``nrmse_percent``).

Where fracid loses on a record the assertion is marked xfail with the measured numbers: the record
stays, the loss is reported, not hidden. The xfail is strict: a record that starts to pass fails the
test until its entry (and the numbers it states) is updated.
"""

from __future__ import annotations

import functools
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent
DATA = HERE.parent.parent / "data"


# ---------------------------------------------------------------------------------------------
# The independent integer-order baseline (scipy only).
# ---------------------------------------------------------------------------------------------


def nrmse_percent(y: np.ndarray, yhat: np.ndarray) -> float:
    """``100 (1 - ||y - yhat|| / ||y - mean(y)||)``: 100 is exact, 0 is the mean's score."""
    den = np.linalg.norm(y - y.mean())
    return float(100.0 * (1.0 - np.linalg.norm(y - yhat) / den))


def rmse(y: np.ndarray, yhat: np.ndarray) -> float:
    return float(np.sqrt(np.mean((y - yhat) ** 2)))


def _den(order: int, p: np.ndarray) -> np.ndarray:
    """Denominator (highest power first, constant term 1) of a stable all-pole model."""
    if order == 1:
        return np.array([np.exp(p[0]), 1.0])
    w, z = np.exp(p[0]), np.exp(p[1])
    d2 = np.array([1.0 / w**2, 2.0 * z / w, 1.0])
    if order == 2:
        return d2
    return np.polymul(d2, [np.exp(p[2]), 1.0])


def _zoh(k_gain: float, den: np.ndarray, dt: float):
    """Exact zero-order-hold discretisation of ``K / den(s)`` (``den(0) = 1``, distinct poles):
    discrete poles ``exp(p dt)``, numerator from the step response sampled exactly
    (``s(t) = K + sum K exp(p t) / (p den'(p))``, the residues of ``K / (s den(s))``)."""
    poles = np.roots(den)
    dden = np.polyval(np.polyder(den), poles)
    n = len(poles)
    k = np.arange(n + 1)
    modes = (k_gain / (poles * dden))[None, :] * np.exp(np.outer(k * dt, poles))
    step = k_gain + np.real(modes.sum(axis=1))
    h = np.diff(step, prepend=0.0)  # h[0] = s(0) = 0 for a strictly proper model
    a = np.real(np.poly(np.exp(poles * dt)))
    b = np.convolve(a, h)[: n + 1]
    return b, a


def _simulate(order, theta, u, dt, delay):
    """``c + K u_past + G (u(k - delay) - u_past)`` from the equilibrium left by ``u_past``."""
    from scipy.signal import lfilter

    k_gain, c, u_past = theta[0], theta[1], theta[2]
    b, a = _zoh(k_gain, _den(order, theta[3:]), dt)
    ud = np.empty_like(u)
    ud[:delay] = u_past
    ud[delay:] = u[: len(u) - delay]
    return c + k_gain * u_past + lfilter(b, a, ud - u_past)


def _starts(order: int, dt: float, span: float):
    taus = np.geomspace(0.5 * dt, span / 3.0, 9)
    if order == 1:
        return [np.log([tau]) for tau in taus]
    out = []
    for tau in taus:
        for z in (0.3, 1.1):  # not 1: distinct poles
            p = [np.log(1.0 / tau), np.log(z)]
            if order == 3:
                p.append(np.log(tau / 3.0))
            out.append(np.array(p))
    return out


def _seeds_from(order: int, p_lower: np.ndarray, dt: float):
    """Starts for ``order`` from the fit of ``order - 1``: the lower model with one fast mode
    added (so the higher order starts where the lower one ended, and cannot end worse by a bad
    start alone)."""
    out = []
    for eps in (dt, 0.05 * np.exp(p_lower[0]) if order == 2 else dt):
        if order == 2:  # (1 + T s)(1 + eps s) = s^2/w^2 + 2 z s/w + 1
            tau = np.exp(p_lower[0])
            w = 1.0 / np.sqrt(tau * eps)
            z = (tau + eps) * w / 2.0
            out.append(np.array([np.log(w), np.log(z)]))
        else:
            out.append(np.r_[p_lower[:2], np.log(eps)])
    return out


def fit_order(t, u, y, n_est, order, max_delay, seeds=()):
    """Best least-squares fit on ``[0, n_est)``: several starts without delay, then each delay
    ``1..max_delay`` samples warm-started from the previous one; the delay with the least
    estimation error wins (the held-out part is never looked at)."""
    from scipy.optimize import least_squares

    dt = float(np.median(np.diff(t)))
    span = float(t[n_est - 1] - t[0])
    ye = y[:n_est]
    # Bounds keep every time constant between dt/10 and 100 record lengths and the damping
    # ratio in [0.01, 20] (no overflow, and nothing the sampling could not see).
    lo_tau, hi_tau = np.log(dt / 10.0), np.log(100.0 * span)
    lo = [-np.inf, -np.inf, -np.inf]
    hi = [np.inf, np.inf, np.inf]
    if order == 1:
        lo += [lo_tau]
        hi += [hi_tau]
    else:
        lo += [-hi_tau, np.log(0.01)]
        hi += [-lo_tau, np.log(20.0)]
        if order == 3:
            lo += [lo_tau]
            hi += [hi_tau]

    def solve(x0, delay):
        def res(x):
            return _simulate(order, x, u, dt, delay)[:n_est] - ye

        x0 = np.clip(x0, np.array(lo) + 1e-9, np.array(hi) - 1e-9)
        try:
            sol = least_squares(res, x0, bounds=(lo, hi), x_scale="jac", max_nfev=300)
        except (ValueError, np.linalg.LinAlgError):
            return None
        if not np.all(np.isfinite(sol.fun)):
            return None
        return float(sol.fun @ sol.fun), sol.x

    def linear_start(p0, delay):
        unit = _simulate(order, np.r_[1.0, 0.0, u[0], p0], u, dt, delay)[:n_est]
        (k0, c0), *_ = np.linalg.lstsq(np.c_[unit, np.ones(n_est)], ye, rcond=None)
        return np.r_[k0, c0, u[0], p0]

    cands = [solve(linear_start(p0, 0), 0) for p0 in [*_starts(order, dt, span), *seeds]]
    sse, x = min((c for c in cands if c is not None), key=lambda c: c[0])
    best = (sse, 0, x)
    for delay in range(1, max_delay + 1):
        got = solve(x, delay)
        if got is None:
            continue
        sse, x = got
        if sse < best[0]:
            best = (sse, delay, x)
    sse, delay, x = best
    yhat = _simulate(order, x, u, dt, delay)
    return {"order": order, "delay_samples": delay, "theta": x, "yhat": yhat, "sse_est": sse}


def integer_baseline(t, u, y, n_est, first, max_delay):
    """Orders 1-3 fitted on ``[0, n_est)``; each scored on ``[first, n)``, simulated on from the
    estimation part (the state carried over)."""
    rows = []
    dt = float(np.median(np.diff(t)))
    for order in (1, 2, 3):
        seeds = _seeds_from(order, rows[-1]["theta"][3:], dt) if rows else ()
        f = fit_order(t, u, y, n_est, order, max_delay, seeds)
        yv, yh = y[first:], f["yhat"][first:]
        f["val_nrmse"] = nrmse_percent(yv, yh)
        f["val_rmse"] = rmse(yv, yh)
        rows.append(f)
    best = max(rows, key=lambda r: r["val_nrmse"])
    return best, rows


@functools.lru_cache(maxsize=None)
def baseline_on_split(name: str, n_est: int, first: int):
    """``integer_baseline`` of record ``name`` on fracid's split, fitted once per split: the plain
    and the ``--diagnose`` test of a record share it (the same split), the fits are the slowest
    part of this file."""
    rel, max_delay = RECORDS[name]
    t, u, y = load_tuy(DATA / rel)
    assert 0 < n_est <= first < len(y), f"{name}: split {n_est}/{first} of {len(y)}"
    return integer_baseline(t, u, y, n_est, first, max_delay)


def load_tuy(path: Path):
    d = np.genfromtxt(path, delimiter=",", names=True)
    return (np.asarray(d["t"], float), np.asarray(d["u"], float), np.asarray(d["y"], float))


# ---------------------------------------------------------------------------------------------
# The records and the comparison.
# ---------------------------------------------------------------------------------------------


def run_fracid(binary, path: Path, *extra: str) -> tuple[dict, int]:
    """``fracid time PATH --json EXTRA``: its report and exit code. Exit 0, or exit 1 with a
    report that says the model is not usable (``"usable": false``, its figures still stated:
    the comparison then records the loss); anything else fails here."""
    p = subprocess.run(
        [str(binary), "time", str(path), "--json", *extra],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode in (0, 1), f"fracid time {path} exit {p.returncode}\n{p.stderr}"
    out = json.loads(p.stdout)
    assert (p.returncode == 0) == bool(out["usable"]), (p.returncode, out["usable"], p.stderr)
    return out, p.returncode


def exit_note(out: dict, code: int) -> str:
    """What an exit other than 0 said, for an assertion's message."""
    if code == 0:
        return ""
    return f" (exit {code}, not usable: {'; '.join(out.get('problems') or [])})"


def held_out(out: dict):
    """fracid's split (estimation ``[0, n_est)``, held out ``[first, n)``), its held-out NRMSE
    and RMSE and how it validated, from ``fracid time --json``."""
    n_est = int(out["split"]["estimation_samples"])
    how = out.get("validated_by") or {}
    first = int(how.get("first", n_est))
    val = out["fit"]["validation"]
    return n_est, first, float(val["nrmse_percent"]), float(val["rmse"]), how.get("kind")


# name -> (file under data/, the largest input delay in samples the baseline tries)
RECORDS = {
    "dcmotor_prbs_open": ("unal_dcmotor/DCmotor_prbs_open_exp.csv", 10),
    "closed_speed_loop": ("unal_dcmotor/DCmotor_stairs_closed_exp.csv", 10),
    "tclab_step": ("apm_tclab/tclab_step_test.csv", 30),
    "motor_generator_steps": ("sysidentpy_motor_generator/motor_generator_steps.csv", 10),
    "dcmotor_step_open": ("unal_dcmotor/DCmotor_step_open_exp.csv", 10),
    "robot_arm_flexible": ("slicot_robot_arm/robot_arm.csv", 10),
    "battery_random_current": ("dmegc_battery/random_current_cycle26.csv", 10),
    "battery_pulse_relaxation": ("dmegc_battery/pulse_discharge.csv", 10),
    "battery_hppc_block": ("ornl_nissan_leaf_cell/hppc_25c_pulse4.csv", 10),
    "cd_player_arm": ("slicot_cd_player_arm/cd_player_arm.csv", 10),
    "dcmotor_prbs_low_speed": ("unal_undcmotor/DCmotor_prbs_open_low.csv", 10),
    "closed_speed_profile": ("unal_undcmotor/DCmotor_profile_closed_exp.csv", 10),
    "tclab_pwm_steps": ("apm_tclab/tclab_pwm_steps.csv", 30),
}

# Where `fracid time FILE --plain` (the single fit of the named structure; the default before the
# loop was closed by default) loses, the measured figures and the reason. Measured 2026-11-26 (session 14, after
# the approximation band and Xue's correction became relative to the step) with `fracid time FILE
# --json` (defaults) and this file's baseline on fracid's split.
# An XPASS here means fracid now wins on that record: remove its entry.
XFAIL_PLAIN: dict[str, str] = {
    # 4093 samples, dt 0.02 s, open-loop PRBS voltage -> speed. fracid with defaults (pmsm, held
    # out samples 2865..4093): RMSE 3.792 deg/s (NRMSE 95.71%); baseline order 3 without delay:
    # RMSE 3.366 (96.19%), order 1 + 1-sample delay 4.958 (94.39%), order 2: 4.960. With
    # --diagnose fracid reaches 2.978 (96.63%), choosing "second order" + delay 0.0126 s.
    "dcmotor_prbs_open": (
        "fracid's held-out RMSE 3.792 (95.71%) vs integer baseline 3.366 (96.19%, third order); "
        "with --diagnose 2.978 (96.63%), an integer second order + delay chosen"
    ),
    # 450 samples, dt 0.02 s, reference stairs r -> speed y, step from rest at t = 0. Since the
    # staircase rule (4-5 input changes hold out the last step(s)) fracid validates on its last two
    # steps (held_out, samples 315..450): RMSE 6.601 deg/s (NRMSE 82.83%); baseline order 1 +
    # 3-sample delay: RMSE 5.581 (85.48%), order 2: 5.876, order 3: 5.932.
    "closed_speed_loop": (
        "fracid's held-out RMSE 6.601 (82.83%) vs integer baseline 5.581 (85.48%, first order "
        "+ 3-sample delay)"
    ),
    # 571 samples, dt 1 s, heater steps 0 -> 150 -> 10 -> 150, temperature in K. fracid's tail
    # (samples 520..571), fitted from rest (the record rests 11 samples before its first change):
    # RMSE 0.4516 K (NRMSE 69.41%; 0.3136 K in session 13, when the refined Oustaloup
    # approximation's correction assumed 1 rad/s as its unit and put a pole at 1.7e-3 rad/s, near
    # this record's lowest frequency 0.011 rad/s: a model that was not its written fractional
    # form there); baseline order 1 + 15 s delay: RMSE 0.2837 (80.78%), order 2: 0.3319, order 3:
    # 0.3022. With --diagnose: 0.2628 K (82.20%), second order + initial_state (session 16, once
    # the second order's start no longer had a repeated pole); 0.2796 K (81.06%), third order +
    # initial_state in session 15 (the
    # record looks idle for 11 s, so the defaults fit it from rest, but its temperature still
    # drifts from before the record, which the baseline's fitted past input u_past covers; the
    # diagnosis now tests that rest and keeps the estimated initial state: 0.3417 -> 0.2796;
    # session 14: 0.2886, third order + saturation; session 13: 0.2220, pmsm + delay). The
    # plain default would need a dead time: the pmsm structure with --delay keeps none (0.4516),
    # the fopdt structure reaches 0.311 from rest, 0.2995 with the initial state estimated.
    "tclab_step": (
        "fracid's tail RMSE 0.452 K vs integer baseline 0.284 K (first order + 15 s delay); "
        "with --diagnose 0.263 K (second order + initial_state)"
    ),
    # 1024 samples, t in samples (no period stated), a flexible robot arm on an electric motor:
    # reaction torque -> arm acceleration, a sine sweep over 0-0.2 cycles/sample, a negative gain
    # and two lightly damped modes (0.059 and 0.126 cycles/sample) with anti-resonances. fracid
    # with defaults (pmsm, started by the coarse search's resonant trials with a negative gain,
    # held out samples 717..1024): RMSE 0.1033 (NRMSE 60.71%), better than the baseline's
    # second order, RMSE 0.1362 (NRMSE 48.18%; first order + 9 samples 0.2562, third order
    # 0.1450), but exit 1: the model's damping term (a1 = 0.0123, its order zeta = 1.0) is not
    # determined (standard errors 10 times the values). With --diagnose: 0.0518 (80.28%), the
    # two-mass chosen, reduced to its determined terms and converged (session 16; session 15:
    # 80.30%, unconverged, singular covariance; before it could not start and the integer second order with a
    # delay of 3.5 samples was chosen at 0.0900, 65.77%). Before session 14 no
    # coarse trial had a positive gain, the fit started from the default values and every
    # structure ended at 0% (RMSE 0.2629, the held-out part's own spread).
    "robot_arm_flexible": (
        "fracid with defaults exits 1 (a1, zeta, theta not determined) although its held-out "
        "RMSE 0.1033 (60.7%) beats the integer baseline's 0.1362 (48.2%, second order)"
    ),
    # 5000 samples (the source's 500000 decimated by 100), t in source samples (period not
    # stated). fracid with defaults, from rest: held-out RMSE 562.0 (NRMSE 39.84%; the same with
    # t divided by 1e4: the fit no longer depends on the time unit; session 13: 1083, -15.9%,
    # exit 1); baseline order 3: RMSE 511.8 (NRMSE 45.22%), order 1 + 2-sample delay: 515.4.
    # With --diagnose: 505.04 (45.94%), pmsm + initial_state (the record looks idle for its first
    # samples, so the defaults fit it from rest; the diagnosis finds it was not at rest), 1.3%
    # below the baseline (511.78, a tie, before session 19 estimated the final model's record
    # parameters exactly with the plant held: the LM had stopped with a level at the wrong edge);
    # 479.0 (48.73%) on the branch that added initial_state, before the
    # variable projection of the fit moved its past levels to other edges of their range (the
    # levels are not determined there: both fits end with three of four at an edge); session 14:
    # 515.0, pmsm + input offset; session 13: 518.8, first order + delay + input offset.
    # The plain default with the initial state estimated (`--initial estimate`) gives the same
    # 511.78; its rule for a record that looks idle does not choose it.
    "motor_generator_steps": (
        "fracid's held-out RMSE 562.0 (39.8%) vs integer baseline 511.8 (45.2%, third order); "
        "with --diagnose 505.04 (45.94%), pmsm + initial_state"
    ),
    # The records added 2026-12-05, measured on main e364c0a (`fracid time FILE
    # --json`, defaults; the baseline on fracid's split). Exit 1 = "not usable", its figures
    # still reported.
    # DMEGC 18650 cell, random current 0-6 A in 120 s steps, 446 samples at 10 s, current ->
    # voltage; held out the last 30% (312..446). fracid (pmsm) exits 1: covariance singular,
    # theta at its bound 2, held-out RMSE 0.4102 V (NRMSE -213.4%); baseline second order 0.1305
    # (0.28%; first and third order 0.1351). No all-pole model holds the cell's ohmic feed-through.
    "battery_random_current": (
        "fracid exits 1 (covariance singular), held-out RMSE 0.4102 V vs integer baseline 0.1305 V"
    ),
    # DMEGC 18650 cell, 11 pulses of 1.30 A (10 min) with 20 min rests, 1981 samples at 10 s;
    # held out 1387..1981. fracid (pmsm, initial state estimated) exits 1: covariance singular,
    # held-out RMSE 0.2856 V (NRMSE -368.3%); baseline first order 0.03850 V (36.89%).
    "battery_pulse_relaxation": (
        "fracid exits 1 (covariance singular), held-out RMSE 0.2856 V vs integer baseline 0.0385 V"
    ),
    # Nissan Leaf cell, one HPPC block (-30 A 30 s, rest, +22.5 A 10 s, -10 A 1080 s), 1161
    # samples at 1 s. fracid's split: estimation 0..80 (the two pulses and the rest between),
    # held out 80..1161 (the 1080 s discharge: a staircase of 4 input changes holds out its last
    # step; the tester's 0.00/0.01 A flicker at rest is no change). fracid --plain (pmsm) exits 1:
    # held-out RMSE 0.02696 V (NRMSE -104.6%), worse than the held-out part's mean; baseline
    # 0.02761 V (-109.5%), within the 2% tie, but fracid's verdict says "not usable".
    "battery_hppc_block": (
        "fracid --plain exits 1 (worse than the mean held out), held-out RMSE 0.0270 V vs "
        "integer baseline 0.0276 V"
    ),
    # CD-player arm (DaISy, SLICOT), input 1 -> output 1, 2048 samples in sample units; held out
    # 1434..2048. fracid (pmsm) exits 1: an absurd static gain (2674), five parameters not
    # determined, held-out RMSE 0.7540 (NRMSE -138.6%); baseline third order 0.1009 (68.06%;
    # first and second order 0.1022).
    "cd_player_arm": (
        "fracid exits 1 (absurd gain), held-out RMSE 0.7540 vs integer baseline 0.1009"
    ),
    # UNDCMotor closed speed loop, reference profile -> speed, 201 samples at 0.02 s; held out
    # 141..201 (the ramp down's end and the rest at 0). fracid (pmsm) 4.852 deg/s (89.98%);
    # baseline third order + 1 sample 1.801 (96.28%), second order + 1 sample 1.803.
    "closed_speed_profile": (
        "fracid's held-out RMSE 4.852 deg/s vs integer baseline 1.801 (third order + 1 sample)"
    ),
    # TCLab heater PWM steps 0 -> 100 -> 255 -> 50, 851 samples at 1 s, degF; validated on the
    # response tail 747..851, fitted from rest (63 s idle). fracid (pmsm) exits 1: an absurd
    # static gain (1.7e8), three parameters not determined; tail RMSE 1.642 degF (NRMSE
    # -73.25%); baseline third order 1.509 (-59.22%; first order + 8 s 1.518).
    "tclab_pwm_steps": (
        "fracid exits 1 (absurd gain), tail RMSE 1.642 degF vs baseline 1.509 degF"
    ),
}

# Where fracid with defaults (the loop closed: structures compared, the best diagnosed) loses or
# exits 1 (strict, as above). Measured 2026-12-05 with `fracid time FILE --json` and no flag (its
# recommended model, `fit`; `--diagnose` names the default): the three below, with the figures
# stated (branch default, after the loop was closed by default again).
# battery_random_current passes since the diagnosed model is judged on its own figures
# (ident::app::verdict): feed-through + initial_state, held-out RMSE 0.07575 V (NRMSE 42.13%)
# against the baseline's 0.1305 V, exit 0 (main 6231ea7; before, exit 1 on the base fit's
# undetermined a1, a2, zeta, theta). battery_pulse_relaxation and cd_player_arm pass since the
# diagnosis compares the general structure when the named ones fit poorly
# (ident::diagnose::general::hook; measured 2026-12-05): general 1/1, held-out RMSE 0.03093 V
# against the baseline's 0.0385 V (the feed-through's 0.04779 before); general 4/6, 0.09415
# against 0.1009, exit 0 (exit 1 before). battery_hppc_block passes since a change of the input is
# a move of 1% of its range from the level of the last one (ident::oe::checks::changes; the
# tester's 0.01 A flicker at rest made 12 changes and an estimation part of 60 samples) and the
# final model's own evaluation counts its parameters as its fit did: the cell, held-out RMSE
# 0.00832 V (NRMSE 36.88%) against the baseline's 0.02761 V, exit 0.
XFAIL: dict[str, str] = {}

# fracid's held-out RMSE may exceed the best integer baseline's by at most this fraction. Both are
# scored on the same samples, so RMSE and NRMSE order the two fits identically; the allowance is
# stated on RMSE because on a step test's settled tail (``validated_by.kind == "response_tail"``)
# ``||y - mean(y)||`` is small and NRMSE points magnify noise-level differences. 2%: the baseline
# is itself a finite multistart optimisation, and a difference of 2% of the residual is a tie.
TOL_RMSE = 0.02


class _OnRecords:
    """fracid against the integer baseline on the records named in ``NAMES``: one subclass per half
    of the records. The suite runs with ``--dist loadscope`` (a class or a module to one worker),
    so the two halves run side by side, and a record's two tests share its baseline fit
    (``baseline_on_split``, the slowest part) in one process."""

    NAMES: tuple[str, ...] = ()

    def test_fracid_beats_integer_baseline(self, fracid_bin, name, request):
        pytest.importorskip("scipy")
        path = DATA / RECORDS[name][0]
        if not path.is_file():
            pytest.fail(f"{path} is missing: the real records ship with the repository in data/")
        if name in XFAIL:
            request.node.add_marker(pytest.mark.xfail(reason=XFAIL[name], strict=True))
        out, code = run_fracid(fracid_bin, path)
        assert out["model_is"].startswith("final"), out["model_is"]
        n_est, first, fr_nrmse, fr_rmse, kind = held_out(out)
        best, rows = baseline_on_split(name, n_est, first)
        table = ", ".join(
            f"order {r['order']} delay {r['delay_samples']}: {r['val_nrmse']:.2f}% / {r['val_rmse']:.4g}"
            for r in rows
        )
        assert code == 0 and fr_rmse <= best["val_rmse"] * (1.0 + TOL_RMSE), (
            f"{name} ({kind}): fracid held-out RMSE {fr_rmse:.4g} (NRMSE {fr_nrmse:.2f}%)"
            f"{exit_note(out, code)} vs integer baseline RMSE {best['val_rmse']:.4g} "
            f"(NRMSE {best['val_nrmse']:.2f}%); rows: {table}"
        )

    # With defaults (no flag: the loop closed) fracid's recommended model, scored on the same
    # held-out samples, is at least as good as the best integer baseline on every record but those
    # in XFAIL (the test above, 12 of 13); with --plain (the named structure fitted once) on every
    # record but those in XFAIL_PLAIN (this test). Measured with the loop closed (then
    # `--diagnose`): the records added 2026-12-05 (main e364c0a): low-speed PRBS 5.472 vs 5.769
    # deg/s (pmsm, the plain fit), closed speed profile 1.836 vs 1.801 (third order; within
    # TOL_RMSE, 1.9% above), TCLab PWM steps 0.3809 vs 1.509 degF (commensurate). Measured (held-out
    # RMSE, fracid --diagnose vs baseline, session 16): UNAL PRBS 2.978 vs 3.366 (integer second
    # order + delay chosen), closed-loop staircase 5.579 vs 5.581 (first order + delay), TCLab
    # 0.2628 K vs 0.2837 K (second order + initial_state: the record only looked at rest; 0.2796
    # with the third order in session 15, when the second order's start had a repeated pole and
    # failed), UNAL step tail 3.2141 vs 3.214 (second order), motor/generator 505.04 vs 511.8 (pmsm
    # + initial_state; 511.78 before session 19), flexible robot arm 0.0518 vs 0.1362 (the two-mass,
    # reduced to its determined terms in session 16; its start's fallback takes the negative gain
    # and the resonance peaks; 0.0900 before session 15, an integer second order + delay; the
    # baseline's second order without delay).
    def test_fracid_plain_against_integer_baseline(self, fracid_bin, name, request):
        pytest.importorskip("scipy")
        if name in XFAIL_PLAIN:
            request.node.add_marker(pytest.mark.xfail(reason=XFAIL_PLAIN[name], strict=True))
        out, code = run_fracid(fracid_bin, DATA / RECORDS[name][0], "--plain")
        assert out["model_is"].startswith("base"), out["model_is"]
        n_est, first, fr_nrmse, fr_rmse, kind = held_out(out)
        best, _ = baseline_on_split(name, n_est, first)
        assert code == 0 and fr_rmse <= best["val_rmse"] * (1.0 + TOL_RMSE), (
            f"{name} ({kind}): fracid --plain held-out RMSE {fr_rmse:.4g} (NRMSE {fr_nrmse:.2f}%)"
            f"{exit_note(out, code)} vs integer baseline RMSE {best['val_rmse']:.4g} "
            f"(NRMSE {best['val_nrmse']:.2f}%)"
        )


class TestRecordsEven(_OnRecords):
    NAMES = tuple(sorted(RECORDS)[0::2])


class TestRecordsOdd(_OnRecords):
    NAMES = tuple(sorted(RECORDS)[1::2])


def pytest_generate_tests(metafunc):
    """Each half's tests over its records."""
    cls = metafunc.cls
    if cls is not None and issubclass(cls, _OnRecords):
        metafunc.parametrize("name", cls.NAMES)


def test_zoh_matches_scipy():
    """The baseline's own discretisation agrees with scipy's (matrix exponential) for each order,
    with a complex pair and with real poles, to 1e-9 of the step response."""
    pytest.importorskip("scipy")
    from scipy.signal import cont2discrete, lfilter

    u = np.ones(3000)  # 30 s: 100 time constants of the slowest mode
    for order, p in [
        (1, [np.log(0.3)]),
        (2, [np.log(20.0), np.log(0.1)]),
        (2, [np.log(20.0), np.log(3.0)]),
        (3, [np.log(20.0), np.log(0.05), np.log(0.2)]),
    ]:
        den = _den(order, np.array(p))
        b, a = _zoh(2.5, den, 0.01)
        bs, as_, _ = cont2discrete(([2.5], den), 0.01, method="zoh")
        ours = lfilter(b, a, u)
        ref = lfilter(np.squeeze(bs), as_, u)
        assert np.max(np.abs(ours - ref)) < 1e-9 * 2.5, (order, p)
        # and the static gain is K
        assert ours[-1] == pytest.approx(2.5, rel=1e-3)  # the static gain is K


def test_baseline_recovers_a_known_first_order_with_delay():
    """The baseline against an analytic truth (not itself): a step at t = 1 s into
    ``2 exp(-0.3 s) / (1 + 0.5 s)`` sampled at 0.05 s, from rest at an output offset of 10, with
    Gaussian noise of 1% of the step (seeded). Gain within 2%, time constant within 5%, delay
    exactly 6 samples (0.3 s), the initial output 10 within 0.02, and the held-out RMSE at the
    noise level (< 0.03 for noise 0.02): a broken fit or discretisation
    fails here before it can flatter or wrong fracid on the real records."""
    pytest.importorskip("scipy")
    dt = 0.05
    t = np.arange(400) * dt
    u = (t >= 1.0).astype(float)
    tt = np.clip(t - 1.0 - 0.3, 0.0, None)
    y = 10.0 + 2.0 * (1.0 - np.exp(-tt / 0.5)) * (t >= 1.3)
    y = y + 0.02 * np.random.default_rng(29).standard_normal(t.size)
    # hold out the last 30% with the step inside the estimation part
    best, rows = integer_baseline(t, u, y, 280, 280, 10)
    first = rows[0]
    assert first["delay_samples"] == 6
    assert first["theta"][0] == pytest.approx(2.0, rel=0.02)
    assert np.exp(first["theta"][3]) == pytest.approx(0.5, rel=0.05)
    assert first["theta"][1] + first["theta"][0] * first["theta"][2] == pytest.approx(10.0, abs=0.02)
    # on a tail this flat the fit percentage is noise-bound; the RMSE is at the noise level
    assert first["val_rmse"] < 0.03
