//! `survey model-gap --model FILE [--survey ID] [--out FILE] [--json]`: compare
//! a positioner model with a stored survey, name what the model lacks, add it,
//! and show the gap shrink (the work is [`survey_processing::modelgap`]).
//!
//! The survey's samples are read in acquisition order (their `seq`), so
//! drift has a time axis even for imported data without timestamps. A model
//! file that does not parse is bad input (exit 2, the file and line named); so
//! is a survey that cannot be compared (an incomplete error map). `--out` is
//! written only when the comparison succeeded, through a temporary file in the
//! same folder renamed over the target, so a failed command leaves no half
//! file. With a tracker reference, a once-per-revolution error found is also
//! what an error in locating the axis looks like: the report says how large
//! that error is expected to be, from the stored axis fit.

use super::support::{emit, load_survey};
use crate::error::{bad_input, path_error};
use crate::progress::{self, Progress};
use anyhow::Context as _;
use clap::Args;
use std::path::{Path, PathBuf};
use survey_processing::geometry::AxisFit;
use survey_processing::model::Model;
use survey_processing::modelgap::{ModelGap, ModelGapOptions};

#[derive(Debug, Args)]
pub struct ModelGapArgs {
    /// The positioner model file (TOML) to compare with the survey.
    #[arg(long, value_name = "FILE")]
    pub model: PathBuf,
    /// Survey id (default: the latest).
    #[arg(long, value_name = "ID")]
    pub survey: Option<i64>,
    /// Write the improved model file (the model with the effects added and adjusted) here.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

pub async fn model_gap(db: &Path, args: ModelGapArgs) -> anyhow::Result<()> {
    let model = Model::from_file(&args.model)?;
    let progress = Progress::spinner("loading the survey", progress::visible(args.json));
    // Samples come in acquisition order (by seq): drift has a time axis even without timestamps.
    let (survey, samples) = load_survey(db, args.survey).await?;
    progress.stage(format!("comparing survey {} ({} samples) with {}", survey.id, samples.len(), args.model.display()));
    let mut gap =
        survey_processing::modelgap::model_gap(&samples, &model, &ModelGapOptions::default()).map_err(|e| {
            bad_input(format!("survey {} cannot be compared with the model {}: {e}", survey.id, args.model.display()))
        })?;
    drop(progress);
    if let Some(axis) = &survey.axis {
        tracker_note(&mut gap, axis);
    }
    if let Some(out) = &args.out {
        write_model(out, &gap, &args.model, survey.id)?;
        eprintln!("wrote the improved model to {}", out.display());
    }
    if args.json {
        let mut doc = serde_json::to_value(&gap).context("the model-gap document does not serialise")?;
        if let Some(o) = doc.as_object_mut() {
            o.insert("survey_id".into(), survey.id.into());
            o.insert("model".into(), args.model.display().to_string().into());
            o.insert("model_out".into(), args.out.as_ref().map(|p| p.display().to_string()).into());
        }
        emit(&format!("{doc}\n"));
    } else {
        let mut text = format!("survey {}, model {}\n", survey.id, args.model.display());
        text += &gap.to_text();
        if let Some(out) = &args.out {
            text += &format!("improved model written to {}\n", out.display());
        }
        emit(&text);
    }
    Ok(())
}

/// With a tracker, an eccentricity found may be the axis fit's error.
fn tracker_note(gap: &mut ModelGap, axis: &AxisFit) {
    let found = gap.effects_added.iter().any(|e| e.kind == "eccentricity")
        || gap.effects_adjusted.iter().any(|e| e.kind == "eccentricity");
    if !found {
        return;
    }
    if axis.points == 0 || axis.radius_mm <= 0.0 {
        return;
    }
    // The centre of a circle fitted to m points with in-plane scatter s is
    // known to about s sqrt(2 / m) per axis; off-centre by d, the angles are
    // off by d / radius once per revolution.
    let expected = (axis.circle_rms_mm * (2.0 / axis.points as f64).sqrt() / axis.radius_mm).to_degrees();
    gap.notes.push(format!(
        "the reference is a tracker whose axis was located from {} SMR positions (circle fit RMS {:.4} mm on a \
         {:.1} mm radius): an error in that location also reads as a once-per-revolution error, of about {expected:.1e} \
         deg here; an eccentricity not much larger than that may be the reference's, not the positioner's (locate the \
         axis from more points to tell them apart)",
        axis.points, axis.circle_rms_mm, axis.radius_mm
    ));
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
