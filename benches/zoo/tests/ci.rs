//! The zoo's CI subset (`zoo::ci`): 50 fixed cases, two per class, generated, fitted through the
//! fleet path (plain and `--diagnose`) by the fracid binary and scored; fails when a class falls
//! below its floor. The binary: `ZOO_FRACID`, else this workspace's `fracid` of the test's own
//! profile, built first (`cargo build -p fracid`, a no-op when it is fresh).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Instant, SystemTime};

use zoo::run::{self, Options};

/// target/<profile> of this test executable (target/<profile>/deps/ci-<hash>).
fn profile_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    exe.parent()
        .and_then(Path::parent)
        .expect("target/<profile>")
        .to_path_buf()
}

/// The newest modification time of the sources the fracid binary is built from.
fn newest_source(root: &Path) -> Option<SystemTime> {
    fn walk(dir: &Path, newest: &mut Option<SystemTime>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for e in entries.flatten() {
            let path = e.path();
            if path.is_dir() {
                walk(&path, newest);
            } else if let Ok(m) = e.metadata().and_then(|m| m.modified()) {
                *newest = (*newest).max(Some(m));
            }
        }
    }
    let mut newest = None;
    for krate in ["fracid", "ident", "fracsim", "drive", "tune"] {
        walk(&root.join("crates").join(krate).join("src"), &mut newest);
        walk(
            &root.join("crates").join(krate).join("Cargo.toml"),
            &mut newest,
        );
    }
    newest
}

/// `ZOO_FRACID`, else target/<profile>/fracid: a workspace `cargo test` has built it (the fracid
/// crate's own integration tests need it); when it is missing or older than its sources (`cargo
/// test -p zoo` alone), it is built here with the cargo that runs this test.
fn fracid_bin() -> PathBuf {
    if let Some(p) = std::env::var_os("ZOO_FRACID") {
        return PathBuf::from(p);
    }
    let dir = profile_dir();
    let bin = dir.join(format!("fracid{}", std::env::consts::EXE_SUFFIX));
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let built_at = std::fs::metadata(&bin).and_then(|m| m.modified()).ok();
    let fresh = match (built_at, newest_source(&root)) {
        (Some(b), Some(s)) => b >= s,
        (Some(_), None) => true,
        _ => false,
    };
    if !fresh {
        let profile = dir
            .file_name()
            .and_then(|s| s.to_str())
            .unwrap_or("debug")
            .to_string();
        let target = dir.parent().expect("target dir").to_path_buf();
        let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
        let mut cmd = Command::new(cargo);
        cmd.args(["build", "-p", "fracid", "--bin", "fracid"])
            .env("CARGO_TARGET_DIR", &target)
            .current_dir(&root);
        if profile != "debug" {
            cmd.args(["--profile", &profile]);
        }
        eprintln!(
            "building {} (missing or older than its sources)",
            bin.display()
        );
        let ok = cmd.status().map(|s| s.success()).unwrap_or(false);
        assert!(
            ok && bin.exists(),
            "{} could not be built: run `cargo build -p fracid` or set ZOO_FRACID",
            bin.display()
        );
    }
    bin
}

#[test]
fn ci_subset_stays_above_its_floors() {
    let fracid = fracid_bin();
    let out = tempfile::tempdir().expect("temporary directory");
    let o = Options {
        seed: zoo::ci::SEED,
        indices: (0..zoo::ci::CASES).collect(),
        sizing: zoo::ci::SIZING,
        out: out.path().to_path_buf(),
        fracid,
        jobs: std::thread::available_parallelism().map_or(2, |n| n.get()),
    };
    let start = Instant::now();
    let r = run::run(&o).expect("the zoo's CI subset runs");
    let table = zoo::score::table::markdown(&r.table);
    eprintln!("{table}");
    eprintln!(
        "CI subset: {} cases in {:.1} s (generation {:.1} s, plain {:.1} s, --diagnose {:.1} s)",
        r.outcomes.len() / 2,
        start.elapsed().as_secs_f64(),
        r.generate_s,
        r.plain.wall_s,
        r.diagnose.wall_s
    );
    assert_eq!(r.outcomes.len(), 2 * zoo::ci::CASES);
    // Every case got a row from both fleets (the fleet path ran on every file).
    let missing: Vec<_> = r
        .outcomes
        .iter()
        .filter(|o| o.exit_code.is_none())
        .map(|o| &o.name)
        .collect();
    assert!(missing.is_empty(), "no summary row for {missing:?}");
    let below = zoo::ci::below_floors(&r.table);
    assert!(
        below.is_empty(),
        "classes below their floors:\n{}\n{table}",
        below.join("\n")
    );
}
