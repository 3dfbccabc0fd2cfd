//! SCPI-style positioner controllers (MI Technologies MI-4190 / MI-4192 style):
//! a sans-IO codec and a [`Positioner`] driver over any byte stream (TCP,
//! serial through `tokio-serial`, an in-memory pipe).
//!
//! # The protocol as implemented
//!
//! ASCII lines. The driver ends every line with LF; it accepts replies ended
//! by LF or CR LF. `<c>` is the controller number and `<a>` the axis number
//! (both 1 by default, see [`Address`]). Numbers go out as the shortest
//! decimal that reads back to the same `f64` (`-90`, `45.125`, or with an
//! exponent, `1.5E-300`, when the plain form would be longer than 24
//! characters), so a target read back is bit-for-bit the target sent.
//!
//! | request | reply | meaning | source |
//! |---|---|---|---|
//! | `CONT<c>:AXIS(<a>):POS:COMM <deg>` | none | commanded (target) position | looked up |
//! | `CONT<c>:AXIS(<a>):POS:COMM?` | `<deg>` | the commanded position | looked up |
//! | `CONT<c>:AXIS(<a>):MOT:STAR` | none | start the move to the commanded position | looked up |
//! | `CONT<c>:AXIS(<a>):MOT:STOP` | none | stop the axis | looked up |
//! | `CONT<c>:AXIS(<a>):POS:CURR?` | `<deg>` | current position (the readout) | looked up |
//! | `CONT<c>:AXIS(<a>):VEL:CURR?` | `<deg/s>` | current velocity (0 at rest) | looked up |
//! | `CONT<c>:AXIS(<a>):STAT?` | `<integer>` | the axis status word (bits below) | looked up (bits 13, 14 chosen) |
//! | `CONT<c>:AXIS(<a>):VEL:COMM <deg/s>` | none | velocity of the following moves | chosen |
//! | `CONT<c>:AXIS(<a>):FAUL:CLE` | none | clear a latched axis fault | chosen |
//! | `CONT<c>:AXIS(<a>):CORR:TABL:CLE` | none | empty the table being loaded | chosen |
//! | `CONT<c>:AXIS(<a>):CORR:TABL <n>,<v>,<v>...` | none | write forward-column values from row `n` (0-based) on | chosen |
//! | `CONT<c>:AXIS(<a>):CORR:TABL:REV <n>,<v>...` | none | the same for the reverse column of a directional table | chosen |
//! | `CONT<c>:AXIS(<a>):CORR:TABL:POIN?` | `<count>` | rows held in the forward column (`:REV:POIN?` for reverse) | chosen |
//! | `CONT<c>:AXIS(<a>):CORR:TABL:LOAD` | none | install the rows as the correction table (not yet applied) | chosen |
//! | `CONT<c>:AXIS(<a>):CORR:STAT ON\|OFF` | none | apply (or stop applying) the table in the feedback path | chosen |
//! | `CONT<c>:AXIS(<a>):CORR:STAT?` | `1\|0` | whether the table is applied | chosen |
//! | `SYST:ERR?` | `<code>,"<text>"` | pop the oldest entry of the error queue; `0,"No error"` when empty | SCPI-99 |
//! | `*CLS` | none | clear the error queue | IEEE 488.2, seen in use |
//! | `*IDN?` | `<maker>,<model>,<serial>,<firmware>` | identification | IEEE 488.2, seen in use |
//!
//! Table rows are correction-table errors in degrees at the readouts
//! `i * 360 / n` (the [`CorrectionTable`] convention); a row `n` beyond the
//! rows already held is refused (`-222`). `CORR:TABL:LOAD` refuses a table of
//! fewer than 2 rows or with columns of different lengths (`-221`).
//!
//! ## The status word (`STAT?`)
//!
//! | bit | meaning | used by the driver | source |
//! |---|---|---|---|
//! | 0 | latch set | no | looked up |
//! | 1 | home switch active | no | looked up |
//! | 2 | reverse limit active | [`Limit::Lower`] | looked up |
//! | 3 | forward limit active | [`Limit::Upper`] | looked up |
//! | 4 | PAU (power amplifier) fault | fault | looked up |
//! | 5 | axis enabled | no | looked up |
//! | 6 | error limit active (following-error limit) | fault | looked up |
//! | 7 | axis in motion | `moving` | looked up |
//! | 8 | axis active | no | looked up |
//! | 9 | axis indexed | no | looked up |
//! | 10 | position trigger active | no | looked up |
//! | 11 | property changed | no | looked up |
//! | 12 | status changed | no | looked up |
//! | 13 | in position: settled in the window at the commanded position | `in_position` | chosen (listed unused) |
//! | 14 | correction table applied | `correction_enabled` | chosen (listed unused) |
//! | 15 | unused | no | looked up |
//!
//! A controller that leaves bits 13 and 14 at 0 never reports `in_position`;
//! those two bits are this project's extension and the simulator implements
//! them.
//!
//! ## Errors
//!
//! Commands have no reply, so after every command the driver asks
//! `SYST:ERR?`. It sends `*CLS` in the same write before the command, so the
//! entry read back is the command's own and never a stale one. A non-zero code
//! becomes a [`DriverError`] carrying the code, with the controller's text as
//! the message. The class follows the SCPI-99 code ranges:
//!
//! - [`ErrorKind::Usage`] (the request itself is wrong, retrying fails the same
//!   way): `-100..=-199` (command errors: syntax, undefined header, wrong
//!   axis suffix `-114`, missing parameter...) and `-220..=-229` (parameter
//!   errors: `-221` settings conflict, e.g. loading a table while moving;
//!   `-222` data out of range, e.g. a target outside the travel or a velocity
//!   that is not positive; `-223` too much data; `-224` illegal value).
//! - [`ErrorKind::Device`] for every other code: `-200` execution error,
//!   `-24x` hardware errors, `-3xx` device-specific errors and the
//!   controller's own positive codes (drive faults).
//!
//! When `STAT?` shows a fault bit (4 or 6), the driver reads `SYST:ERR?` until
//! it answers 0 and reports the newest device-class entry as
//! [`PositionerStatus::fault`]. The entry is remembered while the fault bit
//! stays set, because the queue gives each entry out only once; if it was
//! never seen (another client read it), the fault carries code
//! [`DEVICE_SPECIFIC_ERROR`] (`-300`) and a text naming the status bits.
//!
//! ## Link faults
//!
//! Every request (one write of its lines and, for a query, one reply line)
//! runs under its own deadline, [`ScpiTimeouts::request`] (2 s by default):
//!
//! - no reply by then: [`ErrorKind::Timeout`];
//! - end of stream or an I/O error: [`ErrorKind::Disconnected`]. The driver
//!   then fails every later call at once with `Disconnected`: build a new
//!   one to reconnect;
//! - a reply line with a non-ASCII or control byte, longer than
//!   [`Decoder::DEFAULT_MAX_LINE`], or not the number, status word or error
//!   entry expected: [`ErrorKind::Garbled`]. The line is consumed, so the
//!   next request is in step again.
//!
//! Before each request the driver drops whatever input is already waiting
//! (lines and partial lines), so a late reply is never taken for the next
//! request's answer. After a timeout it also waits
//! [`ScpiTimeouts::resync_grace`] for a reply that is merely slow. A partial
//! line dropped this way makes the decoder skip everything up to the next LF,
//! so its tail cannot pass for a reply either.
//!
//! A correction table is sent in chunks of [`ScpiConfig::table_chunk`] rows
//! after `CORR:TABL:CLE`, all in one write followed by one `SYST:ERR?`, then
//! the driver reads `CORR:TABL:POIN?` (and `:REV:POIN?`) back: a count other
//! than the rows sent means rows were lost on the way ([`ErrorKind::Garbled`],
//! a link fault: loading again may succeed), and only then sends
//! `CORR:TABL:LOAD`.
//!
//! # What was looked up and what was chosen
//!
//! Looked up (no MI Technologies manual is public; these come from two public
//! MATLAB programs that drive real MI-4190/4192 controllers over GPIB):
//!
//! - `github.com/csun-rf-lab/antennameasure`, `+MotionController/MI4190.m`:
//!   `CONT1:AXIS(%d):POS:COMM %f` then `CONT1:AXIS(%d):MOT:STAR` to move,
//!   `POS:COMM?` read back, `POS:INCR`, `MOT:STOP`, `POS:CURR?`, `VEL:CURR?`,
//!   `STAT?` (a 16-bit integer; its comment copies the bit table of "page
//!   3-42 of the MI-4192 manual": the bits 0 to 12 above, 13 to 15 unused),
//!   `UNIT:POS?` (6 = degrees), `POS:LIM:FORW?`/`REV?`, `SYST:ERR:COUN`,
//!   `SYST:ERR:ALL?` (comment: `0, "No error"`), `*CLS`, `*IDN?`,
//!   `CONT1:ABORT`, and its PAU-fault test on bit 4.
//! - `github.com/Ugikie/PositionControl`: the same move, stop and position
//!   commands, and a logged session: `*IDN?` answered
//!   `M. I. Technologies,Model 4192/4195,0,4.2.1`, and `STAT?` at rest
//!   answered `4865` (bits 0, 8, 9, 12: latch, active, indexed, status
//!   changed), through a Prologix GPIB adapter that ends replies with CR LF.
//! - SCPI-99 (the standard error queue `SYST:ERR?`, `<code>,"<text>"`, and the
//!   standard codes -100 to -350 used here; also as listed by the `scpi`
//!   crate's `ErrorCode` on docs.rs).
//!
//! Chosen (no public documentation found, designed in the same style):
//! `VEL:COMM`, `FAUL:CLE`, the whole `CORR:` subsystem, status bits 13 and 14,
//! LF as the terminator sent, which codes mean usage, and the
//! drain/`*CLS`/`SYST:ERR?` discipline above.

use crate::error::{DriverError, ErrorKind, Result};
use crate::traits::{DeviceFault, Limit, Positioner, PositionerStatus};
use async_trait::async_trait;
use std::collections::VecDeque;
use std::fmt;
use std::future::poll_fn;
use std::pin::Pin;
use std::task::Poll;
use std::time::Duration;
use survey_processing::table::CorrectionTable;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt, ReadBuf};
use tokio::net::{TcpStream, ToSocketAddrs};

// ---------------------------------------------------------------------------
// Codes and status bits
// ---------------------------------------------------------------------------

/// `0,"No error"`.
pub const NO_ERROR: i64 = 0;
/// SCPI-99 `-100 Command error`.
pub const COMMAND_ERROR: i64 = -100;
/// SCPI-99 `-101 Invalid character`.
pub const INVALID_CHARACTER: i64 = -101;
/// SCPI-99 `-102 Syntax error`.
pub const SYNTAX_ERROR: i64 = -102;
/// SCPI-99 `-104 Data type error`.
pub const DATA_TYPE_ERROR: i64 = -104;
/// SCPI-99 `-108 Parameter not allowed`.
pub const PARAMETER_NOT_ALLOWED: i64 = -108;
/// SCPI-99 `-109 Missing parameter`.
pub const MISSING_PARAMETER: i64 = -109;
/// SCPI-99 `-113 Undefined header`.
pub const UNDEFINED_HEADER: i64 = -113;
/// SCPI-99 `-114 Header suffix out of range` (no such controller or axis).
pub const HEADER_SUFFIX_OUT_OF_RANGE: i64 = -114;
/// SCPI-99 `-200 Execution error`.
pub const EXECUTION_ERROR: i64 = -200;
/// SCPI-99 `-221 Settings conflict`.
pub const SETTINGS_CONFLICT: i64 = -221;
/// SCPI-99 `-222 Data out of range`.
pub const DATA_OUT_OF_RANGE: i64 = -222;
/// SCPI-99 `-223 Too much data`.
pub const TOO_MUCH_DATA: i64 = -223;
/// SCPI-99 `-300 Device-specific error`.
pub const DEVICE_SPECIFIC_ERROR: i64 = -300;
/// SCPI-99 `-350 Queue overflow`.
pub const QUEUE_OVERFLOW: i64 = -350;

/// Whether a controller error code means the request itself was wrong
/// ([`ErrorKind::Usage`]): SCPI command errors `-100..=-199` and parameter
/// errors `-220..=-229`. Every other non-zero code is [`ErrorKind::Device`].
pub fn is_usage_code(code: i64) -> bool {
    (-199..=-100).contains(&code) || (-229..=-220).contains(&code)
}

/// The bits of the `STAT?` word (see the module documentation).
pub mod bits {
    /// Bit 0: latch set.
    pub const LATCH: u16 = 1 << 0;
    /// Bit 1: home switch active.
    pub const HOME: u16 = 1 << 1;
    /// Bit 2: reverse limit active (lower limit).
    pub const REVERSE_LIMIT: u16 = 1 << 2;
    /// Bit 3: forward limit active (upper limit).
    pub const FORWARD_LIMIT: u16 = 1 << 3;
    /// Bit 4: PAU (power amplifier) fault.
    pub const PAU_FAULT: u16 = 1 << 4;
    /// Bit 5: axis enabled.
    pub const ENABLED: u16 = 1 << 5;
    /// Bit 6: error limit active (following-error limit exceeded).
    pub const ERROR_LIMIT: u16 = 1 << 6;
    /// Bit 7: axis in motion.
    pub const IN_MOTION: u16 = 1 << 7;
    /// Bit 8: axis active.
    pub const ACTIVE: u16 = 1 << 8;
    /// Bit 9: axis indexed.
    pub const INDEXED: u16 = 1 << 9;
    /// Bit 10: position trigger active.
    pub const POSITION_TRIGGER: u16 = 1 << 10;
    /// Bit 11: property changed.
    pub const PROPERTY_CHANGED: u16 = 1 << 11;
    /// Bit 12: status changed.
    pub const STATUS_CHANGED: u16 = 1 << 12;
    /// Bit 13 (chosen): in position.
    pub const IN_POSITION: u16 = 1 << 13;
    /// Bit 14 (chosen): correction table applied.
    pub const CORRECTION: u16 = 1 << 14;
    /// The bits that mean a fault.
    pub const FAULT: u16 = PAU_FAULT | ERROR_LIMIT;
}

/// A decoded `STAT?` word.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct StatusWord(pub u16);

impl StatusWord {
    pub fn has(self, bit: u16) -> bool {
        self.0 & bit != 0
    }
    pub fn moving(self) -> bool {
        self.has(bits::IN_MOTION)
    }
    pub fn in_position(self) -> bool {
        self.has(bits::IN_POSITION)
    }
    /// A fault bit (PAU fault or error limit) is set.
    pub fn fault(self) -> bool {
        self.has(bits::FAULT)
    }
    pub fn correction_enabled(self) -> bool {
        self.has(bits::CORRECTION)
    }
    /// The active limit switch (reverse = lower wins if both are set).
    pub fn limit(self) -> Option<Limit> {
        if self.has(bits::REVERSE_LIMIT) {
            Some(Limit::Lower)
        } else if self.has(bits::FORWARD_LIMIT) {
            Some(Limit::Upper)
        } else {
            None
        }
    }

    /// The names of the fault bits that are set (for messages).
    pub fn fault_names(self) -> String {
        let mut names = Vec::new();
        if self.has(bits::PAU_FAULT) {
            names.push("PAU fault");
        }
        if self.has(bits::ERROR_LIMIT) {
            names.push("error limit active");
        }
        names.join(", ")
    }

    /// The status, with `fault` (learned from `SYST:ERR?`) as its fault.
    pub fn to_status(self, fault: Option<DeviceFault>) -> PositionerStatus {
        PositionerStatus {
            moving: self.moving(),
            in_position: self.in_position(),
            fault,
            limit: self.limit(),
            correction_enabled: self.correction_enabled(),
        }
    }

    /// The word a controller in `status` shows: active, indexed, enabled unless
    /// faulted, a fault as a PAU fault.
    pub fn from_status(status: &PositionerStatus) -> Self {
        let mut w = bits::ACTIVE | bits::INDEXED;
        w |= if status.fault.is_some() { bits::PAU_FAULT } else { bits::ENABLED };
        if status.moving {
            w |= bits::IN_MOTION;
        }
        if status.in_position {
            w |= bits::IN_POSITION;
        }
        if status.correction_enabled {
            w |= bits::CORRECTION;
        }
        w |= match status.limit {
            Some(Limit::Lower) => bits::REVERSE_LIMIT,
            Some(Limit::Upper) => bits::FORWARD_LIMIT,
            None => 0,
        };
        StatusWord(w)
    }

    /// Parse a `STAT?` reply: a decimal integer 0..=65535.
    pub fn parse(line: &str) -> Result<Self, CodecError> {
        let t = line.trim();
        if t.is_empty() || t.len() > 5 || !t.bytes().all(|b| b.is_ascii_digit()) {
            return Err(CodecError::unparsable("a status word (integer 0..=65535)", line));
        }
        t.parse::<u16>().map(StatusWord).map_err(|_| CodecError::unparsable("a status word (integer 0..=65535)", line))
    }
}

impl fmt::Display for StatusWord {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}

// ---------------------------------------------------------------------------
// Codec errors, numbers, error entries
// ---------------------------------------------------------------------------

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
    fn unparsable(expected: &'static str, line: &str) -> Self {
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
    /// `SYST:ERR?`
    ErrorQuery,
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
const MNEMONICS: [(&str, &str); 15] = [
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
                | Command::Identify
        )
    }

    /// Whether the command addresses an axis (`CONT<c>:AXIS(<a>):...`).
    pub fn is_axis_command(&self) -> bool {
        !matches!(self, Command::ErrorQuery | Command::ClearStatus | Command::Identify)
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

// ---------------------------------------------------------------------------
// The driver
// ---------------------------------------------------------------------------

/// Deadlines of the driver.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ScpiTimeouts {
    /// Deadline of one request (write and, for a query, its reply). Default 2 s.
    pub request: Duration,
    /// Deadline of the TCP connect. Default 5 s.
    pub connect: Duration,
    /// After a timeout, how long the next request first waits for a late
    /// reply to throw away. Default 50 ms.
    pub resync_grace: Duration,
}

impl Default for ScpiTimeouts {
    fn default() -> Self {
        Self {
            request: Duration::from_secs(2),
            connect: Duration::from_secs(5),
            resync_grace: Duration::from_millis(50),
        }
    }
}

/// Configuration of a [`ScpiPositioner`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScpiConfig {
    /// Controller and axis addressed. Default `CONT1:AXIS(1)`.
    pub address: Address,
    pub timeouts: ScpiTimeouts,
    /// Rows per `CORR:TABL` line. Default 32 (lines under 1 KiB).
    pub table_chunk: usize,
    /// Longest reply line accepted. Default [`Decoder::DEFAULT_MAX_LINE`].
    pub max_line: usize,
}

impl Default for ScpiConfig {
    fn default() -> Self {
        Self {
            address: Address::default(),
            timeouts: ScpiTimeouts::default(),
            table_chunk: 32,
            max_line: Decoder::DEFAULT_MAX_LINE,
        }
    }
}

/// How many `SYST:ERR?` entries the driver reads at most in one go.
const MAX_ERROR_READS: usize = 16;

/// A positioner controller speaking the protocol of this module over `T`.
pub struct ScpiPositioner<T> {
    io: Option<T>,
    decoder: Decoder,
    cfg: ScpiConfig,
    name: String,
    /// The fault entry last read from the error queue, kept while the status
    /// word shows a fault.
    last_fault: Option<DeviceFault>,
    /// A request timed out: its reply may still come.
    resync: bool,
}

impl<T> fmt::Debug for ScpiPositioner<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ScpiPositioner")
            .field("name", &self.name)
            .field("config", &self.cfg)
            .field("connected", &self.io.is_some())
            .field("last_fault", &self.last_fault)
            .finish()
    }
}

impl ScpiPositioner<TcpStream> {
    /// Connect over TCP (with `TCP_NODELAY`). A refused or failed connect is
    /// [`ErrorKind::Disconnected`]; one that takes longer than
    /// `timeouts.connect` is [`ErrorKind::Timeout`].
    pub async fn connect_tcp(addr: impl ToSocketAddrs + fmt::Debug, timeouts: ScpiTimeouts) -> Result<Self> {
        let label = format!("scpi-tcp {addr:?}");
        let stream = match tokio::time::timeout(timeouts.connect, TcpStream::connect(&addr)).await {
            Err(_) => return Err(DriverError::timeout(label, "connect", timeouts.connect)),
            Ok(Err(e)) => return Err(DriverError::new(ErrorKind::Disconnected, label, format!("connect failed: {e}"))),
            Ok(Ok(s)) => s,
        };
        stream
            .set_nodelay(true)
            .map_err(|e| DriverError::new(ErrorKind::Disconnected, &label, format!("TCP_NODELAY: {e}")))?;
        let name = match stream.peer_addr() {
            Ok(peer) => format!("scpi-tcp {peer}"),
            Err(_) => label,
        };
        let cfg = ScpiConfig { timeouts, ..ScpiConfig::default() };
        Ok(Self::with_config(stream, cfg).named(name))
    }
}

impl ScpiPositioner<tokio_serial::SerialStream> {
    /// Open a serial port (8N1, no flow control) at `baud`.
    pub fn open_serial(path: &str, baud: u32, timeouts: ScpiTimeouts) -> Result<Self> {
        use tokio_serial::SerialPortBuilderExt;
        let name = format!("scpi-serial {path}");
        let stream = tokio_serial::new(path, baud)
            .open_native_async()
            .map_err(|e| DriverError::new(ErrorKind::Disconnected, &name, format!("cannot open {path}: {e}")))?;
        let cfg = ScpiConfig { timeouts, ..ScpiConfig::default() };
        Ok(Self::with_config(stream, cfg).named(name))
    }
}

impl<T> ScpiPositioner<T>
where
    T: AsyncRead + AsyncWrite + Unpin + Send,
{
    /// A driver on an open stream, default configuration.
    pub fn from_stream(stream: T) -> Self {
        Self::with_config(stream, ScpiConfig::default())
    }

    /// A driver on an open stream.
    pub fn with_config(stream: T, cfg: ScpiConfig) -> Self {
        Self {
            io: Some(stream),
            decoder: Decoder::new(cfg.max_line),
            name: "scpi".into(),
            cfg,
            last_fault: None,
            resync: false,
        }
    }

    /// Set the name used in logs and errors.
    pub fn named(mut self, name: impl Into<String>) -> Self {
        self.name = name.into();
        self
    }

    /// Address another controller or axis.
    pub fn with_address(mut self, address: Address) -> Self {
        self.cfg.address = address;
        self
    }

    pub fn config(&self) -> &ScpiConfig {
        &self.cfg
    }

    /// Whether the stream is still open (false after a `Disconnected`).
    pub fn is_connected(&self) -> bool {
        self.io.is_some()
    }

    /// `*IDN?`.
    pub async fn identify(&mut self) -> Result<String> {
        self.query(&[], Command::Identify, "identify").await
    }

    /// `POS:COMM?`: the commanded position.
    pub async fn commanded_position(&mut self) -> Result<f64> {
        let line = self.query(&[], Command::TargetQuery, "commanded position").await?;
        parse_number(&line).map_err(|e| self.garbled("commanded position", e))
    }

    // -- errors -------------------------------------------------------------

    fn disconnected(&self, what: &str, why: impl fmt::Display) -> DriverError {
        DriverError::new(ErrorKind::Disconnected, &self.name, format!("{what}: {why}"))
    }

    fn garbled(&self, what: &str, e: CodecError) -> DriverError {
        DriverError::new(ErrorKind::Garbled, &self.name, format!("reply to {what}: {e}"))
    }

    fn rejected(&self, entry: ErrorEntry, what: &str) -> DriverError {
        DriverError {
            kind: entry.kind().unwrap_or(ErrorKind::Device),
            instrument: self.name.clone(),
            code: Some(entry.code),
            message: format!("{} (the controller refused {what})", entry.text),
        }
    }

    // -- I/O ----------------------------------------------------------------

    /// Throw away input that is already waiting (and, after a timeout, input
    /// that arrives within the grace period).
    async fn drain(&mut self, what: &str) -> Result<()> {
        let mut dropped = self.decoder.clear();
        let mut buf = [0u8; 1024];
        if std::mem::take(&mut self.resync) {
            let deadline = tokio::time::Instant::now() + self.cfg.timeouts.resync_grace;
            while let Some(io) = self.io.as_mut() {
                match tokio::time::timeout_at(deadline, io.read(&mut buf)).await {
                    Err(_) => break,
                    Ok(Ok(0)) => return Err(self.close(what, "connection closed by the controller")),
                    Ok(Ok(n)) => {
                        self.decoder.push(&buf[..n]);
                        dropped += self.decoder.clear();
                    }
                    Ok(Err(e)) => return Err(self.close(what, e)),
                }
            }
        }
        loop {
            let Some(io) = self.io.as_mut() else {
                return Err(self.disconnected(what, "the connection was lost earlier"));
            };
            let ready = poll_fn(|cx| {
                let mut rb = ReadBuf::new(&mut buf);
                match Pin::new(&mut *io).poll_read(cx, &mut rb) {
                    Poll::Ready(Ok(())) => Poll::Ready(Some(Ok(rb.filled().len()))),
                    Poll::Ready(Err(e)) => Poll::Ready(Some(Err(e))),
                    Poll::Pending => Poll::Ready(None),
                }
            })
            .await;
            match ready {
                None => break,
                Some(Ok(0)) => return Err(self.close(what, "connection closed by the controller")),
                Some(Ok(n)) => {
                    self.decoder.push(&buf[..n]);
                    dropped += self.decoder.clear();
                }
                Some(Err(e)) => return Err(self.close(what, e)),
            }
        }
        if dropped > 0 {
            tracing::warn!(instrument = %self.name, what, dropped, "dropped stale input before a request");
        }
        Ok(())
    }

    /// Mark the link dead.
    fn close(&mut self, what: &str, why: impl fmt::Display) -> DriverError {
        self.io = None;
        self.decoder.clear();
        tracing::warn!(instrument = %self.name, what, %why, "connection lost");
        self.disconnected(what, why)
    }

    async fn write_then_read(
        &mut self,
        bytes: &[u8],
        reply: bool,
        what: &str,
    ) -> Result<Option<Result<String, CodecError>>> {
        let Some(io) = self.io.as_mut() else {
            return Err(self.disconnected(what, "the connection was lost earlier"));
        };
        let written = async {
            io.write_all(bytes).await?;
            io.flush().await
        }
        .await;
        if let Err(e) = written {
            return Err(self.close(what, e));
        }
        if !reply {
            return Ok(None);
        }
        let mut buf = [0u8; 1024];
        loop {
            if let Some(line) = self.decoder.next_line() {
                return Ok(Some(line));
            }
            let Some(io) = self.io.as_mut() else {
                return Err(self.disconnected(what, "the connection was lost earlier"));
            };
            match io.read(&mut buf).await {
                Ok(0) => return Err(self.close(what, "connection closed by the controller")),
                Ok(n) => self.decoder.push(&buf[..n]),
                Err(e) => return Err(self.close(what, e)),
            }
        }
    }

    /// One request: drain stale input, write `lines` in one go and, when the
    /// last is a query, read its reply line; all under the request deadline.
    async fn request(&mut self, lines: &[Command], what: &str) -> Result<Option<String>> {
        self.drain(what).await?;
        let mut bytes = Vec::new();
        for c in lines {
            bytes.extend(c.encode(self.cfg.address));
        }
        let reply = lines.last().is_some_and(Command::is_query);
        let limit = self.cfg.timeouts.request;
        match tokio::time::timeout(limit, self.write_then_read(&bytes, reply, what)).await {
            Err(_) => {
                self.resync = true;
                tracing::warn!(instrument = %self.name, what, ?limit, "no reply");
                Err(DriverError::timeout(&self.name, what, limit))
            }
            Ok(Err(e)) => Err(e),
            Ok(Ok(None)) => Ok(None),
            Ok(Ok(Some(Ok(line)))) => Ok(Some(line)),
            Ok(Ok(Some(Err(e)))) => Err(self.garbled(what, e)),
        }
    }

    /// Write `before` then `query`, return the reply line.
    async fn query(&mut self, before: &[Command], query: Command, what: &str) -> Result<String> {
        let mut lines = before.to_vec();
        lines.push(query);
        let line = self.request(&lines, what).await?;
        line.ok_or_else(|| self.garbled(what, CodecError::unparsable("a reply", "")))
    }

    /// Read one entry of the error queue.
    async fn next_error(&mut self, before: &[Command], what: &str) -> Result<ErrorEntry> {
        let line = self.query(before, Command::ErrorQuery, what).await?;
        ErrorEntry::parse(&line).map_err(|e| self.garbled(what, e))
    }

    /// `*CLS`, the commands, `SYST:ERR?`: a non-zero entry is the commands'
    /// refusal.
    async fn command(&mut self, commands: &[Command], what: &str) -> Result<()> {
        let mut lines = Vec::with_capacity(commands.len() + 1);
        lines.push(Command::ClearStatus);
        lines.extend_from_slice(commands);
        let entry = self.next_error(&lines, what).await?;
        if entry.is_error() {
            tracing::debug!(instrument = %self.name, what, %entry, "command refused");
            return Err(self.rejected(entry, what));
        }
        Ok(())
    }

    /// The fault behind a fault bit: the newest device-class entry of the
    /// error queue, else the one remembered, else a generic one.
    async fn fault_detail(&mut self, word: StatusWord) -> Result<DeviceFault> {
        for _ in 0..MAX_ERROR_READS {
            let entry = self.next_error(&[], "status (SYST:ERR? after a fault bit)").await?;
            match entry.kind() {
                None => break,
                Some(ErrorKind::Device) => self.last_fault = Some(DeviceFault { code: entry.code, text: entry.text }),
                Some(_) => tracing::warn!(instrument = %self.name, %entry, "stale command error in the queue"),
            }
        }
        Ok(self.last_fault.clone().unwrap_or_else(|| DeviceFault {
            code: DEVICE_SPECIFIC_ERROR,
            text: format!(
                "axis fault ({}) in status word {word}; the error queue held no entry for it",
                word.fault_names()
            ),
        }))
    }
}

#[async_trait]
impl<T> Positioner for ScpiPositioner<T>
where
    T: AsyncRead + AsyncWrite + Unpin + Send,
{
    fn name(&self) -> &str {
        &self.name
    }

    /// `POS:COMM <target>` (checked), then `MOT:STAR` (checked).
    async fn move_to(&mut self, target_deg: f64) -> Result<()> {
        if !target_deg.is_finite() {
            return Err(DriverError::usage(&self.name, format!("target {target_deg} deg is not a finite angle")));
        }
        self.command(&[Command::SetTarget(target_deg)], "move_to (POS:COMM)").await?;
        self.command(&[Command::Start], "move_to (MOT:STAR)").await
    }

    async fn readout(&mut self) -> Result<f64> {
        let line = self.query(&[], Command::PositionQuery, "readout (POS:CURR?)").await?;
        parse_number(&line).map_err(|e| self.garbled("readout (POS:CURR?)", e))
    }

    async fn status(&mut self) -> Result<PositionerStatus> {
        let line = self.query(&[], Command::StatusQuery, "status (STAT?)").await?;
        let word = StatusWord::parse(&line).map_err(|e| self.garbled("status (STAT?)", e))?;
        let fault = if word.fault() {
            Some(self.fault_detail(word).await?)
        } else {
            self.last_fault = None;
            None
        };
        Ok(word.to_status(fault))
    }

    async fn stop(&mut self) -> Result<()> {
        self.command(&[Command::Stop], "stop (MOT:STOP)").await
    }

    async fn set_velocity(&mut self, deg_per_s: f64) -> Result<()> {
        if !deg_per_s.is_finite() {
            return Err(DriverError::usage(&self.name, format!("velocity {deg_per_s} deg/s is not a finite number")));
        }
        self.command(&[Command::SetVelocity(deg_per_s)], "set_velocity (VEL:COMM)").await
    }

    async fn clear_fault(&mut self) -> Result<()> {
        self.command(&[Command::ClearFault], "clear_fault (FAUL:CLE)").await?;
        self.last_fault = None;
        Ok(())
    }

    async fn load_correction_table(&mut self, table: &CorrectionTable) -> Result<()> {
        let chunk = self.cfg.table_chunk.max(1);
        let mut lines = vec![Command::TableClear];
        let mut columns = vec![(Column::Forward, &table.forward)];
        if let Some(r) = &table.reverse {
            columns.push((Column::Reverse, r));
        }
        for (column, values) in &columns {
            for (i, part) in values.chunks(chunk).enumerate() {
                lines.push(Command::TableData { column: *column, start: i * chunk, values: part.to_vec() });
            }
        }
        self.command(&lines, "load_correction_table (CORR:TABL)").await?;
        for (column, values) in &columns {
            let what = "load_correction_table (CORR:TABL:POIN?)";
            let line = self.query(&[], Command::TablePointsQuery(*column), what).await?;
            let held = parse_count(&line).map_err(|e| self.garbled(what, e))?;
            if held != values.len() {
                return Err(DriverError::new(
                    ErrorKind::Garbled,
                    &self.name,
                    format!(
                        "the controller holds {held} {column:?} rows of the {} sent: rows were lost on the way",
                        values.len()
                    ),
                ));
            }
        }
        self.command(&[Command::TableLoad], "load_correction_table (CORR:TABL:LOAD)").await
    }

    async fn enable_correction(&mut self, enabled: bool) -> Result<()> {
        self.command(&[Command::SetCorrection(enabled)], "enable_correction (CORR:STAT)").await
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn decode_all(chunks: &[&[u8]], max: usize) -> Vec<Result<String, CodecError>> {
        let mut d = Decoder::new(max);
        let mut out = Vec::new();
        for c in chunks {
            d.push(c);
            while let Some(l) = d.next_line() {
                out.push(l);
            }
        }
        out
    }

    #[test]
    fn commands_encode_as_documented() {
        let a = Address::default();
        let line = |c: Command| String::from_utf8(c.encode(a)).unwrap();
        assert_eq!(line(Command::SetTarget(-90.0)), "CONT1:AXIS(1):POS:COMM -90\n");
        assert_eq!(line(Command::SetTarget(45.125)), "CONT1:AXIS(1):POS:COMM 45.125\n");
        assert_eq!(line(Command::Start), "CONT1:AXIS(1):MOT:STAR\n");
        assert_eq!(line(Command::Stop), "CONT1:AXIS(1):MOT:STOP\n");
        assert_eq!(line(Command::PositionQuery), "CONT1:AXIS(1):POS:CURR?\n");
        assert_eq!(line(Command::StatusQuery), "CONT1:AXIS(1):STAT?\n");
        assert_eq!(line(Command::SetVelocity(2.5)), "CONT1:AXIS(1):VEL:COMM 2.5\n");
        assert_eq!(line(Command::ErrorQuery), "SYST:ERR?\n");
        assert_eq!(line(Command::ClearStatus), "*CLS\n");
        assert_eq!(
            line(Command::TableData { column: Column::Reverse, start: 32, values: vec![0.001, -0.5] }),
            "CONT1:AXIS(1):CORR:TABL:REV 32,0.001,-0.5\n"
        );
        assert_eq!(line(Command::TablePointsQuery(Column::Forward)), "CONT1:AXIS(1):CORR:TABL:POIN?\n");
        assert_eq!(line(Command::SetCorrection(true)), "CONT1:AXIS(1):CORR:STAT ON\n");
        let other = Address { controller: 2, axis: 3 };
        assert_eq!(Command::Start.to_line(other), "CONT2:AXIS(3):MOT:STAR");
        // Extreme magnitudes keep lines short and exact.
        assert_eq!(format_number(1e-300), "1E-300");
        assert_eq!(parse_number(&format_number(f64::MAX)).unwrap(), f64::MAX);
    }

    #[test]
    fn parse_accepts_long_forms_and_any_case() {
        let p = Command::parse(":controller2:axis(4):position:command 12.5").unwrap();
        assert_eq!(p.address, Some(Address { controller: 2, axis: 4 }));
        assert_eq!(p.command, Command::SetTarget(12.5));
        let p = Command::parse("CONT:AXIS:MOT:STAR").unwrap();
        assert_eq!(p, Parsed { address: Some(Address::default()), command: Command::Start });
        assert_eq!(Command::parse("syst:err:next?").unwrap().command, Command::ErrorQuery);
        for bad in [
            "CONT1:AXIS(1):POS:COMM",
            "CONT1:AXIS(1):POS:COMM abc",
            "CONT1:AXIS():STAT?",
            "FOO?",
            "*CLS 1",
            "CONT1:AXIS(1):STAT? 3",
        ] {
            assert!(Command::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn replies_parse_and_refuse_garbage() {
        assert_eq!(parse_number(" -89.95 ").unwrap(), -89.95);
        assert_eq!(parse_number("1.5E-3").unwrap(), 1.5e-3);
        for bad in ["", "abc", "inf", "NaN", "1e999", "12,5", "0x10", "1 2"] {
            assert!(parse_number(bad).is_err(), "{bad}");
        }
        assert_eq!(StatusWord::parse("4865").unwrap(), StatusWord(4865));
        for bad in ["70000", "-1", "12.0", "", "0x10"] {
            assert!(StatusWord::parse(bad).is_err(), "{bad}");
        }
        assert_eq!(ErrorEntry::parse("0,\"No error\"").unwrap(), ErrorEntry::none());
        assert_eq!(
            ErrorEntry::parse("-222, \"Data out of range;said \"\"no\"\"\"").unwrap(),
            ErrorEntry::new(-222, "Data out of range;said \"no\"")
        );
        for bad in ["-222", "x,\"a\"", "-222,a", "-222,\"a\"b\"", "-222,\"a"] {
            assert!(ErrorEntry::parse(bad).is_err(), "{bad}");
        }
        assert!(parse_bool("on").unwrap());
        assert!(!parse_bool("0").unwrap());
        assert_eq!(parse_count("720").unwrap(), 720);
        assert!(parse_count("-1").is_err());
    }

    #[test]
    fn status_bits_as_documented() {
        // The logged MI-4192 at rest: latch, active, indexed, status changed.
        let w = StatusWord(4865);
        assert!(!w.moving() && !w.fault() && !w.in_position() && w.limit().is_none());
        let s = StatusWord(bits::IN_MOTION | bits::FORWARD_LIMIT | bits::CORRECTION).to_status(None);
        assert!(s.moving && s.correction_enabled && !s.in_position);
        assert_eq!(s.limit, Some(Limit::Upper));
        assert_eq!(StatusWord(bits::REVERSE_LIMIT).limit(), Some(Limit::Lower));
        assert!(StatusWord(1 << 4).fault() && StatusWord(1 << 6).fault());
        assert_eq!(StatusWord(bits::ERROR_LIMIT).fault_names(), "error limit active");
        assert_eq!(bits::IN_POSITION, 1 << 13);
    }

    #[test]
    fn error_codes_classify() {
        for usage in [
            COMMAND_ERROR,
            SYNTAX_ERROR,
            UNDEFINED_HEADER,
            HEADER_SUFFIX_OUT_OF_RANGE,
            SETTINGS_CONFLICT,
            DATA_OUT_OF_RANGE,
            TOO_MUCH_DATA,
        ] {
            assert_eq!(ErrorEntry::new(usage, "x").kind(), Some(ErrorKind::Usage), "{usage}");
        }
        for device in [EXECUTION_ERROR, -240, DEVICE_SPECIFIC_ERROR, QUEUE_OVERFLOW, 305, 0x8611] {
            assert_eq!(ErrorEntry::new(device, "x").kind(), Some(ErrorKind::Device), "{device}");
        }
        assert_eq!(ErrorEntry::none().kind(), None);
    }

    #[test]
    fn decoder_handles_crlf_garbage_and_long_lines() {
        let out = decode_all(&[b"12.5\r\n\xff\xfe\n4865\n", b"abcdefghijk\nok\n"], 8);
        assert_eq!(
            out,
            vec![
                Ok("12.5".into()),
                Err(CodecError::NonAscii),
                Ok("4865".into()),
                Err(CodecError::LineTooLong(8)),
                Ok("ok".into())
            ]
        );
        // A control byte is garbage too; TAB is not.
        assert_eq!(decode_all(&[b"a\x07b\n\tx\n"], 64), vec![Err(CodecError::NonAscii), Ok("\tx".into())]);
        // Clearing a partial line skips its tail.
        let mut d = Decoder::default();
        d.push(b"12.");
        assert_eq!(d.clear(), 3);
        d.push(b"5\n7\n");
        assert_eq!(d.next_line(), Some(Ok("7".into())));
        assert!(d.is_empty());
    }

    #[tokio::test]
    async fn driver_over_an_in_memory_stream() {
        // A scripted peer: answers the position query, then one stale line
        // arrives before the status query and must not be taken for its answer.
        let (ours, mut theirs) = tokio::io::duplex(4096);
        let mut p = ScpiPositioner::from_stream(ours).named("duplex");
        let peer = tokio::spawn(async move {
            let mut d = Decoder::default();
            let mut buf = [0u8; 256];
            let mut seen = Vec::new();
            while seen.len() < 2 {
                let n = theirs.read(&mut buf).await.unwrap();
                d.push(&buf[..n]);
                while let Some(l) = d.next_line() {
                    let l = l.unwrap();
                    let reply = if l.ends_with("POS:CURR?") { "12.5\n1234\n" } else { "8992\n" };
                    theirs.write_all(reply.as_bytes()).await.unwrap();
                    seen.push(l);
                }
            }
            seen
        });
        assert_eq!(p.readout().await.unwrap(), 12.5);
        // Let the stale line land in our buffer.
        tokio::task::yield_now().await;
        let s = p.status().await.unwrap();
        assert!(s.in_position && !s.correction_enabled && !s.moving && s.fault.is_none(), "{s:?}");
        let seen = peer.await.unwrap();
        assert_eq!(seen, vec!["CONT1:AXIS(1):POS:CURR?", "CONT1:AXIS(1):STAT?"]);
        // The peer is gone: end of stream.
        let e = p.readout().await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
        assert!(!p.is_connected());
    }

    fn arb_f64() -> impl Strategy<Value = f64> {
        prop_oneof![
            -1e4f64..1e4,
            any::<f64>().prop_filter("finite", |v| v.is_finite()),
            (-1000i64..1000).prop_map(|i| i as f64 / 8.0),
        ]
    }

    fn arb_command() -> impl Strategy<Value = Command> {
        let column = prop_oneof![Just(Column::Forward), Just(Column::Reverse)];
        prop_oneof![
            arb_f64().prop_map(Command::SetTarget),
            Just(Command::TargetQuery),
            Just(Command::Start),
            Just(Command::Stop),
            Just(Command::PositionQuery),
            Just(Command::StatusQuery),
            arb_f64().prop_map(Command::SetVelocity),
            Just(Command::VelocityQuery),
            Just(Command::ClearFault),
            Just(Command::TableClear),
            (column.clone(), 0usize..100_000, proptest::collection::vec(arb_f64(), 0..40))
                .prop_map(|(column, start, values)| Command::TableData { column, start, values }),
            column.prop_map(Command::TablePointsQuery),
            Just(Command::TableLoad),
            any::<bool>().prop_map(Command::SetCorrection),
            Just(Command::CorrectionQuery),
            Just(Command::ErrorQuery),
            Just(Command::ClearStatus),
            Just(Command::Identify),
        ]
    }

    proptest! {
        #[test]
        fn command_round_trip(cmd in arb_command(), controller in 1u32..100, axis in 1u32..100) {
            let address = Address { controller, axis };
            let bytes = cmd.encode(address);
            prop_assert!(bytes.len() < 2048);
            let mut d = Decoder::default();
            d.push(&bytes);
            let line = d.next_line().unwrap().unwrap();
            prop_assert!(d.next_line().is_none());
            let parsed = Command::parse(&line).unwrap();
            prop_assert_eq!(parsed.address, cmd.is_axis_command().then_some(address));
            prop_assert_eq!(parsed.command, cmd);
        }

        #[test]
        fn number_round_trip(v in arb_f64()) {
            let s = format_number(v);
            prop_assert!(s.len() <= 24, "{}", s);
            prop_assert_eq!(parse_number(&s).unwrap(), v);
        }

        #[test]
        fn error_entry_round_trip(code in any::<i32>(), text in "[ -~]{0,80}") {
            let e = ErrorEntry::new(code as i64, text);
            prop_assert_eq!(ErrorEntry::parse(&e.to_line()).unwrap(), e);
        }

        #[test]
        fn status_round_trip(moving: bool, in_position: bool, fault: bool, correction: bool, limit in 0u8..3) {
            let status = PositionerStatus {
                moving,
                in_position,
                fault: fault.then(|| DeviceFault { code: 1, text: "f".into() }),
                limit: [None, Some(Limit::Lower), Some(Limit::Upper)][limit as usize],
                correction_enabled: correction,
            };
            let w = StatusWord::from_status(&status);
            prop_assert_eq!(StatusWord::parse(&w.to_string()).unwrap(), w);
            prop_assert_eq!(w.fault(), fault);
            prop_assert_eq!(w.to_status(status.fault.clone()), status);
        }

        #[test]
        fn a_line_split_anywhere_decodes_the_same(cmd in arb_command()) {
            let bytes = cmd.encode(Address::default());
            let whole = decode_all(&[&bytes], Decoder::DEFAULT_MAX_LINE);
            prop_assert_eq!(whole.len(), 1);
            // Split at every boundary, and byte by byte.
            for at in 0..=bytes.len() {
                prop_assert_eq!(&decode_all(&[&bytes[..at], &bytes[at..]], Decoder::DEFAULT_MAX_LINE), &whole);
            }
            let singles: Vec<&[u8]> = bytes.chunks(1).collect();
            prop_assert_eq!(&decode_all(&singles, Decoder::DEFAULT_MAX_LINE), &whole);
        }

        #[test]
        fn arbitrary_bytes_never_panic_and_chunking_does_not_matter(
            bytes in proptest::collection::vec(any::<u8>(), 0..600),
            sizes in proptest::collection::vec(1usize..40, 1..20),
            max in 1usize..64,
        ) {
            let whole = decode_all(&[&bytes], max);
            let mut chunks = Vec::new();
            let mut rest = &bytes[..];
            for s in sizes.iter().cycle() {
                if rest.is_empty() { break; }
                let (a, b) = rest.split_at((*s).min(rest.len()));
                chunks.push(a);
                rest = b;
            }
            prop_assert_eq!(decode_all(&chunks, max), whole.clone());
            for line in whole.into_iter().flatten() {
                prop_assert!(line.len() <= max);
                let _ = Command::parse(&line);
                let _ = parse_number(&line);
                let _ = StatusWord::parse(&line);
                let _ = ErrorEntry::parse(&line);
            }
        }
    }
}
