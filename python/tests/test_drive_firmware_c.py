"""The Python ``DriveClient`` against the C drive firmware (``firmware/``, fracfw, linked into the
simulator; selected with ``firmware="c"``) on a pty: a PRBS record equal to the Rust
firmware's sample for sample, and a sine sweep equal to it within the DFT's Q8 rounding. The same
motor, hidden effects and seed on both. About two seconds."""

from __future__ import annotations

import numpy as np
import pytest

import fracid

BAUD = 921600
FS = 1000
# Every hidden effect that is deterministic for a seed.
EFFECTS = dict(
    delay_s=0.002,
    coulomb_v=0.2,
    noise_std=0.05,
    speed_quant=0.01,
    ripple_v=0.1,
    ripple_hz=37.0,
    seed=7,
)
PRBS = dict(order=7, clock_s=0.003, amplitude_v=1.0, offset_v=6.0, periods=1, settle_s=0.1)


def _run(firmware: str):
    sim = fracid.DriveSimulator(baud=BAUD, firmware=firmware, **EFFECTS)
    with sim:
        with fracid.DriveClient(sim.port, baud=BAUD) as c:
            c.configure(sample_rate_hz=FS)
            prbs = c.run_prbs(**PRBS)
            sweep = c.run_sine_sweep(20, 70, 2, cycles=3, min_settle_s=0.05)
        events = sim.stats()["events"]
    return prbs, sweep, events


@pytest.fixture(scope="module")
def runs():
    return {fw: _run(fw) for fw in ("c", "rust")}


def test_the_c_firmware_ran(runs):
    # the simulator logs the runs of the C engine as such, and only those
    assert any("(C firmware)" in e for e in runs["c"][2]), runs["c"][2]
    assert not any("(C firmware)" in e for e in runs["rust"][2]), runs["rust"][2]


def test_prbs_record_equals_the_rust_firmware_sample_for_sample(runs):
    c, r = runs["c"][0], runs["rust"][0]
    assert c.complete and r.complete, (c.problems, r.problems)
    assert c.total_samples == len(c) == 100 + 127 * 3
    np.testing.assert_array_equal(c.index, r.index)
    # exact equality: the same raw integers from the drive give the same floats
    for name in ("t", "u", "y", "i"):
        np.testing.assert_array_equal(getattr(c, name), getattr(r, name), err_msg=name)
    # and the record is the PRBS of fracid.prbs (an independent generator) after the settling
    ref = fracid.prbs(dt=1 / FS, order=7, clock=0.003, amplitude=1.0, offset=6.0, periods=1)
    np.testing.assert_allclose(c.u[100:], ref, rtol=0, atol=1e-9)
    # the hidden noise is in y (so equality is not a flat trivial record)
    assert np.std(np.diff(c.y[50:100])) > 0.01


def test_sine_sweep_equals_the_rust_firmware(runs):
    c, r = runs["c"][1], runs["rust"][1]
    assert c.lost == [] and r.lost == []
    np.testing.assert_array_equal(c.freq_hz, r.freq_hz)
    # The drive's DFT: C sums in 64-bit fixed point, Rust in f64; both round to Q8 (1/256 LSB of
    # a 1 V amplitude): one Q8 unit at most, far below these tolerances.
    np.testing.assert_allclose(c.gain_db, r.gain_db, rtol=0, atol=1e-3)
    np.testing.assert_allclose(c.phase_deg, r.phase_deg, rtol=0, atol=1e-3)
    # a real response, not zeros: the motor's gain near DC is 6.82 (rad/s)/V = 16.7 dB
    assert np.all(c.gain_db > 0) and np.all(c.gain_db < 20)
