"""The Python bindings agree with the Rust CLI (`fracid`) on the same models and data."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

import fracid

PAPER_FREQ = "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)"
PAPER_TIME = "6.82/(0.00002655 s^1.7452 + 0.0059 s^0.92 + 1)"


def run(binary, *args) -> str:
    p = subprocess.run([str(binary), *map(str, args)], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, f"fracid {' '.join(map(str, args))}: exit {p.returncode}\n{p.stderr}"
    return p.stdout


def test_frequency_response_agrees_with_cli(fracid_bin, tmp_path):
    """Python writes the exact response of one model as Bode data (rad/s, linear gain, radians,
    printed with repr so nothing is lost); the CLI scores that model and another against it
    (`fracid freq --compare`): J of the model itself is zero to rounding, J of the other equals
    Python's error index computed from Python's frequency response."""
    g = fracid.FracTf.parse(PAPER_FREQ)
    other = fracid.FracTf.parse(PAPER_TIME)
    omega = np.logspace(-1, 4, 40)
    h = g.freq_response(omega)
    path = tmp_path / "bode.csv"
    with open(path, "w") as f:
        f.write("omega_rad_s,gain,phase_rad\n")
        for w, z in zip(omega, h):
            f.write(f"{float(w)!r},{float(abs(z))!r},{float(np.angle(z))!r}\n")
    out = json.loads(
        run(fracid_bin, "freq", path, "--rad-s", "--linear-gain", "--radians", "--q", "0.89",
            "--compare", g, "--compare", other, "--json")
    )
    j_self, j_other = (c["J"] for c in out["compare"])
    scale = float(np.mean(np.abs(h) ** 2))
    assert j_self < 1e-24 * scale
    j_py = float(np.mean(np.abs(h - other.freq_response(omega)) ** 2))
    assert j_other == pytest.approx(j_py, rel=1e-10)
    assert fracid.error_index(omega, h, other) == pytest.approx(j_py, rel=1e-12)
    # the CLI's fit at q = 0.89 of exact data recovers the model; Python's fit agrees with it
    py = fracid.fit_bode(omega, h, q=0.89)
    assert out["levy"]["b"] == pytest.approx(py.levy.b, rel=1e-9)
    assert out["levy"]["a"] == pytest.approx(py.levy.a, rel=1e-9)
    assert py.levy.b[0] == pytest.approx(6.77, rel=1e-9)


def test_table1_fit_agrees_with_cli(fracid_bin, table1):
    out = json.loads(run(fracid_bin, "freq", table1, "--no-q-refine", "--json"))
    omega, h = fracid.load_bode(table1)
    py = fracid.fit_bode(omega, h, refine_q=False)
    assert out["q"] == pytest.approx(py.levy.q, abs=1e-12)
    assert out["J"] == pytest.approx(py.levy.J, rel=1e-9)
    assert out["levy"]["b"] == pytest.approx(py.levy.b, rel=1e-9)
    assert out["levy"]["a"] == pytest.approx(py.levy.a, rel=1e-9)
    cli_den = [(t["coef"], t["order"]) for t in out["model"]["den"]]
    assert np.allclose(cli_den, py.levy.model.den, rtol=1e-9, atol=0)


def test_step_response_agrees_with_cli(fracid_bin, tmp_path):
    path = tmp_path / "step.csv"
    run(fracid_bin, "sim", "--model", PAPER_FREQ, "--step", "--dt", "1e-4", "--t-end", "0.05",
        "-o", path)
    lines = [ln for ln in path.read_text().splitlines() if ln and not ln.startswith("#")]
    assert lines[0] == "t,u,y"
    data = np.genfromtxt(lines, delimiter=",", names=True)
    g = fracid.FracTf.parse(PAPER_FREQ)
    y = g.simulate(data["u"], 1e-4)
    np.testing.assert_allclose(y, data["y"], rtol=1e-12, atol=1e-12)


def test_time_fit_agrees_with_cli(fracid_bin, tmp_path):
    """The same record and options give the same model from `fracid time` and `fit_time`: one
    data layer, one set of presets and defaults (operating point, initial state, holdout). The
    record starts in motion (the plant was driven at 8 V before it), so the initial-state
    estimate is exercised. Agreement to 1e-6 relative: the same code runs, only the text round
    trip of the data (printed with repr) stands between them."""
    g = fracid.FracTf.parse(PAPER_TIME)
    dt = 1e-3
    rng = np.random.default_rng(5)
    bits = np.repeat(rng.integers(0, 2, 120) * 6.0 - 3.0, 10)
    u = np.concatenate([np.full(300, 8.0), 8.0 + bits])
    y = g.simulate(u, dt) + rng.normal(0.0, 0.05, u.size)
    u, y = u[300:], y[300:]
    path = tmp_path / "rec.csv"
    with open(path, "w") as f:
        f.write("t,u,y\n")
        for k in range(u.size):
            f.write(f"{k * dt!r},{float(u[k])!r},{float(y[k])!r}\n")
    cli = json.loads(run(fracid_bin, "time", path, "--json", "--quiet"))
    py = fracid.fit_time(u, y, dt, "pmsm")
    for p in cli["params"]:
        assert py.param(p["name"]).value == pytest.approx(p["value"], rel=1e-6, abs=1e-9), p["name"]
    assert py.validation.nrmse_percent == pytest.approx(
        cli["fit"]["validation"]["nrmse_percent"], rel=1e-6
    )
    assert py.usable and cli["usable"]
