"""Fractional transfer functions: construction, parsing, frequency response, simulation, PRBS."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import fracid

PAPER = "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)"


def test_parse_and_construct_agree():
    g = fracid.FracTf.parse(PAPER)
    h = fracid.FracTf([(6.77, 0.0)], [(1.0, 0.0), (0.0064, 0.89), (2.8e-5, 1.78)])
    assert g == h
    assert g.num == [(6.77, 0.0)]
    assert g.den == [(2.8e-5, 1.78), (0.0064, 0.89), (1.0, 0.0)]  # decreasing order
    assert g.delay == 0.0
    assert g.dc_gain() == pytest.approx(6.77, rel=1e-15)
    assert str(g) == PAPER
    assert fracid.FracTf.parse(str(g)) == g
    assert eval(repr(g), {"FracTf": fracid.FracTf}) == g
    assert pickle.loads(pickle.dumps(g)) == g
    d = g.to_dict()
    assert d["den"][1] == {"coef": 0.0064, "order": 0.89}
    # the reports' model object (`fracid time --json`'s `model`), field for field
    assert d == {
        "num": [{"coef": 6.77, "order": 0.0}],
        "den": [{"coef": 1.0, "order": 0.0}, {"coef": 0.0064, "order": 0.89}, {"coef": 2.8e-5, "order": 1.78}],
        "delay": 0.0,
        "text": PAPER,
        "effects": [],
    }


def test_pmsm_and_delay():
    g = fracid.FracTf.pmsm(6.82, 0.0059, 2.655e-5, 0.92, 0.8252)
    assert g.den[0][1] == pytest.approx(1.7452, abs=1e-12)
    gd = g.with_delay(0.001)
    assert gd.delay == 0.001
    w = np.array([10.0, 100.0])
    ratio = gd.freq_response(w) / g.freq_response(w)
    np.testing.assert_allclose(ratio, np.exp(-1j * w * 0.001), rtol=1e-12)
    parsed = fracid.FracTf.parse("2/(0.1 s + 1) * exp(-0.001 s)")
    assert parsed.delay == pytest.approx(0.001)


def test_freq_response_is_the_formula():
    g = fracid.FracTf.parse(PAPER)
    w = np.logspace(-1, 4, 50)
    jw = lambda a: w**a * np.exp(1j * a * np.pi / 2)  # noqa: E731
    expect = 6.77 / (2.8e-5 * jw(1.78) + 0.0064 * jw(0.89) + 1)
    np.testing.assert_allclose(g.freq_response(w), expect, rtol=1e-12)
    mag, ph = g.bode(w)
    np.testing.assert_allclose(mag, 20 * np.log10(np.abs(expect)), rtol=1e-12)
    np.testing.assert_allclose(ph, np.rad2deg(np.unwrap(np.angle(expect))), atol=1e-9)
    # lists work as well as arrays
    assert g.freq_response([1.0]).dtype == np.complex128


def test_bode_phase_is_unwrapped_through_a_delay():
    g = fracid.FracTf.parse("1/(0.01 s + 1)").with_delay(0.01)
    w = np.linspace(1, 2000, 400)
    _, ph = g.bode(w)
    assert np.all(np.diff(ph) < 0)  # monotonic, no +360 jumps
    assert ph[-1] < -1000


def test_step_response_against_mittag_leffler_oracle():
    # docs/design.md §3: K (1 - E_q(-t^q / a)), K = 6.77, a = 0.0064, q = 0.89
    g = fracid.FracTf.parse("6.77/(0.0064 s^0.89 + 1)")
    dt = 1e-5
    u = np.ones(3001)
    oracle = {100: 1.958077, 300: 3.943589, 1000: 6.018918, 3000: 6.615241}
    # Grunwald-Letnikov at the samples (first order in dt), and with the input held over each
    # sample (dt/10 and dt/20, Richardson-extrapolated), as `simulate` runs it.
    y_gl = fracid.gl_simulate(g, u, dt)
    y_held = g.simulate(u, dt, method="gl")
    # refined Oustaloup over the default band (relative to the step: [0.1, 9.4e6] rad/s at 10 us),
    # exact for the held step: measured 2.2e-4 of the oracle at 10 ms and 3.3e-4 at 30 ms (below
    # 2e-4 with the absolute band of sessions 1-13, whose low edge 1e-3 rad/s made the fit depend
    # on the time unit; the relative band's low edge is 2.5 decades below 1/t here)
    y_default = g.simulate(u, dt)
    y_ou = g.simulate(u, dt, method="oustaloup", order=10)
    for k, v in oracle.items():
        assert y_gl[k] == pytest.approx(v, rel=1e-2), k
        assert y_held[k] == pytest.approx(v, rel=1e-4), k
        assert y_default[k] == pytest.approx(v, rel=5e-4), k
        assert y_ou[k] == pytest.approx(v, rel=1e-3), k


def test_simulate_options():
    g = fracid.FracTf.parse("1/(0.1 s + 1)")
    u = np.ones(2000)
    # Exact for a held step: 1 - exp(-t/0.1) at every sample.
    y = g.simulate(u, 1e-3)
    t = np.arange(u.size) * 1e-3
    np.testing.assert_allclose(y, 1.0 - np.exp(-t / 0.1), rtol=0, atol=1e-12)
    y = g.simulate(u, 1e-3, method="trigeassou", band=(1e-2, 1e5), order=6)
    assert y[-1] == pytest.approx(1.0, abs=1e-3)


def test_prbs():
    u = fracid.prbs(dt=1e-3, order=7, clock=0.003, periods=2)
    assert u.shape == (2 * 127 * 3,)
    assert set(np.unique(u)) == {-1.0, 1.0}
    np.testing.assert_array_equal(u[: 127 * 3], u[127 * 3 :])  # periodic
    v = fracid.prbs(dt=1e-3, amplitude=0.5, offset=2.0)
    assert set(np.unique(v)) == {1.5, 2.5}
    # a maximum-length sequence has one more 1 than 0 per period
    bits = u[: 127 * 3 : 3] > 0
    assert bits.sum() == 64
