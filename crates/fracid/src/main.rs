//! `fracid`: fractional-order identification of electric drives, from the command line.
//!
//! Subcommands live in [`cmd`]; errors from every layer are mapped to exit codes in one place,
//! [`exit_code`].

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
    Time(cmd::time::TimeArgs),
    /// Two models side by side: one Bode plot, the largest differences, the coefficients.
    Compare(cmd::compare::CompareArgs),
}

/// Exit codes: 0 success, 1 runtime failure (numerical breakdown, fit failure, drive fault),
/// 2 bad input (malformed model, data or options; clap also uses 2 for usage errors),
/// 3 I/O (a file or port that cannot be opened or written). Drive faults (timeouts, NAKs, protocol
/// violations, a reset) are runtime failures.
fn exit_code(err: &anyhow::Error) -> u8 {
    for cause in err.chain() {
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
            return match e {
                ident::Error::Numerical(_) => 1,
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
        if cause.downcast_ref::<cmd::BadInput>().is_some() {
            return 2;
        }
    }
    1
}

fn main() -> ExitCode {
    // Like every Unix filter: a closed stdout (`fracid time FILE | head`) ends the process
    // quietly by SIGPIPE instead of making the next print panic.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE at start-up, before any thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = Cli::parse();
    let result = match cli.command {
        Commands::Sim(a) => cmd::sim::run(a),
        Commands::Demo(a) => cmd::demo::run(a),
        // -- more dispatch arms are added below, one line each --
        Commands::Drive(a) => cmd::drive::run(a),
        Commands::Freq(a) => cmd::freq::run(a),
        Commands::Time(a) => cmd::time::run(a),
        Commands::Compare(a) => cmd::compare::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
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
