"""The exception hierarchy of fracid.

Every error raised by the Rust core reaches Python as one of these classes, with the message of the
Rust error unchanged.

- :class:`FracidError` -- the base of all of them.
- :class:`ParseError` -- a model expression that does not parse (also a :class:`ValueError`).
- :class:`DataError` -- unusable data or arguments: NaN, empty or mismatched arrays, bad options
  (also a :class:`ValueError`).
- :class:`NumericalError` -- a numerical breakdown: a singular solve, a simulation that diverges
  (also an :class:`ArithmeticError`).
- :class:`InfeasibleError` -- a controller specification that no controller of the form meets
  (:func:`fracid.tune`; the message gives the reason; also a :class:`ValueError`).
- :class:`DriveError` -- the drive or the serial link: a port that cannot be opened, a drive that
  does not answer, rejects a command or resets, a run before ``configure()``.
"""

from __future__ import annotations

__all__ = [
    "FracidError",
    "ParseError",
    "DataError",
    "NumericalError",
    "InfeasibleError",
    "DriveError",
]


class FracidError(Exception):
    """Base class of every fracid error."""


class ParseError(FracidError, ValueError):
    """A model expression could not be parsed; the message gives the position."""


class DataError(FracidError, ValueError):
    """The data or an argument is unusable (NaN, empty, mismatched lengths, out of range)."""


class NumericalError(FracidError, ArithmeticError):
    """A computation broke down numerically (singular system, non-finite simulation)."""


class InfeasibleError(FracidError, ValueError):
    """A controller specification (crossover, phase margin, flatness, bounds) that no controller
    of the requested form meets; the message says why. The design is refused rather than returned
    missing the specification."""


class DriveError(FracidError):
    """The drive or the serial link failed: the port cannot be opened, the drive does not answer
    (after the retries), rejects a command, speaks another protocol version or reset; or the
    client is used before ``configure()`` or after ``close()``."""
