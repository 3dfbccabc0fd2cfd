//! The survey CSV format of `survey import` and `survey export`.
//!
//! Header `run,direction,target_deg,readout_deg,actual_deg`, optionally
//! followed by `timestamp_s`; one row per sample, in acquisition order. `run` is
//! an integer from 1, `direction` is `forward` or `reverse`, the numbers are
//! finite decimals. Cells are trimmed; a `timestamp_s` cell may be empty. LF and
//! CRLF line endings and a UTF-8 byte order mark are accepted.
//!
//! A bad file gives a [`CsvError`] naming the file, the physical line and what
//! is wrong, e.g. `data.csv:7: column 'readout_deg': 'abc' is not a number`.
//! A run holds one sample per target and direction: a second one is refused
//! on its line, naming the line of the first (the statistics could not use
//! the survey).
//! [`write_survey_csv`] writes every number with Rust's shortest round-trip
//! formatting, so parsing an export gives back every value bit for bit.

use std::io::Write;
use std::path::Path;

use survey_processing::iso230::TARGET_TOLERANCE_DEG;
use survey_processing::num::Num;
use survey_processing::{Direction, Sample};

/// The required columns, in order.
pub const REQUIRED_COLUMNS: [&str; 5] = ["run", "direction", "target_deg", "readout_deg", "actual_deg"];
/// The optional last column.
pub const TIMESTAMP_COLUMN: &str = "timestamp_s";

const HEADER_HELP: &str = "header must be run,direction,target_deg,readout_deg,actual_deg[,timestamp_s]";

/// A defect in a survey CSV file. Displays as `{file}:{line}: {what}`, or
/// `{file}: {what}` when the defect is not on one line (an empty file).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{file}{}: {what}", line.map(|l| format!(":{l}")).unwrap_or_default())]
pub struct CsvError {
    /// The file as the user named it.
    pub file: String,
    /// The physical line (from 1), when the defect is on one.
    pub line: Option<u64>,
    /// What is wrong.
    pub what: String,
}

impl CsvError {
    fn at(file: &str, line: u64, what: impl Into<String>) -> Self {
        CsvError { file: file.to_string(), line: Some(line), what: what.into() }
    }

    fn whole(file: &str, what: impl Into<String>) -> Self {
        CsvError { file: file.to_string(), line: None, what: what.into() }
    }
}

/// Read and parse the survey CSV file at `path` (named in errors as given).
/// A file that cannot be read or is not UTF-8 is a [`CsvError`] too.
pub fn read_survey_csv(path: &Path) -> Result<Vec<Sample>, CsvError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| CsvError::whole(&name, format!("cannot read: {e}")))?;
    let text = match String::from_utf8(bytes) {
        Ok(t) => t,
        Err(e) => {
            let good = &e.as_bytes()[..e.utf8_error().valid_up_to()];
            let line = 1 + good.iter().filter(|&&b| b == b'\n').count() as u64;
            return Err(CsvError::at(&name, line, "not valid UTF-8 text"));
        }
    };
    parse_survey_csv(&text, &name)
}

/// Parse a survey CSV document; `source` names it in errors (the file name).
pub fn parse_survey_csv(text: &str, source: &str) -> Result<Vec<Sample>, CsvError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    if text.trim().is_empty() {
        return Err(CsvError::whole(source, "the file is empty"));
    }
    let mut rdr =
        csv::ReaderBuilder::new().has_headers(true).trim(csv::Trim::All).flexible(false).from_reader(text.as_bytes());

    let header = rdr.headers().map_err(|e| from_csv_error(text, source, e))?.clone();
    let has_timestamp = check_header(&header).map_err(|w| {
        let line = line_of(text, header.position().map_or(0, |p| p.byte()));
        CsvError::at(source, line, w)
    })?;

    let mut samples = Vec::new();
    let mut lines = Vec::new();
    let mut counted = Lines::new(text);
    for rec in rdr.records() {
        let rec = rec.map_err(|e| from_csv_error(text, source, e))?;
        let line = counted.line_at(rec.position().map_or(0, |p| p.byte()));
        let sample = parse_row(&rec, has_timestamp).map_err(|w| CsvError::at(source, line, w))?;
        samples.push(sample);
        lines.push(line);
    }
    if samples.is_empty() {
        return Err(CsvError::whole(source, "no samples after the header"));
    }
    if let Some((first, again)) = repeated(&samples) {
        let s = &samples[again];
        return Err(CsvError::at(
            source,
            lines[again],
            format!(
                "run {}, {}, target {} deg is on line {} already: a run gives one sample per target and direction",
                s.run,
                s.direction,
                Num(s.target_deg),
                lines[first]
            ),
        ));
    }
    Ok(samples)
}

/// The first pair of samples of one run, direction and target (targets
/// within [`TARGET_TOLERANCE_DEG`] are one, as the statistics group them),
/// by index `(earlier, later)`, the later as early in the file as can be.
fn repeated(samples: &[Sample]) -> Option<(usize, usize)> {
    let mut order: Vec<usize> = (0..samples.len()).collect();
    let key = |i: usize| (samples[i].run, samples[i].direction == Direction::Reverse);
    order.sort_by(|&a, &b| key(a).cmp(&key(b)).then(samples[a].target_deg.total_cmp(&samples[b].target_deg)));
    order
        .windows(2)
        .filter(|w| {
            key(w[0]) == key(w[1]) && samples[w[1]].target_deg - samples[w[0]].target_deg <= TARGET_TOLERANCE_DEG
        })
        .map(|w| (w[0].min(w[1]), w[0].max(w[1])))
        .min_by_key(|&(_, later)| later)
}

/// Check the header; `Ok(true)` when it has the `timestamp_s` column.
fn check_header(header: &csv::StringRecord) -> Result<bool, String> {
    let names: Vec<&str> = header.iter().collect();
    for required in REQUIRED_COLUMNS {
        if !names.contains(&required) {
            return Err(format!("missing column '{required}' ({HEADER_HELP})"));
        }
    }
    for name in &names {
        if !REQUIRED_COLUMNS.contains(name) && *name != TIMESTAMP_COLUMN {
            return Err(format!("unexpected column '{name}' ({HEADER_HELP})"));
        }
    }
    for (i, name) in names.iter().enumerate() {
        if names[..i].contains(name) {
            return Err(format!("column '{name}' appears twice ({HEADER_HELP})"));
        }
    }
    let expected_order = REQUIRED_COLUMNS.iter().chain([TIMESTAMP_COLUMN].iter());
    if !names.iter().zip(expected_order).all(|(a, b)| a == b) {
        return Err(format!("columns out of order: found {} ({HEADER_HELP})", names.join(",")));
    }
    Ok(names.len() == REQUIRED_COLUMNS.len() + 1)
}

/// The largest angle a survey CSV may hold, in magnitude, degrees.
pub const MAX_ABS_ANGLE_DEG: f64 = 1.0e6;
/// The largest timestamp, in magnitude, seconds.
pub const MAX_ABS_TIME_S: f64 = 1.0e12;
/// The highest run number.
pub const MAX_RUN: u32 = 10_000;

fn parse_row(rec: &csv::StringRecord, has_timestamp: bool) -> Result<Sample, String> {
    let cell = |i: usize| rec.get(i).unwrap_or("");
    let run_text = cell(0);
    let run = match run_text.parse::<u32>() {
        Ok(r) if (1..=MAX_RUN).contains(&r) => r,
        _ => {
            return Err(format!("column 'run': '{run_text}' is not a run number (an integer from 1 to {MAX_RUN})"));
        }
    };
    let direction = cell(1).parse::<Direction>().map_err(|e| format!("column 'direction': {e}"))?;
    let number = |i: usize| -> Result<f64, String> {
        let name = REQUIRED_COLUMNS.get(i).copied().unwrap_or(TIMESTAMP_COLUMN);
        let text = cell(i);
        if text.is_empty() {
            return Err(format!("column '{name}' is empty"));
        }
        // Angles within a million degrees (about 2800 turns) and times within
        // 1e12 s (Unix time fits): beyond that a value is a unit or typing
        // error, and its squares would overflow the statistics.
        let limit = if name == TIMESTAMP_COLUMN { MAX_ABS_TIME_S } else { MAX_ABS_ANGLE_DEG };
        match text.parse::<f64>() {
            Ok(v) if v.is_finite() && v.abs() <= limit => Ok(v),
            Ok(v) if v.is_finite() => Err(format!("column '{name}': {text} is outside -{limit:e}..={limit:e}")),
            Ok(_) => Err(format!("column '{name}': '{text}' is not a finite number")),
            Err(_) => Err(format!("column '{name}': '{text}' is not a number")),
        }
    };
    let target_deg = number(2)?;
    let readout_deg = number(3)?;
    let actual_deg = number(4)?;
    let timestamp_s = if has_timestamp && !cell(5).is_empty() { Some(number(5)?) } else { None };
    Ok(Sample { run, direction, target_deg, readout_deg, actual_deg, timestamp_s })
}

/// The physical line (from 1) of the record the csv reader says starts at byte
/// `start`. (The reader's own line count is off after CRLF endings and blank
/// lines, and its record offsets point at the line breaks before the record.)
/// LF, CRLF and a lone CR each end a line.
fn line_of(text: &str, start: u64) -> u64 {
    Lines::new(text).line_at(start)
}

/// Physical lines counted forward as the reader goes: records come in file
/// order, so each byte is counted once for the whole file ([`line_of`]'s rule;
/// a position before the last one asked counts again from the start).
#[derive(Debug)]
struct Lines<'a> {
    bytes: &'a [u8],
    /// Where counting stopped, and the line breaks before it.
    at: usize,
    breaks: u64,
}

impl<'a> Lines<'a> {
    fn new(text: &'a str) -> Self {
        Lines { bytes: text.as_bytes(), at: 0, breaks: 0 }
    }

    /// The line of the record that starts at byte `start` (see [`line_of`]).
    fn line_at(&mut self, start: u64) -> u64 {
        let bytes = self.bytes;
        let mut to = usize::try_from(start).unwrap_or(usize::MAX).min(bytes.len());
        while to < bytes.len() && (bytes[to] == b'\n' || bytes[to] == b'\r') {
            to += 1;
        }
        if to < self.at {
            (self.at, self.breaks) = (0, 0);
        }
        self.breaks += (self.at..to)
            .filter(|&i| bytes[i] == b'\n' || (bytes[i] == b'\r' && bytes.get(i + 1) != Some(&b'\n')))
            .count() as u64;
        self.at = to;
        1 + self.breaks
    }
}

fn from_csv_error(text: &str, source: &str, e: csv::Error) -> CsvError {
    match e.kind() {
        csv::ErrorKind::UnequalLengths { pos, expected_len, len } => {
            let what =
                format!("the row has {len} field{}, the header has {expected_len}", if *len == 1 { "" } else { "s" });
            match pos {
                Some(p) => CsvError::at(source, line_of(text, p.byte()), what),
                None => CsvError::whole(source, what),
            }
        }
        csv::ErrorKind::Utf8 { pos, .. } => match pos {
            Some(p) => CsvError::at(source, line_of(text, p.byte()), "not valid UTF-8 text"),
            None => CsvError::whole(source, "not valid UTF-8 text"),
        },
        _ => match e.position() {
            Some(p) => CsvError::at(source, line_of(text, p.byte()), e.to_string()),
            None => CsvError::whole(source, e.to_string()),
        },
    }
}

/// Write samples in the survey CSV format: the header (with `timestamp_s` when
/// any sample has a timestamp; an empty cell for those that have none), then one
/// row per sample in the given order. Numbers use Rust's shortest round-trip
/// formatting (`format!("{}", v)`): parsing the output gives back every value bit
/// for bit. Lines end with `\n`.
pub fn write_survey_csv<W: Write>(w: W, samples: &[Sample]) -> std::io::Result<()> {
    let with_timestamp = samples.iter().any(|s| s.timestamp_s.is_some());
    let mut wtr = csv::WriterBuilder::new().terminator(csv::Terminator::Any(b'\n')).from_writer(w);
    let mut header: Vec<&str> = REQUIRED_COLUMNS.to_vec();
    if with_timestamp {
        header.push(TIMESTAMP_COLUMN);
    }
    wtr.write_record(&header)?;
    let mut row: Vec<String> = Vec::with_capacity(6);
    for s in samples {
        row.clear();
        row.push(s.run.to_string());
        row.push(s.direction.as_str().to_string());
        row.push(format!("{}", s.target_deg));
        row.push(format!("{}", s.readout_deg));
        row.push(format!("{}", s.actual_deg));
        if with_timestamp {
            row.push(s.timestamp_s.map(|t| format!("{t}")).unwrap_or_default());
        }
        wtr.write_record(&row)?;
    }
    wtr.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const HEADER: &str = "run,direction,target_deg,readout_deg,actual_deg";

    fn err(text: &str) -> String {
        parse_survey_csv(text, "data.csv").unwrap_err().to_string()
    }

    fn bits(s: &Sample) -> (u32, Direction, u64, u64, u64, Option<u64>) {
        (
            s.run,
            s.direction,
            s.target_deg.to_bits(),
            s.readout_deg.to_bits(),
            s.actual_deg.to_bits(),
            s.timestamp_s.map(f64::to_bits),
        )
    }

    #[test]
    fn numbers_outside_their_physical_range_are_refused_with_the_line() {
        let e = err(&format!("{HEADER}\n1,forward,0,0,0.001\n1,forward,180,180,1e308\n"));
        assert_eq!(e, "data.csv:3: column 'actual_deg': 1e308 is outside -1e6..=1e6");
        let e = err(&format!("{HEADER}\n99999,forward,0,0,0.001\n"));
        assert!(e.starts_with("data.csv:2: column 'run'") && e.contains("1 to 10000"), "{e}");
        let e = err(&format!("{HEADER},timestamp_s\n1,forward,0,0,0.001,1e13\n"));
        assert!(e.starts_with("data.csv:2: column 'timestamp_s': 1e13 is outside"), "{e}");
        assert!(parse_survey_csv(&format!("{HEADER},timestamp_s\n1,forward,-999999,0,0.001,1.7e9\n"), "d").is_ok());
    }

    #[test]
    fn a_second_sample_of_a_run_direction_and_target_is_refused_naming_both_lines() {
        let rows = "1,forward,0,0,0.001\n1,forward,90,90,90.001\n1,reverse,90,90,89.999\n2,forward,0,0,0.002\n";
        assert!(
            parse_survey_csv(&format!("{HEADER}\n{rows}"), "d").is_ok(),
            "other runs and directions repeat a target"
        );
        let e = err(&format!("{HEADER}\n{rows}2,forward,90,90,90.002\n1,forward,90,90,90.003\n"));
        assert_eq!(
            e,
            "data.csv:7: run 1, forward, target 90 deg is on line 3 already: a run gives one sample per target and \
             direction"
        );
        // Targets the statistics take as one (within 1e-9 deg) are one.
        let e = err(&format!("{HEADER}\n{rows}1,reverse,90.0000000001,90,89.998\n"));
        assert!(e.starts_with("data.csv:6: run 1, reverse, target 90.0000000001 deg is on line 4 already"), "{e}");
    }

    fn assert_bit_equal(a: &[Sample], b: &[Sample]) {
        assert_eq!(a.len(), b.len());
        for (x, y) in a.iter().zip(b) {
            assert_eq!(bits(x), bits(y), "{x:?} != {y:?}");
        }
    }

    #[test]
    fn parses_a_plain_file() {
        let text = format!("{HEADER}\n1,forward,0,0.001,0\n1,reverse,30,30.5,30.25\n");
        let s = parse_survey_csv(&text, "data.csv").unwrap();
        assert_eq!(s.len(), 2);
        assert_eq!(
            s[1],
            Sample {
                run: 1,
                direction: Direction::Reverse,
                target_deg: 30.0,
                readout_deg: 30.5,
                actual_deg: 30.25,
                timestamp_s: None
            }
        );
    }

    #[test]
    fn timestamps_may_be_empty_on_some_rows() {
        let text = format!("{HEADER},timestamp_s\n1,forward,0,0,0,1.5\n1,forward,1,1,1,\n2,reverse,2,2,2,3\n");
        let s = parse_survey_csv(&text, "data.csv").unwrap();
        assert_eq!(s[0].timestamp_s, Some(1.5));
        assert_eq!(s[1].timestamp_s, None);
        assert_eq!(s[2].timestamp_s, Some(3.0));
        assert_eq!(s[2].run, 2);
    }

    #[test]
    fn crlf_bom_and_spaces_are_accepted() {
        let text = format!("\u{feff}{HEADER}\r\n1, forward ,0,0.5,0.25\r\n2,reverse, 1 ,1,1\r\n");
        let s = parse_survey_csv(&text, "data.csv").unwrap();
        assert_eq!(s.len(), 2);
        assert_eq!(s[0].direction, Direction::Forward);
        assert_eq!(s[1].target_deg, 1.0);
        // errors on a CRLF file still count physical lines
        let text = format!("{HEADER}\r\n1,forward,0,0,0\r\n1,forward,0,x,0\r\n");
        assert_eq!(err(&text), "data.csv:3: column 'readout_deg': 'x' is not a number");
    }

    #[test]
    fn line_numbers_count_blank_lines_and_every_line_ending() {
        let text = format!("\n\n{HEADER}\n1,forward,0,0,0\n\n\n1,forward,0,0,x\n");
        assert_eq!(err(&text), "data.csv:7: column 'actual_deg': 'x' is not a number");
        let text = format!("{HEADER}\r\n\r\n1,forward,0,0,0\r\n1,forward,0,0\r\n");
        assert_eq!(err(&text), "data.csv:4: the row has 4 fields, the header has 5");
        let text = format!("{HEADER}\r1,forward,0,0,0\r1,backward,0,0,0\r");
        assert!(err(&text).starts_with("data.csv:3: column 'direction'"), "{}", err(&text));
        let text = "\r\n\r\nrun,direction\r\n".to_string();
        assert!(err(&text).starts_with("data.csv:3: missing column 'target_deg'"), "{}", err(&text));
    }

    #[test]
    fn bad_number_names_column_and_line() {
        let mut text = format!("{HEADER}\n");
        for i in 0..5 {
            text.push_str(&format!("1,forward,{i},{i},{i}\n"));
        }
        text.push_str("1,forward,5,abc,5\n");
        assert_eq!(err(&text), "data.csv:7: column 'readout_deg': 'abc' is not a number");
    }

    #[test]
    fn missing_column() {
        assert_eq!(
            err("run,direction,target_deg,readout_deg\n1,forward,0,0\n"),
            "data.csv:1: missing column 'actual_deg' (header must be \
             run,direction,target_deg,readout_deg,actual_deg[,timestamp_s])"
        );
    }

    #[test]
    fn extra_duplicate_and_misordered_columns() {
        let e = err(&format!("{HEADER},temperature\n1,forward,0,0,0,20\n"));
        assert!(e.starts_with("data.csv:1: unexpected column 'temperature' (header must be"), "{e}");
        let e = err(&format!("{HEADER},timestamp_s,timestamp_s\n1,forward,0,0,0,1,1\n"));
        assert!(e.starts_with("data.csv:1: column 'timestamp_s' appears twice"), "{e}");
        let e = err("direction,run,target_deg,readout_deg,actual_deg\nforward,1,0,0,0\n");
        assert!(e.starts_with("data.csv:1: columns out of order: found direction,run,"), "{e}");
        // the header is on line 3 after two blank lines
        let e = err("\n\nrun,direction\n1,forward\n");
        assert!(e.starts_with("data.csv:3: missing column 'target_deg'"), "{e}");
    }

    #[test]
    fn unknown_direction() {
        let text = format!("{HEADER}\n1,forward,0,0,0\n1,fwd,0,0,0\n");
        assert_eq!(
            err(&text),
            "data.csv:3: column 'direction': unknown direction 'fwd' (expected 'forward' or 'reverse')"
        );
    }

    #[test]
    fn bad_run_numbers() {
        for bad in ["0", "-1", "1.5", "x", ""] {
            let text = format!("{HEADER}\n1,forward,0,0,0\n1,forward,0,0,0\n{bad},forward,0,0,0\n");
            assert_eq!(
                err(&text),
                format!("data.csv:4: column 'run': '{bad}' is not a run number (an integer from 1 to 10000)")
            );
        }
    }

    #[test]
    fn empty_files() {
        assert_eq!(err(""), "data.csv: the file is empty");
        assert_eq!(err("\n\n  \r\n"), "data.csv: the file is empty");
        assert_eq!(err("\u{feff}"), "data.csv: the file is empty");
        assert_eq!(err(&format!("{HEADER}\n")), "data.csv: no samples after the header");
        assert_eq!(err(&format!("{HEADER},timestamp_s")), "data.csv: no samples after the header");
    }

    #[test]
    fn wrong_field_count() {
        let text = format!("{HEADER}\n1,forward,0,0,0\n1,forward,0,0\n");
        assert_eq!(err(&text), "data.csv:3: the row has 4 fields, the header has 5");
        let text = format!("{HEADER}\n1,forward,0,0,0,7\n");
        assert_eq!(err(&text), "data.csv:2: the row has 6 fields, the header has 5");
    }

    #[test]
    fn non_finite_and_empty_numbers() {
        for (bad, col) in [("nan", 2), ("inf", 3), ("-inf", 4), ("NaN", 2), ("infinity", 4)] {
            let mut cells = ["1", "forward", "0", "0", "0"];
            cells[col] = bad;
            let text = format!("{HEADER}\n{}\n", cells.join(","));
            assert_eq!(
                err(&text),
                format!("data.csv:2: column '{}': '{bad}' is not a finite number", REQUIRED_COLUMNS[col])
            );
        }
        let text = format!("{HEADER},timestamp_s\n1,forward,0,0,0,nan\n");
        assert_eq!(err(&text), "data.csv:2: column 'timestamp_s': 'nan' is not a finite number");
        let text = format!("{HEADER}\n1,forward,0,,0\n");
        assert_eq!(err(&text), "data.csv:2: column 'readout_deg' is empty");
    }

    #[test]
    fn quoted_cells_and_line_numbers_after_multiline_quotes() {
        let text = format!("{HEADER}\n\"1\",\"forward\",\"0\",\"0\",\"0\"\n1,forward,0,0,0\n1,forward,0,\"a\nb\",0\n");
        assert_eq!(err(&text), "data.csv:4: column 'readout_deg': 'a\nb' is not a number");
    }

    #[test]
    fn read_file_names_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.csv");
        std::fs::write(&path, format!("{HEADER}\n1,forward,0,0,0\n1,up,0,0,0\n")).unwrap();
        let e = read_survey_csv(&path).unwrap_err();
        assert_eq!(e.line, Some(3));
        assert!(e.to_string().starts_with(&format!("{}:3: column 'direction'", path.display())));

        std::fs::write(&path, b"run,direction,target_deg,readout_deg,actual_deg\n1,forward,\xff,0,0\n").unwrap();
        let e = read_survey_csv(&path).unwrap_err();
        assert_eq!(e.line, Some(2));
        assert!(e.to_string().ends_with(":2: not valid UTF-8 text"), "{e}");

        let e = read_survey_csv(&dir.path().join("missing.csv")).unwrap_err();
        assert_eq!(e.line, None);
        assert!(e.to_string().contains("missing.csv: cannot read"), "{e}");
    }

    #[test]
    fn write_header_and_round_trip_with_and_without_timestamps() {
        let mut samples = vec![
            Sample {
                run: 1,
                direction: Direction::Forward,
                target_deg: 0.0,
                readout_deg: -0.0,
                actual_deg: 0.1 + 0.2,
                timestamp_s: None,
            },
            Sample {
                run: 3,
                direction: Direction::Reverse,
                target_deg: 359.99999999999994,
                readout_deg: 1e-300,
                actual_deg: -MAX_ABS_ANGLE_DEG,
                timestamp_s: None,
            },
        ];
        let mut out = Vec::new();
        write_survey_csv(&mut out, &samples).unwrap();
        let text = String::from_utf8(out).unwrap();
        assert!(text.starts_with(&format!("{HEADER}\n1,forward,0,-0,0.30000000000000004\n")), "{text}");
        assert_bit_equal(&parse_survey_csv(&text, "x").unwrap(), &samples);

        samples[1].timestamp_s = Some(12.25);
        let mut out = Vec::new();
        write_survey_csv(&mut out, &samples).unwrap();
        let text = String::from_utf8(out).unwrap();
        assert!(text.starts_with(&format!("{HEADER},timestamp_s\n1,forward,0,-0,0.30000000000000004,\n")));
        assert_bit_equal(&parse_survey_csv(&text, "x").unwrap(), &samples);
    }

    /// Any value a survey CSV may hold: every bit pattern of the range.
    fn finite() -> impl Strategy<Value = f64> {
        prop_oneof![
            any::<f64>().prop_filter("within the range", |v| v.is_finite() && v.abs() <= MAX_ABS_ANGLE_DEG),
            -720.0..720.0f64,
            Just(0.0),
            Just(-0.0),
            Just(f64::MIN_POSITIVE),
            Just(5e-324),
            Just(MAX_ABS_ANGLE_DEG),
            Just(-MAX_ABS_ANGLE_DEG),
        ]
    }

    fn sample() -> impl Strategy<Value = Sample> {
        (1..=MAX_RUN, any::<bool>(), finite(), finite(), finite(), proptest::option::of(finite())).prop_map(
            |(run, fwd, target_deg, readout_deg, actual_deg, timestamp_s)| Sample {
                run,
                direction: if fwd { Direction::Forward } else { Direction::Reverse },
                target_deg,
                readout_deg,
                actual_deg,
                timestamp_s,
            },
        )
    }

    proptest! {
        #[test]
        fn round_trip_is_bit_exact(samples in proptest::collection::vec(sample(), 1..40)) {
            let mut out = Vec::new();
            write_survey_csv(&mut out, &samples).unwrap();
            let text = String::from_utf8(out).unwrap();
            let back = parse_survey_csv(&text, "x.csv").unwrap();
            prop_assert_eq!(back.len(), samples.len());
            for (a, b) in back.iter().zip(&samples) {
                prop_assert_eq!(bits(a), bits(b));
            }
        }

        /// Lines counted forward, at positions in any order, are the lines
        /// counted from the start of the text.
        #[test]
        fn lines_counted_forward_are_lines_counted_from_the_start(
            text in "[a,\r\n]{0,80}",
            mut at in proptest::collection::vec(0u64..90, 0..12),
            sorted in proptest::bool::ANY,
        ) {
            if sorted {
                at.sort_unstable();
            }
            let mut lines = Lines::new(&text);
            for a in at {
                let scratch = {
                    let bytes = text.as_bytes();
                    let mut to = usize::try_from(a).unwrap().min(bytes.len());
                    while to < bytes.len() && (bytes[to] == b'\n' || bytes[to] == b'\r') {
                        to += 1;
                    }
                    let breaks = (0..to)
                        .filter(|&i| bytes[i] == b'\n' || (bytes[i] == b'\r' && bytes.get(i + 1) != Some(&b'\n')))
                        .count();
                    1 + breaks as u64
                };
                prop_assert_eq!(lines.line_at(a), scratch);
            }
        }

        #[test]
        fn parser_never_panics(text in "[a-z_,0-9.\\-\r\n\" ]{0,200}") {
            let with_header = format!("{HEADER}\n{text}");
            let _ = parse_survey_csv(&text, "x.csv");
            let _ = parse_survey_csv(&with_header, "x.csv");
        }
    }
}
