//! `fracid`: fractional-order identification of electric drives, from the command line.
//!
//! Subcommands live in [`cmd`]; errors from every layer are mapped to exit codes in one place,
//! [`exit_code`].

mod alloc;
mod bad_input;
mod cmd;
mod interrupt;
mod plot;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Fractional-order system identification of electric drives.
#[derive(Debug, Parser)]
#[command(name = "fracid", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Commands,
}

#[derive(Debug, Subcommand)]
enum Commands {
    /// Simulate a fractional transfer function on a step, a PRBS or a recorded input.
    Sim(cmd::sim::SimArgs),
    /// The main job end to end: simulated drive, acquisition, identification, diagnosis, report.
    Demo(cmd::demo::DemoArgs),
    // -- more subcommands are added below, one line each --
    /// Talk to an F2812 servo drive (or its simulator): acquisition, status, the simulator.
    Drive(cmd::drive::DriveArgs),
    /// Identify a fractional model from Bode data (weighted Levy, order search, refit).
    Freq(cmd::freq::FreqArgs),
    /// Identify a fractional model from a time record by output error (Levenberg-Marquardt).
    Time(Box<cmd::time::TimeArgs>),
    /// Two models side by side: one Bode plot, the largest differences, the coefficients.
    Compare(cmd::compare::CompareArgs),
    /// Score a given model on a time record (its own initial state and output offset estimated).
    Score(cmd::score::ScoreArgs),
    /// Export a model's approximation as a state space (continuous, or discrete with the exact
    /// hold) to JSON or a MATLAB script.
    Export(cmd::export::ExportArgs),
    /// Design a fractional PI/PID (or integer PI/PID) on a model for a crossover, a phase margin
    /// and a flat phase; its discrete realisation and its closed loop simulated.
    Tune(Box<cmd::tune::TuneArgs>),
}

/// Exit codes: 0 success, 1 runtime failure (numerical breakdown, fit failure, drive fault),
/// 2 bad input (malformed model, data or options; clap also uses 2 for usage errors),
/// 3 I/O (a file or port that cannot be opened or written); an impossible `tune` specification
/// is a runtime failure (1), 128 + N for a drive run ended by
/// signal N after its record was finished (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP, 131 SIGQUIT, ...:
/// `interrupt::handled_signals`). Drive faults (timeouts, NAKs, protocol
/// violations, a reset) are runtime failures.
fn exit_code(err: &anyhow::Error) -> u8 {
    for cause in err.chain() {
        if let Some(i) = cause.downcast_ref::<interrupt::Interrupted>() {
            return i.exit_code();
        }
        if cause.downcast_ref::<std::io::Error>().is_some() {
            return 3;
        }
        if let Some(e) = cause.downcast_ref::<fracsim::Error>() {
            return match e {
                fracsim::Error::Numerical(_) => 1,
                _ => 2,
            };
        }
        if let Some(e) = cause.downcast_ref::<ident::Error>() {
            // An error in a file's content: its kind decides.
            return match e.innermost() {
                ident::Error::Io { .. } => 3,
                ident::Error::Numerical(_) => 1,
                ident::Error::Cancelled(_) => 130,
                ident::Error::Sim(fracsim::Error::Numerical(_)) => 1,
                _ => 2,
            };
        }
        if let Some(e) = cause.downcast_ref::<drive::Error>() {
            return match e {
                drive::Error::InvalidParam(_) => 2,
                drive::Error::Io(_) | drive::Error::Port { .. } => 3,
                _ => 1,
            };
        }
        if let Some(e) = cause.downcast_ref::<tune::Error>() {
            return match e {
                tune::Error::Infeasible(_) | tune::Error::Unsafe(_) => 1,
                tune::Error::Sim(fracsim::Error::Numerical(_)) => 1,
                _ => 2,
            };
        }
        if let Some(e) = cause.downcast_ref::<autotune::Error>() {
            return match e {
                autotune::Error::InvalidParam(_) => 2,
                autotune::Error::Interrupted(_) => 130,
                _ => 1,
            };
        }
        if cause.downcast_ref::<cmd::BadInput>().is_some() {
            return 2;
        }
    }
    1
}

/// Set by the panic hook when `println!` failed to write to standard output.
static STDOUT_FAILED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// A failed write to standard output (`fracid time FILE > /dev/full`) is an I/O error, exit 3 with
/// a message, in every subcommand: `println!` panics on a write error; this hook reports that one
/// panic in words (any other panic keeps the default report) and [`main`] catches it and exits 3
/// after the unwinding has closed (and flushed) every file the command had open. One place for
/// every `println!` of every subcommand.
fn stdout_failure_exits_3() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let msg = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if let Some(reason) = msg.strip_prefix("failed printing to stdout: ") {
            let reason = reason.split(" (os error").next().unwrap_or(reason);
            interrupt::eprint_line(&format!("error: cannot write to standard output: {reason}"));
            STDOUT_FAILED.store(true, std::sync::atomic::Ordering::SeqCst);
            return;
        }
        default(info);
    }));
}

/// A fit allocates and frees buffers of a record's length at every iteration (simulations,
/// sensitivities). glibc's default maps each one fresh from the kernel and returns it on free, so
/// every iteration pays a page fault per 4 KiB written (a fifth of a 1e6-sample fit's time):
/// blocks up to 32 MiB come from the heap instead, and freed memory stays there to be reused.
/// Each heap (arena) keeps what it freed, and glibc gives each new thread one of up to 8 per core:
/// the closed loop's threads (a candidate structure's fit, a diagnosis, each on its own) held as
/// many heaps of freed buffers, 1.27 GB resident on a 1e6-sample record and past a 1 GiB address
/// space (reliability round 2, item 2). One heap per core: the threads running at once (the
/// structure comparison runs one task per core) each have their own, and the freed memory is
/// reused across tasks instead of kept per thread.
fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        let cores = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
        // SAFETY: mallopt only sets allocator parameters; called at start-up before any thread.
        unsafe {
            libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
            libc::mallopt(libc::M_TRIM_THRESHOLD, 1 << 30);
            libc::mallopt(libc::M_ARENA_MAX, cores.clamp(1, 64) as libc::c_int);
        }
    }
}

/// Large blocks on huge pages (see [`alloc`]).
#[global_allocator]
static ALLOC: alloc::HugeForLarge = alloc::HugeForLarge;

fn main() -> ExitCode {
    // Like every Unix filter: a closed stdout (`fracid time FILE | head`) ends the process
    // quietly by SIGPIPE instead of making the next print panic.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE at start-up, before any thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    keep_freed_memory();
    stdout_failure_exits_3();
    let cli = Cli::parse();
    // The command's models share one cache of solved poles (`fracsim::modal::RootsCache`), its
    // own: what it computes depends on nothing that ran before it.
    let mut poles = fracsim::modal::RootsCache::new();
    let run = std::panic::AssertUnwindSafe(|| {
        poles.enter(|| match cli.command {
            Commands::Sim(a) => cmd::sim::run(a),
            Commands::Demo(a) => cmd::demo::run(a),
            // -- more dispatch arms are added below, one line each --
            Commands::Drive(a) => cmd::drive::run(a),
            Commands::Freq(a) => cmd::freq::run(a),
            Commands::Time(a) => cmd::time::run(*a),
            Commands::Compare(a) => cmd::compare::run(a),
            Commands::Score(a) => cmd::score::run(a),
            Commands::Export(a) => cmd::export::run(a),
            Commands::Tune(a) => cmd::tune::run(*a),
        })
    });
    let result = match std::panic::catch_unwind(run) {
        Ok(r) => r,
        Err(_) if STDOUT_FAILED.load(std::sync::atomic::Ordering::SeqCst) => {
            return ExitCode::from(3)
        }
        Err(p) => std::panic::resume_unwind(p),
    };
    // What is still buffered is written now, so that a full disk is an error, not lost output.
    let result = result.and_then(|()| {
        use std::io::Write;
        std::io::stdout()
            .flush()
            .map_err(|e| anyhow::Error::new(e).context("cannot write to standard output"))
    });
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            interrupt::eprint_line(&format!("error: {e:#}"));
            ExitCode::from(exit_code(&e))
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn command_line_definition_is_consistent() {
        use clap::CommandFactory;
        super::Cli::command().debug_assert();
    }
}
