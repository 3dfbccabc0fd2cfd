//! Where each key of a configuration is written: its line and its value as
//! written, from the spans of the parsed document (`toml::de::DeTable`), for
//! messages of the form `FILE:LINE: dotted.key: what is wrong`.

use std::collections::BTreeMap;
use toml::de::{DeTable, DeValue};

/// One defect of a configuration: the line, the dotted key, what is wrong
/// and what is allowed, in words.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Defect {
    pub line: usize,
    pub key: String,
    pub text: String,
}

/// The 1-based line of a byte offset.
pub(super) fn line_at(text: &str, offset: usize) -> usize {
    text.as_bytes()[..offset.min(text.len())].iter().filter(|&&b| b == b'\n').count() + 1
}

/// The dotted key of `key` in the table `path` (the root: "").
pub(super) fn join(path: &str, key: &str) -> String {
    if path.is_empty() { key.to_string() } else { format!("{path}.{key}") }
}

/// Every key of a document with the line it is written on and its value as
/// written, and every table with the line of its header (the root: line 1).
#[derive(Debug, Default)]
pub(super) struct Places {
    keys: BTreeMap<String, (usize, String)>,
    tables: Vec<(String, usize)>,
}

impl Places {
    pub fn of(text: &str, doc: &DeTable<'_>) -> Places {
        let mut p = Places { keys: BTreeMap::new(), tables: vec![(String::new(), 1)] };
        p.walk(text, doc, "");
        p
    }

    fn walk(&mut self, text: &str, table: &DeTable<'_>, prefix: &str) {
        for (k, v) in table.iter() {
            let path = join(prefix, k.get_ref());
            let vs = v.span();
            let written = text.get(vs.clone()).unwrap_or_default().trim().to_string();
            self.keys.insert(path.clone(), (line_at(text, k.span().start), written));
            if let DeValue::Table(t) = v.get_ref() {
                self.tables.push((path.clone(), line_at(text, vs.start)));
                self.walk(text, t, &path);
            }
        }
    }

    /// Whether `key` is written in the file.
    pub fn has(&self, key: &str) -> bool {
        self.keys.contains_key(key)
    }

    /// The value of `key` as written, if it is.
    pub fn written(&self, key: &str) -> Option<&str> {
        self.keys.get(key).map(|(_, w)| w.as_str())
    }

    /// The line of `key` if it is written, else of the header of the
    /// nearest table it belongs to that is, with the key to name there: the
    /// key itself, or the first of its tables that the file lacks (a
    /// missing `[survey]`'s `reference` is named `survey`, at line 1).
    pub fn locate(&self, key: &str) -> (usize, String) {
        if let Some((line, _)) = self.keys.get(key) {
            return (*line, key.to_string());
        }
        let mut named = key;
        let mut parent = key.rsplit_once('.').map_or("", |(p, _)| p);
        loop {
            if let Some((_, line)) = self.tables.iter().find(|(t, _)| t == parent) {
                return (*line, named.to_string());
            }
            named = parent;
            parent = parent.rsplit_once('.').map_or("", |(p, _)| p);
        }
    }

    /// A defect of `key`, at its line (see [`Self::locate`]).
    pub fn defect(&self, key: &str, text: impl Into<String>) -> Defect {
        let (line, key) = self.locate(key);
        Defect { line, key, text: text.into() }
    }

    /// `key` as a reader finds it: `name = value (line N)`, or `name (the
    /// default, D)` when the file does not write it.
    pub fn cite(&self, key: &str, default: &str) -> String {
        match self.keys.get(key) {
            Some((line, written)) => format!("{key} = {written} (line {line})"),
            None => format!("{key} (not given: {default})"),
        }
    }

    /// The deepest key written on `line`, if any.
    fn key_on(&self, line: usize) -> Option<&str> {
        self.keys.iter().filter(|(_, (l, _))| *l == line).map(|(k, _)| k.as_str()).max_by_key(|k| k.len())
    }

    /// The table a line belongs to: the last header at or before it.
    fn table_at(&self, line: usize) -> &str {
        self.tables.iter().filter(|(_, l)| *l <= line).max_by_key(|(_, l)| *l).map_or("", |(t, _)| t.as_str())
    }
}

/// What a reader is told of text that is not TOML: the line, the key
/// written there (or the table the line belongs to) and the parser's reason.
pub(super) fn syntax(text: &str, e: &toml::de::Error) -> Defect {
    let line = e.span().map_or(1, |s| line_at(text, s.start));
    let (doc, _) = DeTable::parse_recoverable(text);
    let places = Places::of(text, doc.get_ref());
    let written = text.lines().nth(line - 1).unwrap_or_default().trim();
    // The key the line writes, in the table it belongs to.
    let bare = written
        .split_once('=')
        .map(|(k, _)| k.trim())
        .filter(|k| !k.is_empty() && k.chars().all(|c| c.is_ascii_alphanumeric() || "_-.".contains(c)));
    let header = written.strip_prefix('[').map(|h| h.trim_matches(['[', ']', ' ']));
    let key = match (bare, header) {
        (Some(k), _) => join(places.table_at(line), k),
        (None, Some(h)) if !h.is_empty() => h.to_string(),
        _ => match places.key_on(line) {
            Some(k) => k.to_string(),
            None if places.table_at(line).is_empty() => "(top level)".to_string(),
            None => places.table_at(line).to_string(),
        },
    };
    let text = if e.message().trim() == "duplicate key" {
        match places.keys.get(&key).map(|(l, _)| *l).filter(|l| *l != line) {
            Some(first) => format!("written twice (first on line {first}): each key and table is written once"),
            None => "written twice: each key and table is written once".to_string(),
        }
    } else {
        format!("this line is not valid TOML: {}", e.message().trim())
    };
    Defect { line, key, text }
}

/// What a reader is told when serde refuses what the schema let through
/// (nothing should reach it): the line and the key there, without serde's
/// words for Rust types.
pub(super) fn unexpected(text: &str, places: &Places, e: &toml::de::Error) -> Defect {
    let line = e.span().map_or(1, |s| line_at(text, s.start));
    let key = places.key_on(line).map_or_else(|| places.table_at(line).to_string(), str::to_string);
    let key = if key.is_empty() { "(top level)".to_string() } else { key };
    Defect { line, key, text: "this value is not accepted here (see docs/configuration.md for what is)".into() }
}
