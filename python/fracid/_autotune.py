"""``fracid.autotune``: ``fracid drive autotune`` from Python (the ``autotune`` crate): the probe,
the identification experiment designed from it, the experiments that separate what its diagnosis
cannot tell apart, a FOPI tuned on the final model and its step measured on the drive."""

from __future__ import annotations

import json
from typing import Any, Dict

from ._fracid import _autotune, _autotune_request_defaults

__all__ = ["autotune", "autotune_request_defaults"]


def autotune_request_defaults() -> Dict[str, Any]:
    """Every option of :func:`autotune` (and ``fracid drive autotune``) with its default: the
    ``autotune::tuner::AutotuneRequest`` defaults, held once in the library."""
    return dict(_autotune_request_defaults())


def autotune(
    port: str,
    *,
    sample_rate: int = 1000,
    baud: int = 115200,
    keepalive_ms: int = 150,
    **options: Any,
) -> Dict[str, Any]:
    """Autotune the drive at ``port``; the report as ``fracid drive autotune --json`` prints it.

    Parameters
    ----------
    port : str
        The serial port (or the path a ``fracid drive sim`` / :class:`DriveSimulator` prints).
    sample_rate, baud, keepalive_ms
        The drive's sample rate (Hz), the line rate, the interval of the host's KEEPALIVE frames
        (a few ms lets a simulator in virtual time run far faster than real time).
    **options
        The request's options by the same names and with the same defaults as
        :func:`autotune_request_defaults`: ``u_limit_v`` (V), ``speed_limit_rad_s``,
        ``budget_s`` (drive time), ``wc`` (rad/s), ``pm_deg``, ``operating_point_v``,
        ``max_rounds``, ``seed``, ``filter`` (for a resonance: ``"auto"``, ``"notch"``,
        ``"low-pass"`` or ``"none"``).

    Returns
    -------
    dict
        The report: ``probe``, ``experiments``, ``rounds`` (each record's error before and
        after), ``model`` (with ``friction_v``, ``resonance``), ``control`` (the step predicted
        and measured), ``usable`` and ``problems``.

    Raises
    ------
    DataError
        An option unknown or out of range.
    DriveError
        The drive or its link failed.
    """
    known = autotune_request_defaults()
    unknown = sorted(set(options) - set(known))
    if unknown:
        from ._errors import DataError

        raise DataError(f"autotune: unknown option(s) {unknown}; known: {sorted(known)}")
    return dict(_autotune(port, json.dumps(options), sample_rate, baud, keepalive_ms))
