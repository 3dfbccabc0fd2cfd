//! The export choices given on the command line, laid over the recipe's
//! `[export]` (replayed or default), and the flag that names each recipe key
//! in an error. The recipe written beside the table holds the result, so a
//! recalibration replaying it writes the same controller files.

use survey_controllers::export::Controller;
use survey_controllers::generic::{Sign, Values};
use survey_controllers::layout::Directions;
use survey_tables::recipe::{ChoiceError, ExportChoices, Recipe};

/// Every export choice the command line can make; `None` keeps the recipe's.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ExportOverrides {
    /// Exactly these controllers.
    pub controllers: Option<Vec<Controller>>,
    /// `export.start_deg`.
    pub start_deg: Option<f64>,
    /// `export.end_deg`.
    pub end_deg: Option<f64>,
    /// `export.interval_deg` (clears `points`).
    pub interval_deg: Option<f64>,
    /// `export.points` (clears `interval_deg`).
    pub points: Option<usize>,
    /// `export.directions`.
    pub directions: Option<Directions>,
    /// `export.reference_deg`.
    pub reference_deg: Option<f64>,
    /// `export.zero_at_reference` (set when true).
    pub zero_at_reference: bool,
    /// `export.sinumerik_absolute` (set when true).
    pub sinumerik_absolute: bool,
    /// `export.sign`.
    pub sign: Option<Sign>,
    /// `export.values`.
    pub values: Option<Values>,
    /// `export.sinumerik_axis`.
    pub sinumerik_axis: Option<String>,
    /// `export.fanuc_unit_deg`.
    pub fanuc_unit_deg: Option<f64>,
    /// `export.fanuc_magnification`.
    pub fanuc_magnification: Option<u32>,
    /// `export.fanuc_reference_number`.
    pub fanuc_reference_number: Option<u32>,
}

impl ExportOverrides {
    /// Whether nothing is overridden.
    pub fn is_empty(&self) -> bool {
        *self == Self::default()
    }

    /// `base` with these choices laid over it.
    pub fn apply(&self, base: &ExportChoices) -> ExportChoices {
        let mut x = base.clone();
        if let Some(list) = &self.controllers {
            x.linuxcnc = list.contains(&Controller::LinuxCnc);
            x.sinumerik_840d = list.contains(&Controller::Sinumerik840d);
            x.fanuc = list.contains(&Controller::Fanuc);
            x.generic = list.contains(&Controller::Generic);
        }
        macro_rules! set {
            ($($f:ident),*) => {$( if let Some(v) = &self.$f { x.$f = Some(v.clone()); } )*};
        }
        set!(start_deg, end_deg, reference_deg, fanuc_reference_number);
        if let Some(d) = self.interval_deg {
            x.interval_deg = Some(d);
            x.points = None;
        }
        if let Some(p) = self.points {
            x.points = Some(p);
            x.interval_deg = None;
        }
        if let Some(d) = self.directions {
            x.directions = d;
        }
        x.zero_at_reference |= self.zero_at_reference;
        x.sinumerik_absolute |= self.sinumerik_absolute;
        if let Some(s) = self.sign {
            x.sign = s;
        }
        if let Some(v) = self.values {
            x.values = v;
        }
        if let Some(a) = &self.sinumerik_axis {
            x.sinumerik_axis = a.clone();
        }
        if let Some(u) = self.fanuc_unit_deg {
            x.fanuc_unit_deg = u;
        }
        if let Some(m) = self.fanuc_magnification {
            x.fanuc_magnification = m;
        }
        x
    }

    /// `base` with these choices, checked as a recipe's would be; a bad value
    /// is bad input naming its flag.
    pub fn resolve(&self, base: &ExportChoices) -> anyhow::Result<ExportChoices> {
        let x = self.apply(base);
        let probe = Recipe { export: x.clone(), ..Recipe::default() };
        probe.validate().map_err(|e| choice_error(&e))?;
        Ok(x)
    }
}

/// The command-line flag of an `[export]` key (`export.interval_deg` ->
/// `--table-interval`), when it has one.
pub fn flag_of(key: &str) -> Option<&'static str> {
    Some(match key.strip_prefix("export.")? {
        "start_deg" => "--table-start",
        "end_deg" => "--table-end",
        "interval_deg" => "--table-interval",
        "points" => "--table-points",
        "directions" => "--table-directions",
        "reference_deg" => "--table-reference",
        "zero_at_reference" => "--table-zero-at-reference",
        "sinumerik_absolute" => "--sinumerik-absolute",
        "sign" => "--table-sign",
        "values" => "--table-values",
        "sinumerik_axis" => "--sinumerik-axis",
        "fanuc_unit_deg" => "--fanuc-unit",
        "fanuc_magnification" => "--fanuc-magnification",
        "fanuc_reference_number" => "--fanuc-reference-number",
        _ => return None,
    })
}

/// An export choice of the command line that cannot be honoured: the flag
/// and the recipe key it sets.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{flag} ({}): {}", choice.key, choice.message)]
pub struct FlagError {
    /// The flag (`--table-points`).
    pub flag: &'static str,
    /// What is wrong with the choice it made.
    pub choice: ChoiceError,
}

/// A choice that cannot be honoured, naming the flag that made it (else the
/// recipe key).
pub fn choice_error(e: &ChoiceError) -> anyhow::Error {
    match flag_of(&e.key) {
        Some(flag) => FlagError { flag, choice: e.clone() }.into(),
        None => e.clone().into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_lay_over_the_recipe_and_name_their_flag() {
        let base = ExportChoices { points: Some(100), ..ExportChoices::default() };
        let o = ExportOverrides {
            controllers: Some(vec![Controller::Fanuc]),
            interval_deg: Some(2.0),
            ..ExportOverrides::default()
        };
        let x = o.resolve(&base).unwrap();
        assert_eq!((x.linuxcnc, x.sinumerik_840d, x.fanuc, x.generic), (false, false, true, false));
        assert_eq!((x.interval_deg, x.points), (Some(2.0), None));
        let bad = ExportOverrides { interval_deg: Some(-1.0), ..ExportOverrides::default() };
        let e = bad.resolve(&base).unwrap_err();
        assert_eq!(crate::error::exit_status(&e), 2);
        assert!(e.to_string().starts_with("--table-interval (export.interval_deg): must be a positive"), "{e}");
        assert!(ExportOverrides::default().is_empty());
    }
}
