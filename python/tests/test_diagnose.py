"""Residual diagnosis from Python (docs/design.md §6): a hidden input delay is found, named and
sized; clean data get no effect."""

from __future__ import annotations

import json

import numpy as np
import pytest

import fracid

DT = 2e-3
N = 3000
# corners near 15 and 45 rad/s, well inside the record's band
TRUTH = fracid.FracTf.parse("2/(0.004 s^1.7 + 0.1 s^0.85 + 1)")


def record(delay: float, seed: int):
    u = fracid.prbs(dt=DT, order=7, clock=0.02, periods=3)[:N]
    y = TRUTH.with_delay(delay).simulate(u, DT)
    rng = np.random.default_rng(seed)
    return u, y + 0.02 * y.std() * rng.standard_normal(y.size)


def test_hidden_delay_is_found():
    tau = 0.012  # 6 samples
    u, y = record(tau, seed=2)
    fit = fracid.fit_time(u, y, DT, "commensurate", offsets="none", diagnose=True)
    d = fit.diagnosis
    assert d is not None
    assert d.names == ["delay"], d.effects
    assert d.effects[0].params["tau"] == pytest.approx(tau, rel=0.2)
    assert d.after.rmse < 0.95 * d.before.rmse
    assert d.validation is not None
    assert d.validation["after"].rmse < d.validation["before"].rmse
    assert d.model.delay == pytest.approx(d.effects[0].params["tau"], rel=1e-9)
    assert "exp(-" in d.final_model
    assert d.effects[0].ssr_removed_percent > 0.0
    s = d.structures
    assert s is not None and 0 <= s["chosen"] < len(s["scores"])
    assert s["scores"][0]["name"] == "commensurate"
    assert s["scores"][s["chosen"]]["effects"] == ["delay"]
    assert d.yhat_after.shape == y.shape
    j = json.loads(json.dumps(fit.to_dict()))
    assert j["diagnosis"]["effects"][0]["name"] == "delay"
    assert {"before", "after", "effects", "unexplained"} <= set(j["diagnosis"])


def test_clean_data_add_nothing():
    u, y = record(0.0, seed=1)
    d = fracid.diagnose(u, y, DT, "commensurate", offsets="none")
    assert d.effects == []
    assert d.after == d.before
