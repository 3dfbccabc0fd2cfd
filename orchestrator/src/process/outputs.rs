//! The files `survey process` writes, all beside the table CSV.
//!
//! - `<table>.csv`: the contract's correction table. Header `readout_deg,error_deg`
//!   (or `readout_deg,error_forward_deg,error_reverse_deg`), one row per table
//!   row at `360 i / n` degrees from 0 up to `360 - 360/n`, numbers in Rust's
//!   shortest round-trip form.
//! - `<stem>.comp0` and `<stem>.comp1`: LinuxCNC joint compensation files,
//!   for `[JOINT_n] COMP_FILE = ...` with `COMP_FILE_TYPE = 0` and `1`
//!   respectively. Looked up in LinuxCNC's source (LinuxCNC/linuxcnc:
//!   `src/emc/ini/inijoint.cc` reads `COMP_FILE_TYPE`, default 0;
//!   `usrmotLoadComp` in `src/emc/motion/usrmotintf.cc` reads one
//!   `nominal forward reverse` triplet per line with `sscanf("%lf %lf %lf")`
//!   and stops at the first line that is not one, so there is no header line;
//!   type 0 holds positions and is turned into trims as `nominal - forward`,
//!   type 1 holds the trims `forward_trim reverse_trim` directly;
//!   `EMCMOT_SET_JOINT_COMP` in `command.c` refuses more than
//!   `EMCMOT_COMP_SIZE` = 256 entries and nominals that do not increase; and
//!   `control.c` adds the forward trim to the motor command while moving up,
//!   the reverse trim while moving down, interpolating linearly between
//!   entries). The motor position is our readout and the trim that puts the
//!   axis on the commanded angle is our error `readout - actual`, so a line is
//!   `nominal  nominal-error_fwd  nominal-error_rev` (type 0: the actual
//!   angles the axis reaches) or `nominal  error_fwd  error_rev` (type 1),
//!   ascending nominals, at most 256 lines (`export.linuxcnc_points`), 10
//!   decimals. Over a full circle the nominals run from 0 to 360 inclusive.
//! - `<stem>.bin`: the binary table of `survey_processing::corrector`.
//! - `<stem>.recipe.toml`: the recipe used; `--recipe` replays it.
//!
//! `<stem>` is the CSV path without its `.csv` extension. Everything is
//! written to temporary files first and renamed into place at the end, so a
//! failed command leaves the previous files as they were.

use crate::error::path_error;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use survey_processing::corrector;
use survey_processing::pipeline::{CompTable, Processed};
use survey_processing::recipe::ExportChoices;
use survey_processing::table::CorrectionTable;

/// The paths of every file written.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct OutputPaths {
    /// The table CSV.
    pub table_csv: PathBuf,
    /// LinuxCNC `COMP_FILE_TYPE = 0` file.
    pub linuxcnc_type0: Option<PathBuf>,
    /// LinuxCNC `COMP_FILE_TYPE = 1` file.
    pub linuxcnc_type1: Option<PathBuf>,
    /// The binary table.
    pub binary: Option<PathBuf>,
    /// The recipe used.
    pub recipe: PathBuf,
}

impl OutputPaths {
    /// The files beside `table_csv` that `export` asks for.
    pub fn beside(table_csv: &Path, export: &ExportChoices) -> Self {
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
            binary: export.binary.then(|| with(".bin")),
            recipe: with(".recipe.toml"),
        }
    }
}

/// The contract's table CSV.
pub fn table_csv(table: &CorrectionTable) -> String {
    let mut s = String::with_capacity(table.len() * 48);
    match &table.reverse {
        None => {
            s.push_str("readout_deg,error_deg\n");
            for (i, e) in table.forward.iter().enumerate() {
                let _ = writeln!(s, "{},{e}", table.readout_at(i));
            }
        }
        Some(r) => {
            s.push_str("readout_deg,error_forward_deg,error_reverse_deg\n");
            for (i, (f, r)) in table.forward.iter().zip(r).enumerate() {
                let _ = writeln!(s, "{},{f},{r}", table.readout_at(i));
            }
        }
    }
    s
}

/// A LinuxCNC `COMP_FILE` of `COMP_FILE_TYPE` 0 (positions) or 1 (trims).
pub fn linuxcnc(comp: &CompTable, file_type: u8) -> String {
    let mut s = String::with_capacity(comp.nominal_deg.len() * 48);
    for ((n, f), r) in comp.nominal_deg.iter().zip(&comp.forward_deg).zip(&comp.reverse_deg) {
        let (a, b) = if file_type == 0 { (n - f, n - r) } else { (*f, *r) };
        let _ = writeln!(s, "{n:.10} {a:.10} {b:.10}");
    }
    s
}

/// A temporary file next to `path`, removed when dropped unless renamed.
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

fn stage(path: &Path, bytes: &[u8]) -> anyhow::Result<Staged> {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
    let tmp = path.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
    let staged = Staged { tmp, path: path.to_path_buf(), done: false };
    let mut file =
        std::fs::File::create(&staged.tmp).map_err(|e| path_error(e, format!("cannot create {}", path.display())))?;
    use std::io::Write as _;
    file.write_all(bytes)
        .and_then(|()| file.sync_all())
        .map_err(|e| anyhow::Error::new(e).context(format!("cannot write {}", path.display())))?;
    Ok(staged)
}

/// Write every file of `paths` from `processed` (see the module documentation).
pub fn write_all(paths: &OutputPaths, processed: &Processed, survey_id: i64) -> anyhow::Result<()> {
    let table = &processed.built.table;
    let mut outputs: Vec<(&Path, Vec<u8>)> = vec![(paths.table_csv.as_path(), table_csv(table).into_bytes())];
    if let (Some(comp), Some(p0), Some(p1)) = (&processed.comp, &paths.linuxcnc_type0, &paths.linuxcnc_type1) {
        outputs.push((p0, linuxcnc(comp, 0).into_bytes()));
        outputs.push((p1, linuxcnc(comp, 1).into_bytes()));
    }
    if let Some(p) = &paths.binary {
        outputs.push((p, corrector::to_bytes(table, processed.recipe.export.binary_format)));
    }
    let recipe = format!(
        "# Made by `survey process` from survey {survey_id}{}.\n{}",
        if processed.replayed { " by replaying a recipe" } else { "" },
        processed.recipe.to_toml()
    );
    outputs.push((paths.recipe.as_path(), recipe.into_bytes()));
    let staged = outputs.iter().map(|(p, b)| stage(p, b)).collect::<Result<Vec<_>, _>>()?;
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
        assert_eq!(p.recipe, Path::new("out/t.recipe.toml"));
        let none = ExportChoices { linuxcnc: false, binary: false, ..ExportChoices::default() };
        let q = OutputPaths::beside(Path::new("table"), &none);
        assert_eq!((q.linuxcnc_type0, q.binary, q.recipe), (None, None, PathBuf::from("table.recipe.toml")));
    }

    #[test]
    fn csv_and_linuxcnc_formats() {
        let t =
            CorrectionTable::directional(vec![0.001, 0.002, 0.003, 0.004], vec![-0.001, 0.0, 0.001, 0.002]).unwrap();
        assert_eq!(
            table_csv(&t),
            "readout_deg,error_forward_deg,error_reverse_deg\n0,0.001,-0.001\n90,0.002,0\n180,0.003,0.001\n270,0.004,0.002\n"
        );
        let one = CorrectionTable::new(vec![0.5, -0.25]).unwrap();
        assert_eq!(table_csv(&one), "readout_deg,error_deg\n0,0.5\n180,-0.25\n");
        let comp = CompTable {
            nominal_deg: vec![0.0, 180.0, 360.0],
            forward_deg: vec![0.001, 0.002, 0.001],
            reverse_deg: vec![-0.001, 0.0, -0.001],
            prediction: None,
        };
        assert_eq!(
            linuxcnc(&comp, 0),
            "0.0000000000 -0.0010000000 0.0010000000\n180.0000000000 179.9980000000 180.0000000000\n360.0000000000 359.9990000000 360.0010000000\n"
        );
        assert_eq!(linuxcnc(&comp, 1).lines().next(), Some("0.0000000000 0.0010000000 -0.0010000000"));
    }

    #[test]
    fn a_failed_write_leaves_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let err = stage(&dir.path().join("missing/t.csv"), b"x");
        assert_eq!(crate::error::exit_status(&err.err().unwrap()), 2);
        let ok = stage(&dir.path().join("t.csv"), b"x").unwrap();
        let tmp = ok.tmp.clone();
        assert!(tmp.exists());
        drop(ok);
        assert!(!tmp.exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}
