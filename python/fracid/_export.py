"""A model's approximation as a state space, for control design in scipy and python-control.

:meth:`fracid.FracTf.to_state_space` returns a :class:`StateSpace`; ``A, B, C, D = ss`` unpacks
it, :meth:`StateSpace.to_scipy` and :meth:`StateSpace.to_control` hand it to those libraries
(imported only when called: ``pip install fracid[scipy]`` / ``fracid[control]``).
"""

from __future__ import annotations

import copy
import json
from dataclasses import dataclass, field
from typing import Any, Dict, Iterator, Optional, Tuple

import numpy as np

from ._errors import DataError

__all__ = ["StateSpace"]


@dataclass(frozen=True)
class StateSpace:
    """``x' = A x + B u, y = C x + D u`` (continuous) or ``x[k+1] = A x[k] + B u[k]``,
    ``y[k] = C x[k] + D u[k]`` (discrete, exact for ``u`` held over each period ``dt``).

    The realisation is real and block-diagonal (one block per mode of the pole-residue form of
    the approximation, each balanced), so it is well conditioned even with tens of states.

    Attributes
    ----------
    a, b, c, d : numpy.ndarray
        The matrices, shapes ``(n, n)``, ``(n, 1)``, ``(1, n)``, ``(1, 1)``.
    dt : float or None
        The sample period in seconds; ``None`` for a continuous model.
    input_delay : float
        A continuous model's input delay in seconds, not held in the matrices (0 when discrete:
        the delay is then in the last ``delay_states`` states, whole and fractional samples).
    delay_states : int
        How many of the last states are the input delay line (discrete).
    model : str
        The fractional model the approximation stands for.
    method, band, order
        The approximation: method, band ``(w_b, w_h)`` in rad/s and order ``N``.
    """

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    d: np.ndarray
    dt: Optional[float]
    input_delay: float
    delay_states: int
    model: str
    method: str
    band: Tuple[float, float]
    order: int
    _doc: Dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def _from_json(cls, text: str) -> "StateSpace":
        """The state space from its JSON document (``fracid export --format json``'s, which
        :meth:`to_dict` gives back)."""
        doc = json.loads(text)
        ap = doc["approximation"]
        return cls(
            a=np.array(doc["a"], dtype=float).reshape(doc["states"], doc["states"]),
            b=np.array(doc["b"], dtype=float).reshape(doc["states"], 1),
            c=np.array(doc["c"], dtype=float).reshape(1, doc["states"]),
            d=np.array(doc["d"], dtype=float).reshape(1, 1),
            dt=doc["dt"],
            input_delay=float(doc["input_delay"]),
            delay_states=int(doc["delay_states"]),
            model=doc["model"],
            method=ap["method"],
            band=(float(ap["band"][0]), float(ap["band"][1])),
            order=int(ap["order"]),
            _doc=doc,
        )

    def __iter__(self) -> Iterator[np.ndarray]:
        """``A, B, C, D = ss``."""
        return iter((self.a, self.b, self.c, self.d))

    @property
    def discrete(self) -> bool:
        """Whether the model is discrete (``dt`` set)."""
        return self.dt is not None

    @property
    def n_states(self) -> int:
        """The number of states."""
        return int(self.a.shape[0])

    def _no_delay(self, what: str) -> None:
        if self.input_delay > 0.0:
            raise DataError(
                f"{what} holds no input delay: this continuous model has {self.input_delay} s; "
                "export it discrete (dt=...), where the delay is exact extra states"
            )

    def to_scipy(self) -> Any:
        """The model as ``scipy.signal.StateSpace``: continuous, or discrete (a ``dlti``, for
        ``scipy.signal.dlsim``) with ``dt``.

        Raises
        ------
        ImportError
            If scipy is not installed (``pip install fracid[scipy]``).
        DataError
            For a continuous model with an input delay (scipy has none).
        """
        # The request is checked first: a delay is refused the same with or without scipy.
        self._no_delay("scipy.signal.StateSpace")
        try:
            from scipy import signal
        except ImportError as e:  # pragma: no cover - exercised only without scipy
            raise ImportError("to_scipy needs scipy: pip install fracid[scipy]") from e
        if self.dt is None:
            return signal.StateSpace(self.a, self.b, self.c, self.d)
        return signal.StateSpace(self.a, self.b, self.c, self.d, dt=self.dt)

    def to_control(self) -> Any:
        """The model as python-control's ``StateSpace`` (``control.ss``), with ``dt`` when
        discrete (for ``control.forced_response``).

        Raises
        ------
        ImportError
            If python-control is not installed (``pip install fracid[control]``).
        DataError
            For a continuous model with an input delay.
        """
        self._no_delay("control.StateSpace")
        try:
            import control
        except ImportError as e:  # pragma: no cover - exercised only without control
            raise ImportError("to_control needs python-control: pip install fracid[control]") from e
        return control.ss(self.a, self.b, self.c, self.d, 0 if self.dt is None else self.dt)

    def to_dict(self) -> Dict[str, Any]:
        """Plain Python types: the document ``fracid export --format json`` writes.

        Raises
        ------
        DataError
            For a state space not made by fracid (``FracTf.to_state_space``).
        """
        if not self._doc:
            raise DataError("to_dict: this StateSpace was not made by FracTf.to_state_space")
        return copy.deepcopy(self._doc)
