//! The configuration's messages, tried as an attacker would: one-line
//! mutations of every shipped example (and of each as `survey sim` writes it
//! back), every refusal checked for its file, line and dotted key, no Rust
//! type name and no number that was not in the input.

use super::*;
use std::ops::Range;
use toml::de::{DeTable, DeValue};

/// The shipped examples, by name, and each as `survey sim` rewrites it
/// (`toml::to_string` of the table, with a time scale).
fn corpus() -> Vec<(String, String)> {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/config");
    let mut files: Vec<_> = std::fs::read_dir(dir)
        .expect("examples/config")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    let mut out = Vec::new();
    for path in files {
        let text = std::fs::read_to_string(&path).unwrap();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let mut table: toml::Table = text.parse().unwrap();
        let timing = table.entry("timing").or_insert_with(|| toml::Value::Table(toml::Table::new()));
        timing.as_table_mut().unwrap().insert("time_scale".into(), toml::Value::Float(10.0));
        out.push((format!("sim {name}"), toml::to_string(&table).unwrap()));
        out.push((name, text));
    }
    out
}

/// What a mutation did, for the check of the line a refusal names.
#[derive(Debug, Clone)]
enum Kind {
    /// A line removed: the defect may be anywhere.
    Deleted,
    /// The value of `key = value` on the first of these lines (1-based)
    /// changed: a value written over several lines leaves the others.
    Value(Range<usize>),
    /// The key of this line misspelt.
    Misspelt(usize),
    /// This line written twice: the second copy is the line after.
    Duplicated(usize),
    /// A `[table]` header on this line changed.
    Header(usize),
}

const VALUES: [&str; 20] = [
    "\"text\"",
    "7",
    "true",
    "1e400",
    "-1e400",
    "123456789012345678901234567890",
    "-123456789012345678901234567890",
    "-1",
    "0",
    "4.5",
    "1e300",
    "-1e-300",
    "65536",
    "4294967296",
    "{ x = 1 }",
    "[1, 2]",
    "\"\"",
    "nan",
    "2026-01-01",
    "0.0",
];

/// Every one-line mutation of `text`, in a fixed order.
fn mutations(text: &str) -> Vec<(String, Kind)> {
    let lines: Vec<&str> = text.lines().collect();
    let with = |i: usize, replacement: Option<&str>, duplicate: bool| {
        let mut out = String::new();
        for (j, l) in lines.iter().enumerate() {
            if j == i {
                if let Some(r) = replacement {
                    out.push_str(r);
                    out.push('\n');
                }
                if duplicate {
                    out.push_str(l);
                    out.push('\n');
                    out.push_str(l);
                    out.push('\n');
                }
            } else {
                out.push_str(l);
                out.push('\n');
            }
        }
        out
    };
    let mut out = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let n = i + 1;
        out.push((with(i, None, false), Kind::Deleted));
        out.push((with(i, None, true), Kind::Duplicated(n)));
        if let Some(name) = t.strip_prefix('[').and_then(|h| h.strip_suffix(']')) {
            out.push((with(i, Some(&format!("{name} = 1")), false), Kind::Header(n)));
            out.push((with(i, Some(&format!("[{name}x]")), false), Kind::Header(n)));
            continue;
        }
        let Some((key, value)) = line.split_once('=') else { continue };
        if key.trim().is_empty() || key.contains('[') || key.contains('"') {
            continue;
        }
        let key = key.trim();
        // The lines the value spans (a list may go on).
        let mut depth = value.matches('[').count() as i64 - value.matches(']').count() as i64;
        let mut last = n;
        while depth > 0 && last < lines.len() {
            depth += lines[last].matches('[').count() as i64 - lines[last].matches(']').count() as i64;
            last += 1;
        }
        for v in VALUES {
            if v != value.trim() {
                out.push((with(i, Some(&format!("{key} = {v}")), false), Kind::Value(n..last + 1)));
            }
        }
        let mut swapped: Vec<char> = key.chars().collect();
        if swapped.len() > 2 {
            swapped.swap(1, 2);
        }
        let swapped: String = swapped.into_iter().collect();
        for misspelt in [format!("{key}x"), swapped] {
            if misspelt != key {
                out.push((with(i, Some(&format!("{misspelt} ={value}")), false), Kind::Misspelt(n)));
            }
        }
    }
    out
}

fn line_at(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}

/// Every key of a parsed document with the lines its key and value span,
/// and every table with the line of its header (the root: line 1).
struct Places {
    keys: Vec<(String, Range<usize>)>,
    tables: Vec<(String, usize)>,
}

impl Places {
    fn of(text: &str) -> Option<Places> {
        let doc = DeTable::parse(text).ok()?;
        let mut p = Places { keys: Vec::new(), tables: vec![(String::new(), 1)] };
        p.walk(text, doc.get_ref(), "");
        Some(p)
    }

    fn walk(&mut self, text: &str, table: &DeTable<'_>, prefix: &str) {
        for (k, v) in table.iter() {
            let path = if prefix.is_empty() { k.get_ref().to_string() } else { format!("{prefix}.{}", k.get_ref()) };
            let (ks, vs) = (k.span(), v.span());
            let lines = line_at(text, ks.start.min(vs.start))..line_at(text, vs.end.max(ks.end).saturating_sub(1)) + 1;
            self.keys.push((path.clone(), lines));
            match v.get_ref() {
                DeValue::Table(t) => {
                    self.tables.push((path.clone(), line_at(text, vs.start)));
                    self.walk(text, t, &path);
                }
                DeValue::Array(a) => {
                    for item in a.iter() {
                        if let DeValue::Table(t) = item.get_ref() {
                            self.walk(text, t, &path);
                        }
                    }
                }
                _ => {}
            }
        }
    }

    /// `key` is written on `line`, or is missing from the table whose header is there.
    fn names(&self, key: &str, line: usize) -> bool {
        let key = key.split('[').next().unwrap_or(key);
        let parent = key.rsplit_once('.').map_or("", |(p, _)| p);
        self.keys.iter().any(|(k, lines)| k == key && lines.contains(&line))
            || self.tables.iter().any(|(t, l)| t == parent && *l == line)
    }
}

/// Words of Rust (and serde's) types a reader was never told about.
const TYPE_WORDS: [&str; 22] = [
    "u8", "u16", "u32", "u64", "u128", "i8", "i16", "i32", "i64", "i128", "f32", "f64", "usize", "isize", "struct",
    "enum", "Option", "Vec", "String", "bool", "str", "tuple",
];

/// The defects of one refusal (empty when it is as it should be).
fn defects(file: &str, text: &str, kind: &Kind, message: &str) -> Vec<&'static str> {
    let mut found = Vec::new();
    let strict = message.strip_prefix(file).and_then(|m| m.strip_prefix(':')).and_then(|m| {
        let (line, rest) = m.split_once(": ")?;
        let (key, what) = rest.split_once(": ")?;
        let ok = !key.is_empty() && key.chars().all(|c| c.is_ascii_alphanumeric() || "_-.[]".contains(c));
        Some((line.parse::<usize>().ok()?, key.to_string(), what)).filter(|_| ok)
    });
    let parsed = match strict {
        Some(p) => Some(p),
        None => {
            found.push("not FILE:LINE: key: ...");
            lenient(file, message)
        }
    };
    match parsed {
        None => found.push("no line"),
        Some((line, key, what)) => {
            let key = key.as_str();
            let places = Places::of(text);
            let named = match &places {
                Some(p) => p.names(key, line),
                // Not TOML: the key of the line the parser stopped at, or
                // the table that line belongs to.
                None => {
                    let last = key.rsplit(['.', '[']).next().unwrap_or(key).trim_end_matches(']');
                    let table = text
                        .lines()
                        .take(line)
                        .filter_map(|l| l.trim().strip_prefix('[').map(|h| h.trim_matches(['[', ']'])))
                        .last()
                        .unwrap_or("");
                    (!last.is_empty() && text.lines().nth(line.wrapping_sub(1)).is_some_and(|l| l.contains(last)))
                        || key == table
                        || key.starts_with(&format!("{table}."))
                }
            };
            if !named {
                found.push("the key is not on that line");
            }
            let target = match kind {
                Kind::Value(lines) => Some(lines.clone()),
                Kind::Misspelt(n) => Some(*n..*n + 1),
                Kind::Duplicated(n) => Some(*n..*n + 2),
                // A header changed moves the keys after it: the defect shows there.
                Kind::Header(n) => Some(*n..usize::MAX),
                Kind::Deleted => None,
            };
            if let Some(t) = target
                && !t.contains(&line)
                && !(t.end < usize::MAX && t.clone().any(|n| what.contains(&format!("line {n}"))))
            {
                found.push("the wrong line");
            }
            if what.split_whitespace().count() < 3 {
                found.push("says nothing of what is allowed");
            }
        }
    }
    if message.contains("is not accepted here") {
        found.push("serde refused what the schema let through");
    }
    let words: Vec<&str> = message.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).collect();
    if words.iter().any(|w| TYPE_WORDS.contains(w)) || words.iter().any(|w| camel_case(w) && !text.contains(w)) {
        found.push("a Rust type name");
    }
    let mut digits = String::new();
    for c in message.chars().chain([' ']) {
        if c.is_ascii_digit() {
            digits.push(c);
        } else {
            if digits.len() >= 20 && !text.contains(&digits) {
                found.push("a long number not in the input");
            }
            digits.clear();
        }
    }
    found
}

/// The messages before this test (`FILE: line N: text`, `FILE: text`),
/// read as kindly as can be for the count of their defects: the line, and
/// the first word of the text that looks like a dotted key.
fn lenient<'m>(file: &str, message: &'m str) -> Option<(usize, String, &'m str)> {
    let rest = message.strip_prefix(file)?.strip_prefix(": ")?;
    let (line, what) = rest.strip_prefix("line ")?.split_once(": ")?;
    let key = what
        .split(|c: char| c.is_whitespace() || "`'=,()".contains(c))
        .find(|w| w.contains('.') && w.chars().next().is_some_and(|c| c.is_ascii_lowercase()))
        .unwrap_or("");
    Some((line.parse().ok()?, key.to_string(), what))
}

/// `ModbusTimeouts`, `RegisterMap`: a Rust type's name (not `SocketCAN`, `CANopen`).
fn camel_case(w: &str) -> bool {
    let mut chars = w.chars();
    chars.next().is_some_and(|c| c.is_ascii_uppercase())
        && w.chars().skip(1).any(|c| c.is_ascii_uppercase())
        && w.chars().any(|c| c.is_ascii_lowercase())
        && !["SocketCAN", "CANopen", "MI", "emScon"].contains(&w)
}

#[test]
fn every_refusal_of_a_mutated_example_names_its_file_line_and_key_in_words() {
    let (mut tried, mut refused, mut bad, mut accepted) = (0u64, 0, 0, 0xcbf2_9ce4_8422_2325u64);
    let mut by_kind: std::collections::BTreeMap<&str, usize> = Default::default();
    let mut shown = Vec::new();
    for (name, text) in corpus() {
        SurveyConfig::parse(&text, "c.toml").unwrap_or_else(|e| panic!("{name}: {e}"));
        for (mutated, kind) in mutations(&text) {
            tried += 1;
            if let Ok(path) = std::env::var("CONFIG_OUTCOMES") {
                use std::io::Write;
                let outcome = SurveyConfig::parse(&mutated, "c.toml").map_or_else(|e| e.to_string(), |_| "ok".into());
                let mut f = std::fs::OpenOptions::new().create(true).append(true).open(path).unwrap();
                writeln!(f, "{tried}\t{name}\t{kind:?}\t{}\t{outcome}", mutated.len()).unwrap();
            }
            let Err(e) = SurveyConfig::parse(&mutated, "c.toml") else {
                // Which mutations load, as a fingerprint: unchanged by the messages.
                accepted = accepted.wrapping_mul(0x100_0000_01b3) ^ tried;
                continue;
            };
            refused += 1;
            let message = e.to_string();

            let found = defects("c.toml", &mutated, &kind, &message);
            if !found.is_empty() {
                bad += 1;
                for d in &found {
                    *by_kind.entry(d).or_default() += 1;
                }
                if shown.len() < 40 {
                    shown.push(format!("{name} {kind:?}: {found:?}\n    {message}"));
                }
            }
        }
    }
    eprintln!("{tried} mutations, {refused} refusals, {bad} with defects: {by_kind:?}; accepted {accepted:x}");
    assert_eq!(bad, 0, "{tried} mutations, {refused} refusals, {bad} defective: {by_kind:?}\n{}", shown.join("\n"));
    assert!(tried > 2000 && refused > tried / 2, "{tried} mutations, {refused} refusals");
}
