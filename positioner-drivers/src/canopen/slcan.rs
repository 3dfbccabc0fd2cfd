//! SLCAN (the Lawicel serial-line CAN protocol): a USB-CAN adapter (CANable,
//! USBtin and many others) on a serial port, as a [`CanBus`].
//!
//! The protocol is ASCII, every message ended by CR (`\r`); an adapter
//! answers a command with a bare CR (done) or BEL (`\x07`, refused). As
//! python-can's `slcan` interface speaks it (`can/interfaces/slcan.py`, the
//! reference implementation checked here):
//!
//! | host sends | meaning | adapter answers |
//! |---|---|---|
//! | `S0`..`S8`, `S9` | bitrate 10k, 20k, 50k, 100k, 125k, 250k, 500k, 750k/800k, 1M, 83.3k (channel closed) | CR, or BEL |
//! | `O` / `L` / `C` | open / open listen-only / close the channel | CR, or BEL |
//! | `V` / `N` / `F` | version `Vhhss` / serial number `Nxxxx` / status flags `Fxx` | the line, CR |
//! | `tiiildd..` | transmit a standard data frame: 3 hex id, 1 digit length, the data in hex | `z` CR on most adapters, or BEL |
//!
//! The adapter sends every frame it receives from the bus as
//! `tiiildd..` CR (`Tiiiiiiiildd..` for 29-bit ids, `r`/`R` for remote
//! frames: CANopen uses neither, they are skipped). Sans-IO: [`encode`],
//! [`Message::parse`] and the [`LineDecoder`] are pure; [`SlcanBus`] runs them
//! over any async byte stream (a serial port, a pty in tests).

use super::frame::{CanBus, CanFrame};
use async_trait::async_trait;
use std::collections::VecDeque;
use std::fmt;
use std::time::Duration;
use survey_drivers::error::{DriverError, ErrorKind, Result};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};

/// The bitrate commands: `(bit/s, n)` of `Sn`. 750 kbit/s is python-can's
/// value for `S7` and 800 kbit/s Lawicel's; both are accepted.
pub const BITRATES: [(u32, u8); 11] = [
    (10_000, 0),
    (20_000, 1),
    (50_000, 2),
    (100_000, 3),
    (125_000, 4),
    (250_000, 5),
    (500_000, 6),
    (750_000, 7),
    (800_000, 7),
    (1_000_000, 8),
    (83_300, 9),
];

/// How many times a command of the adapter's set-up (`Sn`, `O`) is sent
/// before its fault is the set-up's ([`SlcanBus::open`]).
pub const SETUP_COMMAND_TRIES: u32 = 3;

/// The `Sn` digit of `bitrate`, if an adapter has one.
pub fn bitrate_code(bitrate: u32) -> Option<u8> {
    BITRATES.iter().find(|(b, _)| *b == bitrate).map(|(_, n)| *n)
}

/// One SLCAN message, either way.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Message {
    /// `Sn`: set the bitrate.
    Bitrate(u8),
    /// `O`: open the channel.
    Open,
    /// `L`: open the channel listen-only.
    ListenOnly,
    /// `C`: close the channel.
    Close,
    /// `V`: ask the version; or the answer `Vhhss`.
    Version(Option<(u8, u8)>),
    /// `N`: ask the serial number; or the answer `Nxxxx` (4 characters).
    Serial(Option<[u8; 4]>),
    /// `F`: ask the status flags; or the answer `Fxx`.
    Status(Option<u8>),
    /// `t...`: a standard data frame (host to adapter: transmit; adapter to
    /// host: received).
    Frame(CanFrame),
    /// A 29-bit or remote frame (`T`, `r`, `R`): not CANopen's, skipped.
    OtherFrame,
    /// `z` / `Z`: the adapter queued a transmitted frame.
    TransmitAck,
    /// A bare CR: done.
    Ok,
    /// BEL: refused.
    Error,
}

/// Why a line is not SLCAN.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SlcanError {
    /// Not a message of the protocol.
    #[error("not an SLCAN message: {0:?}")]
    Unknown(String),
    /// A frame with a bad id, length or data.
    #[error("bad SLCAN frame {0:?}")]
    BadFrame(String),
    /// A line longer than [`MAX_LINE`] without a terminator.
    #[error("an SLCAN line longer than {MAX_LINE} bytes")]
    TooLong,
}

/// The longest line: `T` + 8 id + 1 length + 16 data + 4 timestamp digits.
pub const MAX_LINE: usize = 32;

fn hex(b: &[u8]) -> Option<u32> {
    if b.is_empty() || b.len() > 8 || !b.iter().all(u8::is_ascii_hexdigit) {
        return None;
    }
    u32::from_str_radix(std::str::from_utf8(b).ok()?, 16).ok()
}

impl Message {
    /// The bytes of this message, terminator included (`Ok` is a CR, `Error` a BEL).
    pub fn encode(&self) -> Vec<u8> {
        let mut s = match self {
            Message::Bitrate(n) => format!("S{n}"),
            Message::Open => "O".into(),
            Message::ListenOnly => "L".into(),
            Message::Close => "C".into(),
            Message::Version(None) => "V".into(),
            Message::Version(Some((hw, sw))) => format!("V{hw:02}{sw:02}"),
            Message::Serial(None) => "N".into(),
            Message::Serial(Some(n)) => format!("N{}", String::from_utf8_lossy(n)),
            Message::Status(None) => "F".into(),
            Message::Status(Some(f)) => format!("F{f:02X}"),
            Message::Frame(f) => {
                let mut s = format!("t{:03X}{}", f.id(), f.len());
                for b in f.data() {
                    s.push_str(&format!("{b:02X}"));
                }
                s
            }
            Message::OtherFrame => "r0000".into(),
            Message::TransmitAck => "z".into(),
            Message::Ok => String::new(),
            Message::Error => return vec![0x07],
        }
        .into_bytes();
        s.push(b'\r');
        s
    }

    /// Parse one line (without its CR; a lone BEL is [`Message::Error`]).
    /// Queries and answers share letters: `V` alone is the query, `Vhhss`
    /// the answer.
    pub fn parse(line: &[u8]) -> std::result::Result<Message, SlcanError> {
        let unknown = || SlcanError::Unknown(String::from_utf8_lossy(line).into_owned());
        let bad = || SlcanError::BadFrame(String::from_utf8_lossy(line).into_owned());
        let Some((&first, rest)) = line.split_first() else {
            return Ok(Message::Ok);
        };
        Ok(match first {
            0x07 if rest.is_empty() => Message::Error,
            b'S' if rest.len() == 1 && rest[0].is_ascii_digit() => Message::Bitrate(rest[0] - b'0'),
            b'O' if rest.is_empty() => Message::Open,
            b'L' if rest.is_empty() => Message::ListenOnly,
            b'C' if rest.is_empty() => Message::Close,
            b'V' if rest.is_empty() => Message::Version(None),
            b'V' if rest.len() == 4 && rest.iter().all(u8::is_ascii_digit) => {
                let d = |i: usize| (rest[i] - b'0') * 10 + (rest[i + 1] - b'0');
                Message::Version(Some((d(0), d(2))))
            }
            b'N' if rest.is_empty() => Message::Serial(None),
            b'N' if rest.len() == 4 && rest.iter().all(u8::is_ascii_alphanumeric) => {
                Message::Serial(Some([rest[0], rest[1], rest[2], rest[3]]))
            }
            b'F' if rest.is_empty() => Message::Status(None),
            b'F' if rest.len() == 2 => Message::Status(Some(hex(rest).ok_or_else(unknown)? as u8)),
            b'z' | b'Z' if rest.is_empty() => Message::TransmitAck,
            b't' => {
                // iii l dd.. (an optional 4-digit timestamp after the data).
                if rest.len() < 4 {
                    return Err(bad());
                }
                let id = hex(&rest[..3]).ok_or_else(bad)? as u16;
                let len = rest[3].checked_sub(b'0').filter(|l| *l <= 8).ok_or_else(bad)? as usize;
                let data = &rest[4..];
                if data.len() != 2 * len && data.len() != 2 * len + 4 {
                    return Err(bad());
                }
                let bytes: Vec<u8> = (0..len)
                    .map(|i| hex(&data[2 * i..2 * i + 2]).map(|v| v as u8))
                    .collect::<Option<_>>()
                    .ok_or_else(bad)?;
                Message::Frame(CanFrame::new(id, &bytes).map_err(|_| bad())?)
            }
            b'T' | b'r' | b'R' => Message::OtherFrame,
            _ => return Err(unknown()),
        })
    }
}

/// Cuts a byte stream into SLCAN lines: at CR, and at BEL (which is a whole
/// message). Sans IO: push bytes, pop lines (without the CR; a BEL line is
/// the single byte 0x07).
#[derive(Debug, Default)]
pub struct LineDecoder {
    buf: Vec<u8>,
    lines: VecDeque<std::result::Result<Vec<u8>, SlcanError>>,
    /// Dropping the rest of an overlong line.
    skipping: bool,
}

impl LineDecoder {
    pub fn new() -> Self {
        Self::default()
    }

    /// Take bytes from the stream.
    pub fn push(&mut self, bytes: &[u8]) {
        for &b in bytes {
            match b {
                b'\r' => {
                    if !std::mem::take(&mut self.skipping) {
                        self.lines.push_back(Ok(std::mem::take(&mut self.buf)));
                    }
                }
                0x07 => {
                    self.buf.clear();
                    self.skipping = false;
                    self.lines.push_back(Ok(vec![0x07]));
                }
                b'\n' if self.buf.is_empty() => {}
                _ if self.skipping => {}
                _ => {
                    self.buf.push(b);
                    if self.buf.len() > MAX_LINE {
                        self.buf.clear();
                        self.skipping = true;
                        self.lines.push_back(Err(SlcanError::TooLong));
                    }
                }
            }
        }
    }

    /// The next complete line.
    pub fn next_line(&mut self) -> Option<std::result::Result<Vec<u8>, SlcanError>> {
        self.lines.pop_front()
    }
}

/// A CAN bus through an SLCAN adapter on a byte stream.
pub struct SlcanBus<S> {
    io: Option<S>,
    decoder: LineDecoder,
    frames: VecDeque<CanFrame>,
    name: String,
}

impl<S> fmt::Debug for SlcanBus<S> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SlcanBus").field("name", &self.name).field("open", &self.io.is_some()).finish()
    }
}

impl SlcanBus<tokio_serial::SerialStream> {
    /// Open the serial port `path` and the adapter's channel at `bitrate`.
    pub async fn open_port(path: &str, bitrate: u32, timeout: Duration) -> Result<Self> {
        use tokio_serial::SerialPortBuilderExt;
        let name = format!("slcan {path}");
        // The line speed of a USB-CAN adapter's virtual serial port does not
        // matter; 115200 is what most expect.
        let stream = tokio_serial::new(path, 115_200)
            .open_native_async()
            .map_err(|e| DriverError::new(ErrorKind::Disconnected, &name, format!("cannot open {path}: {e}")))?;
        Self::open(stream, bitrate, name, timeout).await
    }
}

impl<S: AsyncRead + AsyncWrite + Unpin + Send> SlcanBus<S> {
    /// Set the adapter up on `io`: close the channel (it may be open from
    /// before: the answer is not required), set `bitrate`, open. Each
    /// command waits `timeout` for the adapter's CR; BEL is refused
    /// ([`ErrorKind::Device`]), silence [`ErrorKind::Timeout`]; either is
    /// asked again, up to [`SETUP_COMMAND_TRIES`] times (a lost or garbled
    /// answer, or on a line, a late one read as a refusal). A port the
    /// adapter closed ends the set-up at once.
    pub async fn open(io: S, bitrate: u32, name: impl Into<String>, timeout: Duration) -> Result<Self> {
        let name = name.into();
        let code = bitrate_code(bitrate).ok_or_else(|| {
            let rates: Vec<String> = BITRATES.iter().map(|(b, _)| b.to_string()).collect();
            DriverError::usage(
                &name,
                format!("bitrate {bitrate} bit/s has no SLCAN command (one of {})", rates.join(", ")),
            )
        })?;
        let mut bus = Self { io: Some(io), decoder: LineDecoder::new(), frames: VecDeque::new(), name };
        let _ = bus.command(Message::Close, timeout).await;
        bus.set_up_command(Message::Bitrate(code), timeout).await?;
        bus.set_up_command(Message::Open, timeout).await?;
        tracing::info!(instrument = %bus.name, bitrate, "SLCAN channel open");
        Ok(bus)
    }

    fn lost(&mut self, what: &str, why: impl fmt::Display) -> DriverError {
        self.io = None;
        DriverError::new(ErrorKind::Disconnected, &self.name, format!("{what}: {why}"))
    }

    async fn write(&mut self, bytes: &[u8], what: &str) -> Result<()> {
        let Some(io) = self.io.as_mut() else {
            return Err(DriverError::new(ErrorKind::Disconnected, &self.name, format!("{what}: the port was lost")));
        };
        let written = async {
            io.write_all(bytes).await?;
            io.flush().await
        }
        .await;
        written.map_err(|e| self.lost(what, e))
    }

    /// Read one chunk into the decoder.
    async fn fill(&mut self, what: &str) -> Result<()> {
        let Some(io) = self.io.as_mut() else {
            return Err(DriverError::new(ErrorKind::Disconnected, &self.name, format!("{what}: the port was lost")));
        };
        let mut buf = [0u8; 256];
        match io.read(&mut buf).await {
            Ok(0) => Err(self.lost(what, "the adapter closed the port")),
            Ok(n) => {
                self.decoder.push(&buf[..n]);
                Ok(())
            }
            Err(e) => Err(self.lost(what, e)),
        }
    }

    /// Handle one decoded line: a frame is queued; returns the message.
    fn take(&mut self, line: std::result::Result<Vec<u8>, SlcanError>) -> Option<Message> {
        match line.map_err(|e| e.to_string()).and_then(|l| Message::parse(&l).map_err(|e| e.to_string())) {
            Ok(Message::Frame(f)) => {
                self.frames.push_back(f);
                Some(Message::Frame(f))
            }
            Ok(m) => Some(m),
            Err(e) => {
                tracing::warn!(instrument = %self.name, error = %e, "skipped a line from the adapter");
                None
            }
        }
    }

    /// A command of the set-up, asked again on silence or a refusal.
    async fn set_up_command(&mut self, message: Message, timeout: Duration) -> Result<()> {
        let mut tries = 1;
        loop {
            match self.command(message, timeout).await {
                Err(e) if tries < SETUP_COMMAND_TRIES && matches!(e.kind, ErrorKind::Timeout | ErrorKind::Device) => {
                    tracing::warn!(instrument = %self.name, error = %e, tries, "an adapter set-up command failed: asked again");
                    tries += 1;
                }
                result => return result,
            }
        }
    }

    /// Send a command and wait for the adapter's CR (frames meanwhile are kept).
    async fn command(&mut self, message: Message, timeout: Duration) -> Result<()> {
        let what = format!("{:?}", String::from_utf8_lossy(&message.encode()).trim_end());
        self.write(&message.encode(), &what).await?;
        let wait = async {
            loop {
                while let Some(line) = self.decoder.next_line() {
                    match self.take(line) {
                        Some(Message::Ok) => return Ok(()),
                        Some(Message::Error) => {
                            return Err(DriverError::new(
                                ErrorKind::Device,
                                &self.name,
                                format!("the adapter refused {what} (BEL)"),
                            ));
                        }
                        _ => {}
                    }
                }
                self.fill(&what).await?;
            }
        };
        match tokio::time::timeout(timeout, wait).await {
            Ok(r) => r,
            Err(_) => Err(DriverError::timeout(&self.name, &what, timeout)),
        }
    }

    /// Decode lines already buffered; frames go to the queue.
    fn drain_decoded(&mut self) {
        while let Some(line) = self.decoder.next_line() {
            if let Some(Message::Error) = self.take(line) {
                tracing::warn!(instrument = %self.name, "the adapter refused a frame (BEL): bus off or buffer full?");
            }
        }
    }
}

#[async_trait]
impl<S: AsyncRead + AsyncWrite + Unpin + Send> CanBus for SlcanBus<S> {
    async fn send(&mut self, frame: CanFrame) -> Result<()> {
        self.write(&Message::Frame(frame).encode(), "transmit").await
    }

    /// Cancel-safe: a chunk read is pushed into the decoder before any
    /// await that could be cancelled.
    async fn recv(&mut self) -> Result<CanFrame> {
        loop {
            self.drain_decoded();
            if let Some(f) = self.frames.pop_front() {
                return Ok(f);
            }
            self.fill("receive").await?;
        }
    }

    fn try_recv(&mut self) -> Result<Option<CanFrame>> {
        use std::pin::Pin;
        use std::task::{Context, Poll, Waker};
        loop {
            self.drain_decoded();
            if let Some(f) = self.frames.pop_front() {
                return Ok(Some(f));
            }
            let Some(io) = self.io.as_mut() else {
                return Err(DriverError::new(ErrorKind::Disconnected, &self.name, "try_recv: the port was lost"));
            };
            let mut bytes = [0u8; 256];
            let mut buf = tokio::io::ReadBuf::new(&mut bytes);
            let mut cx = Context::from_waker(Waker::noop());
            match Pin::new(io).poll_read(&mut cx, &mut buf) {
                Poll::Ready(Ok(())) if buf.filled().is_empty() => {
                    return Err(self.lost("try_recv", "the adapter closed the port"));
                }
                Poll::Ready(Ok(())) => {
                    let n = buf.filled().len();
                    self.decoder.push(&bytes[..n]);
                }
                Poll::Ready(Err(e)) => return Err(self.lost("try_recv", e)),
                Poll::Pending => return Ok(None),
            }
        }
    }

    fn describe(&self) -> String {
        self.name.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn messages_as_python_can_writes_and_reads_them() {
        let f = CanFrame::new(0x605, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]).unwrap();
        assert_eq!(Message::Frame(f).encode(), b"t60584041600000000000\r");
        assert_eq!(Message::parse(b"t60584041600000000000"), Ok(Message::Frame(f)));
        assert_eq!(Message::parse(b"t5858000000000000000"), Err(SlcanError::BadFrame("t5858000000000000000".into())));
        let empty = CanFrame::new(0x000, &[]).unwrap();
        assert_eq!(Message::parse(b"t0000"), Ok(Message::Frame(empty)));
        // With a timestamp (Z1): 4 more hex digits after the data.
        assert_eq!(Message::parse(b"t7051051A2B"), Ok(Message::Frame(CanFrame::new(0x705, &[0x05]).unwrap())));
        for (bytes, m) in [
            (&b"S6"[..], Message::Bitrate(6)),
            (b"O", Message::Open),
            (b"L", Message::ListenOnly),
            (b"C", Message::Close),
            (b"V", Message::Version(None)),
            (b"V1013", Message::Version(Some((10, 13)))),
            (b"N", Message::Serial(None)),
            (b"NA1B2", Message::Serial(Some(*b"A1B2"))),
            (b"F", Message::Status(None)),
            (b"F0C", Message::Status(Some(0x0C))),
            (b"z", Message::TransmitAck),
            (b"", Message::Ok),
            (b"\x07", Message::Error),
            (b"T123456781AB", Message::OtherFrame),
            (b"r1230", Message::OtherFrame),
        ] {
            assert_eq!(Message::parse(bytes), Ok(m), "{:?}", String::from_utf8_lossy(bytes));
        }
        assert_eq!(Message::Bitrate(6).encode(), b"S6\r");
        assert_eq!(Message::Ok.encode(), b"\r");
        assert_eq!(Message::Error.encode(), b"\x07");
        assert_eq!(bitrate_code(500_000), Some(6));
        assert_eq!(bitrate_code(750_000), Some(7));
        assert_eq!(bitrate_code(123_456), None);
        for bad in [&b"Q"[..], b"S", b"S10", b"t60", b"t6059", b"t60510", b"tXYZ0", b"F0G"] {
            assert!(Message::parse(bad).is_err(), "{:?}", String::from_utf8_lossy(bad));
        }
    }

    #[test]
    fn the_decoder_cuts_at_cr_and_bel_and_survives_overlong_lines() {
        let mut d = LineDecoder::new();
        d.push(b"t7051");
        d.push(b"05\r\r\x07z\r");
        d.push(&[b'x'; 40]);
        d.push(b"\rV1013\r");
        let lines: Vec<_> = std::iter::from_fn(|| d.next_line()).collect();
        assert_eq!(
            lines,
            vec![
                Ok(b"t705105".to_vec()),
                Ok(vec![]),
                Ok(vec![0x07]),
                Ok(b"z".to_vec()),
                Err(SlcanError::TooLong),
                Ok(b"V1013".to_vec())
            ]
        );
    }

    fn arb_frame() -> impl Strategy<Value = CanFrame> {
        (0u16..=0x7FF, proptest::collection::vec(any::<u8>(), 0..=8)).prop_map(|(id, d)| CanFrame::new(id, &d).unwrap())
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

        #[test]
        fn frames_round_trip_split_anywhere(frames in proptest::collection::vec(arb_frame(), 1..8), cut in 0usize..200) {
            let bytes: Vec<u8> = frames.iter().flat_map(|f| Message::Frame(*f).encode()).collect();
            let cut = cut.min(bytes.len());
            let mut d = LineDecoder::new();
            d.push(&bytes[..cut]);
            d.push(&bytes[cut..]);
            let back: Vec<Message> = std::iter::from_fn(|| d.next_line()).map(|l| Message::parse(&l.unwrap()).unwrap()).collect();
            prop_assert_eq!(back, frames.iter().map(|f| Message::Frame(*f)).collect::<Vec<_>>());
        }

        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
            let mut d = LineDecoder::new();
            d.push(&bytes);
            while let Some(line) = d.next_line() {
                if let Ok(line) = line {
                    prop_assert!(line.len() <= MAX_LINE);
                    let _ = Message::parse(&line);
                }
            }
        }
    }

    /// The bus over an in-memory stream against a scripted adapter: set-up
    /// commands answered with CR, frames both ways, acks and BELs skipped.
    #[tokio::test]
    async fn the_bus_over_a_scripted_adapter() {
        let (ours, mut theirs) = tokio::io::duplex(1024);
        let adapter = tokio::spawn(async move {
            let mut d = LineDecoder::new();
            let mut seen = Vec::new();
            let mut buf = [0u8; 256];
            while seen.len() < 4 {
                let n = theirs.read(&mut buf).await.unwrap();
                d.push(&buf[..n]);
                while let Some(l) = d.next_line() {
                    let l = l.unwrap();
                    let reply: &[u8] = match l.first() {
                        Some(b'C') => b"\x07",
                        Some(b't') => b"z\r\x07t58586000000000000000\r",
                        _ => b"\r",
                    };
                    theirs.write_all(reply).await.unwrap();
                    seen.push(String::from_utf8(l).unwrap());
                }
            }
            (theirs, seen)
        });
        let mut bus = SlcanBus::open(ours, 500_000, "test", Duration::from_secs(1)).await.unwrap();
        bus.send(CanFrame::new(0x605, &[0x40, 0, 0x10, 0, 0, 0, 0, 0]).unwrap()).await.unwrap();
        let f = bus.recv().await.unwrap();
        assert_eq!(f.to_string(), "585#6000000000000000");
        let (_theirs, seen) = adapter.await.unwrap();
        assert_eq!(seen, ["C", "S6", "O", "t60584000100000000000"]);
        assert_eq!(bus.try_recv().unwrap(), None);
        let e = SlcanBus::open(tokio::io::duplex(8).0, 1234, "x", Duration::from_millis(10)).await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Usage, "{e}");
    }
}
