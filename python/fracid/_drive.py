"""The drive client: acquisition from a TI F2812 servo drive (or :class:`DriveSimulator`) over the
fracid serial protocol. A thin layer over the Rust ``drive`` crate; every exchange with the drive
releases the GIL."""

from __future__ import annotations

import os
from types import TracebackType
from typing import Any, Dict, Optional, Type, Union

from ._fracid import _DriveClient
from ._results import Acquisition, BodeSweep

__all__ = ["DriveClient"]


class DriveClient:
    """A connection to a drive over a serial port.

    Opening it says HELLO and checks the protocol version. Commands are resent on timeout, the port
    is reopened if it fails, and a run keeps whatever samples arrived (see
    :class:`Acquisition`). Use it as a context manager to close the port at the end. One client may
    be shared by threads: their commands are serialised.

    Parameters
    ----------
    port : str or path-like
        The serial port, e.g. ``"/dev/ttyUSB0"`` or :attr:`DriveSimulator.port`. It is opened
        exclusively: a second client on the same port fails until this one is closed.
    baud : int
        Line rate in baud (8N1).
    timeout_s : float, optional
        Time to wait for an answer before resending (default: 100 ms plus three frame times).
    retries : int
        Resends after the first attempt before a command fails.

    Raises
    ------
    DriveError
        If the port cannot be opened or the drive does not answer HELLO.
    DataError
        For a bad ``baud``, ``timeout_s`` or ``retries``.

    Examples
    --------
    >>> import fracid
    >>> with fracid.DriveSimulator(baud=921600) as sim, \\
    ...         fracid.DriveClient(sim.port, baud=921600) as drive:
    ...     drive.configure(sample_rate_hz=1000)
    ...     rec = drive.run_prbs(periods=2)
    >>> rec.complete
    True
    """

    def __init__(
        self,
        port: Union[str, "os.PathLike[str]"],
        baud: int = 115200,
        *,
        timeout_s: Optional[float] = None,
        retries: int = 5,
    ) -> None:
        self._c = _DriveClient(os.fspath(port), baud, timeout_s=timeout_s, retries=retries)

    @property
    def port(self) -> str:
        """The port path."""
        return self._c.port

    @property
    def baud(self) -> int:
        """The line rate in baud."""
        return self._c.baud

    @property
    def is_open(self) -> bool:
        """Whether the port is open (``False`` after :meth:`close`)."""
        return self._c.is_open

    @property
    def sample_rate_hz(self) -> Optional[int]:
        """The sample rate set by :meth:`configure`, in Hz (``None`` before)."""
        return self._c.sample_rate_hz

    def hello(self) -> Dict[str, int]:
        """Say HELLO: the drive's identity.

        Returns
        -------
        dict
            ``proto_version``, ``fw_major``, ``fw_minor``, ``n_channels``, ``max_block_samples``,
            ``boot_id`` (changes when the drive resets), ``max_sample_rate_hz``.

        Raises
        ------
        DriveError
            If the drive does not answer or speaks another protocol version.
        """
        return self._c.hello()

    def configure(
        self, sample_rate_hz: int = 1000, *, block_samples: int = 32, keepalive_ms: int = 500
    ) -> None:
        """Configure the acquisition (needed before a run, and again after a reset or ESTOP).

        The channel scales are the protocol's defaults: 1 mV, 10 mrad/s and 1 mA per LSB (the
        command range is +-32.767 V).

        Parameters
        ----------
        sample_rate_hz : int
            Sample rate in Hz (at most the drive's ``max_sample_rate_hz``).
        block_samples : int
            Samples per data block, 1 to 66.
        keepalive_ms : int
            The drive ramps a run down if the host is silent this long, 50 to 5000 ms.

        Raises
        ------
        DataError
            For a value out of range on the host side.
        DriveError
            If the drive rejects the configuration (e.g. a sample rate above its maximum), is busy
            with a run, or does not answer.
        """
        self._c.configure(sample_rate_hz, block_samples, keepalive_ms)

    def status(self) -> Dict[str, Any]:
        """Ask the drive for its state.

        Returns
        -------
        dict
            ``state`` (``"unconfigured"``, ``"idle"``, ``"running"``, ``"fault"``), ``fault``
            (``"none"``, ``"estop"``, ``"keepalive"``, ``"speed_limit"``, ``"current_limit"``,
            ``"other"``), ``fault_code``, ``run_id``, ``samples_done``, ``blocks_dropped``,
            ``boot_id``, ``rx_errors``, ``clamped``.

        Raises
        ------
        DriveError
            If the drive does not answer.
        """
        return self._c.status()

    def stats(self) -> Dict[str, int]:
        """Link counters: ``commands``, ``retries``, ``reconnects``, ``recoveries``, ``frames``,
        ``bad_frames``."""
        return self._c.stats()

    def run_prbs(
        self,
        order: int = 7,
        clock_s: float = 0.003,
        amplitude_v: float = 1.0,
        offset_v: float = 6.0,
        periods: int = 1,
        settle_s: float = 0.3,
        *,
        seed: int = 1,
        csv_path: Union[str, "os.PathLike[str]", None] = None,
    ) -> Acquisition:
        """Run a PRBS experiment and stream the record.

        The drive holds ``offset_v`` for ``settle_s`` (the motor reaches its operating point),
        then applies ``periods`` periods of a maximum-length sequence of ``2^order - 1`` bits, each
        held ``clock_s``, at levels ``offset_v +- amplitude_v``: the same sequence as
        :func:`fracid.prbs` with the same ``order``, ``clock``, ``seed``. The defaults are the
        paper's experiment.

        Parameters
        ----------
        order : int
            LFSR length, 2 to 16.
        clock_s : float
            Bit duration in seconds, a whole number of samples.
        amplitude_v, offset_v : float
            Amplitude and operating point in V.
        periods : int
            Periods of the sequence, at least 1.
        settle_s : float
            Time at the operating point before the sequence, s (>= 0).
        seed : int
            LFSR seed, 1 to ``2^order - 1``.
        csv_path : str or path-like, optional
            Also write the samples to this CSV file (``t,u,y,i``) as they arrive, with a footer
            saying whether the record is complete. The file is checked at once but created only
            when the drive has acknowledged the START: bad parameters, or a run the drive
            refuses or never answers, leave an existing file as it was. Once the run has
            started, the footer is written whatever ends it (a :meth:`stop`, a drive fault, the
            port lost for longer than the reconnect window: ``missing`` and the footer say which
            samples are missing). Comment lines before the footer note a command the drive
            clamped and a record with no excitation left (the input constant after the settling
            part).

        Returns
        -------
        Acquisition
            The record; check ``complete`` (samples lost on the link are listed in ``missing``).

        Raises
        ------
        DataError
            For a bad parameter: an order out of range, a clock that is not a whole number of
            samples, levels out of the command range, ...
        DriveError
            Before :meth:`configure`, or if the drive rejects the run or does not answer.
        OSError
            If ``csv_path`` cannot be written.
        """
        raw = self._c.run_prbs(
            order,
            clock_s,
            amplitude_v,
            offset_v,
            periods,
            settle_s,
            seed,
            None if csv_path is None else os.fspath(csv_path),
        )
        return Acquisition._from_raw(raw)

    def run_sine_sweep(
        self,
        f0_hz: float,
        f1_hz: float,
        n: int,
        amplitude_v: float = 1.0,
        offset_v: float = 6.0,
        *,
        cycles: int = 4,
        settle_cycles: int = 2,
        min_settle_s: float = 0.2,
        attempts: int = 3,
        repeats: int = 1,
    ) -> BodeSweep:
        """Measure the frequency response with sines at ``n`` log-spaced frequencies.

        At each frequency the drive applies ``offset_v + amplitude_v sin(2 pi f t)``, lets it
        settle (``settle_cycles`` cycles and at least ``min_settle_s``), then computes the
        single-bin DFT of input and output over ``cycles`` cycles. A damaged measurement is
        repeated up to ``attempts`` times; a point that never succeeds is left out and reported
        in ``lost``.

        Parameters
        ----------
        f0_hz, f1_hz : float
            First and last frequency in Hz, below half the sample rate.
        n : int
            Number of frequencies, log-spaced (each rounded to the protocol's millihertz).
        amplitude_v, offset_v : float
            Sine amplitude and operating point in V.
        cycles : int
            Cycles measured at each frequency.
        settle_cycles : int
            Cycles before measuring.
        min_settle_s : float
            Minimum settling time in seconds.
        attempts : int
            Measurements of a frequency before giving it up.
        repeats : int
            Measurements per frequency, combined by the paper's trimmed mean (the largest and the
            smallest gain dropped, likewise the phase, the rest averaged); their sample standard
            deviations are in ``gain_db_std`` and ``phase_deg_std`` of the result.

        Returns
        -------
        BodeSweep
            ``(freq_hz, gain_db, phase_deg, lost)``; ``.omega`` and ``.h`` feed
            :func:`fracid.fit_bode`.

        Raises
        ------
        DataError
            For a bad parameter (a frequency at or above half the sample rate, ...).
        DriveError
            Before :meth:`configure`, or if the drive rejects a sine.
        """
        f, g, p, lost, gs, ps = self._c.run_sine_sweep(
            f0_hz,
            f1_hz,
            n,
            amplitude_v,
            offset_v,
            cycles,
            settle_cycles,
            min_settle_s,
            attempts,
            repeats,
        )
        return BodeSweep(f, g, p, list(lost), gain_db_std=gs, phase_deg_std=ps, repeats=repeats)

    def stop(self) -> None:
        """Send STOP: a run going on in the drive ramps down and ends.

        Called from another thread during :meth:`run_prbs` (or :meth:`run_sine_sweep`), it returns
        at once and the run ends at the client's next turn: ``run_prbs`` then returns the samples
        that arrived as an :class:`Acquisition` with ``complete`` False, ``end_reason``
        ``"stopped"`` and the samples never produced in ``missing`` (and the CSV footer says so);
        a sweep returns the frequencies measured so far. A ``stop()`` that comes as the run ends
        anyway does not stop the next one. Without a run of this client, STOP goes to the drive at
        once (for a run the drive is still doing, one started by an earlier client, say).

        Raises
        ------
        DriveError
            If the drive does not answer (only without a run of this client: during one, a STOP
            that is not acknowledged is listed in the acquisition's ``problems``).

        Examples
        --------
        >>> import threading, time
        >>> import fracid
        >>> with fracid.DriveSimulator(baud=921600) as sim, \\
        ...         fracid.DriveClient(sim.port, baud=921600) as drive:
        ...     drive.configure(sample_rate_hz=1000)
        ...     timer = threading.Timer(0.3, drive.stop)
        ...     timer.start()
        ...     rec = drive.run_prbs(periods=20)
        ...     timer.join()
        >>> rec.complete, rec.end_reason
        (False, 'stopped')
        """
        self._c.stop()

    def estop(self) -> None:
        """Emergency stop: the fault is latched until the next :meth:`configure`.

        Raises
        ------
        DriveError
            If the drive does not answer.
        """
        self._c.estop()

    def close(self) -> None:
        """Close the port (idempotent); later commands raise :class:`DriveError`."""
        self._c.close()

    def __enter__(self) -> "DriveClient":
        return self

    def __exit__(
        self,
        exc_type: Optional[Type[BaseException]],
        exc: Optional[BaseException],
        tb: Optional[TracebackType],
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        if not hasattr(self, "_c"):  # __init__ failed
            return "<DriveClient, not open>"
        state = "open" if self.is_open else "closed"
        return f"<DriveClient {self.port} at {self.baud} baud, {state}>"
