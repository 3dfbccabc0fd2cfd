//! [`ElcomatDriver`]: the [`Autocollimator`] driver over any async byte
//! transport.

use super::codec::{Command, Decoder, Discarded, Reply, encode_command, encode_reply};
use crate::error::{DriverError, ErrorKind, Result};
use crate::stream::Drain;
use crate::traits::{AcReading, AcState, Autocollimator};
use async_trait::async_trait;
use std::fmt;
use std::time::{Duration, Instant};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};

/// Default deadline of one request.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(2);

/// Most stale bytes discarded before one request (a unit left streaming would
/// otherwise keep the drain busy forever).
const MAX_DRAIN: usize = 64 * 1024;

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
                self.drain_late().await;
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

    /// After a request timed out, how long the instrument may still answer:
    /// the line is drained for so long (half the timeout) before the timeout
    /// is reported, so a late reading is never taken for the next one's.
    pub fn late_window(&self) -> Duration {
        self.timeout / 2
    }

    /// After a timeout: discard what arrives within the late window.
    async fn drain_late(&mut self) {
        let mut drained = 0usize;
        let mut buf = [0u8; 256];
        let mut late = Drain::late(tokio::time::Instant::now() + self.late_window());
        while let Ok(Some(n)) = late.next(&mut self.io, &mut buf).await {
            drained += n;
        }
        let discarded = self.decoder.discard_pending();
        tracing::warn!(instrument = %self.name, drained, partial_lines = discarded.lines, "drained late replies after a timeout");
    }

    /// Discard bytes already waiting on the transport and whatever the
    /// decoder holds. Stops at the first read that would block, at end of
    /// file or an error (the exchange then meets them), or after
    /// [`MAX_DRAIN`] bytes.
    async fn drain_stale(&mut self) {
        let mut drained = 0usize;
        let mut buf = [0u8; 256];
        let mut stale = Drain::waiting().at_most(MAX_DRAIN);
        while let Ok(Some(n)) = stale.next(&mut self.io, &mut buf).await {
            drained += n;
            self.decoder.push(&buf[..n]);
        }
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
