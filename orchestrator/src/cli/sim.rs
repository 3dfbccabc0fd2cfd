//! `survey sim --config FILE [--preset NAME | --model FILE] [--seed S]
//! [--faults RATE] [--time-scale X]`: serve the simulated instruments of a
//! configuration over their real protocols (see [`crate::sim`]), print one
//! JSON line `{"ready": true, "instruments": {...}}` on stdout when every
//! instrument listens, serve until SIGINT or SIGTERM, then print what was
//! served (`{"stopped": true, "faults": {...}}`) and exit 0.

use super::support::emit;
use crate::config::SurveyConfig;
use crate::sim::{SimOptions, serve};
use crate::stop::Stop;
use clap::Args;
use std::path::PathBuf;
use survey_processing::model::Model;

#[derive(Debug, Args)]
pub struct SimArgs {
    /// The configuration file whose instruments to serve (TCP addresses on loopback).
    #[arg(long, value_name = "FILE")]
    pub config: PathBuf,
    /// Simulated positioner: one of the paper's positioners.
    #[arg(long, value_name = "NAME", default_value = "fig8", value_parser = ["fig1", "fig4", "fig8"])]
    pub preset: String,
    /// Positioner model file (TOML), instead of the preset's model.
    #[arg(long, value_name = "FILE")]
    pub model: Option<PathBuf>,
    /// Seed of every random draw.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Fraction of replies, moves and measurements that meet a fault (0 to 0.5).
    #[arg(long, value_name = "RATE", default_value_t = 0.0)]
    pub faults: f64,
    /// Run the instruments this many times faster than the hardware.
    #[arg(long, value_name = "X", default_value_t = 1.0)]
    pub time_scale: f64,
}

pub async fn sim(args: SimArgs) -> anyhow::Result<()> {
    let cfg = SurveyConfig::from_file(&args.config)?;
    let model = args.model.as_deref().map(Model::from_file).transpose()?;
    let opts =
        SimOptions { preset: args.preset, model, seed: args.seed, faults: args.faults, time_scale: args.time_scale };
    let mut stop = Stop::on_signals();
    let served = serve(&cfg, &opts).await?;
    let ready = serde_json::json!({"ready": true, "instruments": served.instruments});
    emit(&format!("{ready}\n"));
    eprintln!(
        "survey sim: serving {} ({}x real time, faults {}); stop with Ctrl-C or SIGTERM",
        args.config.display(),
        opts.time_scale,
        opts.faults
    );
    let why = stop.wait().await;
    let summary = serde_json::json!({"stopped": true, "signal": why.0, "faults": served.counts.json()});
    drop(served);
    emit(&format!("{summary}\n"));
    Ok(())
}
