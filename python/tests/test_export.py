"""Export of the approximated model as a state space: scipy.signal (dlsim) and python-control
(forced_response) simulate the exported discrete model exactly as fracid's own simulation does
(the same exact zero-order-hold discretisation, independently run), to 1e-6 relative."""

from __future__ import annotations

import json

import numpy as np
import pytest

import fracid

PMSM = "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)"
DT = 1e-4
# 1e-6 of the output's peak: the two recursions differ only by rounding (about 1e-12 measured),
# the tolerance leaves room for BLAS summation orders, not for a discretisation error (which
# would show at 1e-3 or more: a bilinear or sampled-point map is that far off at this step).
REL = 1e-6

MODELS = [
    PMSM,
    "6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)",
    # a delay of 2.5 samples: two whole-sample states and one for the fraction
    "6.77/(0.0064 s^0.89 + 1) exp(-0.00025 s)",
    "(0.3 s^0.5 + 2)/(0.01 s^1.3 + 0.2 s^0.6 + 1)",
]


def _input(n_periods: int = 1) -> np.ndarray:
    u = fracid.prbs(dt=DT, order=7, clock=0.003, periods=n_periods)
    return u + 0.2 * np.sin(np.arange(u.size) * 0.01)


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(np.ravel(a) - np.ravel(b))) / np.max(np.abs(b)))


def test_unpacks_to_numpy_matrices():
    ss = fracid.FracTf.parse(PMSM).to_state_space(DT)
    a, b, c, d = ss
    n = ss.n_states
    assert a.shape == (n, n) and b.shape == (n, 1) and c.shape == (1, n) and d.shape == (1, 1)
    assert ss.discrete and ss.dt == DT and ss.method == "refined" and ss.order == 8
    assert n >= 30  # two operators of 17 cells each (the refined method adds its own)
    # discrete and stable: every eigenvalue inside the unit circle
    assert np.max(np.abs(np.linalg.eigvals(a))) < 1.0
    d_ = ss.to_dict()
    assert json.loads(json.dumps(d_))["states"] == n


@pytest.mark.parametrize("model", MODELS)
def test_scipy_dlsim_agrees_with_fracid(model):
    signal = pytest.importorskip("scipy.signal")
    g = fracid.FracTf.parse(model)
    u = _input()
    want = g.simulate(u, DT)
    sys = g.to_state_space(DT).to_scipy()
    assert isinstance(sys, signal.dlti) and sys.dt == DT
    _, y, _ = signal.dlsim(sys, u)
    assert _rel(y, want) < REL


@pytest.mark.parametrize("model", MODELS)
def test_control_forced_response_agrees_with_fracid(model):
    control = pytest.importorskip("control")
    g = fracid.FracTf.parse(model)
    u = _input()
    want = g.simulate(u, DT)
    sys = g.to_state_space(DT).to_control()
    assert isinstance(sys, control.StateSpace) and sys.dt == DT
    resp = control.forced_response(sys, U=u)
    assert _rel(resp.outputs, want) < REL


def test_other_approximations_agree_too():
    signal = pytest.importorskip("scipy.signal")
    g = fracid.FracTf.parse(PMSM)
    u = _input()
    for method, order, band in [("oustaloup", 5, None), ("trigeassou", 6, (1e-2, 1e5))]:
        want = g.simulate(u, DT, method=method, band=band, order=order)
        ss = g.to_state_space(DT, method=method, band=band, order=order)
        _, y, _ = signal.dlsim(ss.to_scipy(), u)
        assert _rel(y, want) < REL, method


def test_continuous_model_is_the_fractional_one_in_band():
    signal = pytest.importorskip("scipy.signal")
    g = fracid.FracTf.parse(PMSM)
    ss = g.to_state_space(band=(1e-3, 1e6))
    assert not ss.discrete and ss.dt is None
    w = np.logspace(0, 4, 30)
    sys = ss.to_scipy()
    assert isinstance(sys, signal.StateSpace) and sys.dt is None
    # C (jw I - A)^-1 B + D by a linear solve (scipy's freqresp goes through polynomials)
    a, b, c, d = ss
    eye = np.eye(ss.n_states)
    h = np.array([(c @ np.linalg.solve(1j * x * eye - a, b) + d)[0, 0] for x in w])
    exact = g.freq_response(w)
    # Refined Oustaloup, N = 8, two decades and more inside the band: within 0.5 % of the exact
    # fractional response (measured worst 1e-4 or so); an error in the realisation would be O(1).
    assert np.max(np.abs(h - exact) / np.abs(exact)) < 5e-3


def test_delays_and_bad_requests():
    # No scipy needed: a delayed continuous model is refused before scipy is imported (the
    # request is checked first), so this holds where scipy is not installed.
    g = fracid.FracTf.parse("1/(0.1 s + 1) exp(-0.02 s)")
    ss = g.to_state_space(band=(1e-2, 1e4))
    assert ss.input_delay == 0.02
    with pytest.raises(fracid.DataError, match="input delay"):
        ss.to_scipy()
    disc = g.to_state_space(1e-3)
    assert disc.delay_states == 20 and disc.input_delay == 0.0
    with pytest.raises(fracid.DataError, match="band"):
        g.to_state_space()
    with pytest.raises(fracid.DataError):
        g.to_state_space(-1.0)
    with pytest.raises(fracid.DataError):
        g.to_state_space(band=(10.0, 1.0))
