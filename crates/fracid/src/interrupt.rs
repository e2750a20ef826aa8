//! Ctrl-C during a drive run: the first SIGINT asks the drive to STOP (the run ends, what arrived
//! is kept and the record says what is missing); a second one ends the process as usual.
//!
//! The signal handler only sets an atomic flag (async-signal-safe) and resets itself to the
//! default disposition (`SA_RESETHAND`); a small watcher thread turns the flag into
//! [`StopHandle::stop`]. SIGINT is blocked in the thread that runs the acquisition, so the signal
//! lands on the watcher and never interrupts the run's own system calls.

use drive::client::StopHandle;

/// Turns the first Ctrl-C into a STOP while alive; restores the previous SIGINT handling on drop.
/// One at a time per process.
pub struct StopOnInterrupt {
    #[cfg(unix)]
    inner: Option<unix::Armed>,
}

impl StopOnInterrupt {
    /// Arm for the run that `stop` belongs to. If SIGINT is ignored (a background job started
    /// with it ignored, `nohup`), it stays ignored and nothing is armed.
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

    /// Whether a Ctrl-C arrived while armed.
    pub fn interrupted(&self) -> bool {
        #[cfg(unix)]
        {
            self.inner.is_some() && unix::INTERRUPTED.load(std::sync::atomic::Ordering::SeqCst)
        }
        #[cfg(not(unix))]
        {
            false
        }
    }
}

#[cfg(unix)]
mod unix {
    use drive::client::StopHandle;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    use std::thread::JoinHandle;
    use std::time::Duration;

    pub(super) static INTERRUPTED: AtomicBool = AtomicBool::new(false);

    extern "C" fn on_sigint(_: libc::c_int) {
        // Async-signal-safe: one atomic store. SA_RESETHAND already restored the default action.
        INTERRUPTED.store(true, Ordering::SeqCst);
    }

    fn sigint_set() -> libc::sigset_t {
        // SAFETY: sigemptyset initialises the set before sigaddset uses it.
        unsafe {
            let mut set: libc::sigset_t = std::mem::zeroed();
            libc::sigemptyset(&mut set);
            libc::sigaddset(&mut set, libc::SIGINT);
            set
        }
    }

    pub(super) struct Armed {
        old_action: libc::sigaction,
        old_mask: libc::sigset_t,
        done: Arc<AtomicBool>,
        watcher: Option<JoinHandle<()>>,
    }

    impl Armed {
        pub(super) fn new(stop: StopHandle) -> Option<Self> {
            // SAFETY: plain sigaction/pthread_sigmask calls on initialised structures; the
            // handler only touches an atomic.
            unsafe {
                let mut old_action: libc::sigaction = std::mem::zeroed();
                if libc::sigaction(libc::SIGINT, std::ptr::null(), &mut old_action) != 0
                    || old_action.sa_sigaction == libc::SIG_IGN
                {
                    return None;
                }
                INTERRUPTED.store(false, Ordering::SeqCst);
                let done = Arc::new(AtomicBool::new(false));
                let d = done.clone();
                let watcher = std::thread::Builder::new()
                    .name("fracid-sigint".into())
                    .spawn(move || {
                        // This thread takes the signal (the run's thread blocks it).
                        let set = sigint_set();
                        libc::pthread_sigmask(libc::SIG_UNBLOCK, &set, std::ptr::null_mut());
                        let mut sent = false;
                        while !d.load(Ordering::SeqCst) {
                            if !sent && INTERRUPTED.load(Ordering::SeqCst) {
                                stop.stop();
                                sent = true;
                            }
                            std::thread::sleep(Duration::from_millis(10));
                        }
                    })
                    .ok()?;
                let mut action: libc::sigaction = std::mem::zeroed();
                action.sa_sigaction = on_sigint as extern "C" fn(libc::c_int) as libc::sighandler_t;
                action.sa_flags = libc::SA_RESTART | libc::SA_RESETHAND;
                libc::sigemptyset(&mut action.sa_mask);
                libc::sigaction(libc::SIGINT, &action, std::ptr::null_mut());
                let mut old_mask: libc::sigset_t = std::mem::zeroed();
                let set = sigint_set();
                libc::pthread_sigmask(libc::SIG_BLOCK, &set, &mut old_mask);
                Some(Self {
                    old_action,
                    old_mask,
                    done,
                    watcher: Some(watcher),
                })
            }
        }
    }

    impl Drop for Armed {
        fn drop(&mut self) {
            // SAFETY: restoring what `new` saved. A Ctrl-C from here on acts as before the run
            // (by default it ends the process, also one left pending while blocked).
            unsafe {
                libc::sigaction(libc::SIGINT, &self.old_action, std::ptr::null_mut());
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
