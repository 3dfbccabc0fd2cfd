//! [`EmsconTracker`]: the [`Tracker`] driver over any async byte stream.

use super::codes::{
    command, coordinate_system, laser_status, meas_mode, measurement_status_info as msi, statistic_mode, status,
    status_change, tracker_processor_status,
};
use super::frame::DecodeError;
use super::packets::{
    Answer, AnswerBody, MeasurementStatusInfo, Reply, ReplyDecoder, Request, SingleMeasResult, StationaryModeData,
    SystemStatus, SystemUnits,
};
use crate::error::{DriverError, ErrorKind, Result};
use crate::reconnect::Connect;
use crate::stream::Drain;
use crate::traits::{AirEnvironment, SmrMeasurement, StreamedPoint, Tracker, TrackerState};
use async_trait::async_trait;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpStream, ToSocketAddrs};
use tokio::time::Instant;

/// The TCP port emScon servers listen on.
pub const DEFAULT_PORT: u16 = 700;

/// Deadlines of the driver, milliseconds (measured on the real clock: a real
/// instrument can hang).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct EmsconTimeouts {
    /// TCP connect. Default 5000.
    pub connect_ms: u64,
    /// Every command not listed below. Default 3000.
    pub request_ms: u64,
    /// `ES_C_Initialize` (the head moves, the sensor initialises). Default 90000.
    pub initialize_ms: u64,
    /// `ES_C_StartMeasurement` may take the measurement time plus this. Default 5000.
    pub measurement_margin_ms: u64,
    /// `ES_C_GoLastMeasuredPoint` and `ES_C_FindReflector` each. Default 60000.
    pub reacquire_ms: u64,
    /// After a timeout or a packet with an absurd size, how long the next
    /// request first reads and throws away late or unframed input. Default 50.
    pub resync_grace_ms: u64,
}

impl Default for EmsconTimeouts {
    fn default() -> Self {
        Self {
            connect_ms: 5000,
            request_ms: 3000,
            initialize_ms: 90_000,
            measurement_margin_ms: 5000,
            reacquire_ms: 60_000,
            resync_grace_ms: 50,
        }
    }
}

/// Configuration of an [`EmsconTracker`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct EmsconConfig {
    /// `lMeasTime` of `SetStationaryModeParams`, milliseconds (1..=2^31-1).
    /// Default 1000.
    pub measurement_time_ms: u32,
    /// `bUseADM` of `SetStationaryModeParams`. Default false.
    pub use_adm: bool,
    /// Send `ES_C_Initialize` on connect. Default true.
    pub initialize: bool,
    /// `dAproxDistance` of `FindReflector` when no measurement was taken yet,
    /// mm (afterwards the distance of the last measured point is sent).
    /// Default 3000.
    pub approx_distance_mm: f64,
    /// Deadlines.
    pub timeouts: EmsconTimeouts,
}

impl Default for EmsconConfig {
    fn default() -> Self {
        Self {
            measurement_time_ms: 1000,
            use_adm: false,
            initialize: true,
            approx_distance_mm: 3000.0,
            timeouts: EmsconTimeouts::default(),
        }
    }
}

fn ms(v: u64) -> Duration {
    Duration::from_millis(v)
}

/// Why input is thrown away before the next request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Resync {
    /// A request timed out: its answer may still come (it is decoded and
    /// dropped; status changes in it are applied).
    LateAnswer,
    /// A size field was absurd: the bytes that follow cannot be framed.
    FramingLost,
}

/// What a request was answered with.
enum Got {
    Answer(Answer),
    Measurement(SingleMeasResult),
}

/// A Leica laser tracker behind an emScon server, over `T` (a
/// [`TcpStream`] from [`EmsconTracker::connect`], or any byte stream). See
/// the module documentation of [`crate::emscon`].
pub struct EmsconTracker<T> {
    io: Option<T>,
    decoder: ReplyDecoder,
    cfg: EmsconConfig,
    name: String,
    state: TrackerState,
    last_status_change: Option<i32>,
    status_changes: u64,
    last_result: Option<SingleMeasResult>,
    resync: Option<Resync>,
    /// While measuring continuously: the points received, not yet read.
    streamed: Option<Vec<super::stream::MeasValue>>,
}

impl<T> fmt::Debug for EmsconTracker<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("EmsconTracker")
            .field("name", &self.name)
            .field("connected", &self.io.is_some())
            .field("state", &self.state)
            .field("last_status_change", &self.last_status_change)
            .finish_non_exhaustive()
    }
}

impl EmsconTracker<TcpStream> {
    /// Connect to the emScon server at `addr` (port [`DEFAULT_PORT`] on a real
    /// one) and set the tracker up ([`EmsconTracker::setup`]).
    pub async fn connect(addr: impl ToSocketAddrs + fmt::Debug, cfg: EmsconConfig) -> Result<Self> {
        let label = format!("emscon {addr:?}");
        let limit = ms(cfg.timeouts.connect_ms);
        let stream = match tokio::time::timeout(limit, TcpStream::connect(&addr)).await {
            Err(_) => {
                tracing::warn!(instrument = %label, ?limit, "emScon connect timed out");
                return Err(DriverError::timeout(label, "connect", limit));
            }
            Ok(Err(e)) => {
                tracing::warn!(instrument = %label, error = %e, "emScon connect failed");
                return Err(DriverError::new(ErrorKind::Disconnected, label, e.to_string()));
            }
            Ok(Ok(s)) => s,
        };
        stream
            .set_nodelay(true)
            .map_err(|e| DriverError::new(ErrorKind::Disconnected, &label, format!("TCP_NODELAY: {e}")))?;
        let name = stream.peer_addr().map(|p| format!("emscon {p}")).unwrap_or(label);
        let mut tracker = Self::new(stream, cfg).named(name);
        tracker.setup().await?;
        Ok(tracker)
    }
}

impl<T> EmsconTracker<T>
where
    T: AsyncRead + AsyncWrite + Unpin + Send,
{
    /// A driver on an open stream, named `"emscon"`. No I/O: call
    /// [`setup`](Self::setup) (or use [`open`](Self::open)) before measuring.
    pub fn new(io: T, cfg: EmsconConfig) -> Self {
        Self {
            io: Some(io),
            decoder: ReplyDecoder::new(),
            cfg,
            name: "emscon".into(),
            state: TrackerState::NotReady,
            last_status_change: None,
            status_changes: 0,
            last_result: None,
            resync: None,
            streamed: None,
        }
    }

    /// [`new`](Self::new) then [`setup`](Self::setup).
    pub async fn open(io: T, cfg: EmsconConfig) -> Result<Self> {
        let mut tracker = Self::new(io, cfg);
        tracker.setup().await?;
        Ok(tracker)
    }

    /// Set the name used in logs and errors.
    pub fn named(mut self, name: impl Into<String>) -> Self {
        self.name = name.into();
        self
    }

    /// The configuration.
    pub fn config(&self) -> &EmsconConfig {
        &self.cfg
    }

    /// Whether the stream is still usable (false after a disconnection: build
    /// a new driver to reconnect).
    pub fn is_connected(&self) -> bool {
        self.io.is_some()
    }

    /// The last known state, from answers and status-change packets (no I/O;
    /// [`Tracker::status`] asks the tracker).
    pub fn state(&self) -> TrackerState {
        self.state
    }

    /// The last `ES_SystemStatusChange` received, if any.
    pub fn last_status_change(&self) -> Option<i32> {
        self.last_status_change
    }

    /// How many status-change packets were received.
    pub fn status_changes_seen(&self) -> u64 {
        self.status_changes
    }

    /// The last successful measurement, as the tracker sent it.
    pub fn last_result(&self) -> Option<&SingleMeasResult> {
        self.last_result.as_ref()
    }

    /// `Initialize` (if configured), `SetUnits` (mm, degrees, Celsius, mbar,
    /// %RH), `SetCoordinateSystemType` (`ES_CS_RHR`), `SetMeasurementMode`
    /// (`ES_MM_Stationary`), `SetStatisticMode` (standard, both), and
    /// `SetStationaryModeParams` (the configured time).
    pub async fn setup(&mut self) -> Result<()> {
        let meas_time_ms = i32::try_from(self.cfg.measurement_time_ms).ok().filter(|t| *t > 0).ok_or_else(|| {
            DriverError::usage(
                &self.name,
                format!("measurement time {} ms out of 1..=2^31-1", self.cfg.measurement_time_ms),
            )
        })?;
        if !(self.cfg.approx_distance_mm.is_finite() && self.cfg.approx_distance_mm > 0.0) {
            return Err(DriverError::usage(
                &self.name,
                format!("approximate distance {} mm is not a positive number", self.cfg.approx_distance_mm),
            ));
        }
        if self.cfg.initialize {
            self.setup_command(Request::Initialize).await?;
        }
        self.setup_command(Request::SetUnits(SystemUnits::SURVEY)).await?;
        self.setup_command(Request::SetCoordinateSystemType(coordinate_system::RHR)).await?;
        self.setup_command(Request::SetMeasurementMode(meas_mode::STATIONARY)).await?;
        // Standard statistics, so a stationary measurement answers the
        // SingleMeasResultT decoded here (another program may have left the
        // tracker in extended mode; SingleMeasResult2T is decoded too).
        let standard = statistic_mode::STANDARD;
        self.setup_command(Request::SetStatisticMode { stationary: standard, continuous: standard }).await?;
        let params = StationaryModeData { meas_time_ms, use_adm: self.cfg.use_adm };
        self.setup_command(Request::SetStationaryModeParams(params)).await?;
        tracing::info!(instrument = %self.name, meas_time_ms, "emScon tracker set up: mm, RHR, stationary");
        Ok(())
    }

    /// A command of the set-up, asked again in place (up to
    /// [`SETUP_COMMAND_TRIES`] times) while its answer comes garbled (the
    /// next request resynchronises). No answer is the set-up's: on a stream
    /// the answers after a late one come late too, and a new connection is
    /// what gets fresh ones. A refusal of the tracker (a result status: a
    /// second client refused, a sensor not warmed up) is the set-up's, which
    /// [`Reconnecting`](crate::reconnect::Reconnecting) tries again on a new
    /// connection; a lost connection or bad usage ends it at once. Each
    /// setting is the same written twice, so asking again is safe.
    async fn setup_command(&mut self, request: Request) -> Result<Answer> {
        let mut tries = 1;
        loop {
            match self.command(request).await {
                Err(e) if tries < SETUP_COMMAND_TRIES && self.io.is_some() && e.kind == ErrorKind::Garbled => {
                    tracing::warn!(instrument = %self.name, error = %e, tries, "an emScon set-up command failed: asked again");
                    tries += 1;
                }
                result => return result,
            }
        }
    }

    /// Send any modelled command except `StartMeasurement` and return its
    /// successful answer.
    pub async fn command(&mut self, request: Request) -> Result<Answer> {
        match self.exchange(request).await? {
            Got::Answer(a) => Ok(a),
            Got::Measurement(_) => {
                Err(self.garbled(request.command(), "a measurement result where an answer was expected"))
            }
        }
    }

    /// One stationary measurement (`StartMeasurement`), as the tracker sent it.
    pub async fn measure_result(&mut self) -> Result<SingleMeasResult> {
        let m = match self.exchange(Request::StartMeasurement).await? {
            Got::Measurement(m) => m,
            Got::Answer(_) => {
                return Err(self.garbled(command::START_MEASUREMENT, "an answer where a result was expected"));
            }
        };
        if !m.val.iter().chain(&m.std).all(|v| v.is_finite()) {
            let e = self.garbled(command::START_MEASUREMENT, format!("non-finite coordinates or deviations: {m:?}"));
            tracing::warn!(instrument = %self.name, error = %e, "emScon result rejected");
            return Err(e);
        }
        if m.meas_mode != meas_mode::STATIONARY {
            tracing::warn!(instrument = %self.name, mode = m.meas_mode, "result of a non-stationary measurement mode");
        }
        self.state = TrackerState::TargetLocked;
        self.last_result = Some(m);
        Ok(m)
    }

    /// `GetSystemStatus`.
    pub async fn system_status(&mut self) -> Result<SystemStatus> {
        let a = self.command(Request::GetSystemStatus).await?;
        match a.body {
            AnswerBody::SystemStatus(s) => Ok(s),
            other => Err(self.garbled(a.command, format!("GetSystemStatusRT without its status fields: {other:?}"))),
        }
    }

    /// `GetMeasurementStatusInfo`.
    pub async fn measurement_status_info(&mut self) -> Result<MeasurementStatusInfo> {
        let a = self.command(Request::GetMeasurementStatusInfo).await?;
        match a.body {
            AnswerBody::MeasurementStatusInfo(m) => Ok(m),
            other => Err(self.garbled(a.command, format!("GetMeasurementStatusInfoRT without its fields: {other:?}"))),
        }
    }

    /// Process what the tracker sent while no request was pending (status
    /// changes are applied, stale answers dropped), without waiting.
    pub async fn poll_unsolicited(&mut self) -> Result<()> {
        self.prepare("poll").await
    }

    async fn reflector_locked(&mut self) -> Result<bool> {
        Ok(self.measurement_status_info().await?.info & msi::REFLECTOR_FOUND != 0)
    }

    fn limit_for(&self, request: &Request) -> Duration {
        let t = &self.cfg.timeouts;
        match request {
            Request::Initialize => ms(t.initialize_ms),
            Request::StartMeasurement => ms(u64::from(self.cfg.measurement_time_ms) + t.measurement_margin_ms),
            Request::GoLastMeasuredPoint | Request::FindReflector { .. } | Request::GoPosition { .. } => {
                ms(t.reacquire_ms)
            }
            _ => ms(t.request_ms),
        }
    }

    /// Drain, send `request`, wait for its answer under its deadline.
    async fn exchange(&mut self, request: Request) -> Result<Got> {
        let what = command::describe(request.command());
        self.prepare(&what).await?;
        let limit = self.limit_for(&request);
        let started = Instant::now();
        match tokio::time::timeout(limit, self.send_and_wait(&request, &what)).await {
            Err(_) => {
                self.resync = Some(Resync::LateAnswer);
                tracing::warn!(instrument = %self.name, what, ?limit, "emScon tracker did not answer");
                Err(DriverError::timeout(&self.name, &what, limit))
            }
            Ok(Ok(got)) => {
                tracing::debug!(instrument = %self.name, what, elapsed = ?started.elapsed(), "emScon exchange");
                Ok(got)
            }
            Ok(Err(e)) => {
                tracing::warn!(instrument = %self.name, what, kind = %e.kind, error = %e, "emScon request failed");
                Err(e)
            }
        }
    }

    async fn send_and_wait(&mut self, request: &Request, what: &str) -> Result<Got> {
        let bytes = request.encode();
        let Some(io) = self.io.as_mut() else { return Err(self.lost(what)) };
        let written = async {
            io.write_all(&bytes).await?;
            io.flush().await
        }
        .await;
        if let Err(e) = written {
            return Err(self.close(what, e));
        }
        let mut buf = [0u8; 1024];
        loop {
            while let Some(item) = self.decoder.next_reply() {
                if let Some(done) = self.on_reply(item, request) {
                    return done;
                }
            }
            let Some(io) = self.io.as_mut() else { return Err(self.lost(what)) };
            match io.read(&mut buf).await {
                Ok(0) => {
                    let partial = self.decoder.buffered_len();
                    let why = if partial > 0 {
                        format!("connection closed after {partial} bytes of a packet")
                    } else {
                        "connection closed by the tracker".to_string()
                    };
                    return Err(self.close(what, why));
                }
                Ok(n) => self.decoder.push(&buf[..n]),
                Err(e) => return Err(self.close(what, e)),
            }
        }
    }

    /// Handle one packet while `request` waits: `Some` ends the wait.
    fn on_reply(&mut self, item: Result<Reply, DecodeError>, request: &Request) -> Option<Result<Got>> {
        let want = request.command();
        // A StartMeasurement in continuous mode is answered by its
        // acknowledgement; in stationary mode by the result.
        let measuring = matches!(request, Request::StartMeasurement) && self.streamed.is_none();
        match item {
            Err(e) => {
                if e.loses_framing() {
                    // The decoder drops input until the next request resynchronises.
                    self.resync = Some(Resync::FramingLost);
                }
                Some(Err(self.garbled(want, e)))
            }
            Ok(Reply::StatusChange(event)) => {
                self.apply_status_change(event);
                None
            }
            Ok(Reply::MultiMeas(m)) => {
                self.take_points(m);
                None
            }
            Ok(Reply::Error { command: c, status: s }) if c == want => Some(Err(self.refused(c, s))),
            Ok(Reply::Answer(a)) if a.command == want => {
                if a.status != status::ALL_OK {
                    Some(Err(self.refused(a.command, a.status)))
                } else if measuring {
                    // The continuous-mode acknowledgement: the result follows.
                    tracing::debug!(instrument = %self.name, "StartMeasurement acknowledged");
                    None
                } else {
                    Some(Ok(Got::Answer(a)))
                }
            }
            Ok(Reply::SingleMeas(m)) if measuring => Some(if m.status != status::ALL_OK {
                Err(self.refused(want, m.status))
            } else {
                Ok(Got::Measurement(m))
            }),
            Ok(Reply::SingleMeas2(m)) if measuring => Some(if m.status != status::ALL_OK {
                Err(self.refused(want, m.status))
            } else {
                Ok(Got::Measurement(m.into()))
            }),
            Ok(Reply::Other { data_type, body }) => {
                tracing::debug!(instrument = %self.name, data_type, len = body.len(), "skipped a packet of an unused type");
                None
            }
            Ok(stale) => {
                tracing::warn!(instrument = %self.name, ?stale, "discarded a packet that answers another request");
                None
            }
        }
    }

    /// Before a request: throw away late or unframed input if a resync is
    /// due, then take what is already waiting, without blocking.
    async fn prepare(&mut self, what: &str) -> Result<()> {
        if self.io.is_none() {
            return Err(self.lost(what));
        }
        let mut buf = [0u8; 1024];
        let mut stale = 0usize;
        for _ in 0..4 {
            if let Some(resync) = self.resync.take() {
                let mut late = Drain::late(Instant::now() + ms(self.cfg.timeouts.resync_grace_ms));
                loop {
                    let Some(io) = self.io.as_mut() else { return Err(self.lost(what)) };
                    match late.next(io, &mut buf).await {
                        Ok(None) => break,
                        Ok(Some(n)) if resync == Resync::FramingLost => stale += n,
                        Ok(Some(n)) => {
                            self.decoder.push(&buf[..n]);
                            stale += self.take_idle();
                        }
                        Err(lost) => return Err(self.close(what, lost.why("the tracker"))),
                    }
                }
                if resync == Resync::FramingLost {
                    stale += self.decoder.clear().0;
                }
            }
            let mut waiting = Drain::waiting();
            loop {
                let Some(io) = self.io.as_mut() else { return Err(self.lost(what)) };
                match waiting.next(io, &mut buf).await {
                    Ok(None) => break,
                    Ok(Some(n)) => self.decoder.push(&buf[..n]),
                    Err(lost) => return Err(self.close(what, lost.why("the tracker"))),
                }
            }
            stale += self.take_idle();
            if self.resync.is_none() {
                if stale > 0 {
                    tracing::warn!(instrument = %self.name, what, stale, "discarded stale input before a request");
                }
                return Ok(());
            }
        }
        let e = DriverError::new(
            ErrorKind::Garbled,
            &self.name,
            format!("{what}: the tracker keeps sending unframed bytes"),
        );
        tracing::warn!(instrument = %self.name, error = %e, "emScon resynchronisation failed");
        Err(e)
    }

    /// Apply the status changes among the decoded packets and drop the rest;
    /// returns how many were dropped.
    fn take_idle(&mut self) -> usize {
        let mut dropped = 0;
        while let Some(item) = self.decoder.next_reply() {
            match item {
                Ok(Reply::StatusChange(event)) => self.apply_status_change(event),
                Ok(Reply::MultiMeas(m)) => self.take_points(m),
                Ok(Reply::Other { .. }) => {}
                Ok(stale) => {
                    tracing::debug!(instrument = %self.name, ?stale, "stale packet dropped");
                    dropped += 1;
                }
                Err(e) => {
                    tracing::warn!(instrument = %self.name, error = %e, "garbled stale packet dropped");
                    if e.loses_framing() {
                        self.resync = Some(Resync::FramingLost);
                    }
                    dropped += 1;
                }
            }
        }
        dropped
    }

    fn apply_status_change(&mut self, event: i32) {
        self.status_changes += 1;
        self.last_status_change = Some(event);
        let name = status_change::describe(event);
        match event {
            status_change::MEAS_STATUS_NOT_READY => {
                self.state = TrackerState::BeamBroken;
                tracing::warn!(instrument = %self.name, event = %name, "tracker reports it cannot measure (beam broken)");
            }
            status_change::MEAS_STATUS_READY => {
                self.state = TrackerState::TargetLocked;
                tracing::info!(instrument = %self.name, event = %name, "tracker ready to measure");
            }
            status_change::TP_CONNECTION_CLOSING | status_change::SERVER_CLOSING => {
                self.state = TrackerState::NotReady;
                tracing::warn!(instrument = %self.name, event = %name, "emScon server going away");
            }
            _ => tracing::debug!(instrument = %self.name, event = %name, "emScon status change"),
        }
    }

    /// A result status other than `ES_RS_AllOK`: a device fault with the
    /// status as its code and its header name in the text; a status the
    /// header does not define is a garbled packet ([`status::is_defined`]).
    fn refused(&mut self, cmd: i32, code: i32) -> DriverError {
        if !status::is_defined(code) {
            let e = self.garbled(
                cmd,
                format!("{} is no status of the emScon header: a garbled status field", status::describe(code)),
            );
            tracing::warn!(instrument = %self.name, error = %e, "undefined result status");
            return e;
        }
        match code {
            status::MEASUREMENT_STATUS_NOT_READY | status::NO_STATIONARY_RESULT => {
                self.state = TrackerState::BeamBroken
            }
            status::TRACKER_NOT_INITIALIZED
            | status::SENSOR_NOT_WARMED_UP
            | status::SENSOR_NOT_STABLE
            | status::SYSTEM_NOT_READY_FOR_MEASUREMENT => self.state = TrackerState::NotReady,
            _ => {}
        }
        let text = format!("{} ({code}) in answer to {}", status::describe(code), command::describe(cmd));
        DriverError::device(&self.name, i64::from(code), text)
    }

    fn garbled(&self, cmd: i32, why: impl fmt::Display) -> DriverError {
        DriverError::new(ErrorKind::Garbled, &self.name, format!("{}: {why}", command::describe(cmd)))
    }

    fn lost(&self, what: &str) -> DriverError {
        DriverError::new(ErrorKind::Disconnected, &self.name, format!("{what}: the connection was lost earlier"))
    }

    /// Mark the link dead.
    fn close(&mut self, what: &str, why: impl fmt::Display) -> DriverError {
        self.io = None;
        self.decoder.clear();
        self.state = TrackerState::NotReady;
        tracing::warn!(instrument = %self.name, what, %why, "emScon connection lost");
        DriverError::new(ErrorKind::Disconnected, &self.name, format!("{what}: {why}"))
    }
}

/// How many times a command of the tracker's set-up is sent before its
/// fault is the set-up's ([`EmsconTracker::setup`]).
pub const SETUP_COMMAND_TRIES: u32 = 3;

/// Opens an [`EmsconTracker`] over TCP for each connection of a
/// [`Reconnecting`](crate::reconnect::Reconnecting) tracker.
#[derive(Debug, Clone, PartialEq)]
pub struct EmsconConnector {
    /// `host:port` of the emScon server (port 700 on a real one).
    pub addr: String,
    /// The driver's configuration.
    pub cfg: EmsconConfig,
}

#[async_trait]
impl Connect<dyn Tracker> for EmsconConnector {
    async fn connect(&self) -> Result<Box<dyn Tracker>> {
        Ok(Box::new(EmsconTracker::connect(self.addr.as_str(), self.cfg.clone()).await?))
    }

    fn describe(&self) -> String {
        format!("emscon {}", self.addr)
    }
}

#[async_trait]
impl<T> Tracker for EmsconTracker<T>
where
    T: AsyncRead + AsyncWrite + Unpin + Send,
{
    fn name(&self) -> &str {
        &self.name
    }

    /// `GetSystemStatus`: the tracker's serial number and the emScon version.
    async fn identification(&mut self) -> Result<Option<String>> {
        let s = self.system_status().await?;
        let [major, minor, build] = s.version;
        Ok(Some(format!("tracker serial number {}, emScon {major}.{minor}.{build}", s.tracker_serial_number)))
    }

    /// `StartMeasurement` in stationary mode: coordinates and standard
    /// deviations in mm; `measurement_time_s` is the configured `lMeasTime`.
    async fn measure(&mut self) -> Result<SmrMeasurement> {
        let m = self.measure_result().await?;
        Ok(SmrMeasurement {
            x_mm: m.val[0],
            y_mm: m.val[1],
            z_mm: m.val[2],
            std_dev_mm: m.std,
            measurement_time_s: f64::from(self.cfg.measurement_time_ms) / 1000.0,
            environment: AirEnvironment::of_emscon(m.temperature, m.pressure, m.humidity),
        })
    }

    /// `GetSystemStatus`: not initialised or laser not ready -> `NotReady`;
    /// then `GetMeasurementStatusInfo`: `ES_MSI_ReflectorFound` ->
    /// `TargetLocked`, else `BeamBroken`.
    async fn status(&mut self) -> Result<TrackerState> {
        let s = self.system_status().await?;
        let state = if s.tracker_processor_status != tracker_processor_status::INITIALIZED
            || s.laser_status != laser_status::LASER_READY
        {
            TrackerState::NotReady
        } else if self.reflector_locked().await? {
            TrackerState::TargetLocked
        } else {
            TrackerState::BeamBroken
        };
        self.state = state;
        Ok(state)
    }

    /// `GoLastMeasuredPoint`; if it fails with a result status or leaves no
    /// reflector locked, `FindReflector` at the distance of the last measured
    /// point (or the configured one). Still no reflector: a device fault with
    /// `ES_RS_MeasurementStatusNotReady`.
    async fn reacquire(&mut self) -> Result<()> {
        if self.streamed.is_some() {
            return Err(DriverError::usage(&self.name, "measuring continuously: stop the stream before re-acquiring"));
        }
        match self.command(Request::GoLastMeasuredPoint).await {
            Ok(_) => {
                if self.reflector_locked().await? {
                    self.state = TrackerState::TargetLocked;
                    return Ok(());
                }
                tracing::info!(instrument = %self.name, "no reflector at the last measured point: searching");
            }
            Err(e) if e.kind == ErrorKind::Device => {
                tracing::info!(instrument = %self.name, error = %e, "GoLastMeasuredPoint refused: searching");
            }
            Err(e) => return Err(e),
        }
        let approx_distance = match &self.last_result {
            Some(m) => m.val.iter().map(|v| v * v).sum::<f64>().sqrt(),
            None => self.cfg.approx_distance_mm,
        };
        self.command(Request::FindReflector { approx_distance }).await?;
        if self.reflector_locked().await? {
            self.state = TrackerState::TargetLocked;
            Ok(())
        } else {
            self.state = TrackerState::BeamBroken;
            let code = status::MEASUREMENT_STATUS_NOT_READY;
            let e = DriverError::device(
                &self.name,
                i64::from(code),
                format!("{} ({code}): no reflector locked after ES_C_FindReflector", status::describe(code)),
            );
            tracing::warn!(instrument = %self.name, error = %e, "re-acquisition failed");
            Err(e)
        }
    }

    fn can_point(&self) -> bool {
        true
    }

    /// `GoPosition` to `xyz_mm` (the right-handed rectangular frame this
    /// driver sets, in mm), then `FindReflector` at its distance: locked on
    /// the reflector there, or a device fault (no reflector locked). Each
    /// command under its own deadline (`reacquire_ms`: a turn and a search).
    async fn point_at(&mut self, xyz_mm: [f64; 3]) -> Result<()> {
        if self.streamed.is_some() {
            return Err(DriverError::usage(&self.name, "measuring continuously: stop the stream before pointing"));
        }
        let at = format!("({:.1}, {:.1}, {:.1}) mm", xyz_mm[0], xyz_mm[1], xyz_mm[2]);
        // A device's refusal is said with the position it was asked about.
        let placed = |mut e: DriverError| {
            if e.kind == ErrorKind::Device {
                e.message = format!("{} (pointing at {at})", e.message);
            }
            e
        };
        self.command(Request::GoPosition { position: xyz_mm, use_adm: false }).await.map_err(placed)?;
        let approx_distance = xyz_mm.iter().map(|v| v * v).sum::<f64>().sqrt();
        let found = self.command(Request::FindReflector { approx_distance }).await.map_err(placed);
        if let Err(e) = found {
            if e.kind == ErrorKind::Device {
                self.state = TrackerState::BeamBroken;
            }
            return Err(e);
        }
        if self.reflector_locked().await? {
            self.state = TrackerState::TargetLocked;
            Ok(())
        } else {
            self.state = TrackerState::BeamBroken;
            let code = status::MEASUREMENT_STATUS_NOT_READY;
            Err(DriverError::device(
                &self.name,
                i64::from(code),
                format!(
                    "{} ({code}): no reflector locked at {at} after ES_C_GoPosition and ES_C_FindReflector",
                    status::describe(code)
                ),
            ))
        }
    }

    fn can_stream(&self) -> bool {
        true
    }

    /// Continuous time mode, one point every `period` ([`continuous`]).
    async fn start_stream(&mut self, period: Duration) -> Result<()> {
        self.start_continuous(period).await
    }

    async fn read_stream(&mut self) -> Result<Vec<StreamedPoint>> {
        self.read_continuous().await
    }

    async fn stop_stream(&mut self) -> Result<()> {
        self.stop_continuous().await
    }
}

mod continuous;
