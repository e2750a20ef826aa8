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
    Fractional transfer functions: parse, frequency response, Bode, simulation, and
    ``to_state_space`` (a :class:`StateSpace` with ``to_scipy()`` and ``to_control()``).
prbs, gl_simulate
    PRBS input signals; the Grunwald-Letnikov reference simulation.
fit_bode, error_index, load_bode
    Frequency-domain identification (weighted Levy, order search, SK, PMSM refit).
fit_time
    Time-domain output-error identification (Levenberg-Marquardt, exact sensitivities).
tune
    A fractional PI/PID (or integer PI/PID) designed on a model for a crossover, a phase margin
    and a flat phase; its discrete realisation and its closed loop simulated.
DriveClient, DriveSimulator, Acquisition, BodeSweep
    Acquisition from the servo drive over its serial protocol (PRBS records, sine sweeps), and a
    simulated drive on a pseudo-terminal.
FracidError, ParseError, DataError, NumericalError, InfeasibleError, DriveError
    The exceptions.
"""

from __future__ import annotations

import json
import os
import warnings
from typing import Any, Dict, NamedTuple, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

from ._drive import DriveClient
from ._errors import (
    DataError,
    DriveError,
    FracidError,
    InfeasibleError,
    NumericalError,
    ParseError,
)
from ._fracid import DriveSimulator, FracTf, __version__, error_index, gl_simulate, prbs
from ._fracid import (
    _fit_bode,
    _fit_time,
    _fit_time_joint,
    _freq_request_defaults,
    _load_bode,
    _load_csv,
    _structures,
    _time_request_defaults,
)
from ._export import StateSpace
from ._tune import tune
from ._autotune import autotune, autotune_request_defaults
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
    "StateSpace",
    "prbs",
    "gl_simulate",
    "fit_bode",
    "fit_time",
    "fit_time_joint",
    "freq_request_defaults",
    "time_request",
    "time_request_defaults",
    "structures",
    "error_index",
    "load_bode",
    "load_csv",
    "TimeRecord",
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
    "tune",
    "autotune",
    "autotune_request_defaults",
    "DriveClient",
    "DriveSimulator",
    "Acquisition",
    "BodeSweep",
    "FracidError",
    "ParseError",
    "DataError",
    "NumericalError",
    "InfeasibleError",
    "DriveError",
    "__version__",
]

ArrayLike = npt.ArrayLike


class TimeRecord(NamedTuple):
    """A time record read by :func:`load_csv`."""

    t: np.ndarray
    """Time stamps, s (uniform)."""
    u: np.ndarray
    """Input samples."""
    y: np.ndarray
    """Output samples."""
    dt: float
    """The sampling step, s."""
    warnings: Tuple[str, ...]
    """What the reader found (an incomplete or interrupted acquisition, the part kept); each is
    also issued with :func:`warnings.warn`."""
    acquisition: str
    """The acquisition footer's verdict: ``complete``, ``incomplete: missing samples ...``,
    ``interrupted`` or ``unknown`` (no footer, not a ``fracid drive`` file)."""


Column = Union[str, int]


def load_csv(
    path: Union[str, "os.PathLike[str]"],
    *,
    t: Column = "t",
    u: Column = "u",
    y: Column = "y",
    dt: Optional[float] = None,
) -> TimeRecord:
    """Read a time record with the library's reader (the one ``fracid time`` uses).

    Delimited text (``,`` ``;`` or tab, ``#`` comments, quoted names, a headerless file by
    0-based column indices) or a MATLAB level 5 ``.mat`` file (variables by name); at most
    512 MiB, lines of at most 1 MiB. An acquisition footer is honoured: a file marked
    ``# incomplete: missing samples a..b`` (or a ``fracid drive`` file with no footer) gives its
    longest complete contiguous part, with a warning naming what is missing.

    Parameters
    ----------
    path : str or path-like
        The file.
    t, u, y : str or int
        The time, input and output columns: names, or 0-based indices.
    dt : float, optional
        The sampling step of a file with no time column (``t = k dt``; ``t`` is not read).

    Returns
    -------
    TimeRecord
        ``t, u, y, dt, warnings, acquisition``; pass ``rec.u, rec.y, dt=rec.dt`` to
        :func:`fit_time`.

    Raises
    ------
    DataError
        Bad data: a missing column, a non-number, non-uniform time, not text, an incomplete
        acquisition whose complete part is too short.
    OSError
        The file cannot be read.
    """
    raw = _load_csv(os.fspath(path), t, u, y, dt=dt)
    for w in raw["warnings"]:
        warnings.warn(f"{os.fspath(path)}: {w}", stacklevel=2)
    return TimeRecord(
        t=raw["t"],
        u=raw["u"],
        y=raw["y"],
        dt=raw["dt"],
        warnings=tuple(raw["warnings"]),
        acquisition=raw["acquisition"],
    )


def load_bode(
    path: Union[str, "os.PathLike[str]"],
    *,
    columns: Optional[Tuple[Column, Column, Column]] = None,
    rad_s: bool = False,
    linear_gain: bool = False,
    radians: bool = False,
) -> Tuple[np.ndarray, np.ndarray]:
    """Read Bode data with the library's reader (the one ``fracid freq`` uses).

    Parameters
    ----------
    path : str or path-like
        The file: delimited text (``,`` ``;`` or tab, ``#`` comments) with a header naming the
        columns (default ``freq_hz,gain_db,phase_deg``), or a MATLAB level 5 ``.mat`` file with
        variables of those names. A table without a header is refused unless ``columns`` says
        which column is which.
    columns : (freq, gain, phase), optional
        The columns by name or 0-based index.
    rad_s, linear_gain, radians : bool
        Units: frequency in rad/s (else Hz), linear gain (else dB), phase in radians (else
        degrees).

    Returns
    -------
    omega : numpy.ndarray
        Angular frequencies in rad/s.
    h : numpy.ndarray
        The complex response ``|G| exp(j phase)``.

    Raises
    ------
    DataError
        A missing column, a value that is not a finite number, unsorted frequencies, a headerless
        table without ``columns``, a binary file.
    OSError
        The file cannot be read.
    """
    omega, h, _ = _load_bode(
        os.fspath(path),
        columns=columns,
        rad_s=rad_s,
        linear_gain=linear_gain,
        radians=radians,
    )
    return omega, h


def _count(name: str, v: int) -> int:
    """A non-negative integer argument, checked (a negative one is a DataError, not an
    OverflowError deep in the bindings)."""
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
        raise DataError(f"{name} = {v!r} must be an integer")
    if v < 0:
        raise DataError(f"{name} = {v} must be a non-negative integer")
    return int(v)


def _complex_response(h: ArrayLike) -> np.ndarray:
    """``h`` as a complex array; a real one (a magnitude ``|H|``) is refused. A masked array stays
    one (``asanyarray``): the bindings refuse its masked values rather than fit them."""
    a = np.asanyarray(h)
    if a.ndim != 1:
        raise DataError(f"h must be a 1-D array, got an array of shape {a.shape}")
    if a.size and not np.iscomplexobj(a):
        raise DataError(
            "h is real: fit_bode needs the complex response G(j omega) = |G| exp(j phase), not "
            "the magnitude |G| alone; build it as mag * np.exp(1j * phase_rad), or read the "
            "table with load_bode"
        )
    return a.astype(complex)


def fit_bode(
    omega: ArrayLike,
    h: ArrayLike,
    *,
    weights: Union[str, ArrayLike, None] = None,
    point_std: Optional[ArrayLike] = None,
    **options: object,
) -> FreqFit:
    """Identify a commensurate fractional model from frequency-response data.

    The same use case and report as ``fracid freq`` (``ident::app::freq::run``): fits
    ``sum_u b_u s^(u q) / (1 + sum_p a_p s^(p q))`` by Levy's weighted linear least squares
    (QR, Vinagre's weights by default) with the order ``q`` searched on a grid and refined;
    optionally Sanathanan-Koerner iterations, the nonlinear refit of the PMSM structure
    ``K / (a2 s^(zeta+theta) + a1 s^zeta + 1)`` with two free orders, and the residual
    diagnosis. The GIL is released during the fit.

    Parameters
    ----------
    omega : array_like
        Angular frequencies in rad/s, strictly increasing, > 0.
    h : array_like
        Complex response ``G(j omega)`` (linear gain), same length.
    weights : {"auto", "vinagre", "none", "spread"} or array_like
        Weights of the Levy least squares: ``"auto"`` (the default: ``"spread"`` when
        ``point_std`` is given, else ``"vinagre"``, the paper's eq. 29), or one weight per point.
    point_std : array_like, optional
        Standard deviation of each point's complex error per real component (e.g. from the
        spread of repeated sine measurements): with ``weights="spread"`` (the default when given)
        Levy weights by Vinagre's over the relative variance and the refit by the inverse
        variance, its standard errors reflecting it.
    **options
        Every other option of ``fracid freq``, by the same name and with the same default (see
        :func:`freq_request_defaults`): ``n``, ``m`` (degrees in powers of ``s^q``; 2 and 0),
        ``q`` (a fixed order), ``q_step``, ``q_max`` (the grid; 0.01 up to 1), ``refine_q``
        (golden section on the grid's best), ``sk_iterations``, ``refine``, ``diagnose``,
        ``hold`` (a sample period in seconds whose zero-order hold is divided out, or "none"),
        ``compare`` (model texts scored by ``J``).

    Returns
    -------
    FreqFit
        The Levy fits (refined and grid), ``J(q)``, the SK fit and the refit if asked, the
        diagnosis; ``report`` is ``fracid freq --json``'s report itself.

    Raises
    ------
    DataError
        For NaN, empty or mismatched arrays, unsorted frequencies, bad options.
    NumericalError
        If the least-squares problem breaks down.
    """
    known = _freq_request_defaults()
    request: Dict[str, object] = {}
    for name, value in options.items():
        if name not in known or name == "weights":
            raise DataError(
                f"fit_bode has no option {name!r}; the options are {', '.join(sorted(known))}"
            )
        if value is None:
            continue
        if name in ("n", "m", "sk_iterations"):
            value = _count(name, value)  # type: ignore[arg-type]
        if name == "hold" and not isinstance(value, str):
            value = repr(float(value))  # type: ignore[arg-type]
        if name == "compare":
            value = [str(g) for g in value]  # type: ignore[attr-defined]
        request[name] = value
    per_point = None
    if weights is not None:
        if isinstance(weights, str):
            request["weights"] = weights
        else:
            request["weights"] = "given"
            # as given: the bindings convert it, refusing complex or masked values
            per_point = weights
    std = point_std
    report = _fit_bode(omega, _complex_response(h), json.dumps(request), per_point, std)
    return FreqFit._from_report(report)


def freq_request_defaults() -> Dict[str, object]:
    """Every option of :func:`fit_bode` (and ``fracid freq``) with its default: the
    ``ident::app::freq::FreqRequest`` defaults, held once in the library."""
    return dict(_freq_request_defaults())


def fit_time(
    u: ArrayLike,
    y: ArrayLike,
    dt: float,
    structure: Union[str, FracTf, None] = None,
    *,
    validate: Optional[Tuple[ArrayLike, ArrayLike]] = None,
    **options: object,
) -> TimeFit:
    """Identify a fractional model from sampled input and output by output error.

    The same use case and report as ``fracid time`` (``ident::app::time::run``): removes the
    operating point, splits off a validation part (a step test keeps its step and holds out the
    response's tail), starts from the data's frequency response (unless ``start`` is given), then
    minimises ``sum (y - yhat)^2`` by Levenberg-Marquardt with exact sensitivities. The GIL is
    released during the fit, so fits in threads run in parallel.

    Parameters
    ----------
    u, y : array_like
        Input and output samples, same length, finite.
    dt : float
        Sampling step in seconds.
    structure : {"pmsm", "commensurate", "first-order", "second-order", "third-order", "two-mass", "feedthrough", "fopdt", "cell", "auto", "general"} or str or FracTf
        A name of :func:`structures` (the catalogue ``fracid time --structure`` takes and the
        reports print; ``_`` or a space for ``-`` is taken too).
        ``"pmsm"`` (the default): ``K / (a2 s^(zeta+theta) + a1 s^zeta + 1)``;
        ``"commensurate"``: ``K / (a2 s^(2q) + a1 s^q + 1)``; ``"second-order"``: the integer
        ``K / (a2 s^2 + a1 s + 1)``; ``"feedthrough"``: the pmsm with a direct feed-through,
        ``D + K / (a2 s^(zeta+theta) + a1 s^zeta + 1)`` (parameter ``D``); ``"fopdt"``: ``K e^(-tau s) / (T s + 1)``; ``"cell"``: a battery
        cell's ``D + Ki/s + K / (a1 s^q + 1)``; ``"auto"``: pmsm,
        commensurate, the integer first to third order, two-mass (and feedthrough and cell when the
        output responds at once to the input) fitted, the one the data support kept
        (``structures`` says which and why); a model (text or :class:`FracTf`): every coefficient
        and order fitted, starting from its values.
    validate : (array_like, array_like), optional
        A separate validation record ``(u, y)`` of the same plant at the same ``dt`` (``fracid
        time --validate FILE``): the models are scored on it with its own initial state and
        output offset (``validation_file``); ``holdout`` then defaults to 0.
    **options
        Every option of ``fracid time``, by the same name and with the same default (see
        :func:`time_request_defaults`): ``approx`` ("refined", "oustaloup", "trigeassou"),
        ``band`` ((w_b, w_h) rad/s), ``order``, ``integrator``, ``delay``, ``max_delay`` (s),
        ``fix`` ("NAME" or "NAME=VALUE", comma-separated), ``free``, ``start`` (dict of start
        values by parameter name), ``auto_start``, ``holdout`` (fraction held out; default 0.3),
        ``offsets`` ("initial", "mean", "none"), ``fit_offset``, ``initial`` ("auto", "estimate",
        "rest"), ``max_iterations`` (500), ``skip``, ``max_lag`` (25), ``plain`` (False, the
        default, or ``diagnose=True``: the loop closed, the candidate structures compared and the
        best diagnosed, docs/design.md §6, the result in ``TimeFit.diagnosis`` and the final
        model leading; True: the named structure fitted once, the fast path), ``margin``,
        ``min_r2``, ``max_rounds``.

    Returns
    -------
    TimeFit
        The leading model (the final one after a diagnosis), its parameters with standard
        errors, fit figures, caveats; ``report`` is ``fracid time --json``'s report itself.

    Raises
    ------
    DataError
        For NaN, empty or mismatched arrays, too few samples, no excitation, bad options.
    NumericalError
        If the simulation or a solve breaks down.
    """
    request = time_request(structure, **options)
    v = None if validate is None else tuple(validate)
    report, arrays = _fit_time(u, y, dt, json.dumps(request), v)
    return TimeFit._from_report(report, arrays)


def fit_time_joint(
    u: ArrayLike,
    y: ArrayLike,
    dt: float,
    structure: Union[str, FracTf, None] = None,
    *,
    joint: "list[Tuple[ArrayLike, ArrayLike]]",
    validate: Optional[Tuple[ArrayLike, ArrayLike]] = None,
    **options: object,
) -> Dict[str, Any]:
    """One model fitted to several records of the same plant at the same ``dt`` (``fracid time
    --joint``): the plant's parameters shared, each record with its own operating point, output
    offset and initial state, each used whole; scored on ``validate`` when given.

    Takes the options of :func:`fit_time` (the named structure fitted once; not
    ``structure="auto"``) and
    returns the report as ``fracid time --joint --json`` prints it (``model``, ``params``,
    ``records`` named ``record``, ``joint[0]``, ..., ``converged``, ``warnings``, ``fit``,
    ``usable``, ``problems``, ``request``): ``usable`` is the verdict ``fracid time --joint``
    exits on (the rules of a single record's fit on the record it fits worst, and the score on
    ``validate``: predicted worse than its own mean, not usable).

    Raises
    ------
    DataError
        For bad arrays or options, records at other steps.
    """
    request = time_request(structure, **options)
    v = None if validate is None else tuple(validate)
    return dict(_fit_time_joint(u, y, dt, json.dumps(request), [tuple(r) for r in joint], v))


def structures() -> Dict[str, str]:
    """The named structures ``structure=`` takes (and ``fracid time --structure``), each with
    what it is, in the catalogue's order: the names the structure comparison's rows print."""
    return dict(_structures())


def time_request_defaults() -> Dict[str, object]:
    """Every option of :func:`fit_time` (and ``fracid time``) with its default: the
    ``ident::app::time::TimeRequest`` defaults, held once in the library."""
    return dict(_time_request_defaults())


def time_request(structure: Union[str, FracTf, None] = None, **options: object) -> Dict[str, object]:
    """The request :func:`fit_time` sends: the options given (checked by name), the rest left to
    their defaults. A :class:`FracTf` structure is sent as its text.

    Raises
    ------
    DataError
        For an option ``fracid time`` does not have.
    """
    known = _time_request_defaults()
    request: Dict[str, object] = {}
    options = dict(options)
    if "diagnose" in options and "plain" not in options:
        # ``diagnose=True`` names the default, the loop closed (``plain=False``);
        # ``diagnose=False`` the single fit.
        diagnosed = options.pop("diagnose")
        if diagnosed is not None:
            options["plain"] = not diagnosed
    if structure is not None:
        request["structure"] = str(structure)
    for name, value in options.items():
        if name not in known:
            raise DataError(
                f"fit_time has no option {name!r}; the options are {', '.join(sorted(known))}"
            )
        if value is None:
            continue
        if name in ("max_iterations", "skip", "order", "max_lag", "max_rounds"):
            value = _count(name, value)  # type: ignore[arg-type]
        if name == "band":
            value = [float(x) for x in value]  # type: ignore[attr-defined]
        request[name] = value
    return request


def diagnose(
    u: ArrayLike,
    y: ArrayLike,
    dt: float,
    structure: Union[str, FracTf] = "pmsm",
    **kwargs: object,
) -> Diagnosis:
    """Fit ``structure`` by output error and diagnose what the fit cannot explain.

    The same as ``fit_time(u, y, dt, structure, **kwargs).diagnosis`` (the default closes the
    loop); see
    :func:`fit_time` for the parameters.

    Returns
    -------
    Diagnosis
        The error before and after, the effects kept with their parameters and evidence, the
        candidates rejected and why, ambiguities, and whether structure remains unexplained.
    """
    kwargs["plain"] = False
    fit = fit_time(u, y, dt, structure, **kwargs)  # type: ignore[arg-type]
    assert fit.diagnosis is not None
    return fit.diagnosis
