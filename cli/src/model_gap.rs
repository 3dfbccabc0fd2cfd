//! `survey model-gap --model FILE [--survey ID] [--out FILE] [--json]`: compare
//! a positioner model with a stored survey, name what the model lacks, add it,
//! and show the gap shrink (the work is [`survey_modelgap`]).
//!
//! The survey's samples are read in acquisition order (their `seq`), so
//! drift has a time axis even for imported data without timestamps. A model
//! file that does not parse is bad input (exit 2, the file and line named); so
//! is a survey that cannot be compared (an incomplete error map). `--out` is
//! written only when the comparison succeeded, through a temporary file in the
//! same folder renamed over the target, so a failed command leaves no half
//! file.
//!
//! With a tracker reference, the survey compared is the one `survey process`
//! processes: its actual angles recomputed around the axis fitted again from
//! every SMR position ([`survey_lab::refit`]); `--located-axis` compares the angles
//! as stored, around the axis located before the runs. Model-gap is told the
//! reference and how well its axis is known, so what of the gap is the axis
//! location is named as the reference's, with its size.

use super::args::UnitsArg;
use super::support::emit;
use crate::progress::{self, Progress};
use anyhow::Context as _;
use clap::Args;
use std::path::{Path, PathBuf};
use survey_bench::inputs::read_model;
use survey_lab::error::path_error;
use survey_lab::load::{Axis, load_read_only};
use survey_modelgap::{ModelGap, ModelGapOptions};

#[derive(Debug, Args)]
pub struct ModelGapArgs {
    /// The positioner model file (TOML) to compare with the survey.
    #[arg(long, value_name = "FILE", value_hint = clap::ValueHint::FilePath)]
    pub model: PathBuf,
    /// Survey id or uid (default: the latest).
    #[arg(long, value_name = "ID", allow_negative_numbers = true)]
    pub survey: Option<survey_store::survey::SurveyRef>,
    /// Write the improved model file (the model with the effects added and adjusted) here.
    #[arg(long, value_name = "FILE", value_hint = clap::ValueHint::FilePath)]
    pub out: Option<PathBuf>,
    /// Compare the actual angles as stored, around the axis located before
    /// the runs, instead of around the axis fitted again from every SMR
    /// position (tracker surveys).
    #[arg(long)]
    pub located_axis: bool,
    #[command(flatten)]
    pub units: UnitsArg,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

pub async fn model_gap(db: &Path, args: ModelGapArgs) -> anyhow::Result<()> {
    let model = read_model(&args.model)?;
    let progress = Progress::spinner("loading the survey", progress::visible(args.json));
    // Samples come in acquisition order (by seq): drift has a time axis even without timestamps.
    let axis = if args.located_axis { Axis::Located } else { Axis::Refitted };
    let loaded = load_read_only(db, args.survey, axis).await?;
    let (survey, refit) = (&loaded.survey, &loaded.refit);
    let options = ModelGapOptions { reference: loaded.reference_info(), ..ModelGapOptions::default() };
    let compared = &loaded.samples;
    progress.stage(format!(
        "comparing survey {} ({} samples) with {}",
        survey.id,
        compared.len(),
        args.model.display()
    ));
    let gap = survey_modelgap::model_gap(compared, &model, &options)
        .with_context(|| format!("survey {} cannot be compared with the model {}", survey.id, args.model.display()))?;
    drop(progress);
    if let Some(out) = &args.out {
        write_model(out, &gap, &args.model, survey.id)?;
        survey_bench::say!("wrote the improved model to {}", out.display());
    }
    if args.json {
        let mut doc = serde_json::to_value(&gap).context("the model-gap document does not serialise")?;
        if let Some(o) = doc.as_object_mut() {
            o.insert("survey_id".into(), survey.id.into());
            o.insert("axis_refit".into(), serde_json::to_value(refit)?);
            o.insert("model".into(), args.model.display().to_string().into());
            o.insert("model_out".into(), args.out.as_ref().map(|p| p.display().to_string()).into());
        }
        emit(&format!("{doc}\n"));
    } else {
        let units = args.units.units();
        let mut text = format!("survey {}, model {}\n", survey.id, args.model.display());
        if let Some(r) = refit {
            text += &units.text(&r.text());
        }
        text += &gap.to_text_in(units);
        if let Some(out) = &args.out {
            text += &format!("improved model written to {}\n", out.display());
        }
        emit(&text);
    }
    Ok(())
}

/// Write the improved model: a header comment and the model file, through a
/// temporary file renamed over `out`.
fn write_model(out: &Path, gap: &ModelGap, given: &Path, survey_id: i64) -> anyhow::Result<()> {
    let mut text = format!(
        "# Improved by `survey model-gap` from {} on survey {survey_id}: {} effect(s) added, {} adjusted;\n\
         # residual RMS {:.3e} -> {:.3e} deg, noise floor {:.3e} deg.\n",
        given.display(),
        gap.effects_added.len(),
        gap.effects_adjusted.len(),
        gap.rms_before_deg,
        gap.rms_after_deg,
        gap.noise_floor_deg
    );
    for e in &gap.effects_added {
        text += &format!(
            "# added {} {}: {}\n",
            e.kind,
            if e.cycles_per_rev > 0.0 { format!("{}", e.cycles_per_rev) } else { String::new() },
            e.explanation
        );
    }
    text += &gap.model.to_toml();
    let name = out.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "model".into());
    let tmp = out.with_file_name(format!(".{name}.{}.tmp", std::process::id()));
    std::fs::write(&tmp, &text).map_err(|e| path_error(e, format!("cannot write {}", out.display())))?;
    std::fs::rename(&tmp, out).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        path_error(e, format!("cannot write {}", out.display()))
    })
}
