"""Issue 46 item 15: an array whose conversion would lose something without a word is refused
by every entry point that takes arrays (one check in the bindings' array reader): complex values
where real ones are wanted (numpy dropped the imaginary part with only a ComplexWarning) and a
masked array with masked values (numpy's conversion ignored the mask: the masked samples were
fitted). The mask is refused, not honoured: dropping samples would leave a time record unevenly
sampled."""

from __future__ import annotations

import contextlib
import warnings

import numpy as np
import pytest

import fracid

G = fracid.FracTf.parse("2/(0.01 s^0.9 + 1)")
DT = 1e-3


def record(n: int = 600):
    u = fracid.prbs(order=7, clock=5 * DT, dt=DT, periods=5)[:n]
    return u, G.simulate(u, DT)


@contextlib.contextmanager
def no_complex_warning():
    """Warnings as a user sees them (not errors), and none of them numpy's ComplexWarning."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield
    assert not [w for w in caught if "Complex" in type(w.message).__name__], caught


def test_fit_time_refuses_complex_and_masked_arrays():
    u, y = record()
    with no_complex_warning():  # refused before numpy converts (and warns)
        with pytest.raises(TypeError, match=r"argument 'y'.*complex values.*imaginary part"):
            fracid.fit_time(u, y + 1e-3j, DT, G, max_iterations=3)
        with pytest.raises(TypeError, match=r"argument 'u'.*complex"):
            fracid.fit_time(u.astype(complex), y, DT, G, max_iterations=3)
    bad = y.copy()
    bad[100:110] = 1e6  # a glitch the mask hides
    masked = np.ma.masked_array(bad, mask=np.zeros(len(bad), bool))
    masked[100:110] = np.ma.masked
    with pytest.raises(TypeError, match=r"argument 'y'.*masked array with 10 masked value"):
        fracid.fit_time(u, masked, DT, G, max_iterations=3)
    # validation and joint records likewise
    with pytest.raises(TypeError, match="masked"):
        fracid.fit_time(u, y, DT, G, validate=(u, masked), max_iterations=3)
    with pytest.raises(TypeError, match="complex"):
        fracid.fit_time_joint(u, y, DT, G, joint=[(u, y * (1 + 0j) + 1j)], max_iterations=3)
    # a masked array with nothing masked loses nothing: fitted as the plain array is
    plain = fracid.fit_time(u, y, DT, G, max_iterations=3)
    unmasked = fracid.fit_time(u, np.ma.masked_array(y), DT, G, max_iterations=3)
    assert [p.value for p in unmasked.params] == [p.value for p in plain.params]


def test_every_array_entry_point_refuses_lossy_arrays():
    u, y = record()
    omega = np.logspace(0, 3, 20)
    h = G.freq_response(omega)
    mask = np.zeros(len(omega), bool)
    mask[3] = True
    calls = [
        lambda: G.simulate(u + 1j, DT),
        lambda: G.simulate(np.ma.masked_array(u, mask=np.arange(len(u)) == 5), DT),
        lambda: G.freq_response(omega + 0j),
        lambda: G.bode(np.ma.masked_array(omega, mask=mask)),
        lambda: fracid.gl_simulate(G, u + 1j, DT),
        lambda: fracid.fit_bode(omega + 0j, h),
        lambda: fracid.fit_bode(omega, np.ma.masked_array(h, mask=mask)),
        lambda: fracid.fit_bode(omega, h, weights=np.ones(len(omega)) + 1j),
        lambda: fracid.fit_bode(omega, h, point_std=np.ma.masked_array(np.ones(len(omega)), mask=mask)),
        lambda: fracid.error_index(np.ma.masked_array(omega, mask=mask), h, G),
    ]
    for call in calls:
        with no_complex_warning():
            with pytest.raises(TypeError, match="complex values|masked array"):
                call()
    # the complex response itself is complex, as wanted
    assert fracid.fit_bode(omega, h) is not None
