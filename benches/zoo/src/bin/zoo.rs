//! `zoo`: generate the benchmark zoo, run it through fracid's fleet path (plain and `--diagnose`),
//! score it and write the table by class.
//!
//! ```sh
//! cargo run --release -p zoo --bin zoo -- run --cases 300 --out /tmp/zoo
//! cargo run --release -p zoo --bin zoo -- run --ci --out /tmp/zoo-ci      # the CI subset
//! cargo run --release -p zoo --bin zoo -- generate --cases 300 --out /tmp/zoo  # cases only
//! ```

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use zoo::cases::Sizing;
use zoo::run::{self, Options};

#[derive(Parser)]
#[command(
    about = "The benchmark zoo: generated drives with an independent truth, and the scoreboard"
)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(clap::Args)]
struct Common {
    /// Cases (0..N of the zoo; classes cycle, 25 of them)
    #[arg(long, default_value_t = 300)]
    cases: usize,
    /// The zoo's seed
    #[arg(long, default_value_t = 44)]
    seed: u64,
    /// The CI subset instead (its fixed seed, cases and short records)
    #[arg(long)]
    ci: bool,
    /// Output directory (cases/, truth/, reports/, table.*)
    #[arg(long)]
    out: PathBuf,
    /// Fits at once and generator threads (default: the cores)
    #[arg(long)]
    jobs: Option<usize>,
}

#[derive(Subcommand)]
enum Cmd {
    /// Generate, fit (plain and --diagnose, fleet path), score, write the table
    Run {
        #[command(flatten)]
        common: Common,
        /// The fracid binary (default: $ZOO_FRACID, else the workspace's target/{release,debug}/fracid)
        #[arg(long)]
        fracid: Option<PathBuf>,
    },
    /// Score an earlier run again (OUT as `run` left it) and write the table
    Score {
        #[command(flatten)]
        common: Common,
    },
    /// Generate the cases only (OUT/cases/*.csv, OUT/truth/*)
    Generate {
        #[command(flatten)]
        common: Common,
    },
}

fn options(c: &Common, fracid: Option<PathBuf>) -> Result<Options, String> {
    let jobs = c
        .jobs
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let (seed, count, sizing) = if c.ci {
        (zoo::ci::SEED, zoo::ci::CASES, zoo::ci::SIZING)
    } else {
        (c.seed, c.cases, Sizing::ZOO)
    };
    let fracid = match fracid.or_else(run::default_fracid) {
        Some(p) => p,
        None => {
            return Err(
                "no fracid binary: build it (cargo build --release -p fracid) or give --fracid"
                    .into(),
            )
        }
    };
    Ok(Options {
        seed,
        indices: (0..count).collect(),
        sizing,
        out: c.out.clone(),
        fracid,
        jobs: jobs.max(1),
    })
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Cmd::Run { common, fracid } => options(common, fracid.clone()).and_then(|o| {
            if !o.fracid.is_file() {
                return Err(format!("{}: no such fracid binary", o.fracid.display()));
            }
            let r = run::run(&o).map_err(|e| e.to_string())?;
            print!("{}", zoo::score::table::markdown(&r.table));
            print!("\n{}", r.floors.markdown());
            eprintln!(
                "{} cases; generation {:.1} s; plain fleet {:.1} s wall, {} CPU; --diagnose fleet {:.1} s wall, {} CPU; table in {}",
                r.outcomes.len() / 2,
                r.generate_s,
                r.plain.wall_s,
                r.plain.cpu_s.map_or("-".into(), |c| format!("{c:.1} s")),
                r.diagnose.wall_s,
                r.diagnose.cpu_s.map_or("-".into(), |c| format!("{c:.1} s")),
                o.out.join("table.md").display()
            );
            if o.indices.len() == zoo::ci::CASES && common.ci {
                for line in zoo::ci::below_floors(&r.table) {
                    eprintln!("below floor: {line}");
                }
            }
            Ok(())
        }),
        Cmd::Score { common } => options(common, Some(PathBuf::from("fracid"))).and_then(|o| {
            let r = run::rescore(&o).map_err(|e| e.to_string())?;
            print!("{}", zoo::score::table::markdown(&r.table));
            print!("\n{}", r.floors.markdown());
            Ok(())
        }),
        Cmd::Generate { common } => {
            // The fracid binary is not needed to generate.
            let o = options(common, Some(PathBuf::from("fracid")));
            o.and_then(|o| {
                run::prepare(&o.out).map_err(|e| e.to_string())?;
                let t = run::generate(&o).map_err(|e| e.to_string())?;
                eprintln!("{} cases in {}", t.len(), o.out.display());
                Ok(())
            })
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(1)
        }
    }
}
