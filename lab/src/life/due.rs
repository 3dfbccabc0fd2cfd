//! What is due (`survey due`, `survey run --check --due`): each asset's
//! events read from the store ([`events`]: its complete surveys, dated by
//! their `created_at`, what each check decided, each survey's own travel,
//! the `[asset]` keys each was made with) and reviewed by
//! [`super::interval`] as of a time.

use super::interval::{self, Event, Outcome, Settings};
use serde_json::{Value, json};
use std::fmt::Write as _;
use std::time::{Duration, SystemTime, UNIX_EPOCH};
use survey_store::Store;
use survey_store::asset::UNASSIGNED;
use survey_store::survey::{Setup, SurveyRecord};

/// Seconds in a day.
const DAY_S: f64 = 86_400.0;

/// Days since 1970-01-01 UTC of a stored `created_at` (RFC 3339), when it parses.
pub fn days_of(created_at: &str) -> Option<f64> {
    let t = humantime::parse_rfc3339(created_at).ok()?;
    Some(t.duration_since(UNIX_EPOCH).ok()?.as_secs_f64() / DAY_S)
}

/// Days since 1970-01-01 UTC of `t`.
pub fn days_at(t: SystemTime) -> f64 {
    t.duration_since(UNIX_EPOCH).unwrap_or_default().as_secs_f64() / DAY_S
}

/// A date as the store writes one: `2026-03-01T14:02:11Z`.
pub fn date_of(days: f64) -> String {
    let t = UNIX_EPOCH + Duration::from_secs_f64((days * DAY_S).max(0.0).round());
    humantime::format_rfc3339_seconds(t).to_string()
}

/// A time given on the command line (`--at`): RFC 3339 UTC
/// (`2026-03-01T12:00:00Z`) or a date (`2026-03-01`: its midnight, UTC).
pub fn parse_at(text: &str) -> Result<SystemTime, String> {
    let full = if text.len() == 10 { format!("{text}T00:00:00Z") } else { text.to_string() };
    humantime::parse_rfc3339(&full)
        .map_err(|e| format!("'{text}' is not a UTC time ({e}): write 2026-03-01 or 2026-03-01T12:00:00Z"))
}

/// A survey's own travel, revolutions: its runs over its targets' span
/// (a full circle: one revolution), both ways when bidirectional.
pub fn travel(r: &SurveyRecord) -> f64 {
    let Some(plan) = r.plan() else { return 0.0 };
    let t = &plan.targets_deg;
    let n = t.len();
    // A full circle's targets are 360 / n apart from 0: one revolution a way.
    let full_circle = n >= 2 && t[0] == 0.0 && (t[1] * n as f64 - 360.0).abs() < 1e-9;
    let span = match (full_circle, n) {
        (true, _) => 1.0,
        (false, 2..) => (t[n - 1] - t[0]).abs() / 360.0,
        _ => 0.0,
    };
    span * f64::from(plan.runs) * if plan.bidirectional { 2.0 } else { 1.0 }
}

/// The `[asset]` interval keys a survey was made with (defaults unless
/// stated: a configuration's, or those a simulated bench was given).
fn settings(r: &SurveyRecord) -> Settings {
    match &r.setup {
        Setup::Configured(c) => Settings::of(c.config.asset.as_ref()),
        Setup::Simulated(s) => Settings::of(s.asset.as_ref()),
        _ => Settings::default(),
    }
}

/// The events of `asset`: its complete surveys, oldest first.
pub async fn events(store: &Store, asset: &str) -> anyhow::Result<Vec<Event>> {
    let records = store.surveys_of_asset_uncounted(asset).await?;
    let checks = store.checks_of_asset(asset).await?;
    let mut out = Vec::new();
    for r in records.iter().filter(|r| r.is_complete() && r.resolves.is_none()) {
        let Some(at_days) = days_of(&r.created_at) else { continue };
        let check = checks.iter().find(|c| c.survey_id == r.id);
        let outcome = match (super::kind(r), check) {
            ("calibration", _) => Outcome::Calibration,
            ("check", Some(c)) if c.recalibrate && c.reason.starts_with(super::control::OUT_OF_CONTROL) => {
                Outcome::OutOfControl
            }
            ("check", Some(c)) if c.recalibrate => Outcome::OutOfTolerance,
            ("check", Some(c)) if c.verdict == "changed" => Outcome::Changed,
            ("check", Some(_)) => Outcome::InTolerance,
            _ => Outcome::Other,
        };
        out.push(Event {
            survey_id: r.id,
            at_days,
            outcome,
            revolutions: travel(r),
            statistic: check.and_then(super::control::statistic_of),
            settings: settings(r),
        });
    }
    Ok(out)
}

/// One asset's next check.
#[derive(Debug, Clone)]
pub struct AssetDue {
    /// The asset.
    pub asset: String,
    /// Its method (the last survey's keys).
    pub method: interval::Method,
    /// What is due.
    pub due: interval::Due,
}

impl AssetDue {
    /// The contract's entry (`asset`, `last`, `interval_days`, `next_due`,
    /// `overdue`, `method`, `reason`) and more.
    pub fn json(&self) -> Value {
        let d = &self.due;
        let (checks, good) = d.reliability;
        json!({
            "asset": self.asset,
            "last": d.last.as_ref().map(|l| date_of(l.at_days)),
            "last_survey": d.last.as_ref().map(|l| l.survey_id),
            "interval_days": d.last.as_ref().map(|l| l.interval_days),
            "next_due": date_of(d.next_due_days),
            "overdue": d.overdue,
            "method": self.method.as_str(),
            "reason": d.reason,
            "interval_revolutions": d.last.as_ref().and_then(|l| l.revolutions),
            "revolutions_since": d.revolutions_since,
            "reliability": {"checks": checks, "in_tolerance": good,
                "fraction": (checks > 0).then(|| good as f64 / checks as f64)},
        })
    }
}

/// What is due for `asset` (or every asset of the store) as of `now`.
pub async fn due(store: &Store, asset: Option<&str>, now: SystemTime) -> anyhow::Result<Vec<AssetDue>> {
    let assets: Vec<String> = match asset {
        Some(a) => vec![a.to_string()],
        None => {
            let mut all: Vec<String> = store
                .list_uncounted()
                .await?
                .into_iter()
                .filter(|r| r.resolves.is_none() && r.asset != UNASSIGNED)
                .map(|r| r.asset)
                .collect();
            all.sort_unstable();
            all.dedup();
            all
        }
    };
    let now_days = days_at(now);
    let mut out = Vec::with_capacity(assets.len());
    for asset in assets {
        let events = events(store, &asset).await?;
        let method = events.last().map_or(Settings::default().method, |e| e.settings.method);
        out.push(AssetDue { asset, method, due: interval::due(&events, now_days) });
    }
    Ok(out)
}

/// `survey due --json`.
pub fn json(all: &[AssetDue]) -> Value {
    json!({"assets": all.iter().map(AssetDue::json).collect::<Vec<_>>()})
}

/// For people: one line an asset, then its reason.
pub fn text(all: &[AssetDue], now: SystemTime) -> String {
    if all.is_empty() {
        return "no asset: nothing is due\n".into();
    }
    let now_days = days_at(now);
    let mut s = format!(
        "{:<24} {:<13} {:>8}  {:<20}  {:<20}  {}\n",
        "asset", "method", "interval", "last", "next due (UTC)", "state"
    );
    for a in all {
        let d = &a.due;
        let state = match d.overdue {
            true if d.last.is_none() => "due: never calibrated".to_string(),
            true => format!("overdue by {:.0} days", (now_days - d.next_due_days).max(0.0)),
            false => format!("due in {:.0} days", d.next_due_days - now_days),
        };
        let interval = d.last.as_ref().map_or("-".into(), |l| format!("{:.0} d", l.interval_days));
        let last = d.last.as_ref().map_or("-".into(), |l| date_of(l.at_days));
        let _ = writeln!(
            s,
            "{:<24} {:<13} {:>8}  {:<20}  {:<20}  {state}",
            a.asset,
            a.method.as_str(),
            interval,
            last,
            date_of(d.next_due_days)
        );
        let _ = writeln!(s, "    {}", d.reason);
        let (checks, good) = d.reliability;
        if checks > 0 {
            let _ = writeln!(
                s,
                "    in tolerance at {good} of {checks} checks ({:.0} %)",
                100.0 * good as f64 / checks as f64
            );
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates_read_and_write_as_the_store_writes_them() {
        let d = days_of("2026-03-01T12:00:00Z").unwrap();
        assert_eq!(date_of(d), "2026-03-01T12:00:00Z");
        assert_eq!(date_of(d + 90.0), "2026-05-30T12:00:00Z");
        assert!(days_of("yesterday").is_none());
        assert_eq!(days_at(parse_at("2026-03-01").unwrap()) + 0.5, d);
        assert!(parse_at("2026-13-01").unwrap_err().contains("'2026-13-01' is not a UTC time"));
    }
}
