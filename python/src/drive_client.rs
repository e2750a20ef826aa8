//! The drive client and the drive simulator (the `drive` crate): `fracid.DriveSimulator` and
//! `fracid._fracid._DriveClient`, which the Python class `fracid.DriveClient` wraps with typed
//! results.
//!
//! Every call that talks to the serial port (or waits for the simulator's thread) releases the
//! GIL. The Rust objects sit behind a mutex, so one client shared by several Python threads
//! serialises its commands instead of interleaving them on the line. The client's
//! [`StopHandle`] sits outside that mutex: `stop()` from another thread ends a run in progress.

use crate::errors;
use crate::tf::PyFracTf;
use drive::client::{
    Acquisition, Client, ClientConfig, CsvSink, LazyFile, NullSink, PrbsTest, SineSweep, StopHandle,
};
use drive::protocol::{fault, Configure, DriveState, HelloReply, MAX_BLOCK_SAMPLES};
use drive::sim::{DriveSim, Effects, Faults, FirmwareKind, SimConfig};
use numpy::IntoPyArray;
use pyo3::exceptions::PyOSError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString};
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard};
use std::time::Duration;

/// Lock a mutex; a poisoned one (a panic in another thread) is still usable: the state it guards
/// is a port and counters, not an invariant a half-done update could break.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// A finite number >= 0.
fn non_negative(name: &str, x: f64) -> PyResult<f64> {
    if !(x.is_finite() && x >= 0.0) {
        return Err(errors::data(format!(
            "{name} = {x} must be a finite number >= 0"
        )));
    }
    Ok(x)
}

/// A finite number.
fn finite(name: &str, x: f64) -> PyResult<f64> {
    if !x.is_finite() {
        return Err(errors::data(format!("{name} = {x} must be finite")));
    }
    Ok(x)
}

/// An integer argument as Python gave it: its value when it fits 64 bits, else its decimal text.
/// pyo3's own `i64` conversion raises a bare `OverflowError` ("Python int too large to convert to
/// C long") that names neither the argument nor its range; [`int_in`] does.
pub(crate) struct Int(Result<i64, String>);

impl<'py> FromPyObject<'py> for Int {
    fn extract_bound(ob: &Bound<'py, PyAny>) -> PyResult<Self> {
        match ob.extract::<i64>() {
            Ok(v) => Ok(Self(Ok(v))),
            Err(e) if e.is_instance_of::<pyo3::exceptions::PyOverflowError>(ob.py()) => {
                Ok(Self(Err(ob.str()?.to_string())))
            }
            Err(e) => Err(e),
        }
    }
}

impl From<i64> for Int {
    fn from(v: i64) -> Self {
        Self(Ok(v))
    }
}

/// An integer in `lo..=hi`, or a `DataError` (a `ValueError`) naming the argument and the range,
/// also for a Python int beyond 64 bits.
fn int_in<T: TryFrom<i64>>(name: &str, v: impl Into<Int>, lo: i64, hi: i64) -> PyResult<T> {
    let v = match v.into().0 {
        Ok(v) => v,
        Err(text) => {
            return Err(errors::data(format!(
                "{name} = {} must be in {lo}..={hi} (it does not even fit a 64-bit integer)",
                ident::files::shorten(&text)
            )))
        }
    };
    if !(lo..=hi).contains(&v) {
        return Err(errors::data(format!("{name} = {v} must be in {lo}..={hi}")));
    }
    T::try_from(v).map_err(|_| errors::data(format!("{name} = {v} is out of range")))
}

/// A baud rate.
fn baud_of(baud: Int) -> PyResult<u32> {
    int_in("baud", baud, 1, 100_000_000)
}

// ---------------------------------------------------------------------------------------------
// The simulator

/// A simulated TI F2812 servo drive on a pseudo-terminal, speaking the fracid serial protocol.
///
/// The firmware runs in a Rust thread in real time; open `port` with `fracid.DriveClient`. Use it
/// as a context manager or call `stop()`; it also stops when garbage-collected.
///
/// Parameters
/// ----------
/// model : FracTf or str, optional
///     The motor, voltage (V) to speed (rad/s); default the paper's time-domain model
///     `6.82 / (2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)`.
/// baud : int
///     Line rate the simulator paces to.
/// delay_s, coulomb_v, noise_std, speed_quant, ripple_v, ripple_hz, offset_v : float
///     Hidden effects: input delay (s), Coulomb friction (V), speed noise (rad/s, standard
///     deviation), speed quantisation step (rad/s), periodic input disturbance (V, Hz), input
///     offset (V).
/// seed : int
///     Seed of the noise.
/// firmware : str
///     The firmware behind the pty: "rust" (the simulator's own) or "c" (the C firmware of
///     `firmware/`, as flashed on the F2812).
#[pyclass(name = "DriveSimulator", module = "fracid", frozen)]
pub struct PyDriveSimulator {
    sim: Mutex<Option<DriveSim>>,
    port: String,
    model: fracsim::FracTf,
    baud: u32,
}

#[pymethods]
impl PyDriveSimulator {
    #[new]
    #[pyo3(signature = (model = None, baud = Int::from(115_200), delay_s = 0.0, coulomb_v = 0.0, noise_std = 0.0, speed_quant = 0.0, ripple_v = 0.0, ripple_hz = 0.0, seed = Int::from(1), offset_v = 0.0, firmware = "rust"))]
    #[pyo3(
        text_signature = "(model=None, baud=115200, delay_s=0.0, coulomb_v=0.0, noise_std=0.0, speed_quant=0.0, ripple_v=0.0, ripple_hz=0.0, seed=1, offset_v=0.0, firmware='rust')"
    )]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        model: Option<&Bound<'_, PyAny>>,
        baud: Int,
        delay_s: f64,
        coulomb_v: f64,
        noise_std: f64,
        speed_quant: f64,
        ripple_v: f64,
        ripple_hz: f64,
        seed: Int,
        offset_v: f64,
        firmware: &str,
    ) -> PyResult<Self> {
        let firmware = match firmware.to_ascii_lowercase().as_str() {
            "rust" => FirmwareKind::Rust,
            "c" => FirmwareKind::C,
            other => {
                return Err(errors::data(format!(
                    "firmware must be \"rust\" or \"c\", got {other:?}"
                )))
            }
        };
        let mut cfg = SimConfig {
            firmware,
            ..SimConfig::default()
        };
        if let Some(m) = model.filter(|m| !m.is_none()) {
            cfg.model = if let Ok(tf) = m.downcast::<PyFracTf>() {
                tf.get().inner.clone()
            } else if let Ok(s) = m.downcast::<PyString>() {
                s.to_cow()?
                    .parse::<fracsim::FracTf>()
                    .map_err(errors::sim)?
            } else {
                return Err(errors::data(
                    "model must be None, a FracTf or a model string",
                ));
            };
        }
        // The simulator builds its filters at CONFIGURE and would only NAK there: check the model
        // now, at the default 1 kHz, so a bad one fails where it is given.
        fracsim::Simulator::<f64>::new(&cfg.model, 1e-3, &cfg.approx)
            .map_err(|e| errors::data(format!("the model cannot be simulated: {e}")))?;
        cfg.baud = baud_of(baud)?;
        cfg.effects = Effects {
            delay_s: non_negative("delay_s", delay_s)?,
            coulomb_v: non_negative("coulomb_v", coulomb_v)?,
            noise_std: non_negative("noise_std", noise_std)?,
            speed_quant: non_negative("speed_quant", speed_quant)?,
            ripple_v: finite("ripple_v", ripple_v)?,
            ripple_hz: non_negative("ripple_hz", ripple_hz)?,
            offset_v: finite("offset_v", offset_v)?,
            ..Effects::default()
        };
        // the ranges the simulator accepts (a delay of at most drive.sim.MAX_DELAY_S, ...)
        cfg.effects
            .validate()
            .map_err(|e| errors::data(e.to_string()))?;
        cfg.faults = Faults {
            seed: int_in("seed", seed, 0, i64::MAX)?,
            ..Faults::default()
        };
        let model = cfg.model.clone();
        let baud = cfg.baud;
        let sim = py
            .allow_threads(|| DriveSim::spawn(cfg))
            .map_err(errors::drive)?;
        Ok(Self {
            port: sim.port_path().to_string(),
            sim: Mutex::new(Some(sim)),
            model,
            baud,
        })
    }

    /// The path of the simulated serial port (a pty).
    #[getter]
    fn port(&self) -> &str {
        &self.port
    }

    /// The line rate the simulator paces to, baud.
    #[getter]
    fn baud(&self) -> u32 {
        self.baud
    }

    /// The simulated motor model.
    #[getter]
    fn model(&self) -> PyFracTf {
        PyFracTf::from(self.model.clone())
    }

    /// Whether the simulator thread runs.
    #[getter]
    fn running(&self) -> bool {
        lock(&self.sim).as_ref().is_some_and(DriveSim::is_running)
    }

    /// Counters of the simulator (frames, damage, drops, runs, events).
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let st = lock(&self.sim)
            .as_ref()
            .map(DriveSim::stats)
            .unwrap_or_default();
        let d = PyDict::new(py);
        d.set_item("frames_sent", st.frames_sent)?;
        d.set_item("frames_damaged", st.frames_damaged)?;
        d.set_item("bytes_sent", st.bytes_sent)?;
        d.set_item("blocks_dropped", st.blocks_dropped)?;
        d.set_item("rx_overruns", st.rx_overruns)?;
        d.set_item("frames_received", st.frames_received)?;
        d.set_item("rx_errors", st.rx_errors)?;
        d.set_item("replays", st.replays)?;
        d.set_item("runs_started", st.runs_started)?;
        d.set_item("events", st.events)?;
        Ok(d)
    }

    /// Stop the simulator and wait for its thread (idempotent).
    fn stop(&self, py: Python<'_>) {
        let sim = lock(&self.sim).take();
        if let Some(sim) = sim {
            py.allow_threads(|| sim.stop());
        }
    }

    fn __enter__(slf: Bound<'_, Self>) -> Bound<'_, Self> {
        slf
    }

    #[pyo3(signature = (*_args))]
    fn __exit__(&self, py: Python<'_>, _args: &Bound<'_, pyo3::types::PyTuple>) -> bool {
        self.stop(py);
        false
    }

    fn __repr__(&self) -> String {
        format!(
            "<DriveSimulator on {} at {} baud{}>",
            self.port,
            self.baud,
            if self.running() { "" } else { ", stopped" }
        )
    }
}

// ---------------------------------------------------------------------------------------------
// The client

/// The client and the configuration it last sent.
struct ClientState {
    client: Option<Client>,
    conf: Option<Configure>,
}

/// A connection to a drive (`fracid._fracid._DriveClient`; Python wraps it as `DriveClient`).
#[pyclass(name = "_DriveClient", module = "fracid._fracid", frozen)]
pub struct PyDriveClient {
    state: Mutex<ClientState>,
    /// Stops the client's run from any thread, without the lock a run holds.
    stop_req: StopHandle,
    /// Runs in progress or waiting for the lock.
    running: AtomicUsize,
    port: String,
    baud: u32,
}

/// Counts a run (from before it waits for the client's lock) for `stop()`; at its end, withdraws a
/// stop request that came too late for it, so that it does not end the next run.
struct RunGuard<'a>(&'a PyDriveClient);

impl<'a> RunGuard<'a> {
    fn new(c: &'a PyDriveClient) -> Self {
        c.running.fetch_add(1, Ordering::SeqCst);
        Self(c)
    }
}

impl Drop for RunGuard<'_> {
    fn drop(&mut self) {
        self.0.stop_req.cancel();
        self.0.running.fetch_sub(1, Ordering::SeqCst);
    }
}

/// A failure while the GIL is released (turned into a Python exception once it is held again:
/// building one needs the GIL, and waiting for it while holding the client's lock could deadlock).
enum Fail {
    /// An error of the drive crate.
    Drive(drive::Error),
    /// A `DataError`.
    Data(String),
    /// A `DriveError` of the bindings.
    State(String),
    /// An `OSError` (the CSV file).
    Os(String),
}

impl From<drive::Error> for Fail {
    fn from(e: drive::Error) -> Self {
        Self::Drive(e)
    }
}

impl From<Fail> for PyErr {
    fn from(f: Fail) -> Self {
        match f {
            Fail::Drive(e) => errors::drive(e),
            Fail::Data(m) => errors::data(m),
            Fail::State(m) => errors::error(errors::Kind::Drive, m),
            Fail::Os(m) => PyOSError::new_err(m),
        }
    }
}

/// The configuration, or the error of a run before `configure`.
fn configured(conf: &Option<Configure>) -> Result<Configure, Fail> {
    conf.ok_or_else(|| Fail::State("the drive is not configured: call configure() first".into()))
}

impl PyDriveClient {
    /// Run `f` on the open client with the GIL released.
    fn with<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut Client, &mut Option<Configure>) -> Result<T, Fail> + Send,
    ) -> PyResult<T> {
        py.allow_threads(|| {
            let mut st = lock(&self.state);
            let ClientState { client, conf } = &mut *st;
            let c = client
                .as_mut()
                .ok_or_else(|| Fail::State("the drive client is closed".into()))?;
            f(c, conf)
        })
        .map_err(PyErr::from)
    }

    /// Read the state with the GIL released (a run may hold the lock for seconds).
    fn peek<T: Send>(&self, py: Python<'_>, f: impl FnOnce(&ClientState) -> T + Send) -> T {
        py.allow_threads(|| f(&lock(&self.state)))
    }
}

fn hello_dict<'py>(py: Python<'py>, h: &HelloReply) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("proto_version", h.proto_version)?;
    d.set_item("fw_major", h.fw_major)?;
    d.set_item("fw_minor", h.fw_minor)?;
    d.set_item("n_channels", h.n_channels)?;
    d.set_item("max_block_samples", h.max_block_samples)?;
    d.set_item("boot_id", h.boot_id)?;
    d.set_item("max_sample_rate_hz", h.max_sample_rate_hz)?;
    Ok(d)
}

fn state_name(s: DriveState) -> &'static str {
    match s {
        DriveState::Unconfigured => "unconfigured",
        DriveState::Idle => "idle",
        DriveState::Running => "running",
        DriveState::Fault => "fault",
    }
}

fn fault_name(f: u8) -> &'static str {
    match f {
        fault::NONE => "none",
        fault::ESTOP => "estop",
        fault::KEEPALIVE => "keepalive",
        fault::SPEED_LIMIT => "speed_limit",
        fault::CURRENT_LIMIT => "current_limit",
        _ => "other",
    }
}

/// Check that a voltage fits the command channel at the configured scale.
fn volts(name: &str, v: f64, conf: &Configure) -> Result<f64, Fail> {
    let raw = (v / conf.u_lsb()).round();
    if !raw.is_finite() || raw.abs() > 32767.0 {
        return Err(Fail::Data(format!(
            "{name} = {v} V is out of the command range (+-{} V at this configuration)",
            32767.0 * conf.u_lsb()
        )));
    }
    Ok(v)
}

fn acquisition_dict<'py>(py: Python<'py>, a: Acquisition) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("run_id", a.run_id)?;
    d.set_item("sample_rate_hz", a.sample_rate_hz)?;
    d.set_item("total_samples", a.total_samples)?;
    d.set_item("index", a.index.into_pyarray(py))?;
    d.set_item("t", a.t.into_pyarray(py))?;
    d.set_item("u", a.u.into_pyarray(py))?;
    d.set_item("y", a.y.into_pyarray(py))?;
    d.set_item("i", a.i.into_pyarray(py))?;
    d.set_item("complete", a.complete)?;
    let missing = PyList::empty(py);
    for r in &a.missing {
        missing.append((r.start, r.end))?;
    }
    d.set_item("missing", missing)?;
    d.set_item("problems", a.problems)?;
    d.set_item("clamped_blocks", a.clamped_blocks)?;
    d.set_item(
        "end_reason",
        a.end
            .map(|e| format!("{:?}", e.reason).to_ascii_lowercase()),
    )?;
    Ok(d)
}

/// `(freq_hz, gain_db, phase_deg, lost)`: the points of a sweep and what was lost.
type SweepTuple<'py> = (
    Bound<'py, numpy::PyArray1<f64>>,
    Bound<'py, numpy::PyArray1<f64>>,
    Bound<'py, numpy::PyArray1<f64>>,
    Vec<String>,
    Bound<'py, numpy::PyArray1<f64>>,
    Bound<'py, numpy::PyArray1<f64>>,
);

#[pymethods]
impl PyDriveClient {
    /// Open `port`, say HELLO and check the protocol version.
    #[new]
    #[pyo3(signature = (port, baud = Int::from(115_200), timeout_s = None, retries = Int::from(5)))]
    fn new(
        py: Python<'_>,
        port: PathBuf,
        baud: Int,
        timeout_s: Option<f64>,
        retries: Int,
    ) -> PyResult<Self> {
        let port = port
            .to_str()
            .ok_or_else(|| errors::data(format!("port {} is not valid UTF-8", port.display())))?
            .to_string();
        let timeout = match timeout_s {
            Some(t) => {
                if !(t.is_finite() && t > 0.0 && t <= 3600.0) {
                    return Err(errors::data(format!(
                        "timeout_s = {t} must be in (0, 3600] seconds"
                    )));
                }
                Some(Duration::from_secs_f64(t))
            }
            None => None,
        };
        let cfg = ClientConfig {
            baud: baud_of(baud)?,
            timeout,
            retries: int_in("retries", retries, 0, 100)?,
            ..ClientConfig::default()
        };
        let baud = cfg.baud;
        let client = py
            .allow_threads(|| Client::open(&port, cfg))
            .map_err(errors::drive)?;
        Ok(Self {
            stop_req: client.stop_handle(),
            running: AtomicUsize::new(0),
            state: Mutex::new(ClientState {
                client: Some(client),
                conf: None,
            }),
            port,
            baud,
        })
    }

    /// The port path.
    #[getter]
    fn port(&self) -> &str {
        &self.port
    }

    /// The line rate, baud.
    #[getter]
    fn baud(&self) -> u32 {
        self.baud
    }

    /// Whether the port is open.
    #[getter]
    fn is_open(&self, py: Python<'_>) -> bool {
        self.peek(py, |s| s.client.is_some())
    }

    /// The configured sample rate in Hz, or None before `configure`.
    #[getter]
    fn sample_rate_hz(&self, py: Python<'_>) -> Option<u32> {
        self.peek(py, |s| s.conf.map(|c| c.sample_rate_hz))
    }

    /// HELLO: the drive's identity as a dict.
    fn hello<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let h = self.with(py, |c, _| Ok(c.hello()?))?;
        hello_dict(py, &h)
    }

    /// CONFIGURE the acquisition.
    #[pyo3(signature = (sample_rate_hz = Int::from(1000), block_samples = Int::from(32), keepalive_ms = Int::from(500)))]
    fn configure(
        &self,
        py: Python<'_>,
        sample_rate_hz: Int,
        block_samples: Int,
        keepalive_ms: Int,
    ) -> PyResult<()> {
        let conf = Configure {
            sample_rate_hz: int_in("sample_rate_hz", sample_rate_hz, 1, u32::MAX as i64)?,
            block_samples: int_in("block_samples", block_samples, 1, MAX_BLOCK_SAMPLES as i64)?,
            keepalive_ms: int_in("keepalive_ms", keepalive_ms, 50, 5000)?,
            ..Configure::default()
        };
        self.with(py, |c, stored| {
            *stored = None;
            c.configure(&conf)?;
            *stored = Some(conf);
            Ok(())
        })
    }

    /// STATUS as a dict.
    fn status<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.with(py, |c, _| Ok(c.status()?))?;
        let d = PyDict::new(py);
        d.set_item("state", state_name(s.state))?;
        d.set_item("fault", fault_name(s.fault))?;
        d.set_item("fault_code", s.fault)?;
        d.set_item("run_id", s.run_id)?;
        d.set_item("samples_done", s.samples_done)?;
        d.set_item("blocks_dropped", s.blocks_dropped)?;
        d.set_item("boot_id", s.boot_id)?;
        d.set_item("rx_errors", s.rx_errors)?;
        d.set_item("clamped", s.clamped)?;
        Ok(d)
    }

    /// Link counters of the client.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.with(py, |c, _| Ok(c.stats()))?;
        let d = PyDict::new(py);
        d.set_item("commands", s.commands)?;
        d.set_item("retries", s.retries)?;
        d.set_item("reconnects", s.reconnects)?;
        d.set_item("recoveries", s.recoveries)?;
        d.set_item("frames", s.frames)?;
        d.set_item("bad_frames", s.bad_frames)?;
        Ok(d)
    }

    /// Run a PRBS experiment; a dict the Python layer turns into `Acquisition`.
    #[pyo3(signature = (order = Int::from(7), clock_s = 0.003, amplitude_v = 1.0, offset_v = 6.0, periods = Int::from(1), settle_s = 0.3, seed = Int::from(1), csv_path = None))]
    #[allow(clippy::too_many_arguments)]
    fn run_prbs<'py>(
        &self,
        py: Python<'py>,
        order: Int,
        clock_s: f64,
        amplitude_v: f64,
        offset_v: f64,
        periods: Int,
        settle_s: f64,
        seed: Int,
        csv_path: Option<PathBuf>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let order: u32 = int_in("order", order, 2, 16)?;
        let test = PrbsTest {
            order: order.try_into().unwrap_or(16),
            seed: int_in("seed", seed, 1, (1i64 << order) - 1)?,
            clock_s: crate::arrays::positive("clock_s", clock_s)?,
            amplitude_v: non_negative("amplitude_v", amplitude_v)?,
            offset_v: finite("offset_v", offset_v)?,
            periods: int_in("periods", periods, 1, u16::MAX as i64)?,
            settle_s: non_negative("settle_s", settle_s)?,
        };
        let _run = RunGuard::new(self);
        let acq = self.with(py, |c, conf| {
            let conf = configured(conf)?;
            volts("offset_v + amplitude_v", offset_v + amplitude_v, &conf)?;
            volts("offset_v - amplitude_v", offset_v - amplitude_v, &conf)?;
            // Bad parameters fail here, before any file is touched.
            test.to_command(&conf)?;
            match &csv_path {
                Some(p) => {
                    // Created only when the drive has acknowledged the START: a run that never
                    // starts leaves an existing file as it was. The record is finished (footer)
                    // whatever ends the run, a lost port included.
                    let f = LazyFile::new(p)
                        .map_err(|e| Fail::Os(format!("cannot create {}: {e}", p.display())))?;
                    let mut sink = CsvSink::new(f);
                    let acq = c.run_prbs(&test, &mut sink);
                    let written = sink
                        .into_inner()
                        .and_then(|mut f| std::io::Write::flush(&mut f))
                        .map_err(|e| Fail::Os(format!("cannot write {}: {e}", p.display())));
                    let acq = acq?;
                    written?;
                    Ok(acq)
                }
                None => Ok(c.run_prbs(&test, &mut NullSink)?),
            }
        })?;
        acquisition_dict(py, acq)
    }

    /// Run a log sine sweep: `(freq_hz, gain_db, phase_deg, lost, gain_db_std, phase_deg_std)`
    /// (the spread of the `repeats` per frequency; zeros for one repeat).
    #[pyo3(signature = (f0_hz, f1_hz, n, amplitude_v = 1.0, offset_v = 6.0, cycles = Int::from(4), settle_cycles = Int::from(2), min_settle_s = 0.2, attempts = Int::from(3), repeats = Int::from(1)))]
    #[allow(clippy::too_many_arguments)]
    fn run_sine_sweep<'py>(
        &self,
        py: Python<'py>,
        f0_hz: f64,
        f1_hz: f64,
        n: Int,
        amplitude_v: f64,
        offset_v: f64,
        cycles: Int,
        settle_cycles: Int,
        min_settle_s: f64,
        attempts: Int,
        repeats: Int,
    ) -> PyResult<SweepTuple<'py>> {
        let f0 = crate::arrays::positive("f0_hz", f0_hz)?;
        let f1 = crate::arrays::positive("f1_hz", f1_hz)?;
        let n: usize = int_in("n", n, 1, 10_000)?;
        let mut sweep = SineSweep::log(f0, f1, n);
        sweep.amplitude_v = crate::arrays::positive("amplitude_v", amplitude_v)?;
        sweep.offset_v = finite("offset_v", offset_v)?;
        sweep.cycles = int_in("cycles", cycles, 1, u16::MAX as i64)?;
        sweep.settle_cycles = int_in("settle_cycles", settle_cycles, 0, u16::MAX as i64)?;
        sweep.min_settle_s = non_negative("min_settle_s", min_settle_s)?;
        sweep.attempts = int_in("attempts", attempts, 1, 100)?;
        sweep.repeats = int_in("repeats", repeats, 1, 1000)?;
        let _run = RunGuard::new(self);
        let (points, lost) = self.with(py, |c, conf| {
            let conf = configured(conf)?;
            let nyquist = conf.sample_rate_hz as f64 / 2.0;
            if f0.max(f1) >= nyquist {
                return Err(Fail::Data(format!(
                    "frequencies up to {} Hz: must be below half the sample rate ({nyquist} Hz)",
                    f0.max(f1)
                )));
            }
            volts("amplitude_v", amplitude_v, &conf)?;
            volts("offset_v", offset_v, &conf)?;
            Ok(c.run_sine_sweep(&sweep)?)
        })?;
        let f: Vec<f64> = points.iter().map(|p| p.freq_hz).collect();
        let g: Vec<f64> = points.iter().map(|p| p.gain_db).collect();
        let ph: Vec<f64> = points.iter().map(|p| p.phase_deg).collect();
        let gs: Vec<f64> = points
            .iter()
            .map(|p| p.spread.map_or(0.0, |s| s.gain_db_std))
            .collect();
        let ps: Vec<f64> = points
            .iter()
            .map(|p| p.spread.map_or(0.0, |s| s.phase_deg_std))
            .collect();
        Ok((
            f.into_pyarray(py),
            g.into_pyarray(py),
            ph.into_pyarray(py),
            lost,
            gs.into_pyarray(py),
            ps.into_pyarray(py),
        ))
    }

    /// STOP: a run of this client in progress (from any thread) ends at its next turn and returns
    /// what arrived, marked incomplete; without one, STOP goes to the drive at once.
    fn stop(&self, py: Python<'_>) -> PyResult<()> {
        self.stop_req.stop();
        if self.running.load(Ordering::SeqCst) > 0 {
            return Ok(());
        }
        self.with(py, |c, _| {
            // No run holds the lock: the request is not for a run of ours; send STOP itself.
            self.stop_req.cancel();
            Ok(c.stop()?)
        })
    }

    /// Emergency stop (latched until the next `configure`).
    fn estop(&self, py: Python<'_>) -> PyResult<()> {
        self.with(py, |c, conf| {
            c.estop()?;
            *conf = None;
            Ok(())
        })
    }

    /// Close the port (idempotent).
    fn close(&self, py: Python<'_>) {
        py.allow_threads(|| {
            let client = lock(&self.state).client.take();
            drop(client);
        })
    }
}
