//! `survey check --config FILE`: connect to every configured instrument and
//! say plainly what is wrong.

use super::support::emit;
use crate::config::SurveyConfig;
use clap::Args;
use std::path::PathBuf;
use survey_drivers::SystemClock;

#[derive(Debug, Args)]
pub struct CheckArgs {
    /// The configuration file whose instruments to check.
    #[arg(long, value_name = "FILE")]
    pub config: PathBuf,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

pub async fn check(args: CheckArgs) -> anyhow::Result<()> {
    let cfg = SurveyConfig::from_file(&args.config)?;
    let clock = SystemClock::new();
    // An instrument that does not answer takes its timeout: say what is being waited for.
    let progress = crate::progress::Progress::spinner(
        format!("connecting to the instruments of {}", args.config.display()),
        crate::progress::visible(args.json),
    );
    let lines = crate::bench::instruments::check(&cfg, &clock).await;
    drop(progress);
    let failed = lines.iter().filter(|l| !l.ok).count();
    if args.json {
        let doc = serde_json::json!({ "ok": failed == 0, "instruments": lines });
        emit(&format!("{doc}\n"));
    } else {
        let mut text = String::new();
        for l in &lines {
            text += &format!("{:<15} {:<28} {:<20} {}\n", l.instrument, l.address, l.verdict, l.detail);
        }
        emit(&text);
    }
    if failed > 0 {
        return Err(anyhow::anyhow!(
            "{failed} of {} instruments failed the check: fix them before starting a survey",
            lines.len()
        ));
    }
    Ok(())
}
