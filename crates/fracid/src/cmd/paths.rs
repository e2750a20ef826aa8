//! No output overwrites an input: the one check every command that reads and writes files makes
//! before any work (docs/reliability.md). Two paths are one file when they name the same regular
//! file (the same device and inode: a symbolic link, a hard link, `./x` and `x`, `/dev/stdout`
//! redirected to it), or, for a file not yet created, the same name in the same folder (the
//! folder's canonical path). Devices, pipes and folders are no file an output could overwrite
//! (`--input /dev/stdin` with `-o /dev/stdout` on one terminal is fine); the drive commands check
//! their serial port themselves.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The identity of a path for this check.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
enum Key {
    /// An existing regular file: its device and inode (its canonical path off Unix).
    File(u64, u64),
    #[cfg(not(unix))]
    Canonical(PathBuf),
    /// A file not yet created: the canonical folder and the name.
    Planned(PathBuf),
}

/// The identity of `p`, or `None` for what no output overwrites (a device, a pipe, a folder) or
/// a path whose folder does not exist (writing there fails on its own).
fn key(p: &Path) -> Option<Key> {
    match std::fs::metadata(p) {
        Ok(m) if m.is_file() => {
            #[cfg(unix)]
            {
                use std::os::unix::fs::MetadataExt;
                Some(Key::File(m.dev(), m.ino()))
            }
            #[cfg(not(unix))]
            {
                std::fs::canonicalize(p).ok().map(Key::Canonical)
            }
        }
        Ok(_) => None,
        Err(_) => planned(p).map(Key::Planned),
    }
}

/// Where a file not yet created at `p` would be: the canonical folder and the name; a dangling
/// symbolic link is followed (writing creates its target).
fn planned(p: &Path) -> Option<PathBuf> {
    let p = match std::fs::read_link(p) {
        Ok(target) => p.parent().unwrap_or(Path::new("")).join(target),
        Err(_) => p.to_path_buf(),
    };
    let dir = match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    Some(std::fs::canonicalize(dir).ok()?.join(p.file_name()?))
}

/// A file a command reads or writes: what it is to the user (`--input`, `the record`, `--plot`)
/// and its path.
pub type Named<'a> = (&'a str, &'a Path);

/// Refuse (bad input, exit 2) an output that is one of the `inputs` (it would overwrite it) or
/// another output (both would be written into it), naming both, before anything is read or
/// written. Linear in the number of files (a fleet of hundreds checks at once).
///
/// # Errors
/// [`super::BadInput`] naming the two paths.
pub fn check(inputs: &[Named<'_>], outputs: &[Named<'_>]) -> anyhow::Result<()> {
    let mut seen: HashMap<Key, (bool, Named<'_>)> = HashMap::new();
    for &(what, p) in inputs {
        if let Some(k) = key(p) {
            seen.entry(k).or_insert((true, (what, p)));
        }
    }
    for &(what, p) in outputs {
        let Some(k) = key(p) else { continue };
        match seen.get(&k) {
            Some(&(true, (iwhat, ip))) => crate::bad_input!(
                "{what} {} is {iwhat} {}: writing it would overwrite the input (choose another \
                 output file)",
                p.display(),
                ip.display()
            ),
            Some(&(false, (owhat, op))) => crate::bad_input!(
                "{what} {} and {owhat} {} are one file: both would be written into it",
                p.display(),
                op.display()
            ),
            None => {
                seen.insert(k, (false, (what, p)));
            }
        }
    }
    Ok(())
}

/// [`check`] for a fit's files: the `inputs` against `--plot` and, with `--diagnose`, the
/// residual plot written beside it (`fracid time`, `fracid freq`).
///
/// # Errors
/// As [`check`].
pub fn check_plots(
    inputs: &[Named<'_>],
    plot: Option<&Path>,
    diagnose: bool,
) -> anyhow::Result<()> {
    let residual = plot
        .filter(|_| diagnose)
        .map(super::diagnose::residual_plot_path);
    let mut outputs: Vec<Named<'_>> = plot.map(|p| ("--plot", p)).into_iter().collect();
    outputs.extend(residual.as_deref().map(|p| ("the residual plot", p)));
    check(inputs, &outputs)
}

/// The file an argument that is a file or a text names (a model: `fracid export fit.json`, or
/// `--weights`), else none (a transfer function's text, a word).
pub fn file_arg(arg: &str) -> Option<&Path> {
    let p = Path::new(arg);
    p.is_file().then_some(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn links_and_spellings_of_one_file_are_one_file() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.csv");
        std::fs::write(&a, "t,u,y\n").unwrap();
        let dot = dir.path().join(".").join("a.csv");
        assert!(check(&[("--input", &a)], &[("-o", &dot)]).is_err());
        #[cfg(unix)]
        {
            let sym = dir.path().join("sym.csv");
            std::os::unix::fs::symlink(&a, &sym).unwrap();
            let e = check(&[("--input", &a)], &[("-o", &sym)]).unwrap_err();
            assert!(e.to_string().contains("--input"), "{e}");
            assert!(e.to_string().contains("sym.csv"), "{e}");
            let hard = dir.path().join("hard.csv");
            std::fs::hard_link(&a, &hard).unwrap();
            assert!(check(&[("--input", &hard)], &[("-o", &a)]).is_err());
            // a dangling link whose target another output names
            let dangling = dir.path().join("dangling.png");
            std::os::unix::fs::symlink("new.png", &dangling).unwrap();
            let new = dir.path().join("new.png");
            assert!(check(&[], &[("--plot", &dangling), ("-o", &new)]).is_err());
        }
        // two outputs not yet created, spelled differently
        let p = dir.path().join("p.png");
        let q = dir.path().join("sub").join("..").join("p.png");
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        let e = check(&[], &[("--plot", &p), ("-o", &q)]).unwrap_err();
        assert!(e.to_string().contains("one file"), "{e}");
        // different files pass; devices are not files
        let b = dir.path().join("b.csv");
        assert!(check(&[("--input", &a)], &[("-o", &b), ("--plot", &p)]).is_ok());
        #[cfg(unix)]
        assert!(check(
            &[("--input", Path::new("/dev/null"))],
            &[("-o", Path::new("/dev/null"))]
        )
        .is_ok());
    }
}
