//! [`ScpiPositioner`]: the [`Positioner`] driver over any async byte stream.

use super::codec::{
    Address, CodecError, Column, Command, Decoder, ErrorEntry, parse_bool, parse_count, parse_number, parse_status,
};
use super::codes::{DEVICE_SPECIFIC_ERROR, StatusWord};
use async_trait::async_trait;
use std::fmt;
use std::time::Duration;
use survey_drivers::error::{DriverError, ErrorKind, Result};
use survey_drivers::stream::Drain;
use survey_drivers::traits::{DeviceFault, Positioner, PositionerStatus};
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
    /// After a timeout, how long the driver drains late replies at least
    /// (see [`ScpiTimeouts::late_window`]). Default 50 ms.
    pub resync_grace: Duration,
}

impl ScpiTimeouts {
    /// After a request timed out, how long the controller may still answer:
    /// the line is drained for so long (half the request deadline, or the
    /// resync grace when longer) before the timeout is reported, so a late
    /// reply is never taken for the next request's. The driver's own bound
    /// of one request is the deadline and this.
    pub fn late_window(&self) -> Duration {
        (self.request / 2).max(self.resync_grace)
    }
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

/// Which query reads the controller's error queue.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ErrorQueryForm {
    /// `SYST:ERR:ALL?`: every entry in one reply, `0, "No error"` when empty
    /// (what public code sends to MI-4190/4192 controllers). The default.
    #[default]
    All,
    /// `SYST:ERR?`: the oldest entry (SCPI-99; not shown for MI controllers).
    Next,
}

impl ErrorQueryForm {
    fn command(self) -> Command {
        match self {
            ErrorQueryForm::All => Command::ErrorQueryAll,
            ErrorQueryForm::Next => Command::ErrorQuery,
        }
    }
}

/// `UNIT:POS?` of an axis in degrees (public code: 0 encoder counts, 1 m,
/// 2 cm, 3 mm, 4 in, 5 ft, 6 degree, 7 radian, 8 revolution).
pub const UNITS_DEGREE: i64 = 6;

/// Configuration of a [`ScpiPositioner`].
#[derive(Debug, Clone, PartialEq)]
pub struct ScpiConfig {
    /// Controller and axis addressed. Default `CONT1:AXIS(1)`.
    pub address: Address,
    pub timeouts: ScpiTimeouts,
    /// Rows per `CORR:TABL` line. Default 32 (lines under 1 KiB).
    pub table_chunk: usize,
    /// Longest reply line accepted. Default [`Decoder::DEFAULT_MAX_LINE`].
    pub max_line: usize,
    /// How far from the commanded position the axis may be, at rest, to be in
    /// position, degrees. Default 0.01.
    pub in_position_window_deg: f64,
    /// The error query. Default [`ErrorQueryForm::All`].
    pub error_query: ErrorQueryForm,
    /// Send the commands the public record does not show (`VEL:COMM`,
    /// `FAUL:CLE`, the `CORR:` subsystem). Default false: they are refused
    /// with a usage error that says what to do instead.
    pub unverified_commands: bool,
}

impl Default for ScpiConfig {
    fn default() -> Self {
        Self {
            address: Address::default(),
            timeouts: ScpiTimeouts::default(),
            table_chunk: 32,
            max_line: Decoder::DEFAULT_MAX_LINE,
            in_position_window_deg: 0.01,
            error_query: ErrorQueryForm::All,
            unverified_commands: false,
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
    /// The last commanded position (in position is decided against it).
    target: Option<f64>,
    /// `UNIT:POS?` was checked on this connection.
    units_checked: bool,
    /// What the driver last set with `CORR:STAT`.
    correction_on: bool,
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
            Ok(Err(e)) => return Err(DriverError::new(ErrorKind::Disconnected, label, e.to_string())),
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
            target: None,
            units_checked: false,
            correction_on: false,
        }
    }

    /// Check once per connection that the axis reports positions in degrees:
    /// any other unit would be a silent scale error.
    async fn check_units(&mut self) -> Result<()> {
        if self.units_checked {
            return Ok(());
        }
        let what = "position units (UNIT:POS?)";
        let line = match self.query(&[], Command::UnitsQuery, what).await {
            Ok(line) => line,
            Err(e) if e.kind == ErrorKind::Timeout => {
                // A query the controller refused has no reply: its error queue says why
                // (an axis it does not have: -114).
                let entries = self.errors(&[], what).await?;
                return Err(match entries.into_iter().find(ErrorEntry::is_error) {
                    Some(entry) => self.rejected(entry, what),
                    None => e,
                });
            }
            Err(e) => return Err(e),
        };
        let units: i64 =
            line.trim().parse().map_err(|_| self.garbled(what, CodecError::unparsable("a unit code", &line)))?;
        if !(0..=8).contains(&units) {
            // Not a code of the public table: not an answer to this query (a
            // late reply to an earlier one on the same line), so a garbled
            // exchange to retry, not a unit to refuse.
            return Err(self.garbled(what, CodecError::unparsable("a unit code 0..8", &line)));
        }
        if units != UNITS_DEGREE {
            let name = match units {
                0 => "encoder counts",
                1 => "metres",
                2 => "centimetres",
                3 => "millimetres",
                4 => "inches",
                5 => "feet",
                7 => "radians",
                _ => "revolutions",
            };
            return Err(DriverError::usage(
                &self.name,
                format!(
                    "axis {} reports its positions in {name} (UNIT:POS? = {units}), not degrees ({UNITS_DEGREE}): set \
                     the axis's position units to degrees on the controller",
                    self.cfg.address.axis
                ),
            ));
        }
        self.units_checked = true;
        Ok(())
    }

    /// Refuse a command the public record does not show, unless enabled.
    fn unverified(&self, command: &str, instead: &str) -> Result<()> {
        if self.cfg.unverified_commands {
            return Ok(());
        }
        Err(DriverError::usage(
            &self.name,
            format!(
                "{command} is not in the public record of MI-4190/4192 controllers and is not sent unless \
                 `unverified_commands = true` is set for the positioner; {instead}"
            ),
        ))
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

    /// The configuration, to change (the in-position window, the error
    /// query, the unverified commands).
    pub fn config_mut(&mut self) -> &mut ScpiConfig {
        &mut self.cfg
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

    /// Throw away input that is already waiting (`late`: and what arrives
    /// until the late window after a timeout has passed).
    async fn drain(&mut self, what: &str, late: bool) -> Result<()> {
        let mut dropped = self.decoder.clear();
        let mut buf = [0u8; 1024];
        let late_until = late.then(|| tokio::time::Instant::now() + self.cfg.timeouts.late_window());
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
        self.units_checked = false;
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
        self.drain(what, false).await?;
        let mut bytes = Vec::new();
        for c in lines {
            bytes.extend(c.encode(self.cfg.address));
        }
        let reply = lines.last().is_some_and(Command::is_query);
        let limit = self.cfg.timeouts.request;
        match tokio::time::timeout(limit, self.write_then_read(&bytes, reply, what)).await {
            Err(_) => {
                tracing::warn!(instrument = %self.name, what, ?limit, "no reply; draining late replies");
                // A link lost while draining is marked dead there; the
                // request's own failure is the timeout.
                if let Err(e) = self.drain(what, true).await {
                    tracing::debug!(instrument = %self.name, error = %e, "the link was lost while draining");
                }
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

    /// Read the error queue (its oldest entry, or all of them, as
    /// configured); `0, "No error"` when it is empty.
    async fn errors(&mut self, before: &[Command], what: &str) -> Result<Vec<ErrorEntry>> {
        let form = self.cfg.error_query;
        let line = self.query(before, form.command(), what).await?;
        match form {
            ErrorQueryForm::All => ErrorEntry::parse_list(&line).map_err(|e| self.garbled(what, e)),
            ErrorQueryForm::Next => ErrorEntry::parse(&line).map(|e| vec![e]).map_err(|e| self.garbled(what, e)),
        }
    }

    /// `*CLS`, the commands, the error query: an entry other than 0 is the
    /// commands' refusal (the first such entry is reported).
    async fn command(&mut self, commands: &[Command], what: &str) -> Result<()> {
        let mut lines = Vec::with_capacity(commands.len() + 1);
        lines.push(Command::ClearStatus);
        lines.extend_from_slice(commands);
        let entries = self.errors(&lines, what).await?;
        if let Some(entry) = entries.into_iter().find(ErrorEntry::is_error) {
            tracing::debug!(instrument = %self.name, what, %entry, "command refused");
            return Err(self.rejected(entry, what));
        }
        Ok(())
    }

    /// The fault behind a fault bit: the newest device-class entry of the
    /// error queue, else the one remembered, else a generic one.
    async fn fault_detail(&mut self, word: StatusWord) -> Result<DeviceFault> {
        'reads: for _ in 0..MAX_ERROR_READS {
            let entries = self.errors(&[], "status (error query after a fault bit)").await?;
            for entry in entries {
                match entry.kind() {
                    None => break 'reads,
                    Some(ErrorKind::Device) => {
                        self.last_fault = Some(DeviceFault { code: entry.code, text: entry.text })
                    }
                    Some(_) => tracing::warn!(instrument = %self.name, %entry, "stale command error in the queue"),
                }
            }
            if self.cfg.error_query == ErrorQueryForm::All {
                break;
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

    /// `*IDN?`: manufacturer, model, serial number, firmware.
    async fn identification(&mut self) -> Result<Option<String>> {
        Ok(Some(self.identify().await?))
    }

    /// `POS:COMM <target>` (checked), then `MOT:STAR` (checked).
    async fn move_to(&mut self, target_deg: f64) -> Result<()> {
        if !target_deg.is_finite() {
            return Err(DriverError::usage(&self.name, format!("target {target_deg} deg is not a finite angle")));
        }
        self.check_units().await?;
        self.command(&[Command::SetTarget(target_deg)], "move_to (POS:COMM)").await?;
        self.command(&[Command::Start], "move_to (MOT:STAR)").await?;
        self.target = Some(target_deg);
        Ok(())
    }

    async fn readout(&mut self) -> Result<f64> {
        self.check_units().await?;
        let line = self.query(&[], Command::PositionQuery, "readout (POS:CURR?)").await?;
        parse_number(&line).map_err(|e| self.garbled("readout (POS:CURR?)", e))
    }

    /// `STAT?`; at rest (bit 7 clear, no fault) also `POS:CURR?`: the axis is
    /// in position when it is within [`ScpiConfig::in_position_window_deg`]
    /// of the position last commanded (with none commanded yet, at rest is in
    /// position). The status word has no in-position bit: bits 13-15 are
    /// unused.
    async fn status(&mut self) -> Result<PositionerStatus> {
        self.check_units().await?;
        let line = self.query(&[], Command::StatusQuery, "status (STAT?)").await?;
        let word = parse_status(&line).map_err(|e| self.garbled("status (STAT?)", e))?;
        let fault = if word.fault() {
            Some(self.fault_detail(word).await?)
        } else {
            self.last_fault = None;
            None
        };
        let in_position = if word.moving() || fault.is_some() {
            false
        } else {
            match self.target {
                Some(target) => {
                    let what = "status (POS:CURR? at rest)";
                    let line = self.query(&[], Command::PositionQuery, what).await?;
                    let at = parse_number(&line).map_err(|e| self.garbled(what, e))?;
                    (at - target).abs() <= self.cfg.in_position_window_deg
                }
                None => true,
            }
        };
        Ok(word.to_status(fault, in_position, self.correction_on))
    }

    /// `MOT:STOP`: the axis halts where it is, which is then its position
    /// (at rest is in position).
    async fn stop(&mut self) -> Result<()> {
        self.command(&[Command::Stop], "stop (MOT:STOP)").await?;
        self.target = None;
        Ok(())
    }

    async fn set_velocity(&mut self, deg_per_s: f64) -> Result<()> {
        if !deg_per_s.is_finite() {
            return Err(DriverError::usage(&self.name, format!("velocity {deg_per_s} deg/s is not a finite number")));
        }
        self.unverified("VEL:COMM", "set the velocity on the controller")?;
        self.command(&[Command::SetVelocity(deg_per_s)], "set_velocity (VEL:COMM)").await
    }

    /// `FAUL:CLE` when unverified commands are enabled; otherwise what the
    /// public record allows: `*CLS` (the error queue cleared), then `STAT?`.
    /// An axis fault still latched then (PAU fault, error limit) cannot be
    /// cleared from here: [`ErrorKind::Usage`], saying what to do (clear it
    /// at the controller and resume, or send `FAUL:CLE` with
    /// `unverified_commands = true`), so the survey stops at once instead of
    /// trying a move the controller will refuse.
    async fn clear_fault(&mut self) -> Result<()> {
        if self.cfg.unverified_commands {
            self.command(&[Command::ClearFault], "clear_fault (FAUL:CLE)").await?;
            self.last_fault = None;
            return Ok(());
        }
        self.request(&[Command::ClearStatus], "clear_fault (*CLS)").await?;
        let line = self.query(&[], Command::StatusQuery, "clear_fault (STAT? after *CLS)").await?;
        let word = parse_status(&line).map_err(|e| self.garbled("clear_fault (STAT? after *CLS)", e))?;
        if !word.fault() {
            self.last_fault = None;
            return Ok(());
        }
        let what = match self.last_fault.take() {
            Some(f) => format!("{} ({}, code {})", word.fault_names(), f.text, f.code),
            None => word.fault_names(),
        };
        let e = DriverError::usage(
            &self.name,
            format!(
                "the axis fault ({what}) stays latched after *CLS (status word {word}), and the public record of \
                 the MI-4190 shows no command that clears it: clear it at the controller (its front panel or its \
                 own software), then run `survey resume`; or, if this controller takes FAUL:CLE, set \
                 unverified_commands = true under [positioner] and the survey clears such trips itself"
            ),
        );
        tracing::error!(instrument = %self.name, error = %e, "a latched axis fault cannot be cleared over SCPI");
        Err(e)
    }

    async fn load_correction_table(&mut self, table: &CorrectionTable) -> Result<()> {
        self.unverified(
            "the correction-table subsystem (CORR:TABL)",
            "load the table the controller's own way, from the files `survey process` writes",
        )?;
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
        self.unverified("CORR:STAT", "switch the correction on at the controller")?;
        self.command(&[Command::SetCorrection(enabled)], "enable_correction (CORR:STAT)").await?;
        self.correction_on = enabled;
        Ok(())
    }

    /// `CORR:STAT?` with `unverified_commands` (the `CORR:` subsystem is
    /// this project's guess); without, unknown: nothing is sent.
    async fn correction_state(&mut self) -> Result<Option<bool>> {
        if !self.cfg.unverified_commands {
            return Ok(None);
        }
        let what = "correction_state (CORR:STAT?)";
        let line = self.query(&[], Command::CorrectionQuery, what).await?;
        parse_bool(&line).map(Some).map_err(|e| self.garbled(what, e))
    }
}
