//! The sans-IO codec: commands and replies (encode and decode), the line
//! framing, and the incremental reply and command decoders. Bytes in, frames
//! out: no port, no clock.

use crate::traits::AcReading;
use std::collections::VecDeque;

/// Longest reply or command line accepted, bytes (without the line end).
pub const MAX_LINE: usize = 256;

/// Decimals of the X and Y values in an encoded reply.
pub const REPLY_DECIMALS: usize = 2;

/// Status of a valid absolute reading (`4 003`).
pub const STATUS_ABSOLUTE_VALID: u16 = 3;
/// Status of a valid relative reading (`2 103`).
pub const STATUS_RELATIVE_VALID: u16 = 103;
/// Status of an absolute request with no reflection (`4 000`, the simulator's convention).
pub const STATUS_ABSOLUTE_NO_REFLECTION: u16 = 0;
/// Status of a relative request with no reflection (`2 100`, the simulator's convention).
pub const STATUS_RELATIVE_NO_REFLECTION: u16 = 100;

/// A request to the instrument.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Command {
    /// `a`: one absolute measurement.
    Absolute,
    /// `r`: one relative measurement.
    Relative,
}

impl Command {
    /// The command's letter.
    pub fn letter(self) -> char {
        match self {
            Command::Absolute => 'a',
            Command::Relative => 'r',
        }
    }

    /// The type of reply this command is answered with.
    pub fn reply_kind(self) -> ReplyKind {
        match self {
            Command::Absolute => ReplyKind::Absolute,
            Command::Relative => ReplyKind::Relative,
        }
    }
}

/// The bytes of a command: its letter and CR LF.
pub fn encode_command(cmd: Command) -> Vec<u8> {
    vec![cmd.letter() as u8, b'\r', b'\n']
}

/// Decode one command line (without its line end): `a` or `r`, surrounding
/// whitespace ignored.
pub fn decode_command(line: &[u8]) -> Result<Command, DecodeError> {
    if !line.is_ascii() {
        return Err(DecodeError::NotAscii { line: show(line) });
    }
    match std::str::from_utf8(line).unwrap_or_default().trim() {
        "a" => Ok(Command::Absolute),
        "r" => Ok(Command::Relative),
        other => Err(DecodeError::UnknownCommand { line: other.to_string() }),
    }
}

/// The type of a reply (its first field).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ReplyKind {
    /// Type `4`: the answer to `a`.
    Absolute,
    /// Type `2`: the answer to `r`.
    Relative,
}

impl ReplyKind {
    /// The type digit on the wire.
    pub fn type_digit(self) -> char {
        match self {
            ReplyKind::Absolute => '4',
            ReplyKind::Relative => '2',
        }
    }
}

/// One reply line, decoded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reply {
    /// Absolute or relative.
    pub kind: ReplyKind,
    /// The three-digit status field as an integer (0..=999).
    pub status: u16,
    /// The X and Y fields, arcsec, when the reply carries them.
    pub values: Option<(f64, f64)>,
}

impl Reply {
    /// A valid absolute reading: `4 003 <x> <y>`.
    pub fn absolute(x_arcsec: f64, y_arcsec: f64) -> Self {
        Self { kind: ReplyKind::Absolute, status: STATUS_ABSOLUTE_VALID, values: Some((x_arcsec, y_arcsec)) }
    }

    /// A valid relative reading: `2 103 <x> <y>`.
    pub fn relative(x_arcsec: f64, y_arcsec: f64) -> Self {
        Self { kind: ReplyKind::Relative, status: STATUS_RELATIVE_VALID, values: Some((x_arcsec, y_arcsec)) }
    }

    /// The no-reflection reply to a request of `kind`: `4 000` or `2 100`.
    pub fn no_reflection(kind: ReplyKind) -> Self {
        let status = match kind {
            ReplyKind::Absolute => STATUS_ABSOLUTE_NO_REFLECTION,
            ReplyKind::Relative => STATUS_RELATIVE_NO_REFLECTION,
        };
        Self { kind, status, values: None }
    }

    /// The validity digit: 1 X valid, 2 Y valid, 3 both, 0 none.
    pub fn validity(&self) -> u16 {
        self.status % 10
    }

    /// The reading, when both axes are valid.
    pub fn reading(&self) -> Option<AcReading> {
        match (self.validity(), self.values) {
            (3, Some((x_arcsec, y_arcsec))) => Some(AcReading { x_arcsec, y_arcsec }),
            _ => None,
        }
    }

    /// What an invalid status means, for messages.
    pub fn validity_text(&self) -> &'static str {
        match self.validity() {
            3 => "X and Y valid",
            2 => "only Y valid",
            1 => "only X valid",
            0 => "no reflection: neither X nor Y valid",
            _ => "unknown validity",
        }
    }
}

/// The bytes of a reply: `<type> <status:03>[ <x> <y>]` CR LF, values with
/// [`REPLY_DECIMALS`] decimals.
pub fn encode_reply(reply: &Reply) -> Vec<u8> {
    let mut s = format!("{} {:03}", reply.kind.type_digit(), reply.status);
    if let Some((x, y)) = reply.values {
        s.push_str(&format!(" {x:.prec$} {y:.prec$}", prec = REPLY_DECIMALS));
    }
    s.push_str("\r\n");
    s.into_bytes()
}

/// A line that does not decode.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// A byte outside ASCII.
    #[error("non-ASCII bytes in line {line:?}")]
    NotAscii {
        /// The line, shown lossily.
        line: String,
    },
    /// More than [`MAX_LINE`] bytes without a line end.
    #[error("no line end within {MAX_LINE} bytes")]
    LineTooLong,
    /// Not 2 or 4 fields.
    #[error("{count} fields in reply {line:?} (expected 2 or 4)")]
    FieldCount {
        /// How many fields.
        count: usize,
        /// The line.
        line: String,
    },
    /// The first field is not `4` or `2`.
    #[error("unknown reply type {field:?} in {line:?}")]
    UnknownType {
        /// The first field.
        field: String,
        /// The line.
        line: String,
    },
    /// The status is not three digits.
    #[error("bad status {field:?} in {line:?} (expected three digits)")]
    BadStatus {
        /// The status field.
        field: String,
        /// The line.
        line: String,
    },
    /// A value is not a finite signed decimal.
    #[error("bad number {field:?} in {line:?}")]
    BadNumber {
        /// The value field.
        field: String,
        /// The line.
        line: String,
    },
    /// The status says X and Y are valid but the values are missing.
    #[error("valid status without values in {line:?}")]
    MissingValues {
        /// The line.
        line: String,
    },
    /// A command line other than `a` or `r`.
    #[error("unknown command {line:?}")]
    UnknownCommand {
        /// The line.
        line: String,
    },
}

/// A line for an error message: lossy, at most 80 characters.
fn show(line: &[u8]) -> String {
    let s = String::from_utf8_lossy(line);
    if s.chars().count() > 80 { format!("{}...", s.chars().take(80).collect::<String>()) } else { s.into_owned() }
}

/// Decode one reply line (without its line end).
pub fn decode_reply(line: &[u8]) -> Result<Reply, DecodeError> {
    if !line.is_ascii() {
        return Err(DecodeError::NotAscii { line: show(line) });
    }
    let text = std::str::from_utf8(line).unwrap_or_default();
    let fields: Vec<&str> = text.split_ascii_whitespace().collect();
    let line = || show(line);
    if fields.len() != 2 && fields.len() != 4 {
        return Err(DecodeError::FieldCount { count: fields.len(), line: line() });
    }
    let kind = match fields[0] {
        "4" => ReplyKind::Absolute,
        "2" => ReplyKind::Relative,
        other => return Err(DecodeError::UnknownType { field: other.to_string(), line: line() }),
    };
    let st = fields[1];
    if st.len() != 3 || !st.bytes().all(|b| b.is_ascii_digit()) {
        return Err(DecodeError::BadStatus { field: st.to_string(), line: line() });
    }
    let status: u16 = st.parse().map_err(|_| DecodeError::BadStatus { field: st.to_string(), line: line() })?;
    let number = |f: &str| -> Result<f64, DecodeError> {
        let ok_chars = f.bytes().all(|b| b.is_ascii_digit() || matches!(b, b'.' | b'-' | b'+'));
        match f.parse::<f64>() {
            Ok(v) if ok_chars && v.is_finite() => Ok(v),
            _ => Err(DecodeError::BadNumber { field: f.to_string(), line: line() }),
        }
    };
    let values = if fields.len() == 4 { Some((number(fields[2])?, number(fields[3])?)) } else { None };
    if status % 10 == 3 && values.is_none() {
        return Err(DecodeError::MissingValues { line: line() });
    }
    Ok(Reply { kind, status, values })
}

/// Splits a byte stream into lines: CR LF, LF or CR end a line; empty lines
/// are dropped; a line is bounded by [`MAX_LINE`].
#[derive(Debug, Default, Clone)]
struct LineFramer {
    buf: Vec<u8>,
    /// Discard bytes up to the next line end (after an overflow or a resync).
    skipping: bool,
    /// The previous byte was CR (so an LF now is the second half of CR LF).
    last_cr: bool,
}

impl LineFramer {
    /// Feed bytes: each line ended, decoded by `decode` (an overlong one as
    /// [`DecodeError::LineTooLong`]), goes to the back of `ready`.
    fn push<T>(
        &mut self,
        bytes: &[u8],
        decode: fn(&[u8]) -> Result<T, DecodeError>,
        ready: &mut VecDeque<Result<T, DecodeError>>,
    ) {
        for &b in bytes {
            let after_cr = std::mem::replace(&mut self.last_cr, b == b'\r');
            if b == b'\n' && after_cr {
                continue;
            }
            if b == b'\r' || b == b'\n' {
                if self.skipping {
                    self.skipping = false;
                } else if !self.buf.iter().all(|c| c.is_ascii_whitespace()) {
                    ready.push_back(decode(&self.buf));
                }
                self.buf.clear();
                continue;
            }
            if self.skipping {
                continue;
            }
            if self.buf.len() >= MAX_LINE {
                ready.push_back(Err(DecodeError::LineTooLong));
                self.buf.clear();
                self.skipping = true;
                continue;
            }
            self.buf.push(b);
        }
    }

    /// Drop the partial line; if there was one, also skip its remainder.
    /// Returns the number of partial bytes dropped.
    fn resync(&mut self) -> usize {
        let n = self.buf.len();
        if n > 0 {
            self.skipping = true;
        }
        self.buf.clear();
        n
    }
}

/// What [`Decoder::discard_pending`] threw away.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Discarded {
    /// Complete lines (replies or errors) not yet taken.
    pub lines: usize,
    /// Bytes of a partial line.
    pub partial_bytes: usize,
}

/// Incremental reply decoder: push byte chunks of any size, take complete
/// replies (or a [`DecodeError`] per garbled line) in order.
#[derive(Debug, Default, Clone)]
pub struct Decoder {
    framer: LineFramer,
    ready: VecDeque<Result<Reply, DecodeError>>,
}

impl Decoder {
    /// An empty decoder.
    pub fn new() -> Self {
        Self::default()
    }

    /// Feed received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.framer.push(bytes, decode_reply, &mut self.ready);
    }

    /// The next complete reply or decode error, if any.
    pub fn next_reply(&mut self) -> Option<Result<Reply, DecodeError>> {
        self.ready.pop_front()
    }

    /// Bytes held of a line not yet ended (never more than [`MAX_LINE`]).
    pub fn buffered_len(&self) -> usize {
        self.framer.buf.len()
    }

    /// Throw away everything received so far: complete replies not yet
    /// taken, and a partial line together with its remainder (bytes up to the
    /// next line end are skipped).
    pub fn discard_pending(&mut self) -> Discarded {
        let lines = self.ready.len();
        self.ready.clear();
        Discarded { lines, partial_bytes: self.framer.resync() }
    }
}

/// Incremental command decoder for the instrument's side (the simulator).
#[derive(Debug, Default, Clone)]
pub struct CommandDecoder {
    framer: LineFramer,
    ready: VecDeque<Result<Command, DecodeError>>,
}

impl CommandDecoder {
    /// An empty decoder.
    pub fn new() -> Self {
        Self::default()
    }

    /// Feed received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.framer.push(bytes, decode_command, &mut self.ready);
    }

    /// The next complete command or decode error, if any.
    pub fn next_command(&mut self) -> Option<Result<Command, DecodeError>> {
        self.ready.pop_front()
    }
}
