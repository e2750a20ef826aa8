"""fracid: fractional-order identification of PMSM drives, from Python.

The numerics live in Rust (the ``fracsim`` and ``ident`` crates); this package gives them numpy
arrays in and out, typed result objects and Python exceptions.

Examples
--------
>>> import numpy as np, fracid
>>> g = fracid.FracTf.parse("6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)")
>>> round(g.dc_gain(), 2)
6.77
>>> u = fracid.prbs(dt=1e-4, order=7, clock=0.003, periods=2)
>>> y = g.simulate(u, dt=1e-4)
>>> fit = fracid.fit_time(u, y, dt=1e-4, structure="commensurate", offsets="none",
...                       fit_offset=False)
>>> fit.validation.nrmse_percent > 99
True

Contents
--------
FracTf
    Fractional transfer functions: parse, frequency response, Bode, simulation.
prbs, gl_simulate
    PRBS input signals; the Grunwald-Letnikov reference simulation.
fit_bode, error_index, load_bode
    Frequency-domain identification (weighted Levy, order search, SK, PMSM refit).
fit_time
    Time-domain output-error identification (Levenberg-Marquardt, exact sensitivities).
DriveClient, DriveSimulator, Acquisition, BodeSweep
    Acquisition from the servo drive over its serial protocol (PRBS records, sine sweeps), and a
    simulated drive on a pseudo-terminal.
FracidError, ParseError, DataError, NumericalError, DriveError
    The exceptions.
"""

from __future__ import annotations

import os
from typing import Dict, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

from ._drive import DriveClient
from ._errors import DataError, DriveError, FracidError, NumericalError, ParseError
from ._fracid import DriveSimulator, FracTf, __version__, error_index, gl_simulate, prbs
from ._fracid import _fit_bode, _fit_time
from ._results import (
    Acquisition,
    BodeSweep,
    Diagnosis,
    Effect,
    FitMetrics,
    FreqFit,
    LevyFit,
    ParamEstimate,
    PmsmFit,
    QCurve,
    ResidualTest,
    TimeFit,
)

__all__ = [
    "FracTf",
    "prbs",
    "gl_simulate",
    "fit_bode",
    "fit_time",
    "error_index",
    "load_bode",
    "FreqFit",
    "LevyFit",
    "PmsmFit",
    "QCurve",
    "TimeFit",
    "ParamEstimate",
    "FitMetrics",
    "ResidualTest",
    "Diagnosis",
    "Effect",
    "diagnose",
    "DriveClient",
    "DriveSimulator",
    "Acquisition",
    "BodeSweep",
    "FracidError",
    "ParseError",
    "DataError",
    "NumericalError",
    "DriveError",
    "__version__",
]

ArrayLike = npt.ArrayLike


def load_bode(path: Union[str, "os.PathLike[str]"]) -> Tuple[np.ndarray, np.ndarray]:
    """Read Bode data from a CSV file with columns ``freq_hz,gain_db,phase_deg``.

    Parameters
    ----------
    path : str or path-like
        The file: a header line naming the columns, ``,`` separated, ``#`` comments allowed.

    Returns
    -------
    omega : numpy.ndarray
        Angular frequencies in rad/s.
    h : numpy.ndarray
        The complex response ``10^(gain_db/20) exp(j phase)``.

    Raises
    ------
    DataError
        If a column is missing or a value is not a finite number.
    """
    with open(os.fspath(path), encoding="utf-8") as f:
        lines = [ln.split("#", 1)[0].strip() for ln in f]
    lines = [ln for ln in lines if ln]
    if len(lines) < 2:
        raise DataError(f"{os.fspath(path)}: no header and data rows")
    try:
        data = np.genfromtxt(lines, delimiter=",", names=True)
    except ValueError as e:  # ragged rows
        raise DataError(f"{os.fspath(path)}: {e}") from None
    names = data.dtype.names or ()
    for col in ("freq_hz", "gain_db", "phase_deg"):
        if col not in names:
            raise DataError(f"{os.fspath(path)}: no column {col!r} (found {list(names)})")
    data = np.atleast_1d(data)
    f = np.asarray(data["freq_hz"], dtype=float)
    g = np.asarray(data["gain_db"], dtype=float)
    p = np.asarray(data["phase_deg"], dtype=float)
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(g)) and np.all(np.isfinite(p))):
        raise DataError(f"{os.fspath(path)}: a value is missing or not a number")
    return 2 * np.pi * f, 10 ** (g / 20) * np.exp(1j * np.deg2rad(p))


def fit_bode(
    omega: ArrayLike,
    h: ArrayLike,
    *,
    n: int = 2,
    m: int = 0,
    q: Optional[float] = None,
    q_step: float = 0.01,
    q_max: float = 1.0,
    refine_q: bool = True,
    weights: Union[str, ArrayLike, None] = "vinagre",
    sk_iterations: int = 0,
    refine: bool = False,
    point_std: Optional[ArrayLike] = None,
) -> FreqFit:
    """Identify a commensurate fractional model from frequency-response data.

    Fits ``sum_u b_u s^(u q) / (1 + sum_p a_p s^(p q))`` by Levy's weighted linear least squares
    (QR, Vinagre's weights by default) with the order ``q`` searched on a grid and refined;
    optionally Sanathanan-Koerner iterations and the nonlinear refit of the PMSM structure
    ``K / (a2 s^(zeta+theta) + a1 s^zeta + 1)`` with two free orders. The GIL is released
    during the fit.

    Parameters
    ----------
    omega : array_like
        Angular frequencies in rad/s, strictly increasing, > 0.
    h : array_like
        Complex response ``G(j omega)`` (linear gain), same length.
    n, m : int
        Denominator and numerator degrees in powers of ``s^q`` (default 2 and 0).
    q : float, optional
        Fix the order instead of searching it.
    q_step, q_max : float
        The grid ``q_step, 2 q_step, ..., q_max`` (the paper: 0.01 up to 1).
    refine_q : bool
        Refine the best grid ``q`` by golden section (``False``: the paper's grid answer).
    weights : {"vinagre", "uniform"} or array_like
        Weights of the Levy least squares (the paper's eq. 29 by default) or one per point.
    sk_iterations : int
        Sanathanan-Koerner reweightings (0: none).
    refine : bool
        Refit the PMSM structure with two free orders (needs ``n=2, m=0``).
    point_std : array_like, optional
        Standard deviation of each point's complex error per real component (e.g. from the
        spread of repeated sine measurements): the refit then weights by inverse variance and
        its standard errors reflect it. Default: the paper's ``J``, every point alike.

    Returns
    -------
    FreqFit
        The Levy fits (refined and grid), ``J(q)``, the SK fit and the refit if asked.

    Raises
    ------
    DataError
        For NaN, empty or mismatched arrays, unsorted frequencies, bad options.
    NumericalError
        If the least-squares problem breaks down.
    """
    raw = _fit_bode(
        omega,
        np.asarray(h, dtype=complex),
        n=n,
        m=m,
        q=q,
        q_step=q_step,
        q_max=q_max,
        refine_q=refine_q,
        weights=weights,
        sk_iterations=sk_iterations,
        refine=refine,
        point_std=None if point_std is None else np.asarray(point_std, dtype=float),
    )
    return FreqFit._from_raw(raw)


def fit_time(
    u: ArrayLike,
    y: ArrayLike,
    dt: float,
    structure: Union[str, FracTf] = "pmsm",
    *,
    start: Optional[Dict[str, float]] = None,
    holdout: float = 0.3,
    offsets: str = "initial",
    fit_offset: bool = True,
    max_iterations: int = 100,
    skip: int = 0,
    method: str = "refined",
    band: Optional[Tuple[float, float]] = None,
    order: int = 8,
    max_lag: int = 25,
    diagnose: bool = False,
    margin: float = 0.05,
    min_r2: float = 0.005,
    max_rounds: int = 3,
) -> TimeFit:
    """Identify a fractional model from sampled input and output by output error.

    Removes the operating point, holds out the last ``holdout`` of the record for validation,
    starts from a Levy fit on the data's frequency response (unless ``start`` is given), then
    minimises ``sum (y - yhat)^2`` by Levenberg-Marquardt with exact sensitivities. Parameters
    are kept in range (coefficients positive, orders in (0, 2)). The GIL is released during the
    fit, so fits in threads run in parallel.

    Parameters
    ----------
    u, y : array_like
        Input and output samples, same length, finite.
    dt : float
        Sampling step in seconds.
    structure : {"pmsm", "commensurate", "fopdt"} or FracTf
        ``"pmsm"``: ``K / (a2 s^(zeta+theta) + a1 s^zeta + 1)``; ``"commensurate"``:
        ``K / (a2 s^(2q) + a1 s^q + 1)``; ``"fopdt"``: ``K e^(-tau s) / (T s + 1)``; a
        :class:`FracTf`: every coefficient and order fitted, starting from its values.
    start : dict, optional
        Starting values by parameter name (e.g. ``{"K": 6.8, "a1": 0.006}``). When given, no
        start is made from the data: parameters not named keep the structure's defaults
        (``K=1, a1=0.01, a2=1e-4``, orders 0.9).
    holdout : float
        Fraction of the record held out for validation, in [0, 1).
    offsets : {"initial", "mean", "none"}
        How the operating point is removed.
    fit_offset : bool
        Also fit a constant output offset.
    max_iterations : int
        Levenberg-Marquardt iterations at most.
    skip : int
        Leading samples left out of the residual.
    method, band, order
        The approximation of the fractional operators (as :meth:`FracTf.simulate`).
    max_lag : int
        Lags of the residual correlation test.
    diagnose : bool
        Also run the residual diagnosis (DESIGN section 6): test the residual for the signature
        of each effect (delay, Coulomb friction, offset, periodic, abs sensor, saturation, dead
        zone, quantization), refit with each strong candidate, keep those that lower the
        validation error by ``margin`` and lower BIC. The result is in ``TimeFit.diagnosis``.
    margin : float
        Relative fall of the validation RMSE an effect must bring to be kept.
    min_r2 : float
        Evidence (fraction of the residual explained) a candidate needs to be refitted.
    max_rounds : int
        Rounds of the diagnosis loop.

    Returns
    -------
    TimeFit
        Model, parameters with standard errors, fit on estimation and validation data.

    Raises
    ------
    DataError
        For NaN, empty or mismatched arrays, too few samples, no excitation, bad options.
    NumericalError
        If the simulation or a solve breaks down.
    """
    raw = _fit_time(
        u,
        y,
        dt,
        structure,
        start=start,
        holdout=holdout,
        offsets=offsets,
        fit_offset=fit_offset,
        max_iterations=max_iterations,
        skip=skip,
        method=method,
        band=band,
        order=order,
        max_lag=max_lag,
        diagnose=diagnose,
        margin=margin,
        min_r2=min_r2,
        max_rounds=max_rounds,
    )
    return TimeFit._from_raw(raw)


def diagnose(
    u: ArrayLike,
    y: ArrayLike,
    dt: float,
    structure: Union[str, FracTf] = "pmsm",
    **kwargs: object,
) -> Diagnosis:
    """Fit ``structure`` by output error and diagnose what the fit cannot explain.

    The same as ``fit_time(u, y, dt, structure, diagnose=True, **kwargs).diagnosis``; see
    :func:`fit_time` for the parameters.

    Returns
    -------
    Diagnosis
        The error before and after, the effects kept with their parameters and evidence, the
        candidates rejected and why, ambiguities, and whether structure remains unexplained.
    """
    kwargs["diagnose"] = True
    fit = fit_time(u, y, dt, structure, **kwargs)  # type: ignore[arg-type]
    assert fit.diagnosis is not None
    return fit.diagnosis
