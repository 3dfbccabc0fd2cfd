//! What several commands' arguments share: `--units`, and how a whole
//! number is parsed.

use clap::{Args, ValueEnum};
use std::path::PathBuf;
use survey_bench::output::Units;

/// The environment variable naming the survey database when `--db` is not given.
pub const DB_ENV: &str = "SURVEY_DB";

/// `--db`, on every command that reads or writes the survey database (and
/// on `survey` itself, before the command, as `survey --db FILE list`); the
/// commands that never open it (`check`, `sim`, `completions`, `man`) do not
/// offer it.
#[derive(Debug, Clone, Default, Args)]
pub struct DbArg {
    /// The SQLite database that holds the surveys, or a lab store's postgres:// URL (read commands) [default: survey.db; env: SURVEY_DB].
    #[arg(long = "db", value_name = "PATH|URL", value_hint = clap::ValueHint::FilePath)]
    db: Option<PathBuf>,
}

impl DbArg {
    /// The database: this command's `--db`, else `survey --db`, else
    /// `SURVEY_DB` (when set and not empty), else `survey.db`.
    pub fn or(self, top: Option<PathBuf>) -> PathBuf {
        self.db
            .or(top)
            .or_else(|| std::env::var_os(DB_ENV).filter(|v| !v.is_empty()).map(PathBuf::from))
            .unwrap_or_else(|| PathBuf::from(survey_lab::process::DEFAULT_DB))
    }
}

/// `--units deg|arcsec|urad`, the same on every command that prints an
/// error: flatten it into the command's arguments (`#[command(flatten)]`)
/// and print through [`UnitsArg::units`]. `SURVEY_UNITS` sets a default;
/// `--json` documents stay in degrees (the contract's unit).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Args)]
pub struct UnitsArg {
    /// The unit of the errors printed: degrees, arcseconds or microradians (angles along the axis stay in degrees; --json is always degrees).
    #[arg(long = "units", value_enum, value_name = "UNIT", default_value_t = UnitChoice::Deg, env = "SURVEY_UNITS", hide_env_values = true)]
    choice: UnitChoice,
}

/// The units `--units` offers (no doc comment on each: the help lists them on one line).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum UnitChoice {
    Deg,
    Arcsec,
    Urad,
}

impl UnitsArg {
    /// The unit chosen.
    pub fn units(self) -> Units {
        match self.choice {
            UnitChoice::Deg => Units::Deg,
            UnitChoice::Arcsec => Units::Arcsec,
            UnitChoice::Urad => Units::Urad,
        }
    }
}

/// A whole number of at least `MIN` (`--points`, `--runs`, `--seed`, ...).
/// With the flag's `allow_negative_numbers`, a negative number reaches this
/// check and gets the range, as every other bad value does, instead of
/// clap's "unexpected argument '-5' found"; clap names the flag.
pub fn whole<const MIN: i128, T: TryFrom<i128>>(s: &str) -> Result<T, String> {
    match s.trim().parse::<i128>() {
        Ok(n) if n < MIN => Err(format!("must be at least {MIN}, got {n}")),
        Ok(n) => T::try_from(n).map_err(|_| format!("{n} is too large")),
        Err(_) => Err(format!("must be a whole number of at least {MIN}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_whole_number_below_its_range_gets_the_range() {
        assert_eq!(whole::<2, u32>("36"), Ok(36));
        assert_eq!(whole::<2, u32>("-5"), Err("must be at least 2, got -5".to_string()));
        assert_eq!(whole::<2, u32>("1"), Err("must be at least 2, got 1".to_string()));
        assert_eq!(whole::<2, u32>("5000000000"), Err("5000000000 is too large".to_string()));
        assert_eq!(whole::<0, u64>("abc"), Err("must be a whole number of at least 0".to_string()));
        assert_eq!(whole::<0, u64>("18446744073709551615"), Ok(u64::MAX));
    }
}
