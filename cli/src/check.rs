//! `survey check --config FILE`: connect to every configured instrument and
//! say plainly what is wrong.

use super::support::emit;
use clap::Args;
use std::path::PathBuf;
use survey_drivers::SystemClock;
use survey_store::config::SurveyConfig;

#[derive(Debug, Args)]
pub struct CheckArgs {
    /// The configuration file whose instruments to check.
    #[arg(long, value_name = "FILE", value_hint = clap::ValueHint::FilePath)]
    pub config: PathBuf,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

pub async fn check(args: CheckArgs) -> anyhow::Result<()> {
    let cfg = SurveyConfig::from_file_to_open(&args.config)?;
    let clock = SystemClock::new();
    // An instrument that does not answer takes its timeout: say what is being waited for.
    let progress = crate::progress::Progress::spinner(
        format!("connecting to the instruments of {}", args.config.display()),
        crate::progress::visible(args.json),
    );
    let lines = survey_bench::instruments::check(&cfg, &clock).await;
    drop(progress);
    let failed = lines.iter().filter(|l| !l.ok).count();
    // What a continuous scan would be on these instruments (from the
    // configuration: it does not change whether the check passes), once
    // they answer.
    // What the configuration allows is not a scan the instruments were seen to make.
    let continuous = match (survey_bench::instruments::continuous_support(&cfg), failed) {
        (Ok(how), 0) => Ok(how),
        (Ok(how), _) => {
            Err((None, format!("not known: the instruments did not all answer (the configuration allows it: {how})")))
        }
        (Err(why), _) => Err((Some(false), why)),
    };
    if args.json {
        let doc = serde_json::json!({
            "ok": failed == 0,
            "instruments": lines,
            "continuous_scan": match &continuous {
                Ok(how) => serde_json::json!({"possible": true, "detail": how}),
                Err((possible, why)) => serde_json::json!({"possible": possible, "detail": why}),
            },
        });
        emit(&format!("{doc}\n"));
    } else {
        let mut text = String::new();
        for l in &lines {
            text += &format!("{:<15} {:<28} {:<20} {}\n", l.instrument, l.address, l.verdict, l.detail);
        }
        text += &match &continuous {
            Ok(how) => format!("continuous scan: possible ({how})\n"),
            Err((None, why)) => format!("continuous scan: {why}\n"),
            Err((_, why)) => format!("continuous scan: not possible: {why}\n"),
        };
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
