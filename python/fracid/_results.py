"""Typed result objects of the fits and of the drive client. Every one is a frozen dataclass with ``to_dict()``, which
returns plain Python types (numpy arrays become lists, models become the docs/design.md §7 JSON
object) so that ``json.dumps(result.to_dict())`` works."""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, Dict, List, NamedTuple, Optional, Tuple

import numpy as np

import json

from ._fracid import FracTf, _answer_pointer

__all__ = [
    "LevyFit",
    "PmsmFit",
    "QCurve",
    "FreqFit",
    "ParamEstimate",
    "FitMetrics",
    "ResidualTest",
    "TimeFit",
    "Effect",
    "Diagnosis",
    "Acquisition",
    "BodeSweep",
]


def _plain(v: Any) -> Any:
    if isinstance(v, FracTf):
        return v.to_dict()
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    if hasattr(v, "to_dict"):
        return v.to_dict()
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    return v


class _ToDict:
    def to_dict(self) -> Dict[str, Any]:
        """The fields as plain Python types (JSON-serialisable)."""
        return {f.name: _plain(getattr(self, f.name)) for f in fields(self)}  # type: ignore[arg-type]


@dataclass(frozen=True)
class LevyFit(_ToDict):
    """A commensurate-order Levy fit ``sum_u b_u s^(u q) / (1 + sum_p a_p s^(p q))``.

    Attributes
    ----------
    q : float
        The commensurate order.
    b : list of float
        Numerator coefficients ``b_0 .. b_m``.
    a : list of float
        Denominator coefficients ``a_1 .. a_n`` (``a_0 = 1``).
    model : FracTf
        The fitted model.
    J : float
        Error index of the paper's eq. 30, ``(1/f) sum |G(jw) - Ghat(jw)|^2`` (w in rad/s).
    levy_cost : float
        The weighted Levy cost that was minimised.
    sk_iterations : int
        Sanathanan-Koerner iterations done (at most those asked: they stop once converged).
    sk_converged : bool
        Whether they converged (True without them).
        Sanathanan-Koerner iterations done after the first solve.
    """

    q: float
    b: List[float]
    a: List[float]
    model: FracTf
    J: float
    levy_cost: float
    sk_iterations: int
    sk_converged: bool = True


@dataclass(frozen=True)
class PmsmFit(_ToDict):
    """The nonlinear refit of ``K / (a2 s^(zeta+theta) + a1 s^zeta + 1)`` (two free orders).

    Attributes
    ----------
    model : FracTf
        The refitted model.
    K, a1, a2, zeta, theta : float
        Its parameters.
    J : float
        Error index (eq. 30) on the data.
    std_errors : dict or None
        Standard errors by name (``None`` when the Jacobian is singular).
    converged : bool
        Whether Levenberg-Marquardt converged.
    termination : str
        Why it stopped.
    iterations : int
        Levenberg-Marquardt iterations.
    """

    model: FracTf
    K: float
    a1: float
    a2: float
    zeta: float
    theta: float
    J: float
    std_errors: Optional[Dict[str, float]]
    converged: bool
    termination: str
    iterations: int


@dataclass(frozen=True)
class QCurve(_ToDict):
    """The error index ``J`` of the Levy fit at each order ``q`` of the grid.

    Attributes
    ----------
    q : numpy.ndarray
        The orders, increasing.
    J : numpy.ndarray
        ``J(q)`` (``inf`` where the solve broke down).
    """

    q: np.ndarray
    J: np.ndarray


@dataclass(frozen=True)
class FreqFit(_ToDict):
    """The result of :func:`fracid.fit_bode`.

    Attributes
    ----------
    levy : LevyFit
        Levy's fit at the chosen order (refined by golden section unless ``refine_q=False``).
    levy_grid : LevyFit
        Levy's fit at the best order of the grid (the paper's procedure).
    curve : QCurve
        ``J(q)`` on the grid.
    sk : LevyFit or None
        The Sanathanan-Koerner fit, with ``sk_iterations > 0``.
    sk_curve : QCurve
        ``J(q)`` of the SK fit (empty without SK).
    refined : PmsmFit or None
        The PMSM refit, with ``refine=True``.
    best_model : FracTf
        The best model by ``J`` among the above.
    answer : FracTf
        The model the report leads with, by the library's one rule (the diagnosed model, else
        ``best_model``): the one ``fracid tune``, ``compare``, ``export`` and the fleet take, and
        :func:`fracid.tune` takes from this result.
    problems : list of str
        Why the answer cannot be used (empty when it can): unstable (poles in the closed
        right half-plane), non-finite, refit parameters the data do not determine.
    warnings : list of str
        What to know without making the model unusable (a negative static gain, no convergence).
    diagnosis : dict or None
        The residual diagnosis (``diagnose=True``): effects kept with their evidence, ``J``
        before and after, and the final ``model``.
    hold_s : float or None
        The sample period whose zero-order hold was divided out.
    report : dict
        The report as ``fracid freq --json`` prints it.
    """

    levy: LevyFit
    levy_grid: LevyFit
    curve: QCurve
    sk: Optional[LevyFit]
    sk_curve: QCurve
    refined: Optional[PmsmFit]
    best_model: FracTf
    problems: List[str] = field(default_factory=list)
    warnings: List[str] = field(default_factory=list)
    diagnosis: Optional[Dict[str, Any]] = None
    hold_s: Optional[float] = None
    report: Dict[str, Any] = field(default_factory=dict, repr=False)
    answer: Optional[FracTf] = None

    @property
    def usable(self) -> bool:
        """Whether the answer can be used (no ``problems``)."""
        return not self.problems

    @property
    def J(self) -> float:
        """The error index of the best model."""
        cands = [self.levy.J]
        if self.sk is not None:
            cands.append(self.sk.J)
        if self.refined is not None:
            cands.append(self.refined.J)
        return min(cands)

    @classmethod
    def _from_report(cls, r: Dict[str, Any]) -> "FreqFit":
        def levy(d: Dict[str, Any]) -> LevyFit:
            return LevyFit(
                q=d["q"], b=d["b"], a=d["a"], model=_tf_of(d["model"]), J=d["J"],
                levy_cost=d["levy_cost"], sk_iterations=d["sk_iterations"],
                sk_converged=d["sk_converged"],
            )

        def curve(c: Optional[List[Dict[str, Any]]]) -> QCurve:
            c = c or []
            return QCurve(
                q=np.array([p["q"] for p in c], dtype=float),
                J=np.array([np.inf if p["J"] is None else p["J"] for p in c], dtype=float),
            )

        refined = None
        if r.get("refined") is not None:
            d = dict(r["refined"])
            d["model"] = _tf_of(d["model"])
            refined = PmsmFit(**d)
        return cls(
            levy=levy(r["levy"]),
            levy_grid=levy(r["levy_grid"]),
            curve=curve(r["curve"]),
            sk=None if r.get("sk") is None else levy(r["sk"]),
            sk_curve=curve(r.get("sk_curve")),
            refined=refined,
            best_model=_tf_of(r["best_model"]),
            problems=list(r["problems"]),
            warnings=list(r["warnings"]),
            diagnosis=r.get("diagnosis"),
            hold_s=r.get("hold_s"),
            report=r,
            answer=_answer_of(r),
        )


@dataclass(frozen=True)
class ParamEstimate(_ToDict):
    """One parameter of a time-domain fit.

    Attributes
    ----------
    name : str
        Its name (``K``, ``a1``, ``a2``, ``zeta``, ``theta``, ``q``, ``tau``, ``y_offset``, ...).
    value : float
        The estimate.
    std_error : float or None
        Standard error by the delta method (``None`` when fixed or the covariance is singular).
    free : bool
        Whether it was fitted.
    at_bound : bool
        Whether it ended at a bound of its range.
    """

    name: str
    value: float
    std_error: Optional[float]
    free: bool
    at_bound: bool


@dataclass(frozen=True)
class FitMetrics(_ToDict):
    """Fit of a model output to data, as MATLAB's ``compare``.

    Attributes
    ----------
    rmse : float
        Root-mean-square error, in the unit of ``y``.
    nrmse_percent : float
        ``100 (1 - ||y - yhat|| / ||y - mean(y)||)``: 100 is perfect.
    """

    rmse: float
    nrmse_percent: float


@dataclass(frozen=True)
class ResidualTest(_ToDict):
    """Whiteness and input-independence of the estimation residual at the 99% level.

    Attributes
    ----------
    bound : float
        ``2.58 / sqrt(N)``.
    auto_outside : int
        Autocorrelation lags ``1..max_lag`` outside the bound.
    cross_outside : int
        Residual-input cross-correlation lags ``-max_lag..max_lag`` outside the bound.
    cross_peak_lag : int
        Lag of the largest cross-correlation.
    cross_peak : float
        The largest cross-correlation.
    """

    bound: float
    auto_outside: int
    cross_outside: int
    cross_peak_lag: int
    cross_peak: float


@dataclass(frozen=True)
class Effect(_ToDict):
    """An effect the diagnosis kept (docs/design.md §6).

    Attributes
    ----------
    name : str
        Report name: ``delay``, ``coulomb_friction``, ``input_offset``, ``output_offset``,
        ``output_drift``, ``periodic``, ``abs_sensor``, ``saturation``, ``deadzone``,
        ``power_law``.
    params : dict
        Its fitted parameters (e.g. ``{"tau": 0.012}``, ``{"Vc": 0.15}``).
    evidence : str
        What in the residual pointed to it and what the refit gained.
    r2 : float
        Fraction of the residual's sum of squares its signature explained before the refit.
    ssr_removed_percent : float
        Percent of the estimation residual's sum of squares the refit with it removed.
    rmse_change_percent : float
        Relative change of the validation RMSE, percent (negative is better).
    bic_change : float
        Change of BIC on the estimation part (negative is better).
    sampled : bool or None
        For ``coulomb_friction``: its sign decided at the sample instant and held (``True``) or
        at the hold interval's middle (``False``); ``None`` for the other effects. ``tune``
        simulates the loop's friction the same way.
    """

    name: str
    params: Dict[str, float]
    evidence: str
    r2: float
    ssr_removed_percent: float
    rmse_change_percent: float
    bic_change: float
    sampled: Optional[bool] = None


@dataclass(frozen=True)
class Diagnosis(_ToDict):
    """The residual diagnosis of a time-domain fit (``fit_time(..., diagnose=True)``).

    Attributes
    ----------
    before, after : FitMetrics
        Validation fit (estimation fit without a validation part) of the base model and of the
        model with the kept effects.
    estimation, validation : dict
        ``{"before": FitMetrics, "after": FitMetrics}`` per part (``validation`` may be ``None``).
    effects : list of Effect
        Effects kept, in the order they were added.
    rejected : list of dict
        Candidates tested and not kept: ``name``, ``reason``, ``params``.
    ambiguous : list of dict
        Effects these data cannot identify: ``name``, ``confused_with``, ``reason``.
    quantization : dict or None
        Output quantization found (``step``, ``levels``, ``noise_floor_rms``).
    unexplained : bool
        Whether structure remains in the residual that no effect explains.
    remaining : list of str
        What remains.
    residual_before, residual_after : dict
        Residual tests of the base and final model (estimation part).
    model : FracTf
        The final linear part (with its delay).
    final_model : str
        The final model in words: linear part, delay and effects with their parameters.
    structures : dict or None
        The structures compared (each fitted and diagnosed): ``scores`` (name, model, rmse,
        effects, rmse_after, bic_after, ...), ``chosen`` (index) and ``reason``.
    params : dict
        Every parameter of the final model (effects included) by name.
    yhat_before, yhat_after : numpy.ndarray
        Model outputs on the absolute scale, whole record.
    split : int
        First validation sample.
    """

    before: FitMetrics
    after: FitMetrics
    estimation: Dict[str, FitMetrics]
    validation: Optional[Dict[str, FitMetrics]]
    effects: List[Effect]
    rejected: List[Dict[str, Any]]
    ambiguous: List[Dict[str, Any]]
    quantization: Optional[Dict[str, Any]]
    unexplained: bool
    remaining: List[str]
    residual_before: Dict[str, Any]
    residual_after: Dict[str, Any]
    model: FracTf
    params: Dict[str, float]
    yhat_before: np.ndarray = field(repr=False)
    yhat_after: np.ndarray = field(repr=False)
    split: int = 0
    final_model: str = ""
    structures: Optional[Dict[str, Any]] = None

    @property
    def names(self) -> List[str]:
        """Names of the kept effects."""
        return [e.name for e in self.effects]

    @classmethod
    def _from_raw(cls, d: Dict[str, Any]) -> "Diagnosis":
        d = dict(d)
        ba = lambda x: None if x is None else {k: FitMetrics(**v) for k, v in x.items()}  # noqa: E731
        d["before"] = FitMetrics(**d["before"])
        d["after"] = FitMetrics(**d["after"])
        d["estimation"] = ba(d["estimation"])
        d["validation"] = ba(d["validation"])
        d["effects"] = [Effect(**e) for e in d["effects"]]
        known = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in d.items() if k in known})


@dataclass(frozen=True)
class TimeFit(_ToDict):
    """The result of :func:`fracid.fit_time`: the report of ``fracid time --json`` (``report``,
    the same fields) with typed attributes and the model outputs as arrays.

    Attributes
    ----------
    model : FracTf
        The leading model's linear part (offsets not included): the fit, or with the diagnosis
        the final model (``model_is`` says which; the base fit is then in ``base``).
    params : list of ParamEstimate
        The leading model's parameters (the base fit's with standard errors); also by name with
        :meth:`param`.
    estimation : FitMetrics
        The leading model's fit on the estimation part.
    validation : FitMetrics or None
        Its fit on the held-out part (simulated from the start of the record).
    validation_file : dict or None
        Its score on the separate validation record (``validate=``).
    yhat : numpy.ndarray
        The leading model's output on the absolute scale over the whole record.
    yhat_base : numpy.ndarray
        The base fit's output (the same as ``yhat`` without the diagnosis).
    split : int
        Index of the first validation sample (the record's length when nothing is held out, or
        when blocks spread over the record are, ``validated_by["blocks"]``).
    model_is : str
        Which model leads, in words.
    base : dict or None
        With the diagnosis: the base fit (``model``, ``params``, ``fit``, ``alpha_eta``,
        ``warnings``, ``usable``, ``problems``).
    structures : dict or None
        With ``structure="auto"`` (and no diagnosis): the structures fitted and the choice
        (``scores``, ``chosen``, ``held_out``, ``reason``), as ``fracid time --structure auto``.
    validated_by : dict
        How the model was validated: ``kind`` (``held_out``, ``held_out_blocks``,
        ``response_tail``, ``file``, ``none``), ``first`` (first held-out sample), with
        ``held_out_blocks`` the ``blocks`` held out (``[start, end)`` pairs: a sweep), and
        ``note`` (in words).
    offsets : dict
        The operating point removed, ``{"u0": .., "y0": ..}``.
    converged : bool
        Whether Levenberg-Marquardt converged (the base fit).
    termination, stop_reason : str
        Why it stopped (code and sentence).
    iterations, evaluations : int
        Levenberg-Marquardt iterations and simulations.
    seconds : float
        Wall time of the whole use case in seconds (``elapsed_s`` is the same).
    warnings : list of str
        Every caveat: parameters at a bound, no convergence, the validation split, a negative
        static gain.
    usable : bool
        Whether the model can be used; when False, ``problems`` says why.
    problems : list of str
        Why the model cannot be used: unstable, no finite static gain, parameters the data do
        not determine (standard error above the value, singular covariance), non-finite scores.
    alpha_eta : list of (float, float, float)
        ``(order, alpha, eta)`` of each non-integer order (Poinot-Trigeassou).
    start : dict
        The values the fit started from, by name.
    start_report : dict
        How the start was made (``method``, ``note``, ``fit_percent``).
    residual_test : ResidualTest
        Residual whiteness and independence from the input (base fit, estimation part).
    diagnosis : Diagnosis or None
        The residual diagnosis, with ``diagnose=True``.
    report : dict
        The report as ``fracid time --json`` prints it.
    """

    model: FracTf
    params: List[ParamEstimate]
    estimation: FitMetrics
    validation: Optional[FitMetrics]
    yhat: np.ndarray = field(repr=False)
    yhat_base: np.ndarray = field(repr=False)
    split: int
    offsets: Dict[str, float]
    converged: bool
    termination: str
    stop_reason: str
    iterations: int
    evaluations: int
    seconds: float
    warnings: List[str]
    usable: bool
    problems: List[str]
    alpha_eta: List[Tuple[float, float, float]]
    start: Dict[str, float]
    start_report: Dict[str, Any]
    residual_test: ResidualTest
    model_is: str
    diagnosis: Optional[Diagnosis] = None
    validated_by: Dict[str, Any] = field(default_factory=dict)
    structures: Optional[Dict[str, Any]] = None
    base: Optional[Dict[str, Any]] = None
    validation_file: Optional[Dict[str, Any]] = None
    report: Dict[str, Any] = field(default_factory=dict, repr=False)

    def param(self, name: str) -> ParamEstimate:
        """The parameter called ``name``.

        Raises
        ------
        KeyError
            If there is none.
        """
        for p in self.params:
            if p.name == name:
                return p
        raise KeyError(f"no parameter {name!r}; have {[p.name for p in self.params]}")

    @property
    def values(self) -> Dict[str, float]:
        """Parameter values by name."""
        return {p.name: p.value for p in self.params}

    @property
    def elapsed_s(self) -> float:
        """Wall time in seconds (the report's ``seconds``)."""
        return self.seconds

    @classmethod
    def _from_report(cls, r: Dict[str, Any], arrays: Dict[str, Any]) -> "TimeFit":
        fit = r["fit"]
        diagnosis = None
        if r.get("diagnosis") is not None:
            d = dict(r["diagnosis"])
            d["model"] = _tf_of(d["model"])
            d["params"] = dict(arrays["diagnosis_params"])
            d["yhat_before"] = arrays["yhat_before"]
            d["yhat_after"] = arrays["yhat_after"]
            d["split"] = arrays["diagnosis_split"]
            diagnosis = Diagnosis._from_raw(d)
        return cls(
            model=_tf_of(r["model"]),
            params=[ParamEstimate(**p) for p in r["params"]],
            estimation=FitMetrics(**fit["estimation"]),
            validation=None if fit["validation"] is None else FitMetrics(**fit["validation"]),
            validation_file=fit.get("validation_file"),
            yhat=arrays["yhat"],
            yhat_base=arrays["yhat_base"],
            split=r["validated_by"]["first"],
            offsets=r["offsets"],
            converged=r["converged"],
            termination=r["termination"],
            stop_reason=r["stop_reason"],
            iterations=r["iterations"],
            evaluations=r["evaluations"],
            seconds=r["seconds"],
            warnings=r["warnings"],
            usable=r["usable"],
            problems=r["problems"],
            alpha_eta=[(a["order"], a["alpha"], a["eta"]) for a in r["alpha_eta"]],
            start=r["start_values"],
            start_report=r["start"],
            residual_test=ResidualTest(**r["residual_test"]),
            model_is=r["model_is"],
            diagnosis=diagnosis,
            validated_by=r["validated_by"],
            structures=r.get("structures"),
            base=r.get("base"),
            report=r,
        )


def _answer_of(r: Dict[str, Any]) -> FracTf:
    """The model a report leads with, found by the library's one rule (``_answer_pointer``)."""
    node: Any = r
    for key in [k for k in _answer_pointer(json.dumps(r)).split("/") if k]:
        node = node[key]
    return _tf_of(node)


def _tf_of(m: Dict[str, Any]) -> FracTf:
    """The :class:`FracTf` of a report's model object (``num``, ``den``, ``delay``)."""
    terms = lambda ts: [(t["coef"], t["order"]) for t in ts]  # noqa: E731
    return FracTf(terms(m["num"]), terms(m["den"]), m.get("delay", 0.0))


@dataclass(frozen=True)
class Acquisition(_ToDict):
    """A record streamed from the drive by :meth:`DriveClient.run_prbs`.

    Samples that arrived are kept whatever happened; ``complete`` says whether all did. Time is
    ``index / sample_rate_hz``, so a gap in ``index`` (see ``missing``) is a gap in ``t``.

    Attributes
    ----------
    run_id : int
        The drive's id of the run.
    sample_rate_hz : int
        Sample rate in Hz.
    total_samples : int
        Samples the run should have.
    index : numpy.ndarray
        Sample index of each sample received (int, increasing).
    t : numpy.ndarray
        Time of each sample in seconds, from the start of the run.
    u : numpy.ndarray
        The voltage command in V (the drive's input).
    y : numpy.ndarray
        The measured speed in rad/s (the output).
    i : numpy.ndarray
        The current in A.
    complete : bool
        True only if every sample ``0 .. total_samples - 1`` arrived and the run ended normally.
    missing : list of (int, int)
        Missing sample ranges, half-open ``[start, end)``.
    problems : list of str
        Why the run is incomplete (empty when complete).
    clamped_blocks : int
        Data blocks in which the drive clamped the command.
    end_reason : str or None
        How the drive ended the run (``"complete"``, ``"stopped"``, ``"estop"``, ``"keepalive"``,
        ``"limit"``), ``None`` without an end-of-run summary.
    """

    run_id: int
    sample_rate_hz: int
    total_samples: int
    index: np.ndarray = field(repr=False)
    t: np.ndarray = field(repr=False)
    u: np.ndarray = field(repr=False)
    y: np.ndarray = field(repr=False)
    i: np.ndarray = field(repr=False)
    complete: bool = False
    missing: List[Tuple[int, int]] = field(default_factory=list)
    problems: List[str] = field(default_factory=list)
    clamped_blocks: int = 0
    end_reason: Optional[str] = None

    @property
    def dt(self) -> float:
        """The sampling step in seconds, ``1 / sample_rate_hz``."""
        return 1.0 / self.sample_rate_hz

    def __len__(self) -> int:
        return len(self.index)

    @classmethod
    def _from_raw(cls, d: Dict[str, Any]) -> "Acquisition":
        d = dict(d)
        d["missing"] = [(int(a), int(b)) for a, b in d["missing"]]
        return cls(**d)


class _BodeSweepFields(NamedTuple):
    """A frequency response measured by :meth:`DriveClient.run_sine_sweep`.

    A named tuple: ``freq_hz, gain_db, phase_deg, lost = client.run_sine_sweep(...)`` works.

    Attributes
    ----------
    freq_hz : numpy.ndarray
        Frequencies of the points measured, Hz (lost points are left out).
    gain_db : numpy.ndarray
        Gain ``|Y/U|`` in dB, physical units ((rad/s)/V).
    phase_deg : numpy.ndarray
        Phase of ``Y/U`` in degrees, unwrapped along the sweep.
    lost : list of str
        What went wrong: points measured again, points given up, frequencies skipped.
    """

    freq_hz: np.ndarray
    gain_db: np.ndarray
    phase_deg: np.ndarray
    lost: List[str]

    @property
    def omega(self) -> np.ndarray:
        """Angular frequencies in rad/s (for :func:`fracid.fit_bode`)."""
        return 2 * np.pi * np.asarray(self.freq_hz)

    @property
    def h(self) -> np.ndarray:
        """The complex response ``10^(gain_db/20) exp(j phase)`` (for :func:`fracid.fit_bode`)."""
        return 10 ** (np.asarray(self.gain_db) / 20) * np.exp(1j * np.deg2rad(self.phase_deg))


class BodeSweep(_BodeSweepFields):
    """A frequency response measured by :meth:`DriveClient.run_sine_sweep`.

    A named tuple of four: ``freq_hz, gain_db, phase_deg, lost = client.run_sine_sweep(...)``
    works; the spread of the repeats rides along as attributes.

    Attributes
    ----------
    freq_hz, gain_db, phase_deg, lost
        As the tuple's fields (``freq_hz`` is the frequency really applied: moved so the
        measurement window holds whole cycles).
    gain_db_std, phase_deg_std : numpy.ndarray or None
        Sample standard deviations of the repeats per point, dB and deg (zeros with one repeat).
    repeats : int
        Measurements per frequency.
    """

    def __new__(cls, freq_hz, gain_db, phase_deg, lost, gain_db_std=None, phase_deg_std=None, repeats=1):
        self = super().__new__(cls, freq_hz, gain_db, phase_deg, lost)
        self.gain_db_std = None if gain_db_std is None else np.asarray(gain_db_std)
        self.phase_deg_std = None if phase_deg_std is None else np.asarray(phase_deg_std)
        self.repeats = int(repeats)
        return self

    def to_dict(self) -> Dict[str, Any]:
        """The fields as plain Python types (JSON-serialisable)."""
        return {k: _plain(v) for k, v in zip(self._fields, self)}
