//! An asset's history computed once (issue 40): each complete survey's
//! measured [`Summary`] (the history's entry: `A`, `R`, `B`, the table's
//! `U`, the main lines, the samples counted) and each pair of consecutive
//! complete native surveys' [`Pair`] (the change document, or why the two
//! cannot be compared) are kept in the store (migration 8), keyed by the
//! survey (a pair: the later survey and the earlier one's uid) and by
//! [`VERSION`]; `survey history`, the report's section, `survey run
//! --check` and `survey serve` read them.
//!
//! **When they are made.** A command that writes keeps what it makes:
//! [`fill`] runs after `survey run`, `survey resume` and `survey import`
//! (the asset of the survey they completed), after a check survey and its
//! recalibration, and after `survey push` on the lab store (the assets it
//! pushed to: a survey's entries are copied with it, and what the lab
//! store still lacks, a pair of surveys from two stations, is made there).
//! A command that only reads opens the store read-only and never writes:
//! what it does not find (a database older than the cache, an entry of
//! another version, a survey not complete) it computes, exactly as before
//! the cache, and forgets. Only complete surveys are kept: a survey being
//! acquired changes until it completes.
//!
//! **What an entry is worth.** An entry is what [`super::measure`] and
//! [`super::compared`] give, bit for bit ([`super::codec`]: every f64 by its
//! bits, the change document by its JSON tree), so a history read from the
//! cache prints exactly what one computed prints. The survey's own ids are
//! not in it (they are a database's own: the lab store numbers anew) but
//! put in when read. [`VERSION`] is the package version and a fingerprint
//! of the code the entries are computed by (`lab/build.rs`): a build that
//! computes differently never reads an older build's entries, and makes its
//! own. Folding check points into a survey drops its entries (the store).
//!
//! **Memory.** A history holds no survey's samples but while it measures
//! one: a summary at a time, and for a pair not kept the two surveys it
//! compares (the earlier kept from the step before).

use super::codec::{Malformed, Reader, Writer};
use super::{Compared, MainLine, Measured, MotionTotals, Total, kind, measure, not_comparable};
use serde_json::Value;
use std::collections::{HashMap, HashSet};
use survey_modelgap::compare::Verdict;
use survey_store::Store;
use survey_store::survey::{SurveyRecord, SurveyRef};

/// The version of the program that makes an entry: the package version and
/// the fingerprint of what computes the entries (`lab/build.rs`).
pub const VERSION: &str = concat!(env!("CARGO_PKG_VERSION"), "+", env!("SURVEY_HISTORY_FINGERPRINT"));

/// A survey's ISO 230-2 figures as its history shows them, degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Figures {
    /// Accuracy `A`.
    pub a: f64,
    /// Repeatability `R`.
    pub r: f64,
    /// Reversal `B`, measured both ways.
    pub b: Option<f64>,
}

/// A survey measured, as its history shows it (the record aside).
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Its samples (as processed).
    pub samples: u64,
    /// Its ISO 230-2 figures, when it allows them.
    pub iso: Option<Figures>,
    /// Its table's expanded uncertainty `U` (k = 2), degrees.
    pub table_u_deg: Option<f64>,
    /// The lines its table corrects, largest first.
    pub lines: Vec<MainLine>,
    /// Its axis's total radial and axial error motions.
    pub motions: Option<MotionTotals>,
}

impl Summary {
    /// The summary of `m`.
    pub fn of(m: &Measured) -> Summary {
        Summary {
            samples: m.samples.len() as u64,
            iso: m.iso.as_ref().map(|i| Figures { a: i.a, r: i.r, b: i.b }),
            table_u_deg: m.table_u_deg,
            lines: m.lines.clone(),
            motions: m.motions,
        }
    }

    fn encode(&self) -> Vec<u8> {
        let mut w = Writer::default();
        w.u64(self.samples);
        match &self.iso {
            Some(f) => {
                w.u8(1);
                w.f64(f.a);
                w.f64(f.r);
                w.opt_f64(f.b);
            }
            None => w.u8(0),
        }
        w.opt_f64(self.table_u_deg);
        w.u64(self.lines.len() as u64);
        for l in &self.lines {
            w.f64(l.cycles_per_rev);
            w.f64(l.amplitude_deg);
            w.f64(l.phase_deg);
        }
        match &self.motions {
            Some(m) => {
                w.u8(1);
                w.opt_f64(m.radial_um);
                w.opt_f64(m.axial_um);
                w.f64(m.u_radial_um);
                w.f64(m.u_axial_um);
                w.f64(m.limit_um);
                // The tilt across last (since the tilt across was kept): an
                // entry written before it ends one flag short and does not
                // decode; the version (`lab/build.rs` fingerprints this file)
                // keeps it from being looked up at all.
                for t in [&m.axial_on_axis_um, &m.tilt_urad, &m.tilt_across_urad] {
                    match t {
                        Some(t) => {
                            w.u8(1);
                            w.opt_f64(t.total);
                            w.f64(t.u);
                            w.f64(t.limit);
                        }
                        None => w.u8(0),
                    }
                }
            }
            None => w.u8(0),
        }
        w.into_bytes()
    }

    fn decode(bytes: &[u8]) -> Result<Summary, Malformed> {
        let mut r = Reader::new(bytes);
        let samples = r.u64()?;
        let iso = match r.u8()? {
            0 => None,
            1 => Some(Figures { a: r.f64()?, r: r.f64()?, b: r.opt_f64()? }),
            _ => return Err(Malformed),
        };
        let table_u_deg = r.opt_f64()?;
        let n = r.count()?;
        let mut lines = Vec::with_capacity(n);
        for _ in 0..n {
            lines.push(MainLine { cycles_per_rev: r.f64()?, amplitude_deg: r.f64()?, phase_deg: r.f64()? });
        }
        let motions = match r.u8()? {
            0 => None,
            1 => {
                let (radial_um, axial_um, u_radial_um, u_axial_um, limit_um) =
                    (r.opt_f64()?, r.opt_f64()?, r.f64()?, r.f64()?, r.f64()?);
                let mut total = || -> Result<Option<Total>, Malformed> {
                    match r.u8()? {
                        0 => Ok(None),
                        1 => Ok(Some(Total { total: r.opt_f64()?, u: r.f64()?, limit: r.f64()? })),
                        _ => Err(Malformed),
                    }
                };
                let (axial_on_axis_um, tilt_urad, tilt_across_urad) = (total()?, total()?, total()?);
                Some(MotionTotals {
                    radial_um,
                    axial_um,
                    u_radial_um,
                    u_axial_um,
                    limit_um,
                    axial_on_axis_um,
                    tilt_urad,
                    tilt_across_urad,
                })
            }
            _ => return Err(Malformed),
        };
        r.end()?;
        Ok(Summary { samples, iso, table_u_deg, lines, motions })
    }
}

/// What changed from one survey to the next, as the history shows it.
#[derive(Debug, Clone, PartialEq)]
pub struct Change {
    /// `unchanged` or `changed`.
    pub verdict: Verdict,
    /// Recalibrate.
    pub recalibrate: bool,
    /// Why (or why not), in words.
    pub reason: String,
    /// The change document ([`Compared::change_json`]) without the two
    /// surveys' ids and uids.
    doc: Value,
}

/// The keys of the change document that name the two surveys.
const NAMES: [&str; 4] = ["from", "to", "from_uid", "to_uid"];

impl Change {
    /// The change from `a` to `b` that `c` found.
    pub fn of(c: &Compared, a: &Measured, b: &Measured) -> Change {
        let mut doc = c.change_json(a, b);
        if let Value::Object(m) = &mut doc {
            for k in NAMES {
                m.remove(k);
            }
        }
        Change {
            verdict: c.comparison.verdict,
            recalibrate: c.decision.recalibrate,
            reason: c.decision.reason.clone(),
            doc,
        }
    }

    /// The contract's change document from `a` to `b` ([`Compared::change_json`]).
    pub fn json(&self, a: &SurveyRecord, b: &SurveyRecord) -> Value {
        let mut doc = self.doc.clone();
        doc["from"] = a.id.into();
        doc["to"] = b.id.into();
        doc["from_uid"] = a.uid.clone().into();
        doc["to_uid"] = b.uid.clone().into();
        doc
    }

    /// From the document (its verdict, decision and reason are in it).
    fn from_doc(doc: Value) -> Result<Change, Malformed> {
        let verdict = match doc["verdict"].as_str() {
            Some("changed") => Verdict::Changed,
            Some("unchanged") => Verdict::Unchanged,
            _ => return Err(Malformed),
        };
        let recalibrate = doc["recalibrate"].as_bool().ok_or(Malformed)?;
        let reason = doc["reason"].as_str().ok_or(Malformed)?.to_string();
        Ok(Change { verdict, recalibrate, reason, doc })
    }
}

/// A pair of consecutive complete native surveys: what changed, or why
/// they cannot be compared.
#[derive(Debug, Clone, PartialEq)]
pub enum Pair {
    /// Compared.
    Compared(Change),
    /// The comparison's own reason they cannot be compared (the message
    /// names the two surveys: [`Pair::not_compared`]).
    NotComparable(String),
}

impl Pair {
    /// Compare `a` with `b` (surveys of one asset, neither a verification:
    /// anything else is an error, not a pair).
    pub fn of(a: &Measured, b: &Measured) -> anyhow::Result<Pair> {
        super::comparable(a, b)?;
        Ok(match super::tested(a, b, &[]) {
            Ok(c) => Pair::Compared(Change::of(&c, a, b)),
            Err(e) => Pair::NotComparable(e.to_string()),
        })
    }

    /// Why `a` and `b` were not compared, as the history says it.
    pub fn not_compared(why: &str, a: &SurveyRecord, b: &SurveyRecord) -> String {
        format!("{:#}", not_comparable(a.id, b.id, why))
    }

    fn encode(&self) -> Vec<u8> {
        let mut w = Writer::default();
        match self {
            Pair::Compared(c) => {
                w.u8(0);
                w.value(&c.doc);
            }
            Pair::NotComparable(why) => {
                w.u8(1);
                w.str(why);
            }
        }
        w.into_bytes()
    }

    fn decode(bytes: &[u8]) -> Result<Pair, Malformed> {
        let mut r = Reader::new(bytes);
        let pair = match r.u8()? {
            0 => Pair::Compared(Change::from_doc(r.value()?)?),
            1 => Pair::NotComparable(r.str()?),
            _ => return Err(Malformed),
        };
        r.end()?;
        Ok(pair)
    }
}

/// Whether `r` is compared with the surveys around it: a complete
/// calibration or check (a verification, or a survey with the correction
/// kept on, measures the corrected axis).
pub fn is_native(r: &SurveyRecord) -> bool {
    r.is_complete() && !matches!(kind(r), "verification" | "corrected")
}

/// A pair of an asset's history: the indices of its two surveys, and the
/// pair, or the message saying why they are not surveys that compare.
pub type MadePair = (usize, usize, Result<Pair, String>);

/// An asset's surveys made into history: one summary a survey, one pair
/// (or why none: the message) for each two consecutive native surveys.
#[derive(Debug)]
pub struct Made {
    /// A summary for each survey, in order.
    pub summaries: Vec<Summary>,
    /// The consecutive native surveys (indices) and their pair: `Err` with
    /// the message when they are not surveys that compare.
    pub pairs: Vec<MadePair>,
}

/// A summary or pair found in the cache, when it decodes (one that does
/// not is made again, and said at debug level).
fn decoded<T>(bytes: Option<&Vec<u8>>, decode: fn(&[u8]) -> Result<T, Malformed>, what: &str) -> Option<T> {
    let bytes = bytes?;
    decode(bytes).map_err(|e| tracing::debug!("{what}: {e}; made again")).ok()
}

/// The history of `records` (an asset's surveys, in the order they were
/// made): each entry read from the cache, or measured (and kept when the
/// store can write and the survey is complete). See the module documentation.
pub async fn made(store: &Store, records: &[SurveyRecord]) -> anyhow::Result<Made> {
    let Some(asset) = records.first().map(|r| r.asset.as_str()) else {
        return Ok(Made { summaries: Vec::new(), pairs: Vec::new() });
    };
    let keep = store.can_write() && store.has_history_cache();
    let kept_summaries = store.cached_summaries(asset, VERSION).await?;
    let kept_changes = store.cached_changes(asset, VERSION).await?;
    let natives: Vec<usize> = (0..records.len()).filter(|&i| is_native(&records[i])).collect();
    // Each pair read from the cache, or `None` until it is made.
    type Pending = (usize, usize, Option<Result<Pair, String>>);
    let mut pairs: Vec<Pending> = natives
        .windows(2)
        .map(|w| {
            let key = (records[w[1]].id, records[w[0]].uid.clone());
            let what = format!("the change from survey {} to {}", records[w[0]].id, records[w[1]].id);
            (w[0], w[1], decoded(kept_changes.get(&key), Pair::decode, &what).map(Ok))
        })
        .collect();
    // The surveys whose samples a pair to compute needs.
    let needed: HashSet<usize> = pairs.iter().filter(|p| p.2.is_none()).flat_map(|p| [p.0, p.1]).collect();
    let mut summaries = Vec::with_capacity(records.len());
    // The earlier survey of the next pair to compute.
    let mut held: Option<(usize, Measured)> = None;
    for (i, r) in records.iter().enumerate() {
        let what = format!("the summary of survey {}", r.id);
        let kept = r.is_complete().then(|| decoded(kept_summaries.get(&r.id), Summary::decode, &what)).flatten();
        if let (Some(s), false) = (&kept, needed.contains(&i)) {
            summaries.push(s.clone());
            continue;
        }
        let m = measure(store, SurveyRef::Id(r.id)).await?;
        summaries.push(match kept {
            Some(s) => s,
            None => {
                let s = Summary::of(&m);
                if keep && r.is_complete() {
                    store.keep_summary(r.id, VERSION, &s.encode()).await?;
                }
                s
            }
        });
        if !needed.contains(&i) {
            continue;
        }
        if let Some(p) = pairs.iter_mut().find(|p| p.1 == i && p.2.is_none()) {
            let a = match held.take() {
                Some((j, a)) if j == p.0 => a,
                _ => {
                    anyhow::bail!("the history of {asset}: survey {} was not measured before {}", records[p.0].id, r.id)
                }
            };
            let pair = Pair::of(&a, &m).map_err(|e| format!("{e:#}"));
            if let (Ok(pair), true) = (&pair, keep) {
                store.keep_change(r.id, &a.survey.uid, VERSION, &pair.encode()).await?;
            }
            p.2 = Some(pair);
        }
        held = Some((i, m));
    }
    let pairs = pairs.into_iter().map(|(a, b, p)| (a, b, p.expect("every pair read or made"))).collect();
    Ok(Made { summaries, pairs })
}

/// Make and keep what the cache lacks of the history of `asset` (a store
/// opened to write: see the module documentation). What it made: summaries
/// and pairs.
pub async fn fill(store: &Store, asset: &str) -> anyhow::Result<()> {
    let records = store.surveys_of_asset_uncounted(asset).await?;
    made(store, &records).await.map(|_| ())
}

/// [`fill`], after a command completed survey `id` of `asset`: a failure
/// is said (the command's work is done; the history is then computed on
/// read), not returned.
pub async fn fill_after(store: &Store, asset: &str, id: i64) {
    if let Err(e) = fill(store, asset).await {
        tracing::warn!(
            "survey {id}: the history of the asset {asset} could not be kept in {} ({e:#}); `survey history` \
             computes it when it reads it",
            store.path().display()
        );
    }
}

/// The summary of survey `r` kept in the history's cache, when there is one
/// of this version (a survey is kept only once complete).
pub async fn kept_summary(store: &Store, r: &SurveyRecord) -> anyhow::Result<Option<Summary>> {
    if !r.is_complete() {
        return Ok(None);
    }
    let kept = store.cached_summary(r.id, VERSION).await?;
    Ok(decoded(kept.as_ref(), Summary::decode, &format!("the summary of survey {}", r.id)))
}

/// The summary of survey `r` (complete or not): kept, or measured (and kept
/// when the store can write and the survey is complete).
pub async fn summary(store: &Store, r: &SurveyRecord) -> anyhow::Result<Summary> {
    if let Some(s) = kept_summary(store, r).await? {
        return Ok(s);
    }
    let s = Summary::of(&measure(store, SurveyRef::Id(r.id)).await?);
    if store.can_write() && store.has_history_cache() && r.is_complete() {
        store.keep_summary(r.id, VERSION, &s.encode()).await?;
    }
    Ok(s)
}

/// Keep what a command computed anyway: the summaries of `a` and `b` and,
/// when `a` is the native survey just before `b` in its asset's history,
/// their pair (`survey run --check` compares the calibration in force with
/// the check it made, most often the pair the history shows).
pub async fn keep_compared(store: &Store, a: &Measured, b: &Measured) -> anyhow::Result<()> {
    if !(store.can_write() && store.has_history_cache()) {
        return Ok(());
    }
    // As stored now (`b` may have completed since it was measured).
    let records = store.surveys_of_asset_uncounted(&b.survey.asset).await?;
    let complete = |id: i64| records.iter().any(|r| r.id == id && r.is_complete());
    for m in [a, b].into_iter().filter(|m| complete(m.survey.id)) {
        store.keep_summary(m.survey.id, VERSION, &Summary::of(m).encode()).await?;
    }
    let natives: Vec<&SurveyRecord> = records.iter().filter(|r| is_native(r)).collect();
    let before = natives.windows(2).find(|w| w[1].id == b.survey.id).map(|w| w[0].id);
    if before == Some(a.survey.id) {
        store.keep_change(b.survey.id, &a.survey.uid, VERSION, &Pair::of(a, b)?.encode()).await?;
    }
    Ok(())
}

/// The lines the history of `asset` has seen: every main line of every
/// complete calibration and check of it (cycles per revolution, ascending,
/// each once), from the kept summaries (a summary not kept is measured, one
/// survey at a time, and kept when the store can write).
pub async fn lines_seen(store: &Store, asset: &str) -> anyhow::Result<Vec<f64>> {
    let records = store.surveys_of_asset_uncounted(asset).await?;
    let kept: HashMap<i64, Vec<u8>> = store.cached_summaries(asset, VERSION).await?;
    let mut lines: Vec<f64> = Vec::new();
    for r in records.iter().filter(|r| is_native(r)) {
        let what = format!("the summary of survey {}", r.id);
        let s = match decoded(kept.get(&r.id), Summary::decode, &what) {
            Some(s) => s,
            None => summary(store, r).await?,
        };
        lines.extend(s.lines.iter().map(|l| l.cycles_per_rev));
    }
    lines.sort_by(f64::total_cmp);
    lines.dedup();
    Ok(lines)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn a_summary_and_a_pair_come_back_bit_for_bit() {
        let s = Summary {
            samples: 144,
            iso: Some(Figures { a: 0.012_345_678_901_234_5, r: -0.0, b: Some(f64::NAN) }),
            table_u_deg: None,
            lines: vec![MainLine { cycles_per_rev: 1.0, amplitude_deg: 5e-324, phase_deg: -179.9 }],
            motions: Some(MotionTotals {
                radial_um: Some(112.5),
                axial_um: None,
                u_radial_um: 53.6,
                u_axial_um: 53.6,
                limit_um: 36.8,
                axial_on_axis_um: Some(Total { total: Some(84.1), u: 46.0, limit: 36.8 }),
                tilt_urad: Some(Total { total: None, u: 46.0, limit: 52.0 }),
                tilt_across_urad: Some(Total { total: Some(410.4), u: 53.1, limit: 42.5 }),
            }),
        };
        let back = Summary::decode(&s.encode()).unwrap();
        assert_eq!(format!("{back:?}"), format!("{s:?}"));
        let m = s.motions.unwrap();
        assert_eq!(back.motions.unwrap().tilt_across_urad.unwrap().total.map(f64::to_bits), Some(410.4f64.to_bits()));
        // Without the tilt across (SMRs on one line), and below its limit: each comes back as it went.
        for across in [None, Some(Total { total: None, u: 53.1, limit: 42.5 })] {
            let s = Summary { motions: Some(MotionTotals { tilt_across_urad: across, ..m }), ..s.clone() };
            let back = Summary::decode(&s.encode()).unwrap();
            assert_eq!(format!("{back:?}"), format!("{s:?}"));
            assert_eq!(back.motions.unwrap().tilt_across_urad, across);
        }
        // An entry of the format before the tilt across (the motions last, the tilt's flag their
        // last): what this build writes without it, less its flag. It is refused, never misread.
        let old = Summary { motions: Some(MotionTotals { tilt_across_urad: None, ..m }), ..s.clone() };
        let mut old = old.encode();
        assert_eq!(old.pop(), Some(0));
        assert_eq!(Summary::decode(&old), Err(Malformed));
        assert_eq!(back.iso.unwrap().r.to_bits(), (-0.0f64).to_bits());
        let none = Summary { samples: 0, iso: None, table_u_deg: Some(1e-3), lines: Vec::new(), motions: None };
        assert_eq!(Summary::decode(&none.encode()).unwrap(), none);
        let mut cut = s.encode();
        cut.pop();
        assert_eq!(Summary::decode(&cut), Err(Malformed));

        let doc = json!({"verdict": "changed", "recalibrate": true, "reason": "the 1 cycles/rev line changed",
            "lines": [{"p_value": 1e-12, "change_deg": 0.25}], "map": null, "false_alarm_rate": 0.01});
        let pair = Pair::Compared(Change::from_doc(doc).unwrap());
        assert_eq!(Pair::decode(&pair.encode()).unwrap(), pair);
        let not = Pair::NotComparable("survey B has no target measured twice".into());
        assert_eq!(Pair::decode(&not.encode()).unwrap(), not);
        assert_eq!(Pair::decode(&[0, 0]), Err(Malformed), "a document without its verdict");
    }

    /// A survey of 72 targets, 2 runs both ways: a 20 cycles/rev line of
    /// `amplitude` and a little noise (seeded).
    fn survey(amplitude: f64, seed: u64) -> Vec<survey_processing::Sample> {
        use survey_processing::{Direction, Sample};
        let mut state = seed;
        let mut noise = || {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2e-4
        };
        let mut out = Vec::new();
        for run in 1..=2 {
            for direction in [Direction::Forward, Direction::Reverse] {
                for k in 0..72 {
                    let k = if direction == Direction::Forward { k } else { 71 - k };
                    let target_deg = f64::from(k) * 5.0;
                    let error = amplitude * (20.0 * target_deg.to_radians()).sin() + noise();
                    out.push(Sample {
                        run,
                        direction,
                        target_deg,
                        readout_deg: target_deg,
                        actual_deg: target_deg - error,
                        timestamp_s: None,
                    });
                }
            }
        }
        out
    }

    #[tokio::test]
    async fn a_filled_history_reads_as_it_computes_and_its_lines_are_seen() {
        use survey_store::survey::{NewSurvey, Setup, SurveySource, SurveyStatus};
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("s.db");
        let store = Store::open(&db).await.unwrap();
        let new = NewSurvey {
            status: SurveyStatus::Imported,
            source: SurveySource::Import { file: "s.csv".into() },
            setup: Setup::Imported { file: "s.csv".into() },
            asset: "ax".into(),
            ..NewSurvey::default()
        };
        for (k, amplitude) in [0.01, 0.01, 0.02].into_iter().enumerate() {
            store.import(&new, &survey(amplitude, k as u64)).await.unwrap();
        }
        // Read-only, nothing kept: measured, and nothing written.
        let reader = Store::open_read_only(&db).await.unwrap();
        assert!(!reader.can_write());
        let computed = super::super::history::history(&reader, "ax", None).await.unwrap().json();
        assert_eq!(computed["changes"].as_array().map(Vec::len), Some(2), "{computed:#}");
        assert!(reader.cached_summaries("ax", VERSION).await.unwrap().is_empty());
        fill(&store, "ax").await.unwrap();
        assert_eq!(store.cached_summaries("ax", VERSION).await.unwrap().len(), 3);
        assert_eq!(store.cached_changes("ax", VERSION).await.unwrap().len(), 2);
        assert_eq!(super::super::history::history(&reader, "ax", None).await.unwrap().json(), computed, "kept");
        let seen = lines_seen(&reader, "ax").await.unwrap();
        assert!(seen.contains(&20.0), "{seen:?}");
        let mut from_history: Vec<f64> = computed["surveys"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|s| s["lines"].as_array().unwrap().iter().map(|l| l["cycles_per_rev"].as_f64().unwrap()))
            .collect();
        from_history.sort_by(f64::total_cmp);
        from_history.dedup();
        assert_eq!(seen, from_history);
        reader.close().await;
        store.close().await;
    }

    #[test]
    fn the_version_names_the_package_and_the_fingerprint_of_what_computes_the_entries() {
        let (package, fingerprint) = VERSION.split_once('+').unwrap();
        assert_eq!(package, env!("CARGO_PKG_VERSION"));
        assert_eq!(fingerprint.len(), 16);
        assert!(fingerprint.bytes().all(|b| b.is_ascii_hexdigit()));
    }
}
