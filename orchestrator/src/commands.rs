//! What each command does, between the parsed arguments and the library.

use crate::cli::{Cli, Command, ExportArgs, Failure, ImportArgs, StatsArgs};
use crate::csvio::{read_survey_csv, write_survey_csv};
use crate::store::{NewSurvey, Store, SurveyStatus};
use anyhow::Context as _;
use survey_processing::Sample;
use survey_processing::iso230::{Iso230, iso230_2};

pub async fn dispatch(cli: Cli) -> Result<(), Failure> {
    match cli.command {
        Command::Run(args) => crate::run::run(&cli.db, args).await,
        Command::Check(args) => crate::run::check(args).await,
        Command::Resume(args) => crate::run::resume(&cli.db, args).await,
        Command::Report(args) => crate::report::command(&cli.db, args).await,
        Command::Import(args) => import(&cli.db, args).await,
        Command::Export(args) => export(&cli.db, args).await,
        Command::Stats(args) => stats(&cli.db, args).await,
        Command::ModelGap(args) => crate::modelgap::command(&cli.db, args).await,
        Command::Process(args) => crate::process::command(&cli.db, args).await,
    }
}

/// Open an existing database for a read command: a missing file is bad usage.
pub async fn open_existing(db: &std::path::Path) -> Result<Store, Failure> {
    Store::open_existing(db).await.map_err(classify)
}

/// Store errors that name something the user gave (a missing database or
/// survey id) are usage errors; the rest are run-time failures.
pub fn classify(e: anyhow::Error) -> Failure {
    if e.downcast_ref::<crate::store::NotFound>().is_some() { Failure::Usage(e) } else { Failure::Runtime(e) }
}

async fn import(db: &std::path::Path, args: ImportArgs) -> Result<(), Failure> {
    let name = args.file.display().to_string();
    let samples = read_survey_csv(&args.file).map_err(Failure::usage)?;
    let runs = samples.iter().map(|s| s.run).max().unwrap_or(0);
    let bidirectional = samples.iter().any(|s| s.direction == survey_processing::Direction::Reverse);
    let targets = distinct_targets(&samples);
    let store = Store::open(db).await.map_err(classify)?;
    let survey = NewSurvey {
        status: SurveyStatus::Imported,
        source: format!("import:{name}"),
        points: Some(targets as u32),
        runs: Some(runs),
        bidirectional,
        config_json: serde_json::json!({ "imported_from": name }).to_string(),
        model_toml: None,
        instruments_json: "{}".into(),
        planned_samples: Some(samples.len() as u64),
    };
    let id = store.import(&survey, &samples).await.map_err(Failure::runtime)?;
    store.close().await;
    crate::cli::emit(&format!("{id}\n"));
    if let Err(e) = iso230_2(&samples) {
        eprintln!("note: survey {id} cannot give ISO 230-2 statistics yet: {e}");
    }
    eprintln!(
        "imported {} samples ({targets} targets, {runs} runs) from {name} as survey {id} in {}",
        samples.len(),
        db.display()
    );
    Ok(())
}

fn distinct_targets(samples: &[Sample]) -> usize {
    let mut t: Vec<f64> = samples.iter().map(|s| s.target_deg).collect();
    t.sort_by(f64::total_cmp);
    t.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    t.len()
}

async fn export(db: &std::path::Path, args: ExportArgs) -> Result<(), Failure> {
    let store = open_existing(db).await?;
    let survey = store.resolve(args.survey).await.map_err(classify)?;
    let samples: Vec<Sample> =
        store.samples(survey.id).await.map_err(Failure::runtime)?.into_iter().map(|r| r.sample).collect();
    store.close().await;
    let out = std::fs::File::create(&args.csv)
        .with_context(|| format!("cannot create {}", args.csv.display()))
        .map_err(Failure::usage)?;
    write_survey_csv(std::io::BufWriter::new(out), &samples)
        .with_context(|| format!("cannot write {}", args.csv.display()))
        .map_err(Failure::runtime)?;
    eprintln!("wrote {} samples of survey {} to {}", samples.len(), survey.id, args.csv.display());
    Ok(())
}

async fn stats(db: &std::path::Path, args: StatsArgs) -> Result<(), Failure> {
    let store = open_existing(db).await?;
    let survey = store.resolve(args.survey).await.map_err(classify)?;
    let samples: Vec<Sample> =
        store.samples(survey.id).await.map_err(Failure::runtime)?.into_iter().map(|r| r.sample).collect();
    store.close().await;
    let iso = iso230_2(&samples)
        .with_context(|| format!("survey {} cannot give ISO 230-2 statistics", survey.id))
        .map_err(Failure::usage)?;
    if args.json {
        crate::cli::emit(&format!("{}\n", stats_json(survey.id, &iso)));
    } else {
        crate::cli::emit(&stats_text(survey.id, &iso));
    }
    Ok(())
}

/// The `stats --json` document: the contract's keys, plus per-target figures.
pub fn stats_json(survey_id: i64, iso: &Iso230) -> serde_json::Value {
    let mut figures = serde_json::to_value(iso).expect("statistics serialise");
    let targets = figures.as_object_mut().and_then(|o| o.remove("targets")).unwrap_or_default();
    serde_json::json!({ "survey_id": survey_id, "iso230_2": figures, "targets": targets })
}

fn fmt_opt(v: Option<f64>) -> String {
    v.map(|x| format!("{x:>10.6}")).unwrap_or_else(|| format!("{:>10}", "-"))
}

/// The ISO 230-2 figures as a small table, degrees.
pub fn stats_text(survey_id: i64, iso: &Iso230) -> String {
    let bidirectional = iso.b.is_some();
    let mut s = format!(
        "survey {survey_id}: ISO 230-2, {} targets x {} runs, {} (degrees)\n",
        iso.targets.len(),
        iso.runs,
        if bidirectional { "bidirectional" } else { "unidirectional" }
    );
    s += &format!("  {:<28}{:>10} {:>10} {:>10}\n", "", "axis", "forward", "reverse");
    let rows = [
        ("A  accuracy", Some(iso.a), iso.a_up, iso.a_down),
        ("R  repeatability", Some(iso.r), iso.r_up, iso.r_down),
        ("E  systematic deviation", Some(iso.e), iso.e_up, iso.e_down),
    ];
    for (name, all, up, down) in rows {
        s += &format!("  {name:<28}{} {} {}\n", fmt_opt(all), fmt_opt(up), fmt_opt(down));
    }
    if bidirectional {
        s += &format!("  {:<28}{}\n", "B  reversal value", fmt_opt(iso.b));
        s += &format!("  {:<28}{}\n", "B  mean reversal", fmt_opt(iso.b_mean));
        s += &format!("  {:<28}{}\n", "M  mean bidirectional dev.", fmt_opt(iso.m));
    }
    s
}
