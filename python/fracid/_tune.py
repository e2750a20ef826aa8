"""``fracid.tune``: a fractional PI/PID designed on an identified model (the ``tune`` crate)."""

from __future__ import annotations

from typing import Any, Dict, Iterable, Mapping, Optional, Tuple, Union

import json

from ._fracid import FracTf, _tune

__all__ = ["tune"]


def _effects(effects: Optional[Iterable[Any]]) -> list:
    out = []
    for e in effects or ():
        if isinstance(e, Mapping):
            name, params, sampled = e["name"], e.get("params", {}), e.get("sampled")
        else:
            name, params, sampled = e.name, e.params, getattr(e, "sampled", None)
        out.append(
            (str(name), {str(k): float(v) for k, v in dict(params).items()}, bool(sampled))
        )
    return out


def tune(
    model: Union[FracTf, str, Any],
    *,
    wc: float,
    pm: float,
    form: Optional[str] = None,
    flat: Optional[bool] = None,
    dt: Optional[float] = None,
    t_high: Optional[Tuple[float, float]] = None,
    s_low: Optional[Tuple[float, float]] = None,
    lambda_: Optional[float] = None,
    step: Optional[float] = None,
    load: Optional[float] = None,
    effects: Optional[Iterable[Any]] = None,
    mu: Optional[float] = None,
    max_lambda: Optional[float] = None,
    max_mu: Optional[float] = None,
    max_ms: Optional[float] = None,
    min_gm: Optional[float] = None,
    min_lambda: Optional[float] = None,
    u_limit: Optional[float] = None,
) -> Dict[str, Any]:
    """Design ``C(s) = kp + ki / s^lambda (+ kd s^mu)`` on ``model``, as ``fracid tune --json``.

    The gain crossover ``wc``, the phase margin ``pm`` and, with ``flat``, a flat phase at ``wc``
    (``d arg L / d ln w = 0``, iso-damping) are met exactly (Monje, Vinagre, Feliu & Chen 2008);
    every design is checked on the loop (stability counted on its characteristic equation,
    margins on a grid refined around every lightly damped pole, the sampled loop with ``dt``) and
    against the robustness floors; a specification no controller of the form meets raises
    :class:`InfeasibleError` with the binding constraint.

    Parameters
    ----------
    model : FracTf, str, Diagnosis or FreqFit
        The plant (its delay included). A :class:`Diagnosis` gives its final model and its kept
        input effects (saturation, dead band, power law, Coulomb friction, input offset),
        simulated in the loop; a :class:`FreqFit` its ``answer`` (the model the report leads
        with: its diagnosed or best model, as ``fracid tune`` takes it from a report).
    wc : float
        Gain crossover, rad/s.
    pm : float
        Phase margin, degrees.
    form : {"fopi", "fopid", "fopd", "pi", "pid"}, optional
        The controller structure (``fopd``: ``kp + kd s^mu``); ``fopid`` needs ``flat``.

    Every option left at ``None`` takes the library's default (``tune::TuneRequest``, the same
    defaults as ``fracid tune``'s flags): ``form="fopi"``, no flat phase, ``max_ms=2``,
    ``min_gm=6``, ``min_lambda=0.5``, ``step=1``.
    flat : bool, optional
        Flat phase at ``wc``.
    dt : float, optional
        Sample period, s: the hold's half-sample delay joins the design and the report gives the
        discrete realisation (``report["discrete"]``).
    t_high, s_low : (float, float), optional
        ``(w, dB)``: ``|T| <= dB`` over the whole band above ``w``, ``|S| <= dB`` below it.
    lambda_, mu : float, optional
        Fixed orders: the integrator's (``fopi`` without ``flat``, ``fopid``), the
        differentiator's (``fopid``, ``fopd`` without ``flat``).
    max_lambda, max_mu : float, optional
        Caps on the orders searched.
    max_ms, min_gm, min_lambda : float, optional
        The robustness floors (``Ms <= 2``, a gain margin of 6 dB, integral action with
        ``lambda >= 0.5`` by default): a design that misses one is refused.
    step, load : float, optional
        The simulated reference step (output units) and load step at the plant's input (default:
        the input that holds the reference step, ``step / G(0)``).
    u_limit : float, optional
        The voltage limit on the controller's output in the simulated loops, input units: the
        output is clamped there with anti-windup, as the drive does.
    effects : iterable, optional
        Input effects to simulate in the loop: :class:`Effect` objects or mappings
        ``{"name": ..., "params": {...}}`` as a diagnosis reports them.

    Returns
    -------
    dict
        The report of ``fracid tune --json``: ``controller`` (``{num, den, delay, text}``),
        ``params`` (``kp``, ``ki``, ``lambda``, ``kd``, ``mu``), ``loop`` (``wc``, ``pm_deg``,
        ``gm_db``, ``ms``, ...), ``discrete``, ``step`` (the closed loop simulated),
        ``step_with_effects``, ``integer_pi``, ``model`` and ``spec``.

    Examples
    --------
    >>> import fracid
    >>> r = fracid.tune("6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1) exp(-0.001 s)",
    ...                 wc=300, pm=60, flat=True)
    >>> round(r["loop"]["pm_deg"], 3), round(r["params"]["lambda"], 3)
    (60.0, 1.577)
    """
    fx = effects
    if not isinstance(model, (FracTf, str)) and getattr(model, "answer", None) is not None:
        # a frequency-domain result: the model it leads with (its diagnosed or best model)
        model = model.answer
    if not isinstance(model, (FracTf, str)) and hasattr(model, "model"):
        fx = model.effects if effects is None else effects
        model = model.model
    given = {
        "wc": wc,
        "pm": pm,
        "form": None if form is None else str(form).lower(),
        "flat": None if flat is None else bool(flat),
        "dt": dt,
        "t_high": None if t_high is None else {"omega": float(t_high[0]), "db": float(t_high[1])},
        "s_low": None if s_low is None else {"omega": float(s_low[0]), "db": float(s_low[1])},
        "lambda": lambda_,
        "mu": mu,
        "max_lambda": max_lambda,
        "max_mu": max_mu,
        "max_ms": max_ms,
        "min_gm": min_gm,
        "min_lambda": min_lambda,
        "step": step,
        "load": load,
        "u_limit": u_limit,
    }
    # the options given; the others take the library's defaults
    request = {
        k: v if isinstance(v, (bool, str, dict)) else float(v)
        for k, v in given.items()
        if v is not None
    }
    text = _tune(model, json.dumps(request), _effects(fx))
    report: Dict[str, Any] = json.loads(text)
    return report
