//! The sans-IO codec: numbers, the status word, error queue entries, commands
//! (encode and parse) and the line [`Decoder`]. Bytes in, lines out: no sockets, no clock.

use super::codes::{NO_ERROR, StatusWord, is_usage_code};
use std::collections::VecDeque;
use std::fmt;
use survey_drivers::error::ErrorKind;

/// Why a line or a reply could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CodecError {
    /// A byte outside printable ASCII (TAB and CR allowed) in the line.
    #[error("non-ASCII or control byte in the line")]
    NonAscii,
    /// The line grew past the decoder's limit before its LF.
    #[error("line longer than {0} bytes")]
    LineTooLong(usize),
    /// The line is not what was expected.
    #[error("expected {expected}, got {line:?}")]
    Unparsable { expected: &'static str, line: String },
}

impl CodecError {
    pub(super) fn unparsable(expected: &'static str, line: &str) -> Self {
        let mut line: String = line.chars().take(64).collect();
        if line.len() == 64 {
            line.push_str("...");
        }
        CodecError::Unparsable { expected, line }
    }
}

/// A number as sent on the wire: the shortest decimal that reads back to the
/// same `f64`, with an exponent when the plain form would exceed 24 characters.
pub fn format_number(v: f64) -> String {
    let plain = format!("{v}");
    if plain.len() <= 24 { plain } else { format!("{v:E}") }
}

/// Parse a decimal number (SCPI NR1/NR2/NR3: sign, digits, point, exponent).
/// `inf`, `nan` and anything that overflows to infinity are refused.
pub fn parse_number(line: &str) -> Result<f64, CodecError> {
    let t = line.trim();
    let ok_chars = t.bytes().all(|b| b.is_ascii_digit() || matches!(b, b'+' | b'-' | b'.' | b'e' | b'E'));
    match t.parse::<f64>() {
        Ok(v) if ok_chars && !t.is_empty() && v.is_finite() => Ok(v),
        _ => Err(CodecError::unparsable("a decimal number", line)),
    }
}

/// Parse a count (a non-negative decimal integer).
pub fn parse_count(line: &str) -> Result<usize, CodecError> {
    let t = line.trim();
    if t.is_empty() || t.len() > 12 || !t.bytes().all(|b| b.is_ascii_digit()) {
        return Err(CodecError::unparsable("a count", line));
    }
    t.parse().map_err(|_| CodecError::unparsable("a count", line))
}

/// Parse a boolean reply or parameter: `1`/`0`/`ON`/`OFF` (any case).
pub fn parse_bool(line: &str) -> Result<bool, CodecError> {
    match line.trim().to_ascii_uppercase().as_str() {
        "1" | "ON" => Ok(true),
        "0" | "OFF" => Ok(false),
        _ => Err(CodecError::unparsable("1, 0, ON or OFF", line)),
    }
}

/// Parse a `STAT?` reply: a decimal integer 0..=65535.
pub fn parse_status(line: &str) -> Result<StatusWord, CodecError> {
    let t = line.trim();
    if t.is_empty() || t.len() > 5 || !t.bytes().all(|b| b.is_ascii_digit()) {
        return Err(CodecError::unparsable("a status word (integer 0..=65535)", line));
    }
    t.parse::<u16>().map(StatusWord).map_err(|_| CodecError::unparsable("a status word (integer 0..=65535)", line))
}

/// One entry of the controller's error queue: `<code>,"<text>"`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ErrorEntry {
    pub code: i64,
    pub text: String,
}

impl ErrorEntry {
    /// `0,"No error"`.
    pub fn none() -> Self {
        Self { code: NO_ERROR, text: "No error".into() }
    }

    pub fn new(code: i64, text: impl Into<String>) -> Self {
        Self { code, text: text.into() }
    }

    pub fn is_error(&self) -> bool {
        self.code != NO_ERROR
    }

    /// `None` for code 0, else [`ErrorKind::Usage`] or [`ErrorKind::Device`]
    /// by [`is_usage_code`].
    pub fn kind(&self) -> Option<ErrorKind> {
        match self.code {
            NO_ERROR => None,
            c if is_usage_code(c) => Some(ErrorKind::Usage),
            _ => Some(ErrorKind::Device),
        }
    }

    /// The reply line (without terminator): the text quoted with inner quotes
    /// doubled, non-printable characters replaced by `?`.
    pub fn to_line(&self) -> String {
        let text: String = self.text.chars().map(|c| if c == ' ' || c.is_ascii_graphic() { c } else { '?' }).collect();
        format!("{},\"{}\"", self.code, text.replace('"', "\"\""))
    }

    /// Parse a `SYST:ERR:ALL?` reply: one or more entries `<code>, "<text>"`
    /// separated by commas (`0, "No error"` when the queue is empty).
    pub fn parse_list(line: &str) -> Result<Vec<Self>, CodecError> {
        let bad = || CodecError::unparsable("error entries <code>,\"<text>\"[,<code>,\"<text>\"...]", line);
        let mut entries = Vec::new();
        let mut rest = line.trim();
        while !rest.is_empty() {
            // The code, up to its comma; then the quoted text, quotes doubled inside.
            let (code, after) = rest.split_once(',').ok_or_else(bad)?;
            let after = after.trim_start();
            let body = after.strip_prefix('"').ok_or_else(bad)?;
            let mut end = None;
            let bytes = body.as_bytes();
            let mut i = 0;
            while i < bytes.len() {
                if bytes[i] == b'"' {
                    if bytes.get(i + 1) == Some(&b'"') {
                        i += 2;
                        continue;
                    }
                    end = Some(i);
                    break;
                }
                i += 1;
            }
            let end = end.ok_or_else(bad)?;
            entries.push(Self::parse(&format!("{},\"{}\"", code.trim(), &body[..end]))?);
            rest = body[end + 1..].trim_start();
            if let Some(r) = rest.strip_prefix(',') {
                rest = r.trim_start();
                if rest.is_empty() {
                    return Err(bad());
                }
            } else if !rest.is_empty() {
                return Err(bad());
            }
        }
        if entries.is_empty() {
            return Err(bad());
        }
        Ok(entries)
    }

    /// Parse a `SYST:ERR?` reply.
    pub fn parse(line: &str) -> Result<Self, CodecError> {
        let bad = || CodecError::unparsable("an error entry <code>,\"<text>\"", line);
        let t = line.trim();
        let (code, rest) = t.split_once(',').ok_or_else(bad)?;
        let code = code.trim();
        let digits = code.strip_prefix(['-', '+']).unwrap_or(code);
        if digits.is_empty() || digits.len() > 12 || !digits.bytes().all(|b| b.is_ascii_digit()) {
            return Err(bad());
        }
        let code: i64 = code.parse().map_err(|_| bad())?;
        let rest = rest.trim();
        let inner = rest.strip_prefix('"').and_then(|r| r.strip_suffix('"')).ok_or_else(bad)?;
        let mut text = String::with_capacity(inner.len());
        let mut chars = inner.chars();
        while let Some(c) = chars.next() {
            if c == '"' {
                // Inside a string a quote must be doubled.
                if chars.next() != Some('"') {
                    return Err(bad());
                }
            }
            text.push(c);
        }
        Ok(Self { code, text })
    }
}

impl fmt::Display for ErrorEntry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.to_line())
    }
}

// ---------------------------------------------------------------------------
// Commands
// ---------------------------------------------------------------------------

/// Which controller and axis a command addresses (`CONT<c>:AXIS(<a>)`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Address {
    pub controller: u32,
    pub axis: u32,
}

impl Default for Address {
    /// `CONT1:AXIS(1)`.
    fn default() -> Self {
        Self { controller: 1, axis: 1 }
    }
}

/// A column of a correction table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Column {
    /// The forward column (the only one of a table for both directions).
    Forward,
    /// The reverse column of a directional table.
    Reverse,
}

impl Column {
    fn node(self) -> &'static str {
        match self {
            Column::Forward => "",
            Column::Reverse => ":REV",
        }
    }
}

/// A request to the controller (see the table in the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub enum Command {
    /// `POS:COMM <deg>`
    SetTarget(f64),
    /// `POS:COMM?`
    TargetQuery,
    /// `MOT:STAR`
    Start,
    /// `MOT:STOP`
    Stop,
    /// `POS:CURR?`
    PositionQuery,
    /// `STAT?`
    StatusQuery,
    /// `VEL:COMM <deg/s>`
    SetVelocity(f64),
    /// `VEL:CURR?`
    VelocityQuery,
    /// `FAUL:CLE`
    ClearFault,
    /// `CORR:TABL:CLE`
    TableClear,
    /// `CORR:TABL[:REV] <start>,<v>...`
    TableData { column: Column, start: usize, values: Vec<f64> },
    /// `CORR:TABL[:REV]:POIN?`
    TablePointsQuery(Column),
    /// `CORR:TABL:LOAD`
    TableLoad,
    /// `CORR:STAT ON|OFF`
    SetCorrection(bool),
    /// `CORR:STAT?`
    CorrectionQuery,
    /// `SYST:ERR?` (one entry; SCPI-99, not shown for MI controllers)
    ErrorQuery,
    /// `SYST:ERR:ALL?` (every entry; what public code sends to MI controllers)
    ErrorQueryAll,
    /// `UNIT:POS?` (the axis's position units; 6 = degree)
    UnitsQuery,
    /// `*CLS`
    ClearStatus,
    /// `*IDN?`
    Identify,
}

/// A command parsed from a line, with the address it named (`None` for the
/// controller-wide commands `SYST:ERR?`, `*CLS`, `*IDN?`).
#[derive(Debug, Clone, PartialEq)]
pub struct Parsed {
    pub address: Option<Address>,
    pub command: Command,
}

/// Short and long forms of the mnemonics below `CONT<c>:AXIS(<a>)`.
const MNEMONICS: [(&str, &str); 16] = [
    ("POS", "POSITION"),
    ("COMM", "COMMAND"),
    ("CURR", "CURRENT"),
    ("MOT", "MOTION"),
    ("STAR", "START"),
    ("STOP", "STOP"),
    ("STAT", "STATUS"),
    ("VEL", "VELOCITY"),
    ("FAUL", "FAULT"),
    ("CLE", "CLEAR"),
    ("CORR", "CORRECTION"),
    ("TABL", "TABLE"),
    ("POIN", "POINTS"),
    ("LOAD", "LOAD"),
    ("REV", "REVERSE"),
    ("UNIT", "UNIT"),
];

impl Command {
    /// Whether the controller answers this request with a line.
    pub fn is_query(&self) -> bool {
        matches!(
            self,
            Command::TargetQuery
                | Command::PositionQuery
                | Command::StatusQuery
                | Command::VelocityQuery
                | Command::TablePointsQuery(_)
                | Command::CorrectionQuery
                | Command::ErrorQuery
                | Command::ErrorQueryAll
                | Command::UnitsQuery
                | Command::Identify
        )
    }

    /// Whether the command addresses an axis (`CONT<c>:AXIS(<a>):...`).
    pub fn is_axis_command(&self) -> bool {
        !matches!(self, Command::ErrorQuery | Command::ErrorQueryAll | Command::ClearStatus | Command::Identify)
    }

    /// The line for `address`, without terminator.
    pub fn to_line(&self, address: Address) -> String {
        let axis = |tail: &str| format!("CONT{}:AXIS({}):{tail}", address.controller, address.axis);
        match self {
            Command::SetTarget(v) => axis(&format!("POS:COMM {}", format_number(*v))),
            Command::TargetQuery => axis("POS:COMM?"),
            Command::Start => axis("MOT:STAR"),
            Command::Stop => axis("MOT:STOP"),
            Command::PositionQuery => axis("POS:CURR?"),
            Command::StatusQuery => axis("STAT?"),
            Command::SetVelocity(v) => axis(&format!("VEL:COMM {}", format_number(*v))),
            Command::VelocityQuery => axis("VEL:CURR?"),
            Command::ClearFault => axis("FAUL:CLE"),
            Command::TableClear => axis("CORR:TABL:CLE"),
            Command::TableData { column, start, values } => {
                let mut s = format!("CORR:TABL{} {start}", column.node());
                for v in values {
                    s.push(',');
                    s.push_str(&format_number(*v));
                }
                axis(&s)
            }
            Command::TablePointsQuery(column) => axis(&format!("CORR:TABL{}:POIN?", column.node())),
            Command::TableLoad => axis("CORR:TABL:LOAD"),
            Command::SetCorrection(on) => axis(if *on { "CORR:STAT ON" } else { "CORR:STAT OFF" }),
            Command::CorrectionQuery => axis("CORR:STAT?"),
            Command::ErrorQuery => "SYST:ERR?".into(),
            Command::ErrorQueryAll => "SYST:ERR:ALL?".into(),
            Command::UnitsQuery => axis("UNIT:POS?"),
            Command::ClearStatus => "*CLS".into(),
            Command::Identify => "*IDN?".into(),
        }
    }

    /// The bytes for `address`: the line and its LF.
    pub fn encode(&self, address: Address) -> Vec<u8> {
        let mut b = self.to_line(address).into_bytes();
        b.push(b'\n');
        b
    }

    /// Parse a request line: case-insensitive, short or long mnemonics
    /// (`CONTroller`, `POSition:COMMand`...), an optional leading colon,
    /// `CONT` without a number meaning 1, `AXIS(n)` or `AXISn`.
    pub fn parse(line: &str) -> Result<Parsed, CodecError> {
        let bad = || CodecError::unparsable("a command", line);
        let t = line.trim();
        let (header, params) = match t.find([' ', '\t']) {
            Some(i) => (&t[..i], t[i..].trim()),
            None => (t, ""),
        };
        let (header, query) = match header.strip_suffix('?') {
            Some(h) => (h, true),
            None => (header, false),
        };
        let header = header.strip_prefix(':').unwrap_or(header).to_ascii_uppercase();
        let no_params = |c: Command| if params.is_empty() { Ok(c) } else { Err(bad()) };
        let system = |command: Command| Ok(Parsed { address: None, command });
        match (header.as_str(), query) {
            ("*CLS", false) => return system(no_params(Command::ClearStatus)?),
            ("*IDN", true) => return system(no_params(Command::Identify)?),
            ("SYST:ERR" | "SYSTEM:ERROR" | "SYST:ERR:NEXT" | "SYSTEM:ERROR:NEXT", true) => {
                return system(no_params(Command::ErrorQuery)?);
            }
            ("SYST:ERR:ALL" | "SYSTEM:ERROR:ALL", true) => return system(no_params(Command::ErrorQueryAll)?),
            _ => {}
        }
        let mut nodes = header.split(':');
        let controller = numbered(nodes.next().ok_or_else(bad)?, &["CONTROLLER", "CONT"]).ok_or_else(bad)?;
        let axis = axis_node(nodes.next().ok_or_else(bad)?).ok_or_else(bad)?;
        let mut path = Vec::new();
        for node in nodes {
            let short = MNEMONICS.iter().find(|(s, l)| node == *s || node == *l).ok_or_else(bad)?.0;
            path.push(short);
        }
        let number = || parse_number(params).map_err(|_| bad());
        let command = match (path.join(":").as_str(), query) {
            ("POS:COMM", false) => Command::SetTarget(number()?),
            ("POS:COMM", true) => no_params(Command::TargetQuery)?,
            ("MOT:STAR", false) => no_params(Command::Start)?,
            ("MOT:STOP", false) => no_params(Command::Stop)?,
            ("POS:CURR", true) => no_params(Command::PositionQuery)?,
            ("STAT", true) => no_params(Command::StatusQuery)?,
            ("VEL:COMM", false) => Command::SetVelocity(number()?),
            ("VEL:CURR", true) => no_params(Command::VelocityQuery)?,
            ("FAUL:CLE", false) => no_params(Command::ClearFault)?,
            ("CORR:TABL:CLE", false) => no_params(Command::TableClear)?,
            ("CORR:TABL", false) => table_data(Column::Forward, params).ok_or_else(bad)?,
            ("CORR:TABL:REV", false) => table_data(Column::Reverse, params).ok_or_else(bad)?,
            ("CORR:TABL:POIN", true) => no_params(Command::TablePointsQuery(Column::Forward))?,
            ("CORR:TABL:REV:POIN", true) => no_params(Command::TablePointsQuery(Column::Reverse))?,
            ("CORR:TABL:LOAD", false) => no_params(Command::TableLoad)?,
            ("CORR:STAT", false) => Command::SetCorrection(parse_bool(params).map_err(|_| bad())?),
            ("CORR:STAT", true) => no_params(Command::CorrectionQuery)?,
            ("UNIT:POS", true) => no_params(Command::UnitsQuery)?,
            _ => return Err(bad()),
        };
        Ok(Parsed { address: Some(Address { controller, axis }), command })
    }
}

/// `CONT`, `CONT3`, `CONTROLLER3` -> 1, 3, 3.
fn numbered(node: &str, names: &[&str]) -> Option<u32> {
    let rest = names.iter().find_map(|n| node.strip_prefix(n))?;
    if rest.is_empty() {
        return Some(1);
    }
    if rest.len() > 9 || !rest.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    rest.parse().ok()
}

/// `AXIS(2)`, `AXIS2`, `AXIS` -> 2, 2, 1.
fn axis_node(node: &str) -> Option<u32> {
    let rest = node.strip_prefix("AXIS")?;
    match rest.strip_prefix('(').and_then(|r| r.strip_suffix(')')) {
        Some(inner) if !inner.is_empty() => numbered(&format!("AXIS{inner}"), &["AXIS"]),
        Some(_) => None,
        None => numbered(node, &["AXIS"]),
    }
}

fn table_data(column: Column, params: &str) -> Option<Command> {
    let mut parts = params.split(',');
    let start = parse_count(parts.next()?).ok()?;
    let values = parts.map(|p| parse_number(p).ok()).collect::<Option<Vec<f64>>>()?;
    Some(Command::TableData { column, start, values })
}

// ---------------------------------------------------------------------------
// Line decoder
// ---------------------------------------------------------------------------

/// Splits a byte stream into lines (sans IO: push bytes, pop lines).
///
/// A line ends at LF; a CR before the LF is dropped. A line holding a byte
/// outside printable ASCII (TAB and CR allowed) decodes to
/// [`CodecError::NonAscii`] when its LF arrives. A line that grows past the
/// limit (CR included) decodes to [`CodecError::LineTooLong`] at once, and the
/// rest of it, up to its LF, is skipped. The partial line is bounded by the
/// limit; complete lines wait in a queue until popped.
#[derive(Debug, Clone)]
pub struct Decoder {
    line: Vec<u8>,
    bad: bool,
    skipping: bool,
    max_line: usize,
    ready: VecDeque<Result<String, CodecError>>,
}

impl Default for Decoder {
    fn default() -> Self {
        Self::new(Self::DEFAULT_MAX_LINE)
    }
}

impl Decoder {
    /// The default line limit, bytes.
    pub const DEFAULT_MAX_LINE: usize = 4096;

    /// A decoder for lines of at most `max_line` bytes (at least 1).
    pub fn new(max_line: usize) -> Self {
        Self { line: Vec::new(), bad: false, skipping: false, max_line: max_line.max(1), ready: VecDeque::new() }
    }

    /// Feed bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        for &b in bytes {
            if b == b'\n' {
                if !self.skipping {
                    let mut line = std::mem::take(&mut self.line);
                    if line.last() == Some(&b'\r') {
                        line.pop();
                    }
                    let item = if self.bad {
                        Err(CodecError::NonAscii)
                    } else {
                        String::from_utf8(line).map_err(|_| CodecError::NonAscii)
                    };
                    self.ready.push_back(item);
                }
                self.line.clear();
                self.bad = false;
                self.skipping = false;
            } else if self.skipping {
                continue;
            } else if self.line.len() >= self.max_line {
                self.ready.push_back(Err(CodecError::LineTooLong(self.max_line)));
                self.line.clear();
                self.bad = false;
                self.skipping = true;
            } else {
                let printable = (0x20..0x7f).contains(&b) || b == b'\t' || b == b'\r';
                self.bad |= !printable;
                self.line.push(b);
            }
        }
    }

    /// The next complete line, if any.
    pub fn next_line(&mut self) -> Option<Result<String, CodecError>> {
        self.ready.pop_front()
    }

    /// Drop the queued lines and the partial line; returns how many lines and
    /// partial bytes were dropped. After a partial line is dropped, the bytes
    /// up to the next LF are skipped too (they are its tail).
    pub fn clear(&mut self) -> usize {
        let dropped = self.ready.len() + self.line.len();
        self.ready.clear();
        if !self.line.is_empty() {
            self.skipping = true;
        }
        self.line.clear();
        self.bad = false;
        dropped
    }

    /// Whether a line or a part of one is buffered.
    pub fn is_empty(&self) -> bool {
        self.ready.is_empty() && self.line.is_empty()
    }
}
