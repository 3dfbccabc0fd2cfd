//! `survey sim --config FILE [--preset NAME | --model FILE] [--seed S]
//! [--faults RATE] [--fault-rates SPEC] [--time-scale X]`: serve the simulated instruments of a
//! configuration over their real protocols (see [`survey_bench::sim`]), print one
//! JSON line `{"ready": true, "instruments": {...}, "config": PATH}` on stdout
//! when every instrument listens (`config`: the configuration to run against,
//! with the addresses served; with `"drift_run_s"` when the model drifts: the
//! simulator's run length), serve until SIGINT or SIGTERM, then print what was
//! served (`{"stopped": true, "faults": {"replies", "injected", "by_kind",
//! ...}}`) and exit 0.

use super::args::whole;
use super::support::emit;
use clap::Args;
use std::path::PathBuf;
use survey_acquire::stop::Stop;
use survey_bench::inputs::read_model;
use survey_bench::sim::{SimOptions, serve};
use survey_lab::error::bad_input;
use survey_sims::faults::FaultRates;
use survey_store::config::SurveyConfig;

#[derive(Debug, Args)]
pub struct SimArgs {
    /// The configuration file whose instruments to serve (on this machine: see the ready line's "config").
    #[arg(long, value_name = "FILE", value_hint = clap::ValueHint::FilePath)]
    pub config: PathBuf,
    /// Simulated positioner: one of the paper's positioners.
    #[arg(long, value_name = "NAME", default_value = "fig8", value_parser = ["fig1", "fig4", "fig8"])]
    pub preset: String,
    /// Positioner model file (TOML), instead of the preset's model.
    #[arg(long, value_name = "FILE", value_hint = clap::ValueHint::FilePath)]
    pub model: Option<PathBuf>,
    /// Seed of every random draw.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true, value_parser = whole::<0, u64>)]
    pub seed: u64,
    /// Fraction of replies, moves and measurements that meet a fault (0 to
    /// 0.5): RATE/4 for each link kind, RATE for each device kind.
    #[arg(long, value_name = "RATE", default_value_t = 0.0, allow_negative_numbers = true)]
    pub faults: f64,
    /// Rates per kind over those of --faults: `kind=rate,...` with kinds
    /// timeout, garbled, disconnect, stall, device, move, beam, and
    /// beam_hold_s=S (how long a broken beam stays broken).
    #[arg(long, value_name = "SPEC")]
    pub fault_rates: Option<String>,
    /// Run the instruments this many times faster than the hardware.
    #[arg(long, value_name = "X", default_value_t = 1.0, allow_negative_numbers = true)]
    pub time_scale: f64,
}

pub async fn sim(args: SimArgs) -> anyhow::Result<()> {
    let cfg = SurveyConfig::from_file(&args.config)?;
    let model = args.model.as_deref().map(read_model).transpose()?;
    if !(0.0..=0.5).contains(&args.faults) {
        return Err(bad_input(format!(
            "--faults is a fraction of requests from 0 to 0.5, got {}",
            survey_processing::num::Num(args.faults)
        )));
    }
    let faults = FaultRates::uniform(args.faults)
        .parse_over(args.fault_rates.as_deref().unwrap_or(""))
        .map_err(|e| bad_input(format!("--fault-rates: {e}")))?;
    let opts =
        SimOptions { preset: args.preset, model, seed: args.seed, faults, time_scale: args.time_scale, only: None };
    let mut stop = Stop::on_signals();
    let served = serve(&cfg, &opts).await?;
    let text = std::fs::read_to_string(&args.config)
        .map_err(|e| survey_lab::error::path_error(e, format!("cannot read {}", args.config.display())))?;
    let config = served.stand_ins.write_config(&text, &args.config)?;
    let mut ready =
        serde_json::json!({"ready": true, "instruments": served.instruments, "config": config.display().to_string()});
    if let Some(run_s) = served.drift_run_s {
        // The model drifts: its rate per run is per this much simulator time.
        ready["drift_run_s"] = run_s.into();
    }
    emit(&format!("{ready}\n"));
    for moved in &served.stand_ins.moved {
        survey_bench::say!("survey sim: {moved}");
    }
    if opts.time_scale != 1.0 {
        survey_bench::say!(
            "survey sim: at {}x real time a step scan works; a continuous scan needs the instruments in real time \
             and is refused",
            opts.time_scale
        );
    }
    survey_bench::say!(
        "survey sim: serving {} ({}x real time, faults injected: {}); stop with Ctrl-C or SIGTERM\n\
         survey sim: run against it: survey run --config {}",
        args.config.display(),
        opts.time_scale,
        survey_bench::output::fault_rates(&opts.faults),
        config.display()
    );
    let why = stop.wait().await;
    let summary = serde_json::json!({"stopped": true, "signal": why.0, "faults": served.counts_json()});
    drop(served);
    emit(&format!("{summary}\n"));
    Ok(())
}
