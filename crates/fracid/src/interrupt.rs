//! Ctrl-C (SIGINT), SIGTERM, SIGHUP and every other signal whose default action ends the process
//! and that a process may catch ([`HANDLED`]: SIGQUIT (Ctrl-\\), SIGUSR1, SIGUSR2, SIGALRM,
//! SIGVTALRM, SIGPROF, SIGXCPU, SIGXFSZ and, on Linux, SIGPOLL, SIGPWR, SIGSTKFLT and the
//! real-time signals) during a drive run: the first of them asks the drive to STOP (the run ends,
//! what arrived is kept and the record says what is missing); the command then ends with
//! [`Interrupted`], exit code 128 + the signal number (130 for SIGINT, 143 for SIGTERM, 129 for
//! SIGHUP, 131 for SIGQUIT: what a shell reports for a process the signal ended, so a caller such
//! as `timeout` or a service manager sees which signal ended the run). A second signal of the
//! same kind ends the process as usual.
//!
//! Not caught: SIGKILL and SIGSTOP (they cannot be), SIGPIPE (ignored for the whole run by
//! [`PipeErrors`]: a write to a closed output fails instead, and the drive is stopped), and the
//! signals of the program's own faults (SIGSEGV, SIGBUS, SIGILL, SIGFPE, SIGABRT, SIGTRAP,
//! SIGSYS), after which it cannot go on: as for `kill -9`, the drive's keepalive ends the run.
//!
//! The signal handler only sets atomics (async-signal-safe) and resets itself to the default
//! disposition (`SA_RESETHAND`); a small watcher thread turns the flag into [`StopHandle::stop`].
//! The signals are blocked in the thread that runs the acquisition, so they land on the watcher
//! and never interrupt the run's own system calls. A signal ignored when the run starts (SIGHUP
//! under `nohup`, SIGINT in a background job) stays ignored.

use drive::client::StopHandle;

/// Write one line to standard error, never panicking: after SIGHUP from a closed terminal (or
/// with stderr otherwise gone) a write fails with EIO, and `eprintln!` would panic on it, turning
/// a cleanly finished run (record and footer written, drive stopped) into exit 101. The line is
/// dropped instead; the exit code still tells what happened.
pub fn eprint_line(line: &str) {
    use std::io::Write;
    let mut err = std::io::stderr().lock();
    let _ = writeln!(err, "{line}");
}

/// [`eprint_line`] with `format!` arguments.
#[macro_export]
macro_rules! eprintln_safe {
    ($($arg:tt)*) => {
        $crate::interrupt::eprint_line(&format!($($arg)*))
    };
}

/// A command ended by a signal after finishing its record: exit code 128 + the signal number.
#[derive(Debug)]
pub struct Interrupted {
    /// The signal number.
    pub signal: i32,
    /// What was kept and what is missing.
    pub message: String,
}

impl Interrupted {
    /// 128 + the signal number (130 for SIGINT, 143 for SIGTERM, 129 for SIGHUP).
    pub fn exit_code(&self) -> u8 {
        u8::try_from(128 + self.signal.clamp(1, 127)).unwrap_or(130)
    }
}

impl std::fmt::Display for Interrupted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "interrupted by {}: {}",
            signal_name(self.signal),
            self.message
        )
    }
}

impl std::error::Error for Interrupted {}

/// `SIGINT (Ctrl-C)`, `SIGTERM`, `SIGHUP`, `SIGQUIT (Ctrl-\)`, ... (the names of [`HANDLED`]),
/// `SIGRTMIN+k`, or `signal N`.
pub fn signal_name(signal: i32) -> String {
    #[cfg(unix)]
    {
        if let Some((_, name)) = HANDLED.iter().find(|(s, _)| *s == signal) {
            return (*name).into();
        }
        #[cfg(target_os = "linux")]
        if (libc::SIGRTMIN()..=libc::SIGRTMAX()).contains(&signal) {
            return format!("SIGRTMIN+{}", signal - libc::SIGRTMIN());
        }
    }
    format!("signal {signal}")
}

/// The signals a drive run turns into a STOP, with their names: those whose default action ends
/// the process and that may be caught, but for SIGPIPE and the program's own faults (see the
/// module's documentation); on Linux the real-time signals too ([`handled_signals`]).
#[cfg(unix)]
pub const HANDLED: &[(libc::c_int, &str)] = &[
    (libc::SIGINT, "SIGINT (Ctrl-C)"),
    (libc::SIGTERM, "SIGTERM"),
    (libc::SIGHUP, "SIGHUP"),
    (libc::SIGQUIT, "SIGQUIT (Ctrl-\\)"),
    (libc::SIGUSR1, "SIGUSR1"),
    (libc::SIGUSR2, "SIGUSR2"),
    (libc::SIGALRM, "SIGALRM"),
    (libc::SIGVTALRM, "SIGVTALRM"),
    (libc::SIGPROF, "SIGPROF"),
    (libc::SIGXCPU, "SIGXCPU"),
    (libc::SIGXFSZ, "SIGXFSZ"),
    #[cfg(target_os = "linux")]
    (libc::SIGPOLL, "SIGPOLL"),
    #[cfg(target_os = "linux")]
    (libc::SIGPWR, "SIGPWR"),
    #[cfg(target_os = "linux")]
    (libc::SIGSTKFLT, "SIGSTKFLT"),
];

/// The numbers of [`HANDLED`] and, on Linux, of the real-time signals (SIGRTMIN..=SIGRTMAX, as
/// the C library numbers them: not those it keeps for itself).
#[cfg(unix)]
pub fn handled_signals() -> Vec<libc::c_int> {
    #[allow(unused_mut)]
    let mut v: Vec<libc::c_int> = HANDLED.iter().map(|(s, _)| *s).collect();
    #[cfg(target_os = "linux")]
    v.extend(libc::SIGRTMIN()..=libc::SIGRTMAX());
    v
}

/// While alive, a write to a closed pipe (`fracid drive prbs -o - | head -1`) fails with an
/// I/O error (EPIPE) instead of ending the process by SIGPIPE (exit 141, the drive left
/// running): the acquisition then handles it as any lost output, STOPs the drive, and the
/// command exits 3 saying what was lost. `main` restores SIGPIPE's default for the filters'
/// sake; a drive command holds this for its whole run.
pub struct PipeErrors {
    #[cfg(unix)]
    previous: libc::sighandler_t,
}

impl PipeErrors {
    /// Ignore SIGPIPE until dropped.
    pub fn arm() -> Self {
        #[cfg(unix)]
        {
            // SAFETY: setting a signal's disposition to SIG_IGN; the previous one is restored on
            // drop.
            let previous = unsafe { libc::signal(libc::SIGPIPE, libc::SIG_IGN) };
            Self { previous }
        }
        #[cfg(not(unix))]
        {
            Self {}
        }
    }
}

impl Drop for PipeErrors {
    fn drop(&mut self) {
        #[cfg(unix)]
        // SAFETY: restoring the disposition `arm` found.
        unsafe {
            if self.previous != libc::SIG_ERR {
                libc::signal(libc::SIGPIPE, self.previous);
            }
        }
    }
}

/// Turns the first of the signals [`handled_signals`] lists (SIGINT, SIGTERM, SIGHUP, SIGQUIT,
/// ...) into a STOP while alive; restores the previous handling on drop.
/// One at a time per process.
pub struct StopOnInterrupt {
    #[cfg(unix)]
    inner: Option<unix::Armed>,
}

impl StopOnInterrupt {
    /// Arm for the run that `stop` belongs to. A signal ignored now (SIGINT in a background job
    /// started with it ignored, SIGHUP under `nohup`) stays ignored.
    pub fn arm(stop: StopHandle) -> Self {
        #[cfg(unix)]
        {
            Self {
                inner: unix::Armed::new(stop),
            }
        }
        #[cfg(not(unix))]
        {
            let _ = stop;
            Self {}
        }
    }

    /// The signal ([`handled_signals`]) that arrived while armed, if one did.
    pub fn signal(&self) -> Option<i32> {
        #[cfg(unix)]
        {
            let s = unix::SIGNAL.load(std::sync::atomic::Ordering::SeqCst);
            (self.inner.is_some() && s != 0).then_some(s)
        }
        #[cfg(not(unix))]
        {
            None
        }
    }
}

#[cfg(unix)]
mod unix {
    use drive::client::StopHandle;
    use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
    use std::sync::Arc;
    use std::thread::JoinHandle;
    use std::time::Duration;

    /// The first signal that arrived (0: none).
    pub(super) static SIGNAL: AtomicI32 = AtomicI32::new(0);

    extern "C" fn on_signal(sig: libc::c_int) {
        // Async-signal-safe: one atomic operation. SA_RESETHAND already restored the default
        // action for this signal.
        let _ = SIGNAL.compare_exchange(0, sig, Ordering::SeqCst, Ordering::SeqCst);
    }

    fn signal_set(signals: &[libc::c_int]) -> libc::sigset_t {
        // SAFETY: sigemptyset initialises the set before sigaddset uses it.
        unsafe {
            let mut set: libc::sigset_t = std::mem::zeroed();
            libc::sigemptyset(&mut set);
            for &s in signals {
                libc::sigaddset(&mut set, s);
            }
            set
        }
    }

    pub(super) struct Armed {
        /// The signals handled and their previous actions.
        old_actions: Vec<(libc::c_int, libc::sigaction)>,
        old_mask: libc::sigset_t,
        done: Arc<AtomicBool>,
        watcher: Option<JoinHandle<()>>,
    }

    impl Armed {
        pub(super) fn new(stop: StopHandle) -> Option<Self> {
            // SAFETY: plain sigaction/pthread_sigmask calls on initialised structures; the
            // handler only touches an atomic.
            let all = super::handled_signals();
            unsafe {
                let mut old_actions = Vec::new();
                for &sig in &all {
                    let mut old: libc::sigaction = std::mem::zeroed();
                    if libc::sigaction(sig, std::ptr::null(), &mut old) == 0
                        && old.sa_sigaction != libc::SIG_IGN
                    {
                        old_actions.push((sig, old));
                    }
                }
                if old_actions.is_empty() {
                    return None;
                }
                let handled: Vec<libc::c_int> = old_actions.iter().map(|(s, _)| *s).collect();
                SIGNAL.store(0, Ordering::SeqCst);
                let done = Arc::new(AtomicBool::new(false));
                let d = done.clone();
                let watcher = std::thread::Builder::new()
                    .name("fracid-sigint".into())
                    .spawn(move || {
                        // This thread takes the signals (the run's thread blocks them).
                        let set = signal_set(&all);
                        libc::pthread_sigmask(libc::SIG_UNBLOCK, &set, std::ptr::null_mut());
                        let mut sent = false;
                        while !d.load(Ordering::SeqCst) {
                            if !sent && SIGNAL.load(Ordering::SeqCst) != 0 {
                                stop.stop();
                                sent = true;
                            }
                            std::thread::sleep(Duration::from_millis(10));
                        }
                    })
                    .ok()?;
                let mut action: libc::sigaction = std::mem::zeroed();
                action.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
                action.sa_flags = libc::SA_RESTART | libc::SA_RESETHAND;
                libc::sigemptyset(&mut action.sa_mask);
                for &sig in &handled {
                    libc::sigaction(sig, &action, std::ptr::null_mut());
                }
                let mut old_mask: libc::sigset_t = std::mem::zeroed();
                let set = signal_set(&handled);
                libc::pthread_sigmask(libc::SIG_BLOCK, &set, &mut old_mask);
                Some(Self {
                    old_actions,
                    old_mask,
                    done,
                    watcher: Some(watcher),
                })
            }
        }
    }

    impl Drop for Armed {
        fn drop(&mut self) {
            // SAFETY: restoring what `new` saved. A signal from here on acts as before the run
            // (by default it ends the process, also one left pending while blocked).
            unsafe {
                for (sig, old) in &self.old_actions {
                    libc::sigaction(*sig, old, std::ptr::null_mut());
                }
            }
            self.done.store(true, Ordering::SeqCst);
            if let Some(w) = self.watcher.take() {
                let _ = w.join();
            }
            // SAFETY: as above.
            unsafe {
                libc::pthread_sigmask(libc::SIG_SETMASK, &self.old_mask, std::ptr::null_mut());
            }
        }
    }
}
