"""The readers from Python: the library's (one reader for the CLI and Python), clear errors for
bad arrays and arguments (issues 11 and 12)."""

from __future__ import annotations

import struct
import warnings
import zlib

import numpy as np
import pytest

import fracid


def _mat(vars_, compress=False):
    """A MATLAB level 5 .mat file of double variables, written from the format's specification
    (independent of the reader under test)."""

    def element(ty, data):
        e = struct.pack("<II", ty, len(data)) + data
        return e + b"\0" * (-len(e) % 8)

    f = b"MATLAB 5.0 MAT-file, written by fracid's tests".ljust(116) + b"\0" * 8 + b"\x00\x01IM"
    for name, a in vars_:
        a = np.atleast_2d(np.asarray(a, dtype=float))
        m = element(6, struct.pack("<II", 6, 0))
        m += element(5, struct.pack("<ii", *a.shape))
        m += element(1, name.encode())
        m += element(9, a.ravel(order="F").astype("<f8").tobytes())
        mat = element(14, m)
        f += element(15, zlib.compress(mat)) if compress else mat
    return f


def _record(n=400, dt=1e-3):
    u = fracid.prbs(dt=dt, order=7, clock=5 * dt, periods=4)[:n]
    y = fracid.FracTf.parse("2/(0.01 s^0.9 + 1)").simulate(u, dt=dt)
    return np.arange(n) * dt, u, y


def test_load_csv_reads_what_the_cli_reads(tmp_path):
    t, u, y = _record()
    p = tmp_path / "r.csv"
    p.write_text('"time";"volts";"speed"\n' + "".join(f"{a:.6f};{b};{float(c)!r}\n" for a, b, c in zip(t, u, y)))
    rec = fracid.load_csv(p, t="time", u="volts", y="speed")
    assert rec.dt == pytest.approx(1e-3, rel=1e-9)
    np.testing.assert_array_equal(rec.u, u)
    np.testing.assert_array_equal(rec.y, y)
    # by index, no header, no time column
    p = tmp_path / "nohead.csv"
    p.write_text("".join(f"{b},{float(c)!r}\n" for b, c in zip(u, y)))
    rec = fracid.load_csv(p, u=0, y=1, dt=1e-3)
    assert rec.u.size == u.size  # no row lost
    with pytest.raises(fracid.DataError, match="no header line"):
        fracid.load_csv(p)
    with pytest.raises(FileNotFoundError):
        fracid.load_csv(tmp_path / "missing.csv")


def test_incomplete_acquisition_warns_and_keeps_the_complete_part(tmp_path):
    t, u, y = _record()
    rows = [f"{a:.6f},{b},{float(c)!r}\n" for k, (a, b, c) in enumerate(zip(t, u, y)) if not 300 <= k < 340]
    p = tmp_path / "acq.csv"
    p.write_text(
        "# fracid drive acquisition: PRBS\nt,u,y\n"
        + "".join(rows)
        + "# incomplete: missing samples 300..340 (port lost)\n"
    )
    with pytest.warns(UserWarning, match="missing samples 300..340"):
        rec = fracid.load_csv(p)
    assert rec.u.size == 300
    assert rec.acquisition.startswith("incomplete")


def test_mat_files(tmp_path):
    t, u, y = _record()
    for compress in (False, True):
        p = tmp_path / f"r{compress}.mat"
        p.write_bytes(_mat([("t", t[:, None]), ("u", u), ("y", y[:, None])], compress))
        rec = fracid.load_csv(p)
        np.testing.assert_array_equal(rec.y, y)
    p = tmp_path / "bode.mat"
    p.write_bytes(_mat([("freq_hz", [1.0, 10.0]), ("gain_db", [0.0, -20.0]), ("phase_deg", [0.0, -90.0])]))
    omega, h = fracid.load_bode(p)
    np.testing.assert_allclose(omega, [2 * np.pi, 20 * np.pi])
    np.testing.assert_allclose(h[1], -0.1j, atol=1e-12)
    p = tmp_path / "v73.mat"
    p.write_bytes(b"MATLAB 7.3 MAT-file".ljust(512) + b"\x89HDF\r\n\x1a\n")
    with pytest.raises(fracid.DataError, match="v7.3"):
        fracid.load_csv(p)


def test_mat_written_by_scipy(tmp_path):
    # scipy writes each compressed variable as an unpadded miCOMPRESSED element (the format pads
    # neither miMATRIX nor miCOMPRESSED); the reader used to pad it to 8 bytes, read the next tag
    # late and refuse the file ("a small data element of more than 4 bytes"). Issue 12.
    sio = pytest.importorskip("scipy.io")
    t, u, y = _record()
    for compress in (True, False):
        p = tmp_path / f"scipy{compress}.mat"
        sio.savemat(p, {"t": t, "u": u, "y": y, "n": np.int8(3), "note": "text"}, do_compression=compress)
        rec = fracid.load_csv(p)
        np.testing.assert_array_equal(rec.u, u)
        np.testing.assert_array_equal(rec.y, y)


def test_load_bode_is_the_library_reader(tmp_path, table1):
    omega, h = fracid.load_bode(table1)
    # semicolons and tabs (Python's own reader took only commas)
    text = table1.read_text().replace(",", ";")
    p = tmp_path / "semi.csv"
    p.write_text(text)
    omega2, h2 = fracid.load_bode(p)
    np.testing.assert_array_equal(omega, omega2)
    np.testing.assert_array_equal(h, h2)
    # binary: a fracid error, not UnicodeDecodeError
    p = tmp_path / "bin.csv"
    p.write_bytes(b"\xff\xfe\x00\x01" * 100)
    with pytest.raises(fracid.DataError):
        fracid.load_bode(p)
    # headerless: refused, and read when the columns are said
    p = tmp_path / "nohead.csv"
    p.write_text("1,2,0\n10,0.5,-1.2\n")
    with pytest.raises(fracid.DataError, match="no header line"):
        fracid.load_bode(p)
    omega, h = fracid.load_bode(p, columns=(0, 1, 2), linear_gain=True, radians=True)
    assert abs(h[0]) == pytest.approx(2.0)


def test_array_and_integer_arguments_are_explained():
    g = fracid.FracTf.parse("1/(s+1)")
    with pytest.raises(TypeError, match=r"argument 'u'.*shape \(3, 2\)"):
        g.simulate(np.ones((3, 2)), dt=0.1)
    with pytest.raises(TypeError, match=r"shape \(3, 2\)"):
        fracid.fit_time(np.ones((3, 2)), np.ones(3), dt=0.1)
    with pytest.raises(fracid.DataError, match="order = -1"):
        g.simulate(np.ones(3), dt=0.1, order=-1)
    with pytest.raises(fracid.DataError, match="periods = -2"):
        fracid.prbs(dt=1e-3, periods=-2)
    with pytest.raises(fracid.DataError, match="n = -1"):
        fracid.fit_bode([1.0, 2.0], [1 + 0j, 0.5j], n=-1)
    with pytest.raises(fracid.DataError, match="max_iterations = -5"):
        fracid.fit_time(np.ones(10), np.ones(10), dt=0.1, max_iterations=-5)


def test_fit_bode_refuses_a_magnitude():
    omega = np.logspace(0, 3, 20)
    h = fracid.FracTf.parse("1/(0.01 s + 1)").freq_response(omega)
    with pytest.raises(fracid.DataError, match="h is real"):
        fracid.fit_bode(omega, np.abs(h))
    fracid.fit_bode(omega, h, n=1)  # the complex response is fine


def test_parser_and_improper_models():
    for bad in ("1/(s^ + 1)", "1/(s^ - 1)"):
        with pytest.raises(fracid.ParseError, match="missing exponent"):
            fracid.FracTf.parse(bad)
    g = fracid.FracTf.parse("s^3/(s+1)")
    with pytest.raises(fracid.DataError, match="improper"):
        g.simulate(np.ones(5), dt=0.1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        g.freq_response(np.array([1.0]))  # its frequency response is fine
