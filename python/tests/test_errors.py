"""Bad input raises the right exception of the fracid hierarchy, with the Rust message."""

from __future__ import annotations

import numpy as np
import pytest

import fracid
from fracid import DataError, FracidError, NumericalError, ParseError

G = fracid.FracTf.parse("6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)")


def test_hierarchy():
    assert issubclass(ParseError, FracidError) and issubclass(ParseError, ValueError)
    assert issubclass(DataError, FracidError) and issubclass(DataError, ValueError)
    assert issubclass(NumericalError, FracidError) and issubclass(NumericalError, ArithmeticError)


@pytest.mark.parametrize("text", ["", "1/(s +", "1/(0.1 s^^2 + 1)", "abc", "1/(s))"])
def test_parse_errors(text):
    with pytest.raises(ParseError, match="cannot parse model at position"):
        fracid.FracTf.parse(text)


def test_model_errors():
    with pytest.raises(DataError, match="denominator is zero"):
        fracid.FracTf([(1.0, 0.0)], [])
    with pytest.raises(DataError, match="finite"):
        fracid.FracTf([(float("nan"), 0.0)], [(1.0, 0.0)])
    with pytest.raises(DataError, match="negative"):
        fracid.FracTf([(1.0, 0.0)], [(1.0, 0.0)], delay=-1.0)


def test_simulate_errors():
    with pytest.raises(DataError, match="u is empty"):
        G.simulate([], 1e-3)
    with pytest.raises(DataError, match=r"u\[2\] is NaN"):
        G.simulate([0.0, 1.0, np.nan], 1e-3)
    with pytest.raises(DataError, match="dt"):
        G.simulate([1.0], 0.0)
    with pytest.raises(DataError, match="dt"):
        G.simulate([1.0], float("inf"))
    with pytest.raises(DataError, match="method"):
        G.simulate([1.0], 1e-3, method="euler")
    with pytest.raises(DataError, match="band"):
        G.simulate([1.0], 1e-3, band=(10.0, 1.0))
    with pytest.raises(DataError, match="multiple"):
        fracid.prbs(dt=0.001, clock=0.0025)


def test_fit_bode_errors(table1):
    omega, h = fracid.load_bode(table1)
    with pytest.raises(DataError, match="omega has 11 samples but h has 10"):
        fracid.fit_bode(np.append(omega, 1e5), h)
    bad = h.copy()
    bad[3] = np.nan
    with pytest.raises(DataError, match=r"h\[3\]"):
        fracid.fit_bode(omega, bad)
    with pytest.raises(DataError, match="increase"):
        fracid.fit_bode(omega[::-1], h[::-1])
    with pytest.raises(DataError, match="empty"):
        fracid.fit_bode([], [])
    with pytest.raises(DataError, match="not enough information"):
        fracid.fit_bode(omega[:2], h[:2])
    with pytest.raises(DataError, match="q = 3"):
        fracid.fit_bode(omega, h, q=3.0)
    with pytest.raises(DataError, match="weights"):
        fracid.fit_bode(omega, h, weights="magic")
    with pytest.raises(DataError, match="needs n = 2"):
        fracid.fit_bode(omega, h, n=3, refine=True)


def test_fit_time_errors():
    u = fracid.prbs(dt=1e-3, periods=2)
    y = G.simulate(u, 1e-3)
    with pytest.raises(DataError, match="u has 762 samples but y has 761"):
        fracid.fit_time(u, y[:-1], 1e-3)
    with pytest.raises(DataError, match="u is empty"):
        fracid.fit_time([], [], 1e-3)
    y2 = y.copy()
    y2[10] = np.inf
    with pytest.raises(DataError, match=r"y\[10\] is inf"):
        fracid.fit_time(u, y2, 1e-3)
    with pytest.raises(DataError, match="dt"):
        fracid.fit_time(u, y, -1e-3)
    with pytest.raises(DataError, match="structure"):
        fracid.fit_time(u, y, 1e-3, structure="arx")
    with pytest.raises(DataError, match="no parameter 'Q'"):
        fracid.fit_time(u, y, 1e-3, structure="commensurate", start={"Q": 1.0})
    with pytest.raises(DataError, match="holdout"):
        fracid.fit_time(u, y, 1e-3, holdout=1.5)
    with pytest.raises(DataError, match="not enough information"):
        fracid.fit_time(np.zeros(500), np.zeros(500), 1e-3)
    with pytest.raises(DataError, match="not enough information"):
        fracid.fit_time(u[:30], y[:30], 1e-3)


def test_wrong_types():
    with pytest.raises(TypeError, match="1-D array"):  # a string is no array of numbers
        G.simulate("abc", 1e-3)
    with pytest.raises(TypeError):
        G.freq_response(np.ones((2, 2)))
