//! Each controller file checked against its format's rules, read back from
//! its text by a reader written from the format's description (not from the
//! writer), and applied to a survey the way the controller applies it.

use crate::export::{Controller, ControllerExport, ExportChoices, build};
use crate::generic::{Sign, Values};
use crate::layout::Directions;
use survey_processing::table::CorrectionTable;
use survey_processing::{Direction, Sample};

/// The positioner's error `readout - actual` at readout `r`: eccentricity, a
/// 20-cycle gear pass, a third harmonic and 0.004 deg of backlash.
fn truth(r: f64, d: Direction) -> f64 {
    let t = r.to_radians();
    0.01 * (t + 0.3).sin() + 0.006 * (20.0 * t + 1.0).sin() + 0.002 * (3.0 * t).sin() + 0.002 * d.sign() + 0.001
}

/// A survey of 360 targets, 3 runs, both directions, with a small
/// deterministic scatter (+/-0.0002 deg).
fn survey() -> Vec<Sample> {
    let mut out = Vec::new();
    for run in 1..=3u32 {
        for d in [Direction::Forward, Direction::Reverse] {
            for j in 0..360 {
                let t = j as f64;
                let scatter = 0.0001 * (((j * 7 + run as usize * 13) % 5) as f64 - 2.0);
                out.push(Sample {
                    run,
                    direction: d,
                    target_deg: t,
                    readout_deg: t,
                    actual_deg: t - truth(t, d) - scatter,
                    timestamp_s: None,
                });
            }
        }
    }
    out
}

/// The rows of a table (the processing's default count) read from `error`.
fn rows(error: impl Fn(f64) -> f64) -> Vec<f64> {
    const ROWS: usize = 16_384;
    (0..ROWS).map(|i| error(360.0 * i as f64 / ROWS as f64)).collect()
}

/// The directional table of [`truth`] itself: the controller files are
/// checked against what they were given, apart from how well a processing
/// estimates it (`survey-tables` tests that).
fn table_of_truth() -> CorrectionTable {
    let table =
        CorrectionTable::directional(rows(|r| truth(r, Direction::Forward)), rows(|r| truth(r, Direction::Reverse)))
            .unwrap();
    assert!(table.is_directional(), "0.004 deg of backlash makes a directional table");
    table
}

fn export(samples: &[Sample], choices: &ExportChoices) -> Vec<ControllerExport> {
    build(&table_of_truth(), true, (0.0, 360.0), samples, choices).unwrap()
}

fn only(c: Controller) -> ExportChoices {
    ExportChoices {
        linuxcnc: c == Controller::LinuxCnc,
        sinumerik_840d: c == Controller::Sinumerik840d,
        fanuc: c == Controller::Fanuc,
        generic: c == Controller::Generic,
        ..ExportChoices::default()
    }
}

/// `max |e - mean(e)|`: the processing's peak figure (the paper's "+/-").
fn peak(e: &[f64]) -> f64 {
    let mean = e.iter().sum::<f64>() / e.len() as f64;
    e.iter().map(|x| (x - mean).abs()).fold(0.0, f64::max)
}

// ---- LinuxCNC -------------------------------------------------------------

/// `usrmotLoadComp`: `sscanf("%lf %lf %lf")` per line, stopping at the first
/// line that is not three numbers.
fn load_comp(text: &str) -> Vec<[f64; 3]> {
    let mut out = Vec::new();
    for line in text.lines() {
        let v: Vec<f64> = line.split_whitespace().map_while(|w| w.parse().ok()).collect();
        if v.len() < 3 {
            break;
        }
        out.push([v[0], v[1], v[2]]);
    }
    out
}

/// `control.c` with `command.c`'s sentinels: the trim at `pos`, linear
/// between entries, the end values held outside. Type 0 trims are `nominal - actual`.
fn control_c_trim(entries: &[[f64; 3]], file_type: u8, pos: f64, up: bool) -> f64 {
    let trim = |e: &[f64; 3]| {
        let v = if up { e[1] } else { e[2] };
        if file_type == 0 { e[0] - v } else { v }
    };
    if pos < entries[0][0] {
        return trim(&entries[0]);
    }
    let mut i = 0;
    while i + 1 < entries.len() && pos >= entries[i + 1][0] {
        i += 1;
    }
    if i + 1 == entries.len() {
        return trim(&entries[i]);
    }
    let (a, b) = (&entries[i], &entries[i + 1]);
    trim(a) + (trim(b) - trim(a)) * (pos - a[0]) / (b[0] - a[0])
}

/// The error left on each turn of `-720..720` when the joint is commanded to
/// the survey's targets on that turn: the motor goes to `pos + trim`, the axis
/// to `motor - truth(motor)`.
fn linuxcnc_residual_per_turn(entries: &[[f64; 3]], file_type: u8) -> Vec<(f64, f64)> {
    (-2..2)
        .map(|k| {
            let mut native = Vec::new();
            let mut corrected = Vec::new();
            for d in [Direction::Forward, Direction::Reverse] {
                for j in 0..360 {
                    let pos = 360.0 * k as f64 + j as f64 + 0.5;
                    native.push(truth(pos, d));
                    let motor = pos + control_c_trim(entries, file_type, pos, d == Direction::Forward);
                    let actual = motor - truth(motor, d);
                    corrected.push(pos - actual);
                }
            }
            (peak(&native), peak(&corrected))
        })
        .collect()
}

#[test]
fn linuxcnc_covers_several_turns_within_256_points_with_the_right_sign() {
    let samples = survey();
    let choices = ExportChoices { start_deg: Some(-720.0), end_deg: Some(720.0), ..only(Controller::LinuxCnc) };
    let out = export(&samples, &choices);
    let files = &out[0].files;
    assert_eq!((files[0].suffix, files[1].suffix), (".comp0", ".comp1"));
    for (file_type, f) in [(0u8, &files[0]), (1u8, &files[1])] {
        let entries = load_comp(&f.text);
        // Every line loads (no header), at most EMCMOT_COMP_SIZE, strictly increasing.
        assert_eq!(entries.len(), f.text.lines().count());
        assert!(entries.len() <= 256 && entries.len() > 200, "{}", entries.len());
        assert!(entries.windows(2).all(|w| w[1][0] > w[0][0]));
        assert_eq!((entries[0][0], entries[entries.len() - 1][0]), (-720.0, 720.0));
        // Every turn is corrected: native about +/-0.018 deg; what is left is
        // linear interpolation over 5.71 deg of the 20-cycle line (at worst
        // mid-section, 0.006 (1 - cos(20 x 5.71 / 2 deg)) = 0.0027) plus the
        // survey's scatter (0.0002): a fifth of the native error.
        for (native, corrected) in linuxcnc_residual_per_turn(&entries, file_type) {
            assert!(native > 0.015, "{native}");
            assert!(corrected < native / 5.0, "type {file_type}: {corrected} vs {native}");
        }
        // Flipping the sign makes it worse on every turn.
        let flipped: Vec<[f64; 3]> = entries
            .iter()
            .map(|e| if file_type == 0 { [e[0], 2.0 * e[0] - e[1], 2.0 * e[0] - e[2]] } else { [e[0], -e[1], -e[2]] })
            .collect();
        for (native, corrected) in linuxcnc_residual_per_turn(&flipped, file_type) {
            assert!(corrected > native * 1.5, "{corrected} vs {native}");
        }
    }
    assert!(out[0].corrected_peak_deg.unwrap() < 0.0032, "{:?}", out[0].corrected_peak_deg);
    // A table over 0..360 only corrects that turn: LinuxCNC holds its ends.
    let one_turn = export(&samples, &only(Controller::LinuxCnc));
    let entries = load_comp(&one_turn[0].files[0].text);
    let turns = linuxcnc_residual_per_turn(&entries, 0);
    assert!(turns[2].1 < turns[2].0 / 8.0, "255 points per turn hold the 20-cycle line: {turns:?}");
    assert!(turns[0].1 > turns[0].0 / 2.0, "the turn -720..-360 is not corrected by a 0..360 table");
    assert!(one_turn[0].notes.iter().any(|n| n.contains("never wraps")), "{:?}", one_turn[0].notes);
}

#[test]
fn linuxcnc_refuses_more_than_256_points() {
    let samples = survey();
    let choices = ExportChoices { interval_deg: Some(1.0), ..only(Controller::LinuxCnc) };
    let e = build(&table_of_truth(), true, (0.0, 360.0), &samples, &choices).unwrap_err();
    assert_eq!(e.key, "export.interval_deg");
    assert!(e.message.contains("at most 256"), "{e}");
}

// ---- Siemens 840D ---------------------------------------------------------

struct Eec {
    values: Vec<f64>,
    step: f64,
    min: f64,
    max: f64,
    modulo: bool,
}

/// The file read by its documented layout; every line is checked.
fn read_eec(text: &str, axis: &str) -> Eec {
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "%_N_AX_EEC_INI");
    assert_eq!(lines[1], "CHANDATA(1)");
    assert_eq!(*lines.last().unwrap(), "M17");
    let mut values = Vec::new();
    let (mut step, mut min, mut max, mut modulo) = (None, None, None, None);
    // `;` starts a comment in the NC language.
    for l in lines[2..lines.len() - 1].iter().filter(|l| !l.starts_with(';')) {
        let (lhs, rhs) = l.split_once('=').unwrap();
        let v: f64 = rhs.parse().unwrap();
        if let Some(idx) = lhs.strip_prefix("$AA_ENC_COMP[") {
            let parts: Vec<&str> = idx.trim_end_matches(']').split(',').collect();
            assert_eq!((parts[0], parts[2]), ("0", axis));
            assert_eq!(parts[1].parse::<usize>().unwrap(), values.len(), "points numbered from 0 in order");
            values.push(v);
        } else if lhs == format!("$AA_ENC_COMP_STEP[0,{axis}]") {
            step = Some(v);
        } else if lhs == format!("$AA_ENC_COMP_MIN[0,{axis}]") {
            min = Some(v);
        } else if lhs == format!("$AA_ENC_COMP_MAX[0,{axis}]") {
            max = Some(v);
        } else if lhs == format!("$AA_ENC_COMP_IS_MODULO[0,{axis}]") {
            modulo = Some(v == 1.0);
        } else {
            panic!("unexpected line {l}");
        }
    }
    let e = Eec { values, step: step.unwrap(), min: min.unwrap(), max: max.unwrap(), modulo: modulo.unwrap() };
    // (MAX - MIN) / STEP + 1 points.
    assert_eq!(((e.max - e.min) / e.step).round() as usize + 1, e.values.len());
    e
}

impl Eec {
    fn value_at(&self, p: f64) -> f64 {
        let p = if self.modulo { self.min + (p - self.min).rem_euclid(self.max - self.min) } else { p };
        let x = ((p - self.min) / self.step).clamp(0.0, (self.values.len() - 1) as f64);
        let i = (x.floor() as usize).min(self.values.len() - 2);
        self.values[i] + (self.values[i + 1] - self.values[i]) * (x - i as f64)
    }
}

#[test]
fn sinumerik_840d_is_modulo_with_equal_ends_and_its_sign_shrinks_the_error() {
    let samples = survey();
    let out = export(&samples, &only(Controller::Sinumerik840d));
    let f = &out[0].files[0];
    assert_eq!(f.suffix, ".840d.ini");
    let eec = read_eec(&f.text, "C1");
    assert!(eec.modulo && eec.min == 0.0 && eec.max == 360.0 && eec.step == 1.0, "{}", &f.text[..200]);
    assert_eq!(eec.values[0], eec.values[360], "modulo: equal end values");
    // As the control applies it: the compensated position is readout + value.
    let native: Vec<f64> = samples.iter().map(Sample::error_deg).collect();
    let corrected: Vec<f64> =
        samples.iter().map(|s| (s.readout_deg + eec.value_at(s.readout_deg)) - s.actual_deg).collect();
    let flipped: Vec<f64> =
        samples.iter().map(|s| (s.readout_deg - eec.value_at(s.readout_deg)) - s.actual_deg).collect();
    // One table for both directions: the 0.004 deg reversal stays (+/-0.002),
    // plus the scatter (0.0002) and what 1 deg interpolation leaves (7e-5).
    assert!(peak(&native) > 0.017, "{}", peak(&native));
    assert!(peak(&corrected) < 0.0026, "{}", peak(&corrected));
    assert!(peak(&flipped) > 1.8 * peak(&native), "{}", peak(&flipped));
    assert!(out[0].notes.iter().any(|n| n.contains("one table for both directions")), "{:?}", out[0].notes);
    assert!((out[0].corrected_peak_deg.unwrap() - peak(&corrected)).abs() < 1e-6);

    // Zero at the reference point, another axis and a multi-turn range (not modulo).
    let choices = ExportChoices {
        zero_at_reference: true,
        reference_deg: Some(90.0),
        sinumerik_axis: "A1".into(),
        start_deg: Some(-360.0),
        end_deg: Some(360.0),
        interval_deg: Some(2.0),
        ..only(Controller::Sinumerik840d)
    };
    let out = export(&samples, &choices);
    let eec = read_eec(&out[0].files[0].text, "A1");
    assert!(!eec.modulo && eec.min == -360.0 && eec.max == 360.0 && eec.step == 2.0);
    assert_eq!(eec.value_at(90.0), 0.0);
    assert_eq!(eec.value_at(-270.0), 0.0, "the same point a turn before");
}

#[test]
fn sinumerik_840d_is_zero_at_the_reference_point_unless_kept_absolute() {
    let samples = survey();
    // K3: the compensation value at the reference point (0 deg by default) is zero.
    let zeroed = &export(&samples, &only(Controller::Sinumerik840d))[0];
    let text = &zeroed.files[0].text;
    let z = read_eec(text, "C1");
    assert_eq!(z.value_at(0.0), 0.0, "{}", &text[..120]);
    assert!(zeroed.zero_at_reference);
    assert!(text.contains("\n; zero at the reference point 0 deg (K3)"), "{}", &text[text.len() - 200..]);
    // Kept absolute on request, whatever the other formats do: minus the
    // error at 0 (the mean of the directions), the same table shifted.
    for zero_others in [false, true] {
        let choices = ExportChoices {
            sinumerik_absolute: true,
            zero_at_reference: zero_others,
            ..only(Controller::Sinumerik840d)
        };
        let absolute = &export(&samples, &choices)[0];
        let a = read_eec(&absolute.files[0].text, "C1");
        let error_at_0 = 0.5 * (truth(0.0, Direction::Forward) + truth(0.0, Direction::Reverse));
        assert!(error_at_0 > 0.008 && (a.value_at(0.0) + error_at_0).abs() < 3e-4, "{}", a.value_at(0.0));
        for (x, y) in z.values.iter().zip(&a.values) {
            assert!((x - y + a.values[0]).abs() < 2e-7, "{x} {y}");
        }
        assert!(!absolute.zero_at_reference);
        assert!(absolute.files[0].text.contains("\n; absolute values, not zero at the reference point"));
    }
}

#[test]
fn sinumerik_840d_refuses_a_bad_axis_name() {
    let samples = survey();
    let choices = ExportChoices { sinumerik_axis: "1C".into(), ..only(Controller::Sinumerik840d) };
    let e = build(&table_of_truth(), true, (0.0, 360.0), &samples, &choices).unwrap_err();
    assert_eq!(e.key, "export.sinumerik_axis");
}

// ---- Fanuc ----------------------------------------------------------------

struct Pitch {
    params: std::collections::BTreeMap<String, i64>,
    /// (number, position, value) per table, positive direction first.
    tables: Vec<Vec<(i64, f64, i64)>>,
}

fn read_pitch(text: &str) -> Pitch {
    let mut params = std::collections::BTreeMap::new();
    let mut tables: Vec<Vec<(i64, f64, i64)>> = Vec::new();
    let mut section = "";
    for l in text.lines() {
        if l == "PARAMETERS" {
            section = "p";
        } else if l.starts_with("VALUES") {
            section = "v";
            tables.push(Vec::new());
        } else if section == "p" && !l.is_empty() && !l.starts_with("WARNING") {
            let w: Vec<&str> = l.split_whitespace().collect();
            params.insert(w[0].to_string(), w[1].parse().unwrap());
        } else if section == "v" && !l.is_empty() && !l.trim_start().starts_with("number") {
            let w: Vec<&str> = l.split_whitespace().collect();
            tables.last_mut().unwrap().push((w[0].parse().unwrap(), w[1].parse().unwrap(), w[2].parse().unwrap()));
        }
    }
    Pitch { params, tables }
}

#[test]
fn fanuc_rotary_sums_to_zero_and_the_reference_repeats_the_last_point() {
    let samples = survey();
    let choices =
        ExportChoices { interval_deg: Some(5.0), directions: Directions::Separate, ..only(Controller::Fanuc) };
    let out = export(&samples, &choices);
    assert_eq!(out[0].files[0].suffix, ".fanuc.txt");
    let p = read_pitch(&out[0].files[0].text);
    let q = |k: &str| p.params[k];
    // Rotary type: 3621 = 3620, 3622 = 3620 + 3625 / 3624, in units of 0.001 deg.
    assert_eq!((q("3620"), q("3621"), q("3622"), q("3623"), q("3624"), q("3625")), (0, 0, 72, 1, 5000, 360000));
    assert_eq!((q("3605#0"), q("3626")), (1, 73));
    assert_eq!(p.tables.len(), 2);
    for (t, first) in p.tables.iter().zip([0, 73]) {
        assert_eq!(t.len(), 73);
        assert_eq!(t[0].0, first);
        // The values after the reference point sum to exactly zero over a
        // revolution, and the reference point's value is the last point's.
        assert_eq!(t[1..].iter().map(|v| v.2).sum::<i64>(), 0);
        assert_eq!(t[0].2, t[72].2);
        assert!(t.iter().all(|v| (-128..=127).contains(&v.2)));
    }
    // Cumulative rounding: the running sum is the error relative to the
    // reference point, to within half a unit at every point (it never drifts).
    let unit = 0.001;
    let zero = table_of_truth().error_at(0.0, Direction::Forward);
    let mut sum = 0;
    for &(_, pos, v) in &p.tables[0][1..] {
        sum += v;
        // The error as the 5 deg table holds it (lines below 36 cycles: all of them).
        let want = table_of_truth().error_at(pos, Direction::Forward) - zero;
        assert!((sum as f64 * unit - want).abs() <= unit / 2.0 + 1e-9, "{pos}: {sum} vs {want}");
    }
    // 3627: the reverse compensation at the reference point, absolute.
    let rev0 = table_of_truth().error_at(0.0, Direction::Reverse) - zero;
    assert!((q("3627") as f64 * unit - rev0).abs() <= unit / 2.0 + 1e-9);
    // Applied as the control does (the compensation added to the motion: the
    // position it knows is readout - C), the error shrinks in both directions.
    let c_at = |t: &Vec<(i64, f64, i64)>, r: f64, base: i64| {
        let mut acc = base as f64 * unit;
        let mut prev = 0.0;
        for &(_, pos, v) in &t[1..] {
            let next = acc + v as f64 * unit;
            if r <= pos {
                return acc + (next - acc) * (r - prev) / (pos - prev);
            }
            acc = next;
            prev = pos;
        }
        acc
    };
    let corrected: Vec<f64> = samples
        .iter()
        .map(|s| {
            let (t, base) = match s.direction {
                Direction::Forward => (&p.tables[0], 0),
                Direction::Reverse => (&p.tables[1], q("3627")),
            };
            s.error_deg() - c_at(t, s.readout_deg, base)
        })
        .collect();
    // Separate directions remove the reversal; linear interpolation over 5 deg
    // of the 20-cycle line leaves up to 0.006 (1 - cos(20 x 5 / 2 deg)) =
    // 0.0021 mid-section, the scatter 0.0002 and the rounding 0.0005 more.
    let native: Vec<f64> = samples.iter().map(Sample::error_deg).collect();
    assert!(peak(&corrected) < 0.003 && peak(&native) > 0.017, "{} {}", peak(&corrected), peak(&native));
    assert!((out[0].corrected_peak_deg.unwrap() - peak(&corrected)).abs() < 1e-9);
}

#[test]
fn fanuc_linear_type_numbers_from_the_reference_and_warns_past_the_common_limit() {
    let samples = survey();
    let choices = ExportChoices {
        start_deg: Some(-30.0),
        end_deg: Some(60.0),
        interval_deg: Some(1.0),
        reference_deg: Some(0.0),
        fanuc_unit_deg: 0.00001,
        directions: Directions::Combined,
        ..only(Controller::Fanuc)
    };
    let out = export(&samples, &choices);
    let p = read_pitch(&out[0].files[0].text);
    let q = |k: &str| p.params[k];
    // 30 sections below the reference: 3621 = 3620 - 30 + 1, 3622 = 3620 + 60.
    assert_eq!((q("3620"), q("3621"), q("3622"), q("3625")), (29, 0, 89, 0));
    assert!(!p.params.contains_key("3605#0"));
    assert_eq!(p.tables[0].len(), 90);
    assert_eq!((p.tables[0][0].1, p.tables[0][89].1), (-29.0, 60.0));
    // Up to 0.02 deg over a 1 deg section at 1e-5 deg units: beyond 127, a warning not a failure.
    assert!(p.tables[0].iter().any(|v| v.2.abs() > 127));
    assert!(out[0].notes.iter().any(|n| n.contains("-128..127")), "{:?}", out[0].notes);
    assert!(out[0].files[0].text.contains("WARNING"));
    // A reference off the grid is refused, naming the key.
    let bad = ExportChoices { reference_deg: Some(0.5), ..choices };
    let e = build(&table_of_truth(), true, (0.0, 360.0), &samples, &bad).unwrap_err();
    assert_eq!(e.key, "export.reference_deg");
}

// ---- Generic --------------------------------------------------------------

#[test]
fn generic_sign_and_increments() {
    let samples = survey();
    // 1 deg holds every line of the table (1, 3 and 20 cycles), so the file reads the table itself.
    let base = ExportChoices { interval_deg: Some(1.0), directions: Directions::Combined, ..only(Controller::Generic) };
    let rows = |c: &ExportChoices| -> (String, Vec<Vec<f64>>) {
        let text = export(&samples, c)[0].files[0].text.clone();
        let mut lines = text.lines();
        let header = lines.next().unwrap().to_string();
        (header, lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect())
    };
    let (h, err) = rows(&base);
    assert_eq!(h, "position_deg,error_deg");
    assert_eq!(err.len(), 361);
    let (h, corr) = rows(&ExportChoices { sign: Sign::Correction, ..base.clone() });
    assert_eq!(h, "position_deg,correction_deg");
    for (a, b) in err.iter().zip(&corr) {
        assert_eq!(a[1], -b[1]);
    }
    // The error column reads the table: the mean of forward and reverse.
    let t = table_of_truth();
    let mean = 0.5 * (t.error_at(30.0, Direction::Forward) + t.error_at(30.0, Direction::Reverse));
    assert!((err[30][1] - mean).abs() < 1e-9, "{} vs {mean}", err[30][1]);
    let (h, inc) = rows(&ExportChoices { values: Values::Incremental, directions: Directions::Separate, ..base });
    assert_eq!(h, "position_deg,forward_error_increment_deg,reverse_error_increment_deg");
    let mut sum = 0.0;
    for (i, r) in inc.iter().enumerate() {
        sum += r[1];
        assert!((sum - t.error_at(i as f64, Direction::Forward)).abs() < 1e-8, "{i}");
    }
}

#[test]
fn a_partial_range_table_is_written_over_its_measured_range_only() {
    // An elevation axis, -10..90 deg.
    let mut samples = Vec::new();
    for run in 1..=2u32 {
        for j in 0..=50 {
            let t = -10.0 + 2.0 * j as f64;
            let e = 0.004 * (6.0 * t.to_radians()).sin() + 0.0001 * run as f64;
            samples.push(Sample {
                run,
                direction: Direction::Forward,
                target_deg: t,
                readout_deg: t,
                actual_deg: t - e,
                timestamp_s: None,
            });
        }
    }
    // The table of the error itself over the circle (a partial-range fit
    // holds the measured span; outside it the files never read).
    let table = CorrectionTable::new(rows(|t| 0.004 * (6.0 * t.to_radians()).sin() + 0.00015)).unwrap();
    let controllers = build(&table, false, (-10.0, 90.0), &samples, &ExportChoices::default()).unwrap();
    let names: Vec<&str> = controllers.iter().map(|c| c.controller.as_str()).collect();
    assert_eq!(names, ["linuxcnc", "840d", "fanuc"]);
    for c in &controllers {
        assert_eq!((c.grid.start_deg, c.grid.end_deg()), (-10.0, 90.0), "{}", c.controller.as_str());
        assert!(!c.modulo);
        assert!(c.corrected_peak_deg.unwrap() < 0.001, "{:?}", c.corrected_peak_deg);
    }
    let eec = read_eec(&controllers[1].files[0].text, "C1");
    assert!(!eec.modulo && eec.min == -10.0 && eec.max == 90.0);
    let choices = ExportChoices { end_deg: Some(120.0), ..ExportChoices::default() };
    let e = build(&table, false, (-10.0, 90.0), &samples, &choices).unwrap_err();
    assert_eq!(e.key, "export.end_deg");
}
