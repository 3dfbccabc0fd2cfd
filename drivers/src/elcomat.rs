//! Moeller-Wedel ELCOMAT autocollimator over RS-232: a sans-IO codec and an
//! async driver generic over its byte transport.
//!
//! # The protocol as implemented
//!
//! Link: RS-232, 8 data bits, no parity, 1 stop bit, no flow control; the baud
//! rate is the caller's (the instrument's setting).
//!
//! | direction | bytes | meaning |
//! |---|---|---|
//! | host -> instrument | `a` CR LF | one absolute measurement |
//! | host -> instrument | `r` CR LF | one relative measurement (relative to the zero stored in the instrument) |
//! | instrument -> host | `4 003 <x> <y>` CR LF | absolute reading, X and Y valid |
//! | instrument -> host | `2 103 <x> <y>` CR LF | relative reading, X and Y valid |
//! | instrument -> host | `4 000` CR LF / `2 100` CR LF | no reflection (the simulator's convention, see below) |
//!
//! A reply is `<type> <status> [<x> <y>]`: fields separated by ASCII
//! whitespace; `<type>` is `4` (absolute) or `2` (relative); `<status>` is
//! exactly three digits whose last digit tells which axes are valid (`1` X,
//! `2` Y, `3` both, `0` none); `<x>` and `<y>` are signed decimals in
//! arcseconds (`-12.35`). A reply whose validity digit is not 3 is the
//! instrument saying it has no (complete) reading: the driver reports it as a
//! [`ErrorKind::Device`] error whose code is the status field as an integer
//! (`4 000` -> code 0, `2 100` -> code 100), and [`Autocollimator::status`]
//! answers [`AcState::NoReflection`] for it.
//!
//! ## What was looked up
//!
//! No Moeller-Wedel manual or interface description was found in the searched
//! documentation. What is here comes from third-party code that talks to real
//! units:
//!
//! - LNLS (James Citadini), Python module "Elcomat communication" (several
//!   copies found by code search; the index did not name their repository):
//!   serial 8N1; commands `a` (absolute) and `r` (relative) sent with CR LF;
//!   accepted replies are exactly `4 003 <x> <y>` after `a` and `2 103 <x> <y>`
//!   after `r`, split on CR; the values are arcseconds (converted to degrees
//!   by /3600 and to radians by /206264.8).
//! - Diamond Light Source EPICS support, `dls-controls/elcomat3000`
//!   (`elcomat3000App/src/elcomat3000.cpp`, `etc/simulations/elcomat3000.py`)
//!   and `dls-controls/ADElcomat` (`ADElcomatApp/src/ADElcomat.cpp`,
//!   `etc/simulations/elcomat.py`): commands are sent with LF and replies are
//!   read up to CR; the second field is a status whose third digit means
//!   `1` = X valid, `2` = Y valid, `3` = both valid; `A` / `R` start
//!   continuous output (types `3 003` / `1 103`), `s` stops it, `d` returns a
//!   type-8 device-information line; values in arcseconds.
//!
//! ## What was chosen here (not documented by what was found)
//!
//! - The reply to a measurement with no reflection. By the DLS reading of the
//!   status digit, "nothing valid" is a validity digit of 0; the simulator
//!   answers `4 000` (after `a`) or `2 100` (after `r`) with no value fields.
//!   The decoder also accepts value fields after an invalid status (ignored,
//!   but they must be numbers), in case a real unit sends them. A partially
//!   valid reply (validity 1 or 2) is a device error too: the trait needs both
//!   axes.
//! - No zero-setting command: none was found (`s` is "stop continuous
//!   output" in the DLS code, not "set zero"), so only `a` and `r` are sent.
//!   The simulator's relative zero is part of its configuration.
//! - Line ends: commands are sent with CR LF (as LNLS does); replies may end
//!   in CR LF, a lone LF or a lone CR (DLS reads up to CR). Empty and blank
//!   lines are skipped. A line longer than [`MAX_LINE`] bytes without a line
//!   end is garbled; the rest of it, up to the next line end, is discarded.
//! - Values are printed with [`REPLY_DECIMALS`] decimals (0.01 arcsec).
//! - The streaming (`A`/`R`/`s`) and device-information (`d`) commands are
//!   not used.
//!
//! # The driver
//!
//! [`ElcomatDriver`] runs over any `AsyncRead + AsyncWrite` byte transport (a
//! [`tokio_serial::SerialStream`] from [`ElcomatDriver::open_serial`], a pty,
//! an in-memory duplex). Every request has its own deadline (default
//! [`DEFAULT_TIMEOUT`], 2 s), measured on the real clock because a real
//! instrument can hang. Before each request it discards stale input: bytes
//! already waiting on the transport, complete replies not yet taken, and (if
//! a line was cut in the middle) the rest of that line, so that a late reply
//! to a request that timed out is not taken as the answer to the next one. A
//! reply of the other type (an absolute reply while waiting for a relative
//! one) is discarded as stale too. The protocol has no sequence numbers, so a
//! late reply of the right type that arrives after the next request was sent
//! cannot be told from the answer: keep the timeout above the instrument's
//! worst reply time.
//!
//! Faults: no reply within the deadline -> [`ErrorKind::Timeout`]; end of
//! file or an I/O error -> [`ErrorKind::Disconnected`] (also when part of a
//! line had arrived: a truncated line followed by a closed port is a
//! disconnection, not a garbled frame); a line that does not decode ->
//! [`ErrorKind::Garbled`] (the receive buffer is discarded; the next request
//! works normally); an out-of-range reply -> [`ErrorKind::Device`] with the
//! device's status code.

use crate::error::{DriverError, ErrorKind, Result};
use crate::traits::{AcReading, AcState, Autocollimator};
use async_trait::async_trait;
use std::collections::VecDeque;
use std::fmt;
use std::future::poll_fn;
use std::pin::Pin;
use std::task::Poll;
use std::time::{Duration, Instant};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt, ReadBuf};

/// Longest reply or command line accepted, bytes (without the line end).
pub const MAX_LINE: usize = 256;

/// Decimals of the X and Y values in an encoded reply.
pub const REPLY_DECIMALS: usize = 2;

/// Default deadline of one request.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(2);

/// Status of a valid absolute reading (`4 003`).
pub const STATUS_ABSOLUTE_VALID: u16 = 3;
/// Status of a valid relative reading (`2 103`).
pub const STATUS_RELATIVE_VALID: u16 = 103;
/// Status of an absolute request with no reflection (`4 000`, the simulator's convention).
pub const STATUS_ABSOLUTE_NO_REFLECTION: u16 = 0;
/// Status of a relative request with no reflection (`2 100`, the simulator's convention).
pub const STATUS_RELATIVE_NO_REFLECTION: u16 = 100;

/// Most stale bytes discarded before one request (a unit left streaming would
/// otherwise keep the drain busy forever).
const MAX_DRAIN: usize = 64 * 1024;

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

enum LineEvent<'a> {
    Line(&'a [u8]),
    TooLong,
}

impl LineFramer {
    fn push(&mut self, bytes: &[u8], mut emit: impl FnMut(LineEvent<'_>)) {
        for &b in bytes {
            let after_cr = std::mem::replace(&mut self.last_cr, b == b'\r');
            if b == b'\n' && after_cr {
                continue;
            }
            if b == b'\r' || b == b'\n' {
                if self.skipping {
                    self.skipping = false;
                } else if !self.buf.iter().all(|c| c.is_ascii_whitespace()) {
                    emit(LineEvent::Line(&self.buf));
                }
                self.buf.clear();
                continue;
            }
            if self.skipping {
                continue;
            }
            if self.buf.len() >= MAX_LINE {
                emit(LineEvent::TooLong);
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
        let ready = &mut self.ready;
        self.framer.push(bytes, |ev| {
            ready.push_back(match ev {
                LineEvent::Line(line) => decode_reply(line),
                LineEvent::TooLong => Err(DecodeError::LineTooLong),
            })
        });
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
        let ready = &mut self.ready;
        self.framer.push(bytes, |ev| {
            ready.push_back(match ev {
                LineEvent::Line(line) => decode_command(line),
                LineEvent::TooLong => Err(DecodeError::LineTooLong),
            })
        });
    }

    /// The next complete command or decode error, if any.
    pub fn next_command(&mut self) -> Option<Result<Command, DecodeError>> {
        self.ready.pop_front()
    }
}

/// The ELCOMAT driver over a byte transport `T`. See the module documentation.
pub struct ElcomatDriver<T> {
    io: T,
    name: String,
    timeout: Duration,
    decoder: Decoder,
}

impl<T> fmt::Debug for ElcomatDriver<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ElcomatDriver")
            .field("name", &self.name)
            .field("timeout", &self.timeout)
            .field("buffered", &self.decoder.buffered_len())
            .finish_non_exhaustive()
    }
}

impl ElcomatDriver<tokio_serial::SerialStream> {
    /// Open a serial port: `baud`, 8N1, no flow control.
    ///
    /// Errors: a bad argument is [`ErrorKind::Usage`]; a port that cannot be
    /// opened is [`ErrorKind::Disconnected`].
    pub fn open_serial(path: &str, baud: u32) -> Result<Self> {
        use tokio_serial::SerialPortBuilderExt;
        let name = format!("elcomat {path}");
        let stream = tokio_serial::new(path, baud)
            .data_bits(tokio_serial::DataBits::Eight)
            .parity(tokio_serial::Parity::None)
            .stop_bits(tokio_serial::StopBits::One)
            .flow_control(tokio_serial::FlowControl::None)
            .open_native_async()
            .map_err(|e| {
                let kind = match e.kind() {
                    tokio_serial::ErrorKind::InvalidInput => ErrorKind::Usage,
                    _ => ErrorKind::Disconnected,
                };
                tracing::warn!(port = path, baud, error = %e, "cannot open the ELCOMAT serial port");
                DriverError::new(kind, name.clone(), format!("cannot open {path} at {baud} baud: {e}"))
            })?;
        Ok(Self::new(stream).with_name(name))
    }
}

impl<T> ElcomatDriver<T>
where
    T: AsyncRead + AsyncWrite + Unpin + Send,
{
    /// A driver over an open transport, named `"elcomat"`, with the default
    /// timeout.
    pub fn new(io: T) -> Self {
        Self { io, name: "elcomat".to_string(), timeout: DEFAULT_TIMEOUT, decoder: Decoder::new() }
    }

    /// Set the name used in logs and errors.
    pub fn with_name(mut self, name: impl Into<String>) -> Self {
        self.name = name.into();
        self
    }

    /// Set the deadline of each request.
    pub fn with_timeout(mut self, timeout: Duration) -> Self {
        self.timeout = timeout;
        self
    }

    /// Change the deadline of each request.
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.timeout = timeout;
    }

    /// The deadline of each request.
    pub fn timeout(&self) -> Duration {
        self.timeout
    }

    /// The transport back.
    pub fn into_inner(self) -> T {
        self.io
    }

    /// One absolute measurement (`a`).
    pub async fn read_absolute(&mut self) -> Result<AcReading> {
        self.reading(Command::Absolute).await
    }

    /// One relative measurement (`r`), relative to the zero stored in the
    /// instrument.
    pub async fn read_relative(&mut self) -> Result<AcReading> {
        self.reading(Command::Relative).await
    }

    async fn reading(&mut self, cmd: Command) -> Result<AcReading> {
        let reply = self.exchange(cmd).await?;
        reply.reading().ok_or_else(|| self.device_error(&reply))
    }

    fn device_error(&self, reply: &Reply) -> DriverError {
        let text = String::from_utf8_lossy(&encode_reply(reply)).trim_end().to_string();
        tracing::warn!(instrument = %self.name, status = reply.status, reply = %text, "ELCOMAT reports no valid reading");
        DriverError::device(
            self.name.clone(),
            i64::from(reply.status),
            format!("{} (reply {text:?})", reply.validity_text()),
        )
    }

    /// One request and its reply, whatever the reply's status: drains stale
    /// input, sends `cmd`, waits (up to the timeout) for a reply of the
    /// matching type.
    pub async fn exchange(&mut self, cmd: Command) -> Result<Reply> {
        self.drain_stale().await;
        let started = Instant::now();
        let limit = self.timeout;
        match tokio::time::timeout(limit, self.send_and_receive(cmd)).await {
            Err(_) => {
                tracing::warn!(instrument = %self.name, command = %cmd.letter(), ?limit, "ELCOMAT did not answer");
                Err(DriverError::timeout(self.name.clone(), &format!("'{}'", cmd.letter()), limit))
            }
            Ok(Ok(reply)) => {
                tracing::debug!(instrument = %self.name, command = %cmd.letter(), ?reply, elapsed = ?started.elapsed(), "ELCOMAT exchange");
                Ok(reply)
            }
            Ok(Err(e)) => {
                tracing::warn!(instrument = %self.name, command = %cmd.letter(), error = %e, "ELCOMAT exchange failed");
                Err(e)
            }
        }
    }

    /// Discard bytes already waiting on the transport and whatever the
    /// decoder holds. Stops at the first read that would block, at end of
    /// file or an error (the exchange then meets them), or after
    /// [`MAX_DRAIN`] bytes.
    async fn drain_stale(&mut self) {
        let mut drained = 0usize;
        let mut buf = [0u8; 256];
        let io = &mut self.io;
        let decoder = &mut self.decoder;
        poll_fn(|cx| {
            while drained < MAX_DRAIN {
                let mut rb = ReadBuf::new(&mut buf);
                match Pin::new(&mut *io).poll_read(cx, &mut rb) {
                    Poll::Ready(Ok(())) if !rb.filled().is_empty() => {
                        drained += rb.filled().len();
                        decoder.push(rb.filled());
                    }
                    _ => break,
                }
            }
            Poll::Ready(())
        })
        .await;
        let discarded = self.decoder.discard_pending();
        if drained > 0 || discarded != Discarded::default() {
            tracing::warn!(
                instrument = %self.name,
                stale_bytes = drained,
                stale_lines = discarded.lines,
                partial_bytes = discarded.partial_bytes,
                "discarded stale input before a request"
            );
        }
    }

    async fn send_and_receive(&mut self, cmd: Command) -> Result<Reply> {
        let disconnected = |name: &str, what: &str, e: std::io::Error| {
            DriverError::new(ErrorKind::Disconnected, name, format!("{what}: {e}"))
        };
        let bytes = encode_command(cmd);
        self.io.write_all(&bytes).await.map_err(|e| disconnected(&self.name, "write failed", e))?;
        self.io.flush().await.map_err(|e| disconnected(&self.name, "flush failed", e))?;
        let want = cmd.reply_kind();
        let mut buf = [0u8; 256];
        loop {
            while let Some(item) = self.decoder.next_reply() {
                match item {
                    Ok(reply) if reply.kind == want => return Ok(reply),
                    Ok(reply) => {
                        tracing::warn!(instrument = %self.name, command = %cmd.letter(), ?reply, "discarded a reply of the other type (stale)");
                    }
                    Err(e) => {
                        let discarded = self.decoder.discard_pending();
                        return Err(DriverError::new(
                            ErrorKind::Garbled,
                            self.name.clone(),
                            format!(
                                "garbled reply to '{}': {e} ({} more lines discarded)",
                                cmd.letter(),
                                discarded.lines
                            ),
                        ));
                    }
                }
            }
            let n = self.io.read(&mut buf).await.map_err(|e| disconnected(&self.name, "read failed", e))?;
            if n == 0 {
                let partial = self.decoder.discard_pending().partial_bytes;
                let msg = if partial > 0 {
                    format!("port closed after {partial} bytes of an unterminated reply to '{}'", cmd.letter())
                } else {
                    format!("port closed while waiting for the reply to '{}'", cmd.letter())
                };
                return Err(DriverError::new(ErrorKind::Disconnected, self.name.clone(), msg));
            }
            self.decoder.push(&buf[..n]);
        }
    }
}

#[async_trait]
impl<T> Autocollimator for ElcomatDriver<T>
where
    T: AsyncRead + AsyncWrite + Unpin + Send,
{
    fn name(&self) -> &str {
        &self.name
    }

    /// `a`: an absolute reading; no reflection is a device error.
    async fn read(&mut self) -> Result<AcReading> {
        self.read_absolute().await
    }

    /// `a`, judged by its status: `InRange` when X and Y are valid,
    /// `NoReflection` otherwise. Link faults are errors.
    async fn status(&mut self) -> Result<AcState> {
        let reply = self.exchange(Command::Absolute).await?;
        Ok(if reply.reading().is_some() { AcState::InRange } else { AcState::NoReflection })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use tokio::io::{AsyncBufReadExt, BufReader, DuplexStream, duplex};

    fn decode_all(bytes: &[u8]) -> Vec<Result<Reply, DecodeError>> {
        let mut d = Decoder::new();
        d.push(bytes);
        std::iter::from_fn(|| d.next_reply()).collect()
    }

    #[test]
    fn commands_encode_and_decode() {
        assert_eq!(encode_command(Command::Absolute), b"a\r\n");
        assert_eq!(encode_command(Command::Relative), b"r\r\n");
        let mut d = CommandDecoder::new();
        d.push(b"a\r\nr\nx\r\n a \rA\r\n");
        let got: Vec<_> = std::iter::from_fn(|| d.next_command()).collect();
        assert_eq!(got.len(), 5);
        assert_eq!(got[0], Ok(Command::Absolute));
        assert_eq!(got[1], Ok(Command::Relative));
        assert!(matches!(got[2], Err(DecodeError::UnknownCommand { .. })));
        assert_eq!(got[3], Ok(Command::Absolute));
        // Upper-case `A` starts streaming on a real unit: not served here.
        assert!(matches!(got[4], Err(DecodeError::UnknownCommand { .. })));
    }

    #[test]
    fn replies_of_every_form_decode() {
        assert_eq!(decode_reply(b"4 003 -12.35 3.20"), Ok(Reply::absolute(-12.35, 3.2)));
        assert_eq!(decode_reply(b"2 103 0.00 -0.01"), Ok(Reply::relative(0.0, -0.01)));
        assert_eq!(decode_reply(b"4 000"), Ok(Reply::no_reflection(ReplyKind::Absolute)));
        assert_eq!(decode_reply(b"2 100"), Ok(Reply::no_reflection(ReplyKind::Relative)));
        // DLS test data: six decimals and tab separators are fine.
        assert_eq!(decode_reply(b"4\t003  4.500000 2.300000"), Ok(Reply::absolute(4.5, 2.3)));
        // An invalid status with values (a real unit may send them).
        let r = decode_reply(b"4 001 12.00 0.00").unwrap();
        assert_eq!((r.validity(), r.reading()), (1, None));
        assert_eq!(Reply::no_reflection(ReplyKind::Absolute).reading(), None);
        assert_eq!(encode_reply(&Reply::absolute(-12.345, 3.2)), b"4 003 -12.35 3.20\r\n".to_vec());
        assert_eq!(encode_reply(&Reply::no_reflection(ReplyKind::Relative)), b"2 100\r\n".to_vec());
    }

    #[test]
    fn garbled_lines_are_errors() {
        let bad: [&[u8]; 9] = [
            b"4 003 1.0",
            b"4 003 1.0 2.0 3.0",
            b"5 003 1.0 2.0",
            b"4 03 1.0 2.0",
            b"4 0x3 1.0 2.0",
            b"4 003 1.0 abc",
            b"4 003 inf 2.0",
            b"4 003",
            b"4 003 \xff 2.0",
        ];
        for line in bad {
            assert!(decode_reply(line).is_err(), "{:?}", String::from_utf8_lossy(line));
        }
        assert!(matches!(decode_reply(b"4 003"), Err(DecodeError::MissingValues { .. })));
        assert!(matches!(decode_reply(b"4 003 \xff 2.0"), Err(DecodeError::NotAscii { .. })));
    }

    #[test]
    fn line_ends_and_blank_lines() {
        let got = decode_all(b"4 003 1.00 2.00\r\n2 103 3.00 4.00\n4 000\r\r\n  \r\n2 100\r");
        assert_eq!(
            got,
            vec![
                Ok(Reply::absolute(1.0, 2.0)),
                Ok(Reply::relative(3.0, 4.0)),
                Ok(Reply::no_reflection(ReplyKind::Absolute)),
                Ok(Reply::no_reflection(ReplyKind::Relative)),
            ]
        );
    }

    #[test]
    fn an_overlong_line_is_one_error_then_decoding_resumes() {
        let mut bytes = vec![b'7'; 3 * MAX_LINE];
        bytes.extend_from_slice(b"\r\n4 003 1.00 2.00\r\n");
        let got = decode_all(&bytes);
        assert_eq!(got, vec![Err(DecodeError::LineTooLong), Ok(Reply::absolute(1.0, 2.0))]);
        // Exactly MAX_LINE bytes is still a line (garbled, but not too long).
        let mut exact = vec![b' '; MAX_LINE - 5];
        exact.extend_from_slice(b"4 000\r\n");
        assert_eq!(decode_all(&exact), vec![Ok(Reply::no_reflection(ReplyKind::Absolute))]);
    }

    #[test]
    fn discard_pending_skips_the_rest_of_a_cut_line() {
        let mut d = Decoder::new();
        d.push(b"4 003 1.00 2.00\r\n4 003 5.0");
        assert_eq!(d.discard_pending(), Discarded { lines: 1, partial_bytes: 9 });
        d.push(b"0 6.00\r\n2 103 7.00 8.00\r\n");
        assert_eq!(d.next_reply(), Some(Ok(Reply::relative(7.0, 8.0))));
        assert_eq!(d.next_reply(), None);
        // Nothing partial: nothing skipped.
        d.push(b"4 000\r\n");
        assert_eq!(d.discard_pending(), Discarded { lines: 1, partial_bytes: 0 });
        d.push(b"4 000\r\n");
        assert_eq!(d.next_reply(), Some(Ok(Reply::no_reflection(ReplyKind::Absolute))));
    }

    fn reply_strategy() -> impl Strategy<Value = Reply> {
        let kind = prop_oneof![Just(ReplyKind::Absolute), Just(ReplyKind::Relative)];
        (kind, 0u16..1000, proptest::option::of((-1.0e5..1.0e5f64, -1.0e5..1.0e5f64))).prop_map(
            |(kind, status, values)| {
                // A valid status needs values.
                let status = if values.is_none() && status % 10 == 3 { status - 3 } else { status };
                Reply { kind, status, values }
            },
        )
    }

    fn same_within_print(a: &Reply, b: &Reply) -> bool {
        let tol = 0.5 * 10f64.powi(-(REPLY_DECIMALS as i32)) + 1e-9;
        a.kind == b.kind
            && a.status == b.status
            && match (a.values, b.values) {
                (None, None) => true,
                (Some((x, y)), Some((x2, y2))) => (x - x2).abs() <= tol && (y - y2).abs() <= tol,
                _ => false,
            }
    }

    /// A stream of lines: valid replies, garbled lines and an overlong one.
    fn stream_strategy() -> impl Strategy<Value = Vec<u8>> {
        let line = prop_oneof![
            4 => reply_strategy().prop_map(|r| encode_reply(&r)),
            1 => proptest::collection::vec(any::<u8>(), 0..20).prop_map(|mut v| { v.extend_from_slice(b"\r\n"); v }),
            1 => Just(vec![b'9'; MAX_LINE + 10]),
            1 => prop_oneof![Just(b"\n".to_vec()), Just(b"\r".to_vec()), Just(b"\r\n".to_vec())],
        ];
        proptest::collection::vec(line, 0..8).prop_map(|v| v.concat())
    }

    proptest! {
        #[test]
        fn every_reply_form_round_trips(r in reply_strategy()) {
            let got = decode_all(&encode_reply(&r));
            prop_assert_eq!(got.len(), 1);
            let back = got[0].clone().unwrap();
            prop_assert!(same_within_print(&r, &back), "{:?} -> {:?}", r, back);
            // Printing a decoded reply again gives the same bytes.
            prop_assert_eq!(encode_reply(&back), encode_reply(&r));
        }

        #[test]
        fn chunk_boundaries_do_not_matter(bytes in stream_strategy(), cuts in proptest::collection::vec(any::<prop::sample::Index>(), 0..6)) {
            let whole = decode_all(&bytes);
            // Every single boundary.
            for i in 0..=bytes.len() {
                let mut d = Decoder::new();
                d.push(&bytes[..i]);
                d.push(&bytes[i..]);
                let split: Vec<_> = std::iter::from_fn(|| d.next_reply()).collect();
                prop_assert_eq!(&split, &whole, "split at {}", i);
            }
            // Several boundaries at once.
            let mut at: Vec<usize> = cuts.iter().map(|c| c.index(bytes.len() + 1)).collect();
            at.sort_unstable();
            let mut d = Decoder::new();
            let mut start = 0;
            for &c in &at {
                d.push(&bytes[start..c]);
                start = c;
            }
            d.push(&bytes[start..]);
            let split: Vec<_> = std::iter::from_fn(|| d.next_reply()).collect();
            prop_assert_eq!(&split, &whole);
        }

        #[test]
        fn arbitrary_bytes_never_panic(chunks in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..400), 0..6)) {
            let mut d = Decoder::new();
            let mut c = CommandDecoder::new();
            for chunk in &chunks {
                d.push(chunk);
                c.push(chunk);
                prop_assert!(d.buffered_len() <= MAX_LINE);
                while d.next_reply().is_some() {}
                while c.next_command().is_some() {}
            }
            d.discard_pending();
            prop_assert_eq!(d.buffered_len(), 0);
        }
    }

    /// A scripted instrument on the far end of a duplex: reads one command
    /// line, then the test writes what it wants.
    struct FakeUnit {
        lines: BufReader<tokio::io::ReadHalf<DuplexStream>>,
        tx: tokio::io::WriteHalf<DuplexStream>,
    }

    impl FakeUnit {
        async fn expect(&mut self, cmd: &str) {
            let mut line = String::new();
            self.lines.read_line(&mut line).await.unwrap();
            assert_eq!(line, format!("{cmd}\r\n"));
        }
        async fn send(&mut self, bytes: &[u8]) {
            self.tx.write_all(bytes).await.unwrap();
        }
    }

    fn rig(timeout: Duration) -> (ElcomatDriver<DuplexStream>, FakeUnit) {
        let (a, b) = duplex(4096);
        let (rx, tx) = tokio::io::split(b);
        (ElcomatDriver::new(a).with_timeout(timeout), FakeUnit { lines: BufReader::new(rx), tx })
    }

    #[tokio::test(start_paused = true)]
    async fn a_late_reply_is_not_the_answer_to_the_next_request() {
        let (mut drv, mut unit) = rig(Duration::from_secs(2));
        let first = tokio::spawn(async move {
            let e = drv.read().await.unwrap_err();
            (drv, e)
        });
        unit.expect("a").await;
        // No answer: the driver times out (virtual time).
        let (mut drv, e) = first.await.unwrap();
        assert_eq!(e.kind, ErrorKind::Timeout);
        // The late answer arrives, part of another line too.
        unit.send(b"4 003 1.00 1.00\r\n4 003 9.").await;
        let second = tokio::spawn(async move { (drv.read().await, drv) });
        unit.expect("a").await;
        unit.send(b"99 9.99\r\n4 003 2.00 -2.00\r\n").await;
        let (r, _drv) = second.await.unwrap();
        assert_eq!(r.unwrap(), AcReading { x_arcsec: 2.0, y_arcsec: -2.0 });
    }

    #[tokio::test(start_paused = true)]
    async fn a_reply_of_the_other_type_is_skipped_and_faults_are_classified() {
        let (mut drv, mut unit) = rig(Duration::from_millis(500));
        let task = tokio::spawn(async move {
            let rel = drv.read_relative().await;
            let dev = drv.read().await;
            let st = drv.status().await;
            let garbled = drv.read().await;
            let ok = drv.read().await;
            let closed = drv.read().await;
            (rel, dev, st, garbled, ok, closed)
        });
        unit.expect("r").await;
        unit.send(b"4 003 1.00 1.00\r\n2 103 0.50 -0.25\r\n").await;
        unit.expect("a").await;
        unit.send(b"4 000\r\n").await;
        unit.expect("a").await;
        unit.send(b"4 000\r\n").await;
        unit.expect("a").await;
        unit.send(b"4 0\xff3 ### 1.00\r\n").await;
        unit.expect("a").await;
        unit.send(b"4 003 3.00 4.00\r\n").await;
        unit.expect("a").await;
        unit.send(b"4 003 1.2").await;
        drop(unit);
        let (rel, dev, st, garbled, ok, closed) = task.await.unwrap();
        assert_eq!(rel.unwrap(), AcReading { x_arcsec: 0.5, y_arcsec: -0.25 });
        let dev = dev.unwrap_err();
        assert_eq!((dev.kind, dev.code), (ErrorKind::Device, Some(0)));
        assert!(dev.message.contains("no reflection"), "{dev}");
        assert_eq!(st.unwrap(), AcState::NoReflection);
        assert_eq!(garbled.unwrap_err().kind, ErrorKind::Garbled);
        assert_eq!(ok.unwrap(), AcReading { x_arcsec: 3.0, y_arcsec: 4.0 });
        let closed = closed.unwrap_err();
        assert_eq!(closed.kind, ErrorKind::Disconnected);
        assert!(closed.message.contains("unterminated"), "{closed}");
    }

    #[tokio::test]
    async fn opening_a_missing_port_is_a_disconnection() {
        let e = ElcomatDriver::open_serial("/dev/does-not-exist-elcomat", 9600).unwrap_err();
        assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
    }
}
