//! The files `survey process` writes, all beside the table CSV.
//!
//! - `<table>.csv`: the contract's correction table.
//! - `<stem>.comp0` and `<stem>.comp1`: LinuxCNC joint compensation files
//!   (`COMP_FILE_TYPE = 0` and `1`), at most 256 lines over the joint range
//!   (default 0 to 360 inclusive).
//! - `<stem>.840d.ini`: Siemens 840D measuring-system error compensation.
//! - `<stem>.fanuc.txt`: Fanuc pitch-error compensation values and parameters.
//! - `<stem>.generic.csv`: the generic table (when asked for).
//! - `<stem>.bin`: the binary table of `survey_controllers::corrector`.
//! - `<stem>.recipe.toml`: the recipe used; `--recipe` replays it.
//!
//! The bytes of every format come from `survey_controllers` (pure);
//! this module only names the files and puts them on disk.
//!
//! `<stem>` is the CSV path without its `.csv` extension. Everything is
//! written to temporary files first (`.<name>.tmp-<pid>` beside it) and
//! renamed into place at the end, so a failed command leaves the previous
//! files as they were. Temporary files of ours that a killed process left
//! beside them (their process is gone) are removed.

use crate::error::{bad_input, path_error};
use std::path::{Path, PathBuf};
use survey_controllers::corrector;
use survey_controllers::table_csv;
use survey_tables::pipeline::Processed;
use survey_tables::recipe::ExportChoices;

/// The paths of every file written.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct OutputPaths {
    /// The table CSV.
    pub table_csv: PathBuf,
    /// LinuxCNC `COMP_FILE_TYPE = 0` file.
    pub linuxcnc_type0: Option<PathBuf>,
    /// LinuxCNC `COMP_FILE_TYPE = 1` file.
    pub linuxcnc_type1: Option<PathBuf>,
    /// Siemens 840D EEC file.
    pub sinumerik_840d: Option<PathBuf>,
    /// Fanuc pitch-error file.
    pub fanuc: Option<PathBuf>,
    /// The generic table.
    pub generic: Option<PathBuf>,
    /// The binary table.
    pub binary: Option<PathBuf>,
    /// The recipe used (none when the table goes to a device or a pipe).
    pub recipe: Option<PathBuf>,
}

impl OutputPaths {
    /// The files beside `table_csv` that `export` asks for. When `table_csv`
    /// is a device or a pipe (`/dev/stdout`, a FIFO) there is no "beside":
    /// the table alone is written there.
    pub fn beside(table_csv: &Path, export: &ExportChoices) -> Self {
        if matches!(target(table_csv), Ok(Target::Stream(_))) {
            return Self {
                table_csv: table_csv.to_path_buf(),
                linuxcnc_type0: None,
                linuxcnc_type1: None,
                sinumerik_840d: None,
                fanuc: None,
                generic: None,
                binary: None,
                recipe: None,
            };
        }
        let stem = match table_csv.extension() {
            Some(e) if e.eq_ignore_ascii_case("csv") => table_csv.with_extension(""),
            _ => table_csv.to_path_buf(),
        };
        let with = |suffix: &str| {
            let mut s = stem.clone().into_os_string();
            s.push(suffix);
            PathBuf::from(s)
        };
        Self {
            table_csv: table_csv.to_path_buf(),
            linuxcnc_type0: export.linuxcnc.then(|| with(".comp0")),
            linuxcnc_type1: export.linuxcnc.then(|| with(".comp1")),
            sinumerik_840d: export.sinumerik_840d.then(|| with(".840d.ini")),
            fanuc: export.fanuc.then(|| with(".fanuc.txt")),
            generic: export.generic.then(|| with(".generic.csv")),
            binary: export.binary.then(|| with(".bin")),
            recipe: Some(with(".recipe.toml")),
        }
    }

    /// The path of a controller file of `kind` (`linuxcnc_type0`, `sinumerik_840d`...).
    pub fn of_kind(&self, kind: &str) -> Option<&Path> {
        match kind {
            "linuxcnc_type0" => self.linuxcnc_type0.as_deref(),
            "linuxcnc_type1" => self.linuxcnc_type1.as_deref(),
            "sinumerik_840d" => self.sinumerik_840d.as_deref(),
            "fanuc" => self.fanuc.as_deref(),
            "generic" => self.generic.as_deref(),
            _ => None,
        }
    }
}

/// Where a file goes, and how.
#[derive(Debug, Clone, PartialEq)]
enum Target {
    /// A regular file, or none yet: written to a temporary file in the same
    /// folder and renamed over it (atomic: the old file or the new, never half).
    Replace(PathBuf),
    /// A device or a pipe: written to in place (it cannot be replaced, and
    /// must not be by a regular file).
    Stream(PathBuf),
}

/// The target of `path`, following symbolic links (a link is never replaced
/// by a file: the file it names is written).
fn target(path: &Path) -> anyhow::Result<Target> {
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let link =
                    std::fs::read_link(&p).map_err(|e| path_error(e, format!("cannot follow {}", p.display())))?;
                p = match p.parent() {
                    Some(dir) if link.is_relative() => dir.join(link),
                    _ => link,
                };
            }
            Ok(m) if m.is_file() => return Ok(Target::Replace(p)),
            Ok(m) if m.is_dir() => {
                return Err(bad_input(format!("{} is a folder: name a file to write", path.display())));
            }
            Ok(_) => return Ok(Target::Stream(p)),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Target::Replace(p)),
            Err(e) => return Err(path_error(e, format!("cannot write {}", path.display()))),
        }
    }
    Err(bad_input(format!("{}: too many levels of symbolic links", path.display())))
}

/// A temporary file next to its target, removed when dropped unless renamed.
struct Staged {
    tmp: PathBuf,
    path: PathBuf,
    done: bool,
}

impl Drop for Staged {
    fn drop(&mut self) {
        if !self.done {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// The name of `target`'s temporary files: `.<name>.tmp-` and a process id.
fn tmp_prefix(target: &Path) -> String {
    let name = target.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
    format!(".{name}.tmp-")
}

/// Remove the temporary files of `target` that a process that is gone left
/// beside it (killed between writing and renaming). Those of a live process
/// (another `survey` writing the same file now) are left alone.
fn remove_stale(target: &Path) {
    let prefix = tmp_prefix(target);
    let dir = match target.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(|n| n.strip_prefix(&prefix)).and_then(|p| p.parse::<i32>().ok()) else {
            continue;
        };
        // Signal 0 only asks whether the process exists.
        let gone = nix::sys::signal::kill(nix::unistd::Pid::from_raw(pid), None) == Err(nix::errno::Errno::ESRCH);
        if gone && entry.file_type().is_ok_and(|t| t.is_file()) {
            match std::fs::remove_file(entry.path()) {
                Ok(()) => tracing::info!(file = %entry.path().display(), "a stale temporary file removed"),
                Err(e) => tracing::warn!(file = %entry.path().display(), %e, "a stale temporary file stays"),
            }
        }
    }
}

/// Write `bytes` to a temporary file beside `target` (named for `shown`).
fn stage(target: &Path, shown: &Path, bytes: &[u8]) -> anyhow::Result<Staged> {
    let tmp = target.with_file_name(format!("{}{}", tmp_prefix(target), std::process::id()));
    let staged = Staged { tmp, path: target.to_path_buf(), done: false };
    let mut file =
        std::fs::File::create(&staged.tmp).map_err(|e| path_error(e, format!("cannot create {}", shown.display())))?;
    use std::io::Write as _;
    file.write_all(bytes)
        .and_then(|()| file.sync_all())
        .map_err(|e| path_error(e, format!("cannot write {}", shown.display())))?;
    Ok(staged)
}

/// Write `bytes` into a device or pipe. A write error (a full device) is a
/// run-time failure, exit status 1.
fn stream(target: &Path, shown: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    use std::io::Write as _;
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .open(target)
        .map_err(|e| path_error(e, format!("cannot open {}", shown.display())))?;
    // The path was fine (it opened): whatever the write meets is a run-time failure.
    file.write_all(bytes)
        .and_then(|()| file.flush())
        .map_err(|e| anyhow::Error::new(e).context(format!("cannot write {}", shown.display())))
}

/// Write every file of `paths` from `processed` (see the module
/// documentation): regular files are staged and renamed into place only when
/// every file was written, so a failure leaves the previous files as they were.
/// `crash_when_staged` (tests) aborts the process between the two.
pub fn write_all(
    paths: &OutputPaths,
    processed: &Processed,
    survey_id: i64,
    crash_when_staged: bool,
) -> anyhow::Result<()> {
    let table = &processed.built.table;
    let mut outputs: Vec<(&Path, Vec<u8>)> = vec![(paths.table_csv.as_path(), table_csv(table).into_bytes())];
    for file in processed.controllers.iter().flat_map(|c| &c.files) {
        if let Some(p) = paths.of_kind(file.kind) {
            outputs.push((p, file.text.clone().into_bytes()));
        }
    }
    if let Some(p) = &paths.binary {
        outputs.push((p, corrector::to_bytes(table, processed.recipe.export.binary_format)));
    }
    if let Some(p) = &paths.recipe {
        let recipe = format!(
            "# Made by `survey process` from survey {survey_id}{}.\n{}",
            if processed.replayed { " by replaying a recipe" } else { "" },
            processed.recipe.to_toml()
        );
        outputs.push((p.as_path(), recipe.into_bytes()));
    }
    let mut staged = Vec::new();
    let mut streams = Vec::new();
    for (shown, bytes) in &outputs {
        match target(shown)? {
            Target::Replace(t) => {
                remove_stale(&t);
                staged.push(stage(&t, shown, bytes)?);
            }
            Target::Stream(t) => streams.push((t, *shown, bytes)),
        }
    }
    if crash_when_staged {
        // A simulated power loss: the temporary files stay, none is renamed.
        std::process::abort();
    }
    for (t, shown, bytes) in streams {
        stream(&t, shown, bytes)?;
    }
    for mut s in staged {
        std::fs::rename(&s.tmp, &s.path).map_err(|e| path_error(e, format!("cannot write {}", s.path.display())))?;
        s.done = true;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_take_the_stem_of_the_csv() {
        let p = OutputPaths::beside(Path::new("out/t.csv"), &ExportChoices::default());
        assert_eq!(p.linuxcnc_type0.as_deref(), Some(Path::new("out/t.comp0")));
        assert_eq!(p.linuxcnc_type1.as_deref(), Some(Path::new("out/t.comp1")));
        assert_eq!(p.binary.as_deref(), Some(Path::new("out/t.bin")));
        assert_eq!(p.sinumerik_840d.as_deref(), Some(Path::new("out/t.840d.ini")));
        assert_eq!(p.fanuc.as_deref(), Some(Path::new("out/t.fanuc.txt")));
        assert_eq!((p.generic.as_deref(), p.of_kind("fanuc")), (None, Some(Path::new("out/t.fanuc.txt"))));
        assert_eq!(p.recipe.as_deref(), Some(Path::new("out/t.recipe.toml")));
        let none = ExportChoices {
            linuxcnc: false,
            sinumerik_840d: false,
            fanuc: false,
            binary: false,
            ..ExportChoices::default()
        };
        let q = OutputPaths::beside(Path::new("table"), &none);
        assert_eq!((q.linuxcnc_type0, q.binary, q.recipe), (None, None, Some(PathBuf::from("table.recipe.toml"))));
    }

    #[test]
    fn a_failed_write_leaves_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("missing/t.csv");
        let err = stage(&missing, &missing, b"x");
        assert_eq!(crate::error::exit_status(&err.err().unwrap()), 2);
        let t = dir.path().join("t.csv");
        let ok = stage(&t, &t, b"x").unwrap();
        let tmp = ok.tmp.clone();
        assert!(tmp.exists());
        drop(ok);
        assert!(!tmp.exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}
