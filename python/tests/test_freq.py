"""The frequency-domain fit from Python: the paper's Table 1 numbers (docs/design.md §4)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import fracid

REL = 5e-3  # 0.5% on coefficients, as the reference values are printed to 4-5 digits


def test_load_bode_reads_table1(table1):
    omega, h = fracid.load_bode(table1)
    assert omega.shape == h.shape and omega.size >= 10
    assert np.all(np.diff(omega) > 0)
    assert np.iscomplexobj(h)


def test_levy_at_q_089_matches_reference(table1):
    omega, h = fracid.load_bode(table1)
    fit = fracid.fit_bode(omega, h, q=0.89)
    assert fit.levy.q == 0.89
    assert fit.levy.b[0] == pytest.approx(6.7853, rel=REL)
    assert fit.levy.a[0] == pytest.approx(6.632e-3, rel=REL)
    assert fit.levy.a[1] == pytest.approx(2.5906e-5, rel=REL)
    assert fit.levy.J == pytest.approx(3.675e-3, rel=1e-2)
    # the model object agrees with the coefficients
    assert fit.levy.model.dc_gain() == pytest.approx(fit.levy.b[0], rel=1e-12)
    assert fracid.error_index(omega, h, fit.levy.model) == pytest.approx(fit.levy.J, rel=1e-12)


def test_grid_best_q_is_091(table1):
    omega, h = fracid.load_bode(table1)
    fit = fracid.fit_bode(omega, h, refine_q=False)
    assert fit.levy_grid.q == pytest.approx(0.91, abs=1e-9)
    assert fit.levy_grid.J == pytest.approx(3.555e-3, rel=1e-2)
    assert fit.levy_grid.b[0] == pytest.approx(6.7832, rel=REL)
    assert fit.levy_grid.a[0] == pytest.approx(6.208e-3, rel=REL)
    assert fit.levy_grid.a[1] == pytest.approx(1.9176e-5, rel=REL)
    # J(q) on the 0.01 grid over (0, 1]: its minimum is the grid best
    assert fit.curve.q.shape == (100,)
    assert fit.curve.q[np.nanargmin(fit.curve.J)] == pytest.approx(0.91)


def test_refinements_lower_j(table1):
    omega, h = fracid.load_bode(table1)
    fit = fracid.fit_bode(omega, h, refine=True, sk_iterations=5)
    assert fit.levy.J <= fit.levy_grid.J + 1e-15  # golden-section refinement around the grid best
    assert fit.refined is not None and fit.sk is not None
    # the two-order refit reaches J of about 1.9e-3 (docs/design.md §4)
    assert fit.refined.J == pytest.approx(1.9e-3, rel=0.05)
    assert fit.J == min(fit.levy.J, fit.sk.J, fit.refined.J)
    assert 0 < fit.refined.zeta < 2 and 0 < fit.refined.theta < 2
    d = fit.to_dict()
    json.dumps(d)  # plain types throughout
    assert d["levy"]["model"]["num"][0]["order"] == 0.0
    assert set(d) >= {"levy", "levy_grid", "curve", "sk", "refined", "best_model"}


def test_weights_options(table1):
    omega, h = fracid.load_bode(table1)
    vin = fracid.fit_bode(omega, h, q=0.89)
    # explicit Vinagre weights (paper eq. 29) give the same fit
    w = np.empty_like(omega)
    w[0] = (omega[1] - omega[0]) / (2 * omega[0] ** 2)
    w[1:-1] = (omega[2:] - omega[:-2]) / (2 * omega[1:-1] ** 2)
    w[-1] = (omega[-1] - omega[-2]) / (2 * omega[-1] ** 2)
    per = fracid.fit_bode(omega, h, q=0.89, weights=w)
    assert per.levy.b[0] == pytest.approx(vin.levy.b[0], rel=1e-9)
    uni = fracid.fit_bode(omega, h, q=0.89, weights="uniform")
    assert uni.levy.b[0] != pytest.approx(vin.levy.b[0], rel=1e-6)


def test_exact_data_are_recovered():
    truth = fracid.FracTf.pmsm(3.0, 0.05, 0.002, 0.8, 0.8)
    omega = np.logspace(-1, 3, 30)
    fit = fracid.fit_bode(omega, truth.freq_response(omega))
    assert fit.levy.q == pytest.approx(0.8, abs=1e-3)
    assert fit.levy.J < 1e-10


def test_an_unstable_fit_is_flagged_and_sk_stops_when_converged(table1):
    # random gains and phases (issue 12: `freq` returned an unstable model without a word)
    rng = np.random.default_rng(12)
    omega = 2 * np.pi * np.logspace(-1, 2, 20)
    h = 10 ** (rng.normal(0, 10, 20) / 20) * np.exp(1j * rng.uniform(-np.pi, np.pi, 20))
    fit = fracid.fit_bode(omega, h)
    a1, a2 = fit.levy.a
    roots = np.roots([a2, a1, 1.0])  # Matignon: unstable when |arg| < q pi/2
    n_unstable = int(np.sum(np.abs(np.angle(roots)) < fit.levy.q * np.pi / 2))
    # a table of noise is never usable: unstable, or fitting too little of the response
    assert not fit.usable
    if n_unstable:
        assert f"unstable: {n_unstable} pole(s)" in fit.problems[0]
    # the paper's table: usable; SK stops before the 200 allowed and says so
    omega, h = fracid.load_bode(table1)
    fit = fracid.fit_bode(omega, h, q=0.9, sk_iterations=200)
    assert fit.usable and fit.problems == []
    assert fit.sk.sk_converged and 1 <= fit.sk.sk_iterations < 200
    json.dumps(fit.to_dict())


def test_the_answer_is_the_best_model_by_the_librarys_rule(table1):
    # Table 1 without weights: the Sanathanan-Koerner fit beats Levy's, and the result's answer
    # (what fracid.tune takes from it, as `fracid tune` from the report) is it, not Levy's
    omega, h = fracid.load_bode(table1)
    fit = fracid.fit_bode(omega, h, weights="none", sk_iterations=10)
    assert fit.sk.J < fit.levy.J
    assert str(fit.answer) == str(fit.best_model) == str(fit.sk.model) != str(fit.levy.model)
    r = fracid.tune(fit, wc=300, pm=60)
    assert r["model"]["text"] == fit.report["sk"]["model"]["text"]
