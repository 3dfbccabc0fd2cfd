//! The keys a configuration may hold and what each allows, in words, and
//! the walk that checks a parsed document against them before serde reads
//! it: a key unknown, missing, of the wrong kind or out of its range is
//! named with its line (`place`), its value as written, and what it takes.
//! Serde's own messages name Rust types (`expected u32`) and print floats
//! in full; none of them reaches a reader.

use super::place::{Defect, join, line_at};
use survey_processing::num::Num;
use toml::Spanned;
use toml::de::{DeTable, DeValue};

/// The lower end of a range of numbers: inclusive or not.
#[derive(Debug, Clone, Copy)]
pub(super) enum Low {
    From(f64),
    Above(f64),
}

/// What a key takes.
#[derive(Debug, Clone, Copy)]
pub(super) enum Ty {
    /// A whole number in `min..=max`.
    Whole(i128, i128),
    /// A finite number within a range, with its unit.
    Number(Low, f64, &'static str),
    /// Any finite number.
    AnyNumber,
    Text,
    Flag,
    /// One of these words.
    Choice(&'static [&'static str]),
    /// Two numbers, each within the range.
    Pair(Low, f64, &'static str),
    /// Three numbers (a point or three angles), each within the range.
    Triple(Low, f64, &'static str),
    /// A list of numbers, each within the range.
    Numbers(Low, f64, &'static str),
    /// A list of whole numbers, each in `min..=max`.
    Wholes(i128, i128),
    /// Text a function accepts (it says why not), with what it takes in words.
    Checked(fn(&str) -> Result<(), String>, &'static str),
    Table(&'static [Field]),
    /// A table whose keys depend on its tag key's word.
    Tagged(&'static str, &'static [(&'static str, &'static [Field])]),
}

/// One key of a table.
#[derive(Debug, Clone, Copy)]
pub(super) struct Field {
    pub key: &'static str,
    pub ty: Ty,
    pub required: bool,
}

const fn opt(key: &'static str, ty: Ty) -> Field {
    Field { key, ty, required: false }
}

const fn req(key: &'static str, ty: Ty) -> Field {
    Field { key, ty, required: true }
}

const U8: Ty = Ty::Whole(0, u8::MAX as i128);
const U16: Ty = Ty::Whole(0, u16::MAX as i128);
const U32: Ty = Ty::Whole(0, u32::MAX as i128);
const U64: Ty = Ty::Whole(0, u64::MAX as i128);
const SECONDS: Ty = Ty::Number(Low::From(0.0), 3600.0, "s");
const POSITIVE_SECONDS: Ty = Ty::Number(Low::Above(0.0), 3600.0, "s");

/// A whole configuration file.
pub(super) const ROOT: &[Field] = &[
    opt("survey", Ty::Table(SURVEY)),
    req("positioner", Ty::Tagged("driver", POSITIONERS)),
    opt("tracker", Ty::Tagged("driver", &[("emscon", EMSCON)])),
    opt("autocollimator", Ty::Tagged("driver", &[("elcomat", &[req("port", Ty::Text), opt("baud", U32)])])),
    opt("arm", Ty::Table(ARM)),
    opt(
        "polygon",
        Ty::Table(&[
            req("faces", Ty::Whole(0, 3600)),
            opt("certificate_arcsec", Ty::Numbers(Low::From(-3600.0), 3600.0, "arcsec")),
            opt("certificate_u_arcsec", Ty::Number(Low::Above(0.0), 60.0, "arcsec")),
            opt("turns", Ty::Wholes(0, 3599)),
        ]),
    ),
    opt("timing", Ty::Table(TIMING)),
    opt("certificate", Ty::Table(CERTIFICATE)),
    opt(
        "drift_control",
        Ty::Table(&[
            req("every_steps", Ty::Whole(1, 1_000_000)),
            opt("reference_deg", Ty::Number(Low::From(-3600.0), 3600.0, "deg")),
            opt("correct", Ty::Flag),
        ]),
    ),
    opt("asset", Ty::Table(ASSET)),
    opt("rehearsal", Ty::Table(&[req("simulator", Ty::Checked(crate::check_field, FIELD_WORDS))])),
    opt(
        "smrs",
        Ty::Table(&[
            req("phases_deg", Ty::Numbers(Low::From(-360.0), 360.0, "deg")),
            opt("heights_mm", Ty::Numbers(Low::From(-10_000.0), 10_000.0, "mm")),
        ]),
    ),
    opt(
        "machine_frame",
        Ty::Table(&[
            req("origin_mm", Ty::Triple(Low::From(-MAX_ORIGIN_MM), MAX_ORIGIN_MM, "mm")),
            opt("rotation_deg", Ty::Triple(Low::From(-360.0), 360.0, "deg")),
            opt("origin_u_mm", Ty::Number(Low::From(0.0), survey_processing::frame::MAX_ORIGIN_U_MM, "mm")),
            opt("rotation_u_deg", Ty::Number(Low::From(0.0), survey_processing::frame::MAX_ROTATION_U_DEG, "deg")),
        ]),
    ),
];

const MAX_ORIGIN_MM: f64 = survey_processing::frame::MAX_ORIGIN_MM;

/// `[asset]`: the axis, and how the interval between its checks is set
/// (ILAC-G24; `survey due`).
const ASSET: &[Field] = &[
    req("id", Ty::Text),
    opt("interval_days", DAYS),
    opt("interval_method", Ty::Choice(&["staircase", "control-chart", "in-use", "fixed"])),
    opt("interval_min_days", DAYS),
    opt("interval_max_days", DAYS),
    opt("interval_revolutions", Ty::Number(Low::Above(0.0), 1e9, "revolutions")),
];

/// An interval in days: a day to ten years.
const DAYS: Ty = Ty::Number(Low::From(1.0), 3650.0, "days");

const SURVEY: &[Field] = &[
    opt("points", Ty::Whole(2, u32::MAX as i128)),
    opt("runs", Ty::Whole(2, u32::MAX as i128)),
    opt("bidirectional", Ty::Flag),
    opt("reference", Ty::Choice(&["tracker", "autocollimator"])),
    opt("travel_deg", Ty::Pair(Low::From(-3600.0), 3600.0, "deg")),
    opt("overrun_deg", Ty::Number(Low::Above(0.0), 10.0, "deg")),
    opt("scan", Ty::Choice(&["step", "continuous"])),
];

const IN_POSITION: Field = opt("in_position_window_deg", Ty::Number(Low::Above(0.0), 1.0, "deg"));
const ERROR_QUERY: Field = opt("error_query", Ty::Choice(&["all", "next"]));
const UNVERIFIED: Field = opt("unverified_commands", Ty::Flag);
const MODBUS_TIMEOUTS: Field = opt("timeouts", Ty::Table(&[opt("connect_ms", U64), opt("request_ms", U64)]));

const POSITIONERS: &[(&str, &[Field])] = &[
    (
        "scpi-tcp",
        &[req("address", Ty::Text), opt("controller", U32), opt("axis", U32), IN_POSITION, ERROR_QUERY, UNVERIFIED],
    ),
    (
        "scpi-serial",
        &[
            req("port", Ty::Text),
            opt("baud", U32),
            opt("controller", U32),
            opt("axis", U32),
            IN_POSITION,
            ERROR_QUERY,
            UNVERIFIED,
        ],
    ),
    ("modbus-tcp", &[req("address", Ty::Text), opt("map", Ty::Table(MAP)), MODBUS_TIMEOUTS]),
    (
        "modbus-rtu",
        &[req("port", Ty::Text), opt("baud", U32), opt("slave", U8), opt("map", Ty::Table(MAP)), MODBUS_TIMEOUTS],
    ),
    ("canopen", CANOPEN),
];

const CANOPEN: &[Field] = &[
    opt("transport", Ty::Choice(&["socketcan", "slcan"])),
    opt("interface", Ty::Text),
    opt("port", Ty::Text),
    opt("bitrate", U32),
    opt("node_id", U8),
    opt("counts_per_degree", Ty::Number(Low::Above(0.0), 1.0e9, "counts/deg")),
    opt("sdo_timeout_ms", U64),
    opt("resync_grace_ms", U64),
    opt("set_point_polls", U32),
    opt("transition_timeout_ms", U64),
    opt("fault_text_index", U16),
    opt("correction_objects", Ty::Flag),
];

const LOCATION: Ty = Ty::Table(&[req("table", Ty::Choice(&["holding", "input"])), req("address", U16)]);

const MAP: &[Field] = &[
    opt("unit_id", U8),
    opt(
        "position_encoding",
        Ty::Tagged("kind", &[("counts", &[req("counts_per_degree", Ty::AnyNumber)]), ("float32", &[])]),
    ),
    opt("word_order", Ty::Choice(&["high_first", "low_first"])),
    opt("command_position", U16),
    opt("velocity", U16),
    opt("command", U16),
    opt(
        "command_codes",
        Ty::Table(&[
            opt("move_absolute", U16),
            opt("stop", U16),
            opt("clear_fault", U16),
            opt("correction_enable", U16),
            opt("correction_disable", U16),
            opt("load_table", U16),
        ]),
    ),
    opt("actual_position", LOCATION),
    opt("status", LOCATION),
    opt(
        "status_bits",
        Ty::Table(&[
            opt("moving", U8),
            opt("in_position", U8),
            opt("fault", U8),
            opt("lower_limit", U8),
            opt("upper_limit", U8),
            opt("correction_enabled", U8),
        ]),
    ),
    opt("fault_code", LOCATION),
    opt(
        "table",
        Ty::Table(&[opt("header", U16), opt("window", U16), opt("chunk_rows", U16), opt("checksum", LOCATION)]),
    ),
];

const EMSCON: &[Field] = &[
    req("address", Ty::Text),
    opt("measurement_time_ms", U32),
    opt("use_adm", Ty::Flag),
    opt("initialize", Ty::Flag),
    opt("approx_distance_mm", Ty::Number(Low::Above(0.0), 1.0e6, "mm")),
    opt(
        "timeouts",
        Ty::Table(&[
            opt("connect_ms", U64),
            opt("request_ms", U64),
            opt("initialize_ms", U64),
            opt("measurement_margin_ms", U64),
            opt("reacquire_ms", U64),
            opt("resync_grace_ms", U64),
        ]),
    ),
];

const ARM: &[Field] = &[
    req("radius_mm", Ty::Number(Low::Above(0.0), 100_000.0, "mm")),
    opt("radius_tolerance_mm", Ty::Number(Low::Above(0.0), 100_000.0, "mm")),
];

const TIMING: &[Field] = &[
    opt("call_timeout_s", POSITIVE_SECONDS),
    opt("measure_timeout_s", POSITIVE_SECONDS),
    opt("move_margin_s", SECONDS),
    opt("poll_interval_s", Ty::Number(Low::Above(0.0), 60.0, "s")),
    opt("dwell_s", SECONDS),
    opt("max_retries", Ty::Whole(0, 1000)),
    opt("retry_backoff_s", SECONDS),
    opt("locate_points", Ty::Whole(3, 10_000)),
    opt("velocity_deg_s", Ty::Number(Low::Above(0.0), 3600.0, "deg/s")),
    opt("accel_deg_s2", Ty::Number(Low::Above(0.0), 1.0e6, "deg/s^2")),
    opt("settle", Ty::Choice(&["adaptive", "in-position"])),
    opt("settle_window_deg", Ty::Number(Low::Above(0.0), 1.0, "deg")),
    opt("settle_stable_s", Ty::Number(Low::From(0.0), 60.0, "s")),
    opt("settle_poll_s", Ty::Number(Low::Above(0.0), 60.0, "s")),
    opt("settle_time_s", SECONDS),
    opt("scan_velocity_deg_s", Ty::Number(Low::Above(0.0), 3600.0, "deg/s")),
    opt("calibration_velocity_deg_s", Ty::Number(Low::Above(0.0), 3600.0, "deg/s")),
    opt("capture_period_s", Ty::Number(Low::Above(0.0), 1.0, "s")),
    opt("stream_period_s", Ty::Number(Low::Above(0.0), 1.0, "s")),
    opt("fetch_interval_s", Ty::Number(Low::Above(0.0), 10.0, "s")),
    opt("beam_wait_s", Ty::Number(Low::From(0.0), 86_400.0, "s")),
    opt("beam_retry_s", POSITIVE_SECONDS),
    opt("time_scale", Ty::Number(Low::Above(0.0), 10_000.0, "x real time")),
];

/// What a certificate's text field takes, in words.
const FIELD_WORDS: &str = "text in quotes on one line, 1 to 400 characters, no control characters";
/// What a certificate number takes, in words.
const NUMBER_WORDS: &str = "text in quotes on one line, 1 to 64 characters, no control characters";

const CERTIFICATE: &[Field] = &[
    opt("positioner", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("reference", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("reference_uncertainty_deg", Ty::Number(Low::Above(0.0), 1.0, "deg")),
    opt("reference_mpe_um", Ty::Number(Low::From(0.0), 1000.0, "um")),
    opt("reference_mpe_um_per_m", Ty::Number(Low::From(0.0), 1000.0, "um/m")),
    opt("operator", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("customer", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("temperature_c", Ty::Number(Low::From(-50.0), 100.0, "°C")),
    opt("number", Ty::Checked(crate::check_number, NUMBER_WORDS)),
    opt("laboratory", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("traceability", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("tolerance_deg", Ty::Number(Low::Above(0.0), 360.0, "deg")),
    opt("signatory", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("location", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("performance_location", Ty::Choice(&["laboratory", "customer", "laboratoryBranch", "customerBranch", "other"])),
    opt("item_condition", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("received", Ty::Checked(crate::check_date, "a date in quotes, \"YYYY-MM-DD\"")),
    opt("country", Ty::Checked(crate::check_country, "an ISO 3166-1 alpha-2 code in quotes, such as \"DE\"")),
    opt("laboratory_address", Ty::Table(ADDRESS)),
    opt("customer_address", Ty::Table(ADDRESS)),
    opt("item", Ty::Table(EQUIPMENT)),
    opt("reference_instrument", Ty::Table(EQUIPMENT)),
];

/// A postal address, as the DCC's `location` holds one.
const ADDRESS: &[Field] = &[
    opt("street", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("street_no", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("post_code", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("city", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("state", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("country", Ty::Checked(crate::check_country, "an ISO 3166-1 alpha-2 code in quotes, such as \"DE\"")),
];

/// An instrument's identifications and, for a reference, its calibration.
const EQUIPMENT: &[Field] = &[
    opt("manufacturer", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("model", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("serial", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("inventory", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("certificate", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("calibrated_by", Ty::Checked(crate::check_field, FIELD_WORDS)),
    opt("calibrated", Ty::Checked(crate::check_date, "a date in quotes, \"YYYY-MM-DD\"")),
    opt("due", Ty::Checked(crate::check_date, "a date in quotes, \"YYYY-MM-DD\"")),
];

/// A range of numbers in words: `from 0 to 3600 s`, `above 0, at most 1 deg`.
pub(super) fn range_words(low: Low, max: f64, unit: &str) -> String {
    match low {
        Low::From(lo) => format!("from {} to {} {unit}", Num(lo), Num(max)),
        Low::Above(lo) => format!("above {}, at most {} {unit}", Num(lo), Num(max)),
    }
}

/// Whether `v` lies in the range.
pub(super) fn in_range(v: f64, low: Low, max: f64) -> bool {
    let above = match low {
        Low::From(lo) => v >= lo,
        Low::Above(lo) => v > lo,
    };
    v.is_finite() && above && v <= max
}

/// A list of words: `"a", "b" or "c"`.
fn one_of(words: &[&str]) -> String {
    let quoted: Vec<String> = words.iter().map(|w| format!("\"{w}\"")).collect();
    match quoted.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        _ => quoted.join(""),
    }
}

/// What `ty` allows, in words, for the key `key`.
fn allowed(ty: Ty, key: &str) -> String {
    match ty {
        // Past 2^53 a bound reads as a number nobody writes.
        Ty::Whole(lo, hi) if hi >= 1 << 53 => format!("a whole number, {lo} or more"),
        Ty::Whole(lo, hi) => format!("a whole number from {lo} to {hi}"),
        Ty::Number(low, max, unit) => format!("a number {}", range_words(low, max, unit)),
        Ty::AnyNumber => "a finite number".into(),
        Ty::Text => "text in quotes".into(),
        Ty::Checked(_, words) => words.into(),
        Ty::Flag => "true or false".into(),
        Ty::Choice(words) => format!("one of {}", one_of(words)),
        Ty::Pair(low, max, unit) => format!("two numbers [low, high], each {}", range_words(low, max, unit)),
        Ty::Triple(low, max, unit) => format!("three numbers [x, y, z], each {}", range_words(low, max, unit)),
        Ty::Numbers(low, max, unit) => format!("a list of numbers [a, b, ...], each {}", range_words(low, max, unit)),
        Ty::Wholes(lo, hi) => format!("a list of whole numbers [a, b, ...], each from {lo} to {hi}"),
        Ty::Table(fields) => {
            let keys: Vec<&str> = fields.iter().map(|f| f.key).collect();
            format!("a table [{key}] with the keys {}", keys.join(", "))
        }
        Ty::Tagged(tag, variants) => {
            let words: Vec<&str> = variants.iter().map(|(w, _)| *w).collect();
            format!("a table [{key}] with {tag} = {}", one_of(&words))
        }
    }
}

/// A value as a reader wrote it, for messages (a long text cut short).
fn shown(text: &str, v: &Spanned<DeValue<'_>>) -> String {
    match v.get_ref() {
        DeValue::Table(_) => "a table".into(),
        DeValue::Array(a) => format!("a list of {}", a.len()),
        _ => {
            let written = text.get(v.span()).unwrap_or_default().trim();
            if written.chars().count() > 40 {
                format!("{}...", written.chars().take(40).collect::<String>())
            } else {
                written.to_string()
            }
        }
    }
}

/// What kind of value it is, in words, against what the key takes.
fn kind(v: &DeValue<'_>, ty: Ty) -> &'static str {
    match (v, ty) {
        (DeValue::Float(_), Ty::Whole(..)) => "is not a whole number",
        (DeValue::String(_), _) => "is text",
        (DeValue::Integer(_), _) => "is a whole number",
        (DeValue::Float(_), _) => "is a number",
        (DeValue::Boolean(_), _) => "is a yes-or-no value",
        (DeValue::Datetime(_), _) => "is a date or time",
        (DeValue::Array(_), Ty::Pair(..)) => "is not two values",
        (DeValue::Array(_), Ty::Triple(..)) => "is not three values",
        (DeValue::Array(_) | DeValue::Table(_), _) => "is not allowed here",
    }
}

/// The number a TOML number holds, or why it holds none.
fn number(v: &DeValue<'_>) -> Option<Result<f64, &'static str>> {
    match v {
        DeValue::Integer(i) => {
            let digits = i.as_str().replace('_', "");
            // Past 64 bits serde reads no whole number into a float behind
            // a tagged table: refused everywhere alike.
            Some(match i64::from_str_radix(&digits, i.radix()) {
                Ok(n) => Ok(n as f64),
                Err(_) => Err("is too large for a whole number (write it with an exponent)"),
            })
        }
        DeValue::Float(f) => {
            let written = f.as_str().replace('_', "");
            Some(match written.parse::<f64>() {
                Ok(x) if x.is_nan() || written.contains("inf") => Err("is not a finite number"),
                Ok(x) if x.is_infinite() => Err("is too large in size to be a number"),
                Ok(x) => Ok(x),
                Err(_) => Err("is not a number"),
            })
        }
        _ => None,
    }
}

/// Checks a document against the keys, collecting every defect.
pub(super) struct Walk<'a> {
    pub text: &'a str,
    pub defects: Vec<Defect>,
}

impl<'a> Walk<'a> {
    /// The first defect of the document by line, if any.
    pub fn first(text: &'a str, doc: &DeTable<'_>) -> Option<Defect> {
        let mut walk = Walk { text, defects: Vec::new() };
        walk.table("", 0, doc, ROOT, "the top level");
        // A key written wrong before a key missing (often the same, misspelt).
        walk.defects.into_iter().min_by_key(|d| (d.text.starts_with("missing:"), d.line))
    }

    fn push(&mut self, at: usize, key: &str, text: String) {
        self.defects.push(Defect { line: line_at(self.text, at), key: key.to_string(), text });
    }

    /// A table's keys: each known, each required one given.
    fn table(&mut self, path: &str, header: usize, table: &DeTable<'_>, fields: &[Field], what: &str) {
        self.table_but(path, header, table, fields, what, "");
    }

    /// A table's keys but `skip` (its tag, checked already).
    fn table_but(&mut self, path: &str, header: usize, table: &DeTable<'_>, fields: &[Field], what: &str, skip: &str) {
        for (k, v) in table.iter().filter(|(k, _)| k.get_ref() != skip) {
            let key = join(path, k.get_ref());
            match fields.iter().find(|f| f.key == k.get_ref().as_ref()) {
                Some(f) => self.value(&key, v, f.ty),
                None => {
                    let names: Vec<&str> = fields.iter().map(|f| f.key).collect();
                    let near = names.iter().find(|n| close(n, k.get_ref())).map(|n| format!("did you mean {n}? "));
                    let keys = if names.is_empty() { "none".to_string() } else { names.join(", ") };
                    let text = format!("no such key in {what}; {}the keys are: {keys}", near.unwrap_or_default());
                    self.push(k.span().start, &key, text);
                }
            }
        }
        for f in fields.iter().filter(|f| f.required && !table.iter().any(|(k, _)| k.get_ref() == f.key)) {
            let key = join(path, f.key);
            let text = format!("missing: {what} needs {}, {}", f.key, allowed(f.ty, &key));
            self.push(header, &key, text);
        }
    }

    /// One value against what its key takes.
    fn value(&mut self, key: &str, v: &Spanned<DeValue<'_>>, ty: Ty) {
        let at = v.span().start;
        let wrong = |w: &Self| format!("{} {}: it takes {}", shown(w.text, v), kind(v.get_ref(), ty), allowed(ty, key));
        match (ty, v.get_ref()) {
            (Ty::Whole(lo, hi), DeValue::Integer(i)) => {
                let n = i128::from_str_radix(&i.as_str().replace('_', ""), i.radix()).ok();
                if !n.is_some_and(|n| (lo..=hi).contains(&n)) {
                    let text = format!("{} is out of range: it takes {}", shown(self.text, v), allowed(ty, key));
                    self.push(at, key, text);
                }
            }
            (Ty::Number(..) | Ty::AnyNumber, DeValue::Integer(_) | DeValue::Float(_)) => self.number(key, v, ty),
            (Ty::Text, DeValue::String(text)) => {
                // Text may be printed (an address on the certificate): never a control character.
                if let Some((place, c)) = crate::control_character(text) {
                    let text = format!(
                        "{} holds the control character U+{:04X} at character {place}: it takes text in quotes \
                         without control characters",
                        shown(self.text, v),
                        c as u32
                    );
                    self.push(at, key, text);
                }
            }
            (Ty::Flag, DeValue::Boolean(_)) => {}
            (Ty::Checked(check, words), DeValue::String(text)) => {
                if let Err(why) = check(text) {
                    let why = why.strip_prefix("not ").map_or(why.clone(), |rest| format!("is not {rest}"));
                    self.push(at, key, format!("{} {why}: it takes {words}", shown(self.text, v)));
                }
            }
            (Ty::Choice(words), DeValue::String(s)) => {
                if !words.contains(&s.as_ref()) {
                    let text =
                        format!("{} is not among the choices: it takes {}", shown(self.text, v), allowed(ty, key));
                    self.push(at, key, text);
                }
            }
            (Ty::Pair(low, max, unit), DeValue::Array(a)) if a.len() == 2 => {
                self.numbers(key, a, Ty::Number(low, max, unit));
            }
            (Ty::Triple(low, max, unit), DeValue::Array(a)) if a.len() == 3 => {
                self.numbers(key, a, Ty::Number(low, max, unit));
            }
            (Ty::Numbers(low, max, unit), DeValue::Array(a)) => self.numbers(key, a, Ty::Number(low, max, unit)),
            (Ty::Wholes(lo, hi), DeValue::Array(a)) => self.numbers(key, a, Ty::Whole(lo, hi)),
            (Ty::Table(fields), DeValue::Table(t)) => self.table(key, at, t, fields, &format!("[{key}]")),
            (Ty::Tagged(tag, variants), DeValue::Table(t)) => self.tagged(key, v, t, tag, variants),
            _ => {
                let text = wrong(self);
                self.push(at, key, text);
            }
        }
    }

    fn numbers(&mut self, key: &str, items: &[Spanned<DeValue<'_>>], ty: Ty) {
        for (i, item) in items.iter().enumerate() {
            self.value(&format!("{key}[{i}]"), item, ty);
        }
    }

    /// A number: finite, within its range.
    fn number(&mut self, key: &str, v: &Spanned<DeValue<'_>>, ty: Ty) {
        let problem = match (number(v.get_ref()), ty) {
            // A whole number past 64 bits is past every range too.
            (Some(Err(_)), Ty::Number(..)) if v.get_ref().is_integer() => Some("is out of range"),
            (Some(Err(why)), _) => Some(why),
            (Some(Ok(x)), Ty::Number(low, max, _)) if !in_range(x, low, max) => Some("is out of range"),
            _ => None,
        };
        if let Some(why) = problem {
            let text = format!("{} {why}: it takes {}", shown(self.text, v), allowed(ty, key));
            self.push(v.span().start, key, text);
        }
    }

    /// A table whose keys depend on its tag: the tag first, then its keys.
    fn tagged(
        &mut self,
        key: &str,
        v: &Spanned<DeValue<'_>>,
        table: &DeTable<'_>,
        tag: &'static str,
        variants: &[(&'static str, &'static [Field])],
    ) {
        let words: Vec<&str> = variants.iter().map(|(w, _)| *w).collect();
        let tag_key = join(key, tag);
        let Some((_, word)) = table.iter().find(|(k, _)| k.get_ref() == tag) else {
            if let Some((k, _)) = table.iter().find(|(k, _)| close(tag, k.get_ref())) {
                let text = format!("no such key in [{key}]; did you mean {tag}? It takes one of {}", one_of(&words));
                return self.push(k.span().start, &join(key, k.get_ref()), text);
            }
            let text = format!("missing: [{key}] needs {tag}, one of {}", one_of(&words));
            return self.push(v.span().start, &tag_key, text);
        };
        let Some((name, fields)) = variants.iter().find(|(w, _)| word.get_ref().as_str() == Some(w)) else {
            let choice = Ty::Choice(&[]);
            let why = if word.get_ref().is_str() { "is not among the choices" } else { kind(word.get_ref(), choice) };
            let text = format!("{} {why}: it takes one of {}", shown(self.text, word), one_of(&words));
            return self.push(word.span().start, &tag_key, text);
        };
        let what = format!("[{key}] with {tag} = \"{name}\"");
        self.table_but(key, v.span().start, table, fields, &what, tag);
    }
}

/// Whether a misspelt key is one edit (or one swap) from a known one, or
/// the known one without its unit (`request` for `request_ms`).
fn close(known: &str, written: &str) -> bool {
    if written.len() >= 3 && known.strip_prefix(written).is_some_and(|unit| unit.starts_with('_')) {
        return true;
    }
    let (a, b): (Vec<char>, Vec<char>) = (known.chars().collect(), written.chars().collect());
    if a.len().abs_diff(b.len()) > 1 {
        return false;
    }
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() && a[i] == b[j] {
        i += 1;
        j += 1;
    }
    let (ra, rb) = (&a[i..], &b[j..]);
    ra.get(1..) == rb.get(1..)
        || ra.get(1..) == Some(rb)
        || Some(ra) == rb.get(1..)
        || (ra.len() >= 2 && rb.len() >= 2 && ra[0] == rb[1] && ra[1] == rb[0] && ra[2..] == rb[2..])
}
