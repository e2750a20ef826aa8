"""``fracid.autotune``: the library's autotune (``autotune::tuner::run``) from Python, on the
drive simulator in real time with a hidden Coulomb friction at the identification's operating
point (settings used by no other test)."""

import fracid
import pytest


def test_request_defaults_are_the_library_s():
    d = fracid.autotune_request_defaults()
    assert d["u_limit_v"] == 12.0 and d["speed_limit_rad_s"] == 200.0 and d["budget_s"] == 20.0
    assert d["wc"] is None and d["max_rounds"] == 3


def test_unknown_option_is_refused():
    with pytest.raises(fracid.DataError):
        fracid.autotune("/dev/null", u_limit=3.0)


def test_autotune_separates_friction_and_measures_the_step():
    with fracid.DriveSimulator(coulomb_v=0.42, noise_std=0.025, seed=31) as s:
        r = fracid.autotune(s.port, keepalive_ms=50, budget_s=12.0)
    assert r["usable"], r["problems"]
    names = [a["name"] for a in r["rounds"][0]["ambiguous"]]
    assert "coulomb_friction" in names
    assert any(x["experiment"] == "reversals" for x in r["rounds"])
    # the paper's PMSM (the simulator's default model): the friction comes out 16% low there
    # (0.354 V for 0.42 V measured in real time), within 15% on the must-show's plant (Rust test)
    vc = r["model"]["friction_v"]
    assert vc is not None and abs(vc - 0.42) <= 0.25 * 0.42, vc
    c = r["control"]
    assert abs(c["predicted"]["overshoot_percent"] - c["measured"]["overshoot_percent"]) <= 3.0
