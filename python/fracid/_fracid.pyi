"""Type stubs of the Rust extension module ``fracid._fracid``."""

from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

class FracTf:
    """A fractional transfer function ``sum_i b_i s^beta_i / sum_j a_j s^alpha_j * exp(-delay s)``.

    Parameters
    ----------
    num, den : list of (float, float)
        Terms ``(coef, order)`` of numerator and denominator; orders >= 0.
    delay : float
        Input delay in seconds (>= 0).

    Raises
    ------
    DataError
        Non-finite or negative values, a zero denominator.
    """

    def __init__(
        self,
        num: List[Tuple[float, float]],
        den: List[Tuple[float, float]],
        delay: float = 0.0,
    ) -> None: ...
    @staticmethod
    def parse(text: str) -> "FracTf":
        """Parse e.g. ``"6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)"`` (``exp(-0.001 s)`` may be
        a factor).

        Raises
        ------
        ParseError
            With the position of the problem.
        """
    @staticmethod
    def pmsm(k: float, a1: float, a2: float, zeta: float, theta: float) -> "FracTf":
        """The PMSM structure ``k / (a2 s^(zeta+theta) + a1 s^zeta + 1)`` (paper eq. 10)."""
    @property
    def num(self) -> List[Tuple[float, float]]:
        """Numerator terms ``(coef, order)``, decreasing order."""
    @property
    def den(self) -> List[Tuple[float, float]]:
        """Denominator terms ``(coef, order)``, decreasing order."""
    @property
    def delay(self) -> float:
        """Input delay in seconds."""
    def dc_gain(self) -> float:
        """The static gain ``G(0)`` (``inf`` for an integrating model)."""
    def with_delay(self, delay: float) -> "FracTf":
        """The same model with another input delay (seconds)."""
    def freq_response(self, omega: npt.ArrayLike) -> npt.NDArray[np.complex128]:
        """``G(j omega)`` at each omega in rad/s, exact: ``(jw)^a = w^a e^(j a pi/2)``."""
    def bode(
        self, omega: npt.ArrayLike
    ) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Magnitude in dB and unwrapped phase in degrees at each omega (rad/s)."""
    def simulate(
        self,
        u: npt.ArrayLike,
        dt: float,
        method: str = "refined",
        band: Optional[Tuple[float, float]] = None,
        order: int = 8,
    ) -> npt.NDArray[np.float64]:
        """Simulate from rest on input ``u`` sampled every ``dt`` seconds and held between samples
        (``u[k]`` acts on ``[t_k, t_(k+1))``, ``y[k]`` is the output at ``t_k``).

        Parameters
        ----------
        u : array_like
            Input samples (finite, at least one).
        dt : float
            Sampling step in seconds.
        method : {"oustaloup", "refined", "trigeassou", "gl"}
            An Oustaloup, refined Oustaloup or Poinot-Trigeassou approximation of each operator,
            the whole model discretised exactly for the held input; or ``"gl"``, the
            Grunwald-Letnikov reference at dt/10 and dt/20, Richardson-extrapolated (the whole
            memory: at most 10000 samples).
        band : (float, float), optional
            Approximation band in rad/s (default ``[1e-6/dt, 30 pi/dt]``).
        order : int
            Approximation order N (2N+1 cells).

        Returns
        -------
        numpy.ndarray
            The output, same length as ``u``.
        """
    def to_state_space(
        self,
        dt: Optional[float] = None,
        method: str = "refined",
        band: Optional[Tuple[float, float]] = None,
        order: int = 8,
        continuous: bool = False,
    ) -> Any:
        """The approximation as a :class:`fracid.StateSpace` (numpy ``a, b, c, d``).

        Parameters
        ----------
        dt : float, optional
            Sample period in seconds: the discrete model, exact for an input held over each
            period (the same discretisation as :meth:`simulate`), its input delay as extra
            states. ``None``: the continuous model (then ``band`` is needed), its delay in
            ``input_delay``.
        method, band, order
            The approximation (as :meth:`simulate`; band default ``[1e-6/dt, 30 pi/dt]``).
        continuous : bool
            With ``dt``: the continuous model anyway (``dt`` only sets the default band).

        Returns
        -------
        fracid.StateSpace
            ``A, B, C, D = ss``; ``ss.to_scipy()``, ``ss.to_control()``.

        Raises
        ------
        DataError
            Bad band, order or dt, a continuous export without a band, an improper model.
        """
    def to_dict(self) -> Dict[str, Any]:
        """``{"num": [{"coef", "order"}], "den": [...], "delay", "text", "effects": []}``: the
        reports' model object (docs/design.md §7)."""
    def __eq__(self, other: object) -> bool: ...
    def __reduce__(self) -> Any: ...

def gl_simulate(tf: FracTf, u: npt.ArrayLike, dt: float) -> npt.NDArray[np.float64]:
    """Grunwald-Letnikov simulation of ``tf`` (the implicit reference scheme)."""

def prbs(
    dt: float,
    order: int = 7,
    clock: float = 0.003,
    amplitude: float = 1.0,
    offset: float = 0.0,
    periods: int = 1,
    seed: int = 1,
) -> npt.NDArray[np.float64]:
    """A PRBS: a maximum-length sequence of ``2^order - 1`` bits held ``clock`` seconds each,
    levels ``offset +- amplitude``, ``periods`` periods, sampled every ``dt`` (``clock`` must be a
    whole multiple of ``dt``)."""

def error_index(omega: npt.ArrayLike, h: npt.ArrayLike, model: FracTf) -> float:
    """The error index ``J = (1/f) sum |G(j w) - Ghat(j w)|^2`` (paper eq. 30), w in rad/s."""

def _fit_bode(
    omega: npt.ArrayLike,
    h: npt.ArrayLike,
    request: str,
    weights: Optional[npt.ArrayLike] = None,
    point_std: Optional[npt.ArrayLike] = None,
) -> Dict[str, Any]: ...
def _freq_request_defaults() -> Dict[str, Any]: ...
def _answer_pointer(report: str) -> str: ...
def _load_csv(
    path: str, t: Union[str, int], u: Union[str, int], y: Union[str, int], dt: Optional[float] = ...
) -> Dict[str, Any]: ...
def _load_bode(
    path: str,
    columns: Optional[Tuple[Union[str, int], Union[str, int], Union[str, int]]] = ...,
    rad_s: bool = ...,
    linear_gain: bool = ...,
    radians: bool = ...,
    weights: Optional[Union[str, int]] = ...,
) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.complex128], Optional[npt.NDArray[np.float64]]]: ...
def _fit_time(
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    dt: float,
    request: str,
    validation: Optional[Tuple[npt.ArrayLike, npt.ArrayLike]] = None,
) -> Tuple[Dict[str, Any], Dict[str, Any]]: ...
def _time_request_defaults() -> Dict[str, Any]: ...
def _structures() -> List[Tuple[str, str]]: ...
def _fit_time_joint(
    u: npt.ArrayLike,
    y: npt.ArrayLike,
    dt: float,
    request: str,
    joint: List[Tuple[npt.ArrayLike, npt.ArrayLike]],
    validation: Optional[Tuple[npt.ArrayLike, npt.ArrayLike]] = None,
) -> Dict[str, Any]: ...

def _tune(
    model: Union[FracTf, str],
    request: str,
    effects: List[Tuple[str, Dict[str, float]]] = ...,
) -> str: ...

class DriveSimulator:
    """A simulated TI F2812 servo drive on a pseudo-terminal, speaking the fracid serial protocol.

    The firmware runs in a Rust thread in real time: the motor is a fractional model simulated
    at the configured sample rate, with hidden effects the identification is not told about; the
    line is paced to ``baud``. Open :attr:`port` with :class:`fracid.DriveClient`. Use it as a
    context manager, or call :meth:`stop`; it also stops when garbage-collected.

    Parameters
    ----------
    model : FracTf or str, optional
        The motor, voltage (V) to speed (rad/s). Default: the paper's time-domain model
        ``6.82 / (2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)``.
    baud : int
        Line rate the simulator paces to (921600 keeps runs fast).
    delay_s : float
        Hidden input (transport) delay, s.
    coulomb_v : float
        Hidden Coulomb friction as a voltage at the input, V.
    noise_std : float
        Hidden speed-measurement noise, standard deviation in rad/s.
    speed_quant : float
        Speed quantisation step (encoder resolution), rad/s; 0 for none.
    ripple_v, ripple_hz : float
        Hidden periodic disturbance at the input: amplitude (V) and frequency (Hz).
    seed : int
        Seed of the noise.
    offset_v : float
        Hidden constant offset added to the command at the input, V.
    firmware : str
        The firmware behind the pty: ``"rust"`` (the simulator's own) or ``"c"`` (the C
        firmware of ``firmware/``, as flashed on the F2812).

    Raises
    ------
    ParseError
        If ``model`` is a string that does not parse.
    DataError
        For a negative or non-finite effect, a bad ``baud`` or ``firmware``, a model that cannot
        be simulated.
    DriveError
        If the pseudo-terminal cannot be opened.

    Examples
    --------
    >>> import fracid
    >>> with fracid.DriveSimulator(baud=921600, noise_std=0.05) as sim:
    ...     with fracid.DriveClient(sim.port, baud=921600) as drive:
    ...         drive.configure(sample_rate_hz=1000)
    ...         rec = drive.run_prbs()
    """

    def __init__(
        self,
        model: Union[FracTf, str, None] = None,
        baud: int = 115200,
        delay_s: float = 0.0,
        coulomb_v: float = 0.0,
        noise_std: float = 0.0,
        speed_quant: float = 0.0,
        ripple_v: float = 0.0,
        ripple_hz: float = 0.0,
        seed: int = 1,
        offset_v: float = 0.0,
        firmware: str = "rust",
    ) -> None: ...
    @property
    def port(self) -> str:
        """The path of the simulated serial port (a pty), for :class:`fracid.DriveClient`."""
    @property
    def baud(self) -> int:
        """The line rate the simulator paces to, baud."""
    @property
    def model(self) -> FracTf:
        """The simulated motor model (the hidden effects are not part of it)."""
    @property
    def running(self) -> bool:
        """Whether the simulator thread runs."""
    def stats(self) -> Dict[str, Any]:
        """Counters: ``frames_sent``, ``frames_damaged``, ``bytes_sent``, ``blocks_dropped``,
        ``rx_overruns``, ``frames_received``, ``rx_errors``, ``replays``, ``runs_started``,
        ``events`` (list of str)."""
    def stop(self) -> None:
        """Stop the simulator and wait for its thread (idempotent)."""
    def __enter__(self) -> "DriveSimulator": ...
    def __exit__(self, *args: object) -> bool: ...

class _DriveClient:
    def __init__(
        self,
        port: str,
        baud: int = 115200,
        timeout_s: Optional[float] = None,
        retries: int = 5,
    ) -> None: ...
    @property
    def port(self) -> str: ...
    @property
    def baud(self) -> int: ...
    @property
    def is_open(self) -> bool: ...
    @property
    def sample_rate_hz(self) -> Optional[int]: ...
    def hello(self) -> Dict[str, int]: ...
    def configure(
        self, sample_rate_hz: int = 1000, block_samples: int = 32, keepalive_ms: int = 500
    ) -> None: ...
    def status(self) -> Dict[str, Any]: ...
    def stats(self) -> Dict[str, int]: ...
    def run_prbs(
        self,
        order: int = 7,
        clock_s: float = 0.003,
        amplitude_v: float = 1.0,
        offset_v: float = 6.0,
        periods: int = 1,
        settle_s: float = 0.3,
        seed: int = 1,
        csv_path: Optional[str] = None,
    ) -> Dict[str, Any]: ...
    def run_sine_sweep(
        self,
        f0_hz: float,
        f1_hz: float,
        n: int,
        amplitude_v: float = 1.0,
        offset_v: float = 6.0,
        cycles: int = 4,
        settle_cycles: int = 2,
        min_settle_s: float = 0.2,
        attempts: int = 3,
        repeats: int = 1,
    ) -> Tuple[
        npt.NDArray[np.float64],
        npt.NDArray[np.float64],
        npt.NDArray[np.float64],
        List[str],
        npt.NDArray[np.float64],
        npt.NDArray[np.float64],
    ]: ...
    def stop(self) -> None:
        """STOP: a run of this client in progress (from any thread) ends at its next turn and
        returns what arrived, marked incomplete; without one, STOP goes to the drive at once."""
    def estop(self) -> None: ...
    def close(self) -> None: ...

def _autotune(
    port: str,
    request: str,
    sample_rate_hz: int = 1000,
    baud: int = 115200,
    keepalive_ms: int = 150,
) -> Dict[str, Any]: ...
def _autotune_request_defaults() -> Dict[str, Any]: ...
