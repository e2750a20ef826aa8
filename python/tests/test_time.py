"""Time-domain round trips: simulate a known model with fracid, add seeded noise, fit, compare."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

import fracid

DT = 1e-4  # the model's corners (~150 and 650 rad/s) far below the sampling frequency

# The structures every comparison fits (`structure="auto"`), in the catalogue's order and words.
COMPARED = ["pmsm", "commensurate", "first-order", "second-order", "third-order", "two-mass"]


def record(model: fracid.FracTf, noise: float, seed: int):
    """4 periods of the paper's PRBS (order 7, 3 ms clock); noise as a fraction of std(y)."""
    u = fracid.prbs(dt=DT, order=7, clock=0.003, periods=4)
    y = model.simulate(u, DT)
    rng = np.random.default_rng(seed)
    return u, y + noise * y.std() * rng.standard_normal(y.size)


def test_commensurate_round_trip():
    truth = fracid.FracTf.parse("6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)")
    u, y = record(truth, 0.01, seed=7)
    fit = fracid.fit_time(u, y, DT, "commensurate", offsets="none", fit_offset=False)
    v = fit.values
    assert v["K"] == pytest.approx(6.77, rel=0.01)
    assert v["a1"] == pytest.approx(0.0064, rel=0.05)
    assert v["a2"] == pytest.approx(2.8e-5, rel=0.10)
    assert v["q"] == pytest.approx(0.89, abs=0.015)
    assert fit.converged
    assert fit.validation is not None and fit.validation.nrmse_percent > 98.0
    assert fit.estimation.nrmse_percent > 98.0
    for p in fit.params:
        if p.name.startswith("u_past"):
            continue  # the record's initial state (at rest here), not the plant
        assert p.free and p.std_error is not None and 0 < p.std_error < 0.05 * abs(p.value)
    assert fit.model.den[0][1] == pytest.approx(2 * v["q"], rel=1e-12)
    assert fit.yhat.shape == y.shape
    assert fit.split == int(round(0.7 * y.size)) or abs(fit.split - 0.7 * y.size) <= 1


def test_general_model_round_trip_and_to_dict():
    truth = fracid.FracTf.parse("6.77/(0.0064 s^0.89 + 1)")
    u, y = record(truth, 0.01, seed=11)
    start = fracid.FracTf.parse("5/(0.01 s^0.7 + 1)")
    fit = fracid.fit_time(u, y, DT, start, offsets="none", fit_offset=False)
    g = fit.model
    assert g.dc_gain() == pytest.approx(6.77, rel=0.01)
    (coef, order), _ = g.den
    assert coef == pytest.approx(0.0064, rel=0.05)
    assert order == pytest.approx(0.89, abs=0.01)
    d = fit.to_dict()
    s = json.dumps(d)
    assert '"nrmse_percent"' in s
    assert d["model"]["num"][0]["order"] == 0.0
    assert isinstance(d["yhat"], list) and len(d["yhat"]) == y.size
    assert {p["name"] for p in d["params"]} >= {"b0", "a0", "a0_order"}


def test_operating_point_and_offset():
    truth = fracid.FracTf.parse("6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)")
    # at rest at u = 2 (y = 2 K) for 50 ms, then the PRBS around it
    prbs = fracid.prbs(dt=DT, periods=4)
    u = np.concatenate([np.zeros(500), prbs]) + 2.0
    y = truth.simulate(u - 2.0, DT) + 2.0 * 6.77
    y += 0.01 * y.std() * np.random.default_rng(3).standard_normal(y.size)
    fit = fracid.fit_time(u, y, DT, "commensurate")
    assert fit.offsets["u0"] == 2.0
    assert fit.offsets["y0"] == pytest.approx(2 * 6.77, abs=0.05)
    assert fit.param("K").value == pytest.approx(6.77, rel=0.01)
    assert fit.param("y_offset").value == pytest.approx(0.0, abs=0.05)
    assert fit.validation.nrmse_percent > 98.0
    with pytest.raises(KeyError):
        fit.param("zeta")


def test_a_step_at_the_first_sample_is_fitted_from_rest():
    """A step test as a lab writes it (the input at its level from the first sample, the output
    rising from rest): fitted with defaults, validated on the tail of the response, and the
    static gain is the analytic one (a first-order lag 2/(0.01 s + 1), noise 1% of the step)."""
    dt = 1e-4
    t = np.arange(2000) * dt
    u = np.ones_like(t)
    rng = np.random.default_rng(3)
    y = 2.0 * (1.0 - np.exp(-t / 0.01)) + 0.02 * rng.standard_normal(t.size)
    fit = fracid.fit_time(u, y, dt)
    assert fit.usable, fit.problems
    assert fit.validated_by["kind"] == "response_tail"
    assert "--validate" in fit.validated_by["note"]
    assert fit.offsets == {"u0": 0.0, "y0": y[0]}
    assert fit.model.dc_gain() == pytest.approx(2.0, rel=0.02)
    assert any("step at the first sample" in w for w in fit.warnings)


def test_structure_auto_matches_the_cli(fracid_bin):
    """``structure="auto"`` runs the same comparison as ``fracid time --structure auto`` and
    reports the same choice and model (the UNAL PRBS record, a real DC motor)."""
    import subprocess
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "data" / "unal_dcmotor" / "DCmotor_prbs_open_exp.csv"
    rows = np.loadtxt(path, delimiter=",", skiprows=1)
    t, u, y = rows[:, 0], rows[:, 1], rows[:, 2]
    # The comparison alone (``plain``): the default would diagnose its choice as well.
    fit = fracid.fit_time(u, y, float(np.mean(np.diff(t))), "auto", plain=True)
    cli = json.loads(
        subprocess.run(
            [str(fracid_bin), "time", str(path), "--structure", "auto", "--plain", "--json",
             "--quiet"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout
    )
    assert fit.structures is not None
    assert fit.structures["chosen"] == cli["structures"]["chosen"]
    names = [r["name"] for r in fit.structures["scores"]]
    assert names == COMPARED
    assert fit.validation.rmse == pytest.approx(cli["fit"]["validation"]["rmse"], rel=1e-9)


def test_ctrl_c_stops_a_diagnosis_between_stages():
    """Ctrl-C (here SIGALRM raising KeyboardInterrupt, 2 ms into the call) reaches a fit running
    with the GIL released: the use case's observer runs Python's signal handlers between stages
    and the KeyboardInterrupt comes out of `fit_time`, instead of the whole diagnosis (about a
    second on this record) running to its end."""
    import signal
    import time

    truth = fracid.FracTf.parse("6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)")
    u, y = record(truth, 0.01, seed=3)
    u, y = np.tile(u, 8), np.tile(y, 8)

    def interrupt(*_):
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGALRM, interrupt)
    try:
        t0 = time.perf_counter()
        signal.setitimer(signal.ITIMER_REAL, 0.002)
        with pytest.raises(KeyboardInterrupt):
            fracid.fit_time(u, y, DT, diagnose=True)
        stopped = time.perf_counter() - t0
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    # the whole diagnosis, for comparison: the interrupted call ended well before it would have
    t0 = time.perf_counter()
    fracid.fit_time(u, y, DT, diagnose=True)
    whole = time.perf_counter() - t0
    assert stopped < 0.5 * whole, (stopped, whole)


def test_a_joint_fit_of_noise_is_not_usable():
    # two records of pure noise fitted jointly: the report says so (as `fracid time --joint`
    # exits 1), where it had neither `usable` nor `problems`
    rng = np.random.default_rng(7)
    u = np.repeat(rng.choice([-1.0, 1.0], 100), 20)
    y1, y2 = rng.normal(0, 0.3, u.size), rng.normal(0, 0.3, u.size)
    r = fracid.fit_time_joint(u, y1, 1e-3, joint=[(u, y2)])
    assert r["usable"] is False and r["problems"], r["problems"]


def test_structures_are_one_catalogue_with_its_spellings():
    """`fracid.structures()` is the library's catalogue (the names `fracid time --structure` takes
    and the comparison's rows print): the docstring of `fit_time` names every one, another
    spelling of a name is sent as the name, and a word that is no structure is a DataError with
    the library's words (no position in a JSON the user never wrote)."""
    names = list(fracid.structures())
    assert names == COMPARED + ["feedthrough", "fopdt", "cell"]
    assert all(f'"{n}"' in (fracid.fit_time.__doc__ or "") for n in names)
    truth = fracid.FracTf.parse("2/(0.0001 s^2 + 0.01 s + 1)")
    u, y = record(truth, 0.01, seed=5)
    fit = fracid.fit_time(u, y, DT, "Second order", offsets="none", fit_offset=False)
    assert fit.report["request"]["structure"] == "second-order"
    assert fit.values["K"] == pytest.approx(2.0, rel=0.01)
    with pytest.raises(fracid.DataError, match="structure 'arx' is not pmsm, commensurate, first-order") as e:
        fracid.fit_time(u, y, DT, "arx")
    assert "line 1" not in str(e.value)
    for name, word, says in [
        ("offsets", "median", "offsets 'median' must be initial, mean or none"),
        ("initial", "past", "initial state 'past' must be auto, estimate or rest"),
        ("approx", "pade", "'pade' (expected oustaloup, refined or trigeassou)"),
        ("fix", "K=abc", "fix 'K=abc': 'abc' is not a number"),
    ]:
        with pytest.raises(fracid.DataError, match=re.escape(says)):
            fracid.fit_time(u, y, DT, **{name: word})
