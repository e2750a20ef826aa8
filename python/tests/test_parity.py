"""One use case under the CLI and Python (issue 30): the same request, fed to `fracid time --json`
and to `fracid.fit_time`, gives the same report, field by field, for every option.

The CLI reads the record from a file written with repr (nothing lost); Python gets the arrays.
Both parse their options into `ident::app::time::TimeRequest` and call `ident::app::time::run`,
so the reports must agree to the last digit: numbers are compared to 1e-9 relative (the time
column's text round trip is the only difference), everything else exactly. Only `seconds` (wall
time) and the validation record's name (a path for the CLI) differ by nature.
"""

from __future__ import annotations

import json
import math
import subprocess

import numpy as np
import pytest

import fracid

PAPER = "6.82/(0.00002655 s^1.7452 + 0.0059 s^0.92 + 1)"
DT = 1e-3

# Every request option and the `fracid time` flag that sets it (a bool: the flag alone; the
# two defaults-true options by their negation).
FLAGS = {
    "structure": "--structure",
    "approx": "--approx",
    "band": "--band",
    "order": "--order",
    "integrator": "--integrator",
    "delay": "--delay",
    "max_delay": "--max-delay",
    "fix": "--fix",
    "free": "--free",
    "start": "--start",
    "auto_start": "--no-auto-start",
    "holdout": "--holdout",
    "offsets": "--offsets",
    "fit_offset": "--no-offset",
    "initial": "--initial",
    "max_iterations": "--max-iter",
    "skip": "--skip",
    "max_lag": "--max-lag",
    "plain": "--diagnose",
    "margin": "--margin",
    "min_r2": "--min-r2",
    "max_rounds": "--max-rounds",
}

# Option sets that together set every option away from its default.
CASES = {
    "defaults": {},
    "approximation_and_split": {
        "structure": "commensurate",
        "approx": "oustaloup",
        "band": (1e-2, 1e4),
        "order": 6,
        "holdout": 0.25,
        "offsets": "mean",
        "fit_offset": False,
        "initial": "rest",
        "max_iterations": 40,
        "skip": 5,
        "max_lag": 10,
    },
    "delay_fix_start": {
        "delay": True,
        "max_delay": 0.02,
        "fix": "theta=0.85",
        "free": "zeta",
        "start": {"K": 6.0, "a1": 0.005, "a2": 3e-5},
        "auto_start": False,
    },
    "diagnose": {"plain": False, "margin": 0.08, "min_r2": 0.01, "max_rounds": 2},
    "auto": {"structure": "auto"},
    "integrator": {"integrator": True, "max_iterations": 30},
}


def cli_args(options: dict) -> list:
    args = []
    for name, value in options.items():
        flag = FLAGS[name]
        if name in ("auto_start", "fit_offset", "plain"):
            assert value is False
            args.append(flag)
        elif isinstance(value, bool):
            assert value is True
            args.append(flag)
        elif name == "band":
            args += [flag, f"{value[0]!r},{value[1]!r}"]
        elif name == "start":
            args += [flag, ",".join(f"{k}={v!r}" for k, v in value.items())]
        else:
            args += [flag, str(value)]
    return args


def record(seed: int, n: int = 1500):
    """The paper's PMSM driven by a PRBS from motion (8 V before the record), with a 3 ms delay
    nobody declared and measurement noise."""
    g = fracid.FracTf.parse(PAPER).with_delay(0.003)
    rng = np.random.default_rng(seed)
    bits = np.repeat(rng.integers(0, 2, n // 10 + 30) * 6.0 - 3.0, 10)
    u = np.concatenate([np.full(300, 8.0), 8.0 + bits[:n]])
    y = g.simulate(u, DT) + rng.normal(0.0, 0.05, u.size)
    return u[300:], y[300:]


def write(path, u, y):
    with open(path, "w") as f:
        f.write("t,u,y\n")
        for k in range(u.size):
            f.write(f"{k * DT!r},{float(u[k])!r},{float(y[k])!r}\n")


def same(a, b):
    """`a` and `b` equal field by field: numbers to 1e-9 relative, the rest exactly."""
    same_to(a, b, rel=1e-9)


def test_every_request_option_has_a_cli_flag():
    assert set(fracid.time_request_defaults()) == set(FLAGS)
    covered = {k for case in CASES.values() for k in case}
    assert covered == set(FLAGS), set(FLAGS) - covered


def test_an_unknown_option_is_refused():
    with pytest.raises(fracid.DataError, match="no option 'holdot'"):
        fracid.time_request(holdot=0.2)


@pytest.mark.parametrize("case", sorted(CASES))
def test_cli_and_python_give_the_same_report(fracid_bin, tmp_path, case):
    options = CASES[case]
    u, y = record(7)
    path = tmp_path / "rec.csv"
    write(path, u, y)
    p = subprocess.run(
        [str(fracid_bin), "time", str(path), "--json", "--quiet", *cli_args(options)],
        capture_output=True, text=True, timeout=300,
    )
    # exit 1 is an unusable model (the integrator on a record that does not integrate): the
    # report is still printed, and Python returns it with usable False.
    assert p.returncode in (0, 1), p.stderr
    cli = json.loads(p.stdout)
    opts = dict(options)
    structure = opts.pop("structure", None)
    py = fracid.fit_time(u, y, DT, structure, **opts)
    assert (p.returncode == 0) == py.usable
    for r in (cli, py.report):
        r.pop("seconds")
    assert cli["request"] == py.report["request"]
    same(cli, py.report)
    # the typed attributes are the report's
    assert py.model_is == cli["model_is"]
    assert [q.value for q in py.params] == [q["value"] for q in py.report["params"]]
    if py.validation is not None:
        assert py.validation.rmse == py.report["fit"]["validation"]["rmse"]


def test_a_validation_record_is_scored_alike(fracid_bin, tmp_path):
    u, y = record(7)
    uv, yv = record(8, 1000)
    path, vpath = tmp_path / "rec.csv", tmp_path / "val.csv"
    write(path, u, y)
    write(vpath, uv, yv)
    cli = json.loads(
        subprocess.run(
            [str(fracid_bin), "time", str(path), "--json", "--quiet", "--diagnose",
             "--validate", str(vpath)],
            capture_output=True, text=True, timeout=300, check=True,
        ).stdout
    )
    py = fracid.fit_time(u, y, DT, diagnose=True, validate=(uv, yv))
    text = json.dumps(cli).replace(str(vpath), "validation")
    cli = json.loads(text)
    for r in (cli, py.report):
        r.pop("seconds")
    same(cli, py.report)
    # both models are scored on the separate record, each with its own figures
    assert py.validated_by["kind"] == "file"
    assert py.validation_file is not None and py.base is not None
    assert py.base["fit"]["validation_file"]["rmse"] > 0.0
    # with the loop closed the choice is made on a held-out part of the estimation record (the
    # default 30%), so that the validation record stays an independent test of it
    assert py.report["request"]["holdout"] is None and py.split == round(0.7 * u.size)


# -- the frequency domain: `fracid freq --json` and `fracid.fit_bode` -------------------------

FREQ_FLAGS = {
    "n": "--n",
    "m": "--m",
    "q": "--q",
    "q_step": "--q-step",
    "q_max": "--q-max",
    "refine_q": "--no-q-refine",
    "weights": "--weights",
    "sk_iterations": "--sk",
    "refine": "--refine",
    "diagnose": "--diagnose",
    "hold": "--hold",
    "compare": "--compare",
}

FREQ_PAPER = "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)"

FREQ_CASES = {
    "defaults": {},
    "fixed_order_uniform_zero": {"q": 0.89, "weights": "none", "m": 1},
    "grid_sk_refit_hold": {
        "n": 2,
        "q_step": 0.02,
        "q_max": 1.2,
        "refine_q": False,
        "sk_iterations": 3,
        "refine": True,
        "hold": "0.0005",
    },
    "diagnose_compare": {"diagnose": True, "compare": [FREQ_PAPER, PAPER]},
}


def freq_cli_args(options: dict) -> list:
    args = []
    for name, value in options.items():
        flag = FREQ_FLAGS[name]
        if name == "refine_q":
            assert value is False
            args.append(flag)
        elif isinstance(value, bool):
            assert value is True
            args.append(flag)
        elif name == "compare":
            for g in value:
                args += [flag, g]
        else:
            args += [flag, str(value)]
    return args


def test_every_freq_option_has_a_cli_flag():
    assert set(fracid.freq_request_defaults()) == set(FREQ_FLAGS)
    covered = {k for case in FREQ_CASES.values() for k in case}
    assert covered == set(FREQ_FLAGS), set(FREQ_FLAGS) - covered


@pytest.mark.parametrize("case", sorted(FREQ_CASES))
def test_freq_cli_and_python_give_the_same_report(fracid_bin, tmp_path, case):
    """The paper's PMSM with a 1 ms delay and 2% complex noise at 30 frequencies, written in
    rad/s, linear gain and radians with repr; Python reads the table with the same reader."""
    options = FREQ_CASES[case]
    g = fracid.FracTf.parse(FREQ_PAPER).with_delay(0.001)
    omega = np.logspace(0, 3.5, 30)
    rng = np.random.default_rng(11)
    h = g.freq_response(omega) * (1 + 0.02 * (rng.standard_normal(30) + 1j * rng.standard_normal(30)))
    path = tmp_path / "bode.csv"
    with open(path, "w") as f:
        f.write("omega_rad_s,gain,phase_rad\n")
        for w, z in zip(omega, h):
            f.write(f"{float(w)!r},{float(abs(z))!r},{float(np.angle(z))!r}\n")
    p = subprocess.run(
        [str(fracid_bin), "freq", str(path), "--rad-s", "--linear-gain", "--radians", "--json",
         "--allow-unusable", *freq_cli_args(options)],
        capture_output=True, text=True, timeout=300,
    )
    assert p.returncode == 0, p.stderr
    cli = json.loads(p.stdout)
    # the table read by the library's reader, as the CLI reads it: the same numbers exactly
    omega_read, h_read = fracid.load_bode(path, rad_s=True, linear_gain=True, radians=True)
    py = fracid.fit_bode(omega_read, h_read, **options)
    assert cli["request"] == py.report["request"]
    same_to(cli, py.report, rel=1e-9)
    assert py.usable == cli["usable"]


def same_to(a, b, rel, where="report"):
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), (where, sorted(a), sorted(b))
        for k in a:
            same_to(a[k], b[k], rel, f"{where}.{k}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), (where, a, b)
        for i, (x, z) in enumerate(zip(a, b)):
            same_to(x, z, rel, f"{where}[{i}]")
    elif isinstance(a, float) or isinstance(b, float):
        if a is None or b is None:
            assert a == b, (where, a, b)
        else:
            assert a == pytest.approx(b, rel=rel, abs=1e-12), (where, a, b)
    elif isinstance(a, str) and isinstance(b, str) and a != b:
        # a model's text prints its numbers in full: compare them as numbers
        import re

        num = re.compile(r"[-+]?\d+\.?\d*(?:[eE][-+]?\d+)?")
        assert num.sub("#", a) == num.sub("#", b), (where, a, b)
        for x, z in zip(num.findall(a), num.findall(b)):
            assert float(x) == pytest.approx(float(z), rel=rel, abs=1e-12), (where, a, b)
    else:
        assert a == b, (where, a, b)


def test_a_joint_fit_is_the_same(fracid_bin, tmp_path):
    """`fracid time A --joint B --validate C --json` and `fracid.fit_time_joint`: the same report
    (the records named by path in one, by position in the other)."""
    (u, y), (ub, yb), (uv, yv) = record(7), record(9, 1200), record(8, 1000)
    paths = [tmp_path / f"{n}.csv" for n in ("a", "b", "v")]
    for p, (uu, yy) in zip(paths, [(u, y), (ub, yb), (uv, yv)]):
        write(p, uu, yy)
    p = subprocess.run(
        [str(fracid_bin), "time", str(paths[0]), "--joint", str(paths[1]), "--validate",
         str(paths[2]), "--json", "--quiet", "--structure", "commensurate"],
        capture_output=True, text=True, timeout=300, check=True,
    )
    text = p.stdout
    for path, name in zip(paths, ("record", "joint[0]", "validation")):
        text = text.replace(json.dumps(str(path))[1:-1], name)
    cli = json.loads(text)
    py = fracid.fit_time_joint(
        u, y, DT, "commensurate", joint=[(ub, yb)], validate=(uv, yv)
    )
    same(cli, py)
    assert [r["file"] for r in py["records"]] == ["record", "joint[0]"]
    # a model of the plant on a third record (82% measured: it has no term for the 3 ms delay)
    assert py["fit"]["validation_file"]["nrmse_percent"] > 70.0
