//! [`ScpiPositioner`]: the [`Positioner`] driver over any async byte stream.

use super::codec::{Address, CodecError, Column, Command, Decoder, ErrorEntry, parse_count, parse_number};
use super::codes::{DEVICE_SPECIFIC_ERROR, StatusWord};
use crate::error::{DriverError, ErrorKind, Result};
use crate::stream::Drain;
use crate::traits::{DeviceFault, Positioner, PositionerStatus};
use async_trait::async_trait;
use std::fmt;
use std::time::Duration;
use survey_processing::table::CorrectionTable;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpStream, ToSocketAddrs};

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
        let late_until =
            std::mem::take(&mut self.resync).then(|| tokio::time::Instant::now() + self.cfg.timeouts.resync_grace);
        let mut stale = Drain::new(late_until);
        loop {
            let Some(io) = self.io.as_mut() else {
                return Err(self.disconnected(what, "the connection was lost earlier"));
            };
            match stale.next(io, &mut buf).await {
                Ok(None) => break,
                Ok(Some(n)) => {
                    self.decoder.push(&buf[..n]);
                    dropped += self.decoder.clear();
                }
                Err(lost) => return Err(self.close(what, lost.why("the controller"))),
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
