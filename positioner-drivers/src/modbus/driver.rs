//! The [`Positioner`] driver over a tokio-modbus client context.

use super::line::{LateReplies, line};
use super::map::{Location, MAX_READ_REGISTERS, MAX_WRITE_REGISTERS, RegisterMap, RegisterTable, table_checksum};
use async_trait::async_trait;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;
use std::fmt;
use std::sync::Arc;
use std::time::Duration;
use survey_drivers::error::{DriverError, ErrorKind, Result};
use survey_drivers::traits::{Positioner, PositionerStatus};
use survey_processing::table::CorrectionTable;
use tokio::io::{AsyncRead, AsyncWrite};
use tokio::net::{TcpStream, ToSocketAddrs};
use tokio_modbus::client::{Client as _, Context};
use tokio_modbus::{ExceptionCode, Request, Response, Slave};
use tokio_serial::SerialPortBuilderExt as _;

/// The most Read Device Identification requests one identification makes
/// (a device answers the regular objects in one or two).
const MAX_ID_REQUESTS: usize = 4;

/// The Modbus application protocol's names of objects 0x00-0x06.
const ID_OBJECT_NAMES: [&str; 7] =
    ["vendor", "product code", "revision", "vendor URL", "product", "model", "application"];

/// Deadlines of the driver. In configuration files they are milliseconds:
/// `connect_ms`, `request_ms`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ModbusTimeouts {
    /// Opening the TCP connection or the serial port (default 3 s).
    #[serde(rename = "connect_ms", with = "millis")]
    pub connect: Duration,
    /// One Modbus request and its reply (default 1 s).
    #[serde(rename = "request_ms", with = "millis")]
    pub request: Duration,
}

impl ModbusTimeouts {
    /// After a request timed out on RTU, how long the device may still
    /// answer: the line is drained for so long (half the request deadline)
    /// before the timeout is reported. The driver's own bound of one request
    /// is the deadline and this.
    pub fn late_window(&self) -> Duration {
        self.request / 2
    }
}

impl Default for ModbusTimeouts {
    fn default() -> Self {
        Self { connect: Duration::from_secs(3), request: Duration::from_secs(1) }
    }
}

mod millis {
    use serde::{Deserialize, Deserializer, Serializer};
    use std::time::Duration;

    pub fn serialize<S: Serializer>(d: &Duration, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u64(d.as_millis().min(u128::from(u64::MAX)) as u64)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Duration, D::Error> {
        Ok(Duration::from_millis(u64::deserialize(d)?))
    }
}

/// The class of a Modbus exception code (see the module documentation).
pub fn exception_kind(code: ExceptionCode) -> ErrorKind {
    match code {
        ExceptionCode::IllegalFunction | ExceptionCode::IllegalDataAddress | ExceptionCode::IllegalDataValue => {
            ErrorKind::Usage
        }
        ExceptionCode::GatewayPathUnavailable => ErrorKind::Disconnected,
        ExceptionCode::GatewayTargetDevice => ErrorKind::Timeout,
        _ => ErrorKind::Device,
    }
}

/// The name of an exception code, from the Modbus Application Protocol V1.1b3, section 7.
pub fn exception_name(code: ExceptionCode) -> &'static str {
    match code {
        ExceptionCode::IllegalFunction => "illegal function",
        ExceptionCode::IllegalDataAddress => "illegal data address",
        ExceptionCode::IllegalDataValue => "illegal data value",
        ExceptionCode::ServerDeviceFailure => "server device failure",
        ExceptionCode::Acknowledge => "acknowledge",
        ExceptionCode::ServerDeviceBusy => "server device busy",
        ExceptionCode::MemoryParityError => "memory parity error",
        ExceptionCode::GatewayPathUnavailable => "gateway path unavailable",
        ExceptionCode::GatewayTargetDevice => "gateway target device failed to respond",
        ExceptionCode::Custom(_) => "non-standard exception",
    }
}

/// The class of a tokio-modbus link error: a reply that does not match the
/// request or does not decode is garbled, every other I/O error is a lost
/// connection.
pub fn link_error_kind(e: &tokio_modbus::Error) -> ErrorKind {
    match e {
        tokio_modbus::Error::Protocol(_) => ErrorKind::Garbled,
        tokio_modbus::Error::Transport(io) if io.kind() == std::io::ErrorKind::InvalidData => ErrorKind::Garbled,
        tokio_modbus::Error::Transport(_) => ErrorKind::Disconnected,
    }
}

/// A tokio-modbus link error in words: its own text shows the mismatched
/// reply in Rust's debug notation (`mismatching function codes: 4
/// Ok(Custom(94, ...))`), which is no message for an event log.
pub fn link_error_words(e: &tokio_modbus::Error) -> String {
    use tokio_modbus::ProtocolError;
    match e {
        tokio_modbus::Error::Protocol(ProtocolError::HeaderMismatch { message, .. }) => {
            format!("the reply's header does not match the request ({message})")
        }
        tokio_modbus::Error::Protocol(ProtocolError::FunctionCodeMismatch { request, result }) => {
            let got = match result {
                Ok(r) => format!("function {}", r.function_code().value()),
                Err(x) => format!("an exception to function {}", x.function.value()),
            };
            format!("the reply is to another function: asked function {}, got {got}", request.value())
        }
        tokio_modbus::Error::Transport(io) => format!("the link failed: {io}"),
    }
}

/// A positioner controller on Modbus TCP or RTU. See the [module
/// documentation](super) for the protocol and the fault handling.
pub struct ModbusPositioner {
    name: String,
    map: RegisterMap,
    timeouts: ModbusTimeouts,
    ctx: Option<Context>,
    /// On RTU: the line's late replies, drained after a timeout.
    late: Option<Arc<dyn LateReplies>>,
    /// Why the link is dead (after a link fault).
    dead: Option<String>,
}

impl fmt::Debug for ModbusPositioner {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ModbusPositioner")
            .field("name", &self.name)
            .field("map", &self.map)
            .field("timeouts", &self.timeouts)
            .field("connected", &self.ctx.is_some())
            .field("dead", &self.dead)
            .finish()
    }
}

fn check_map(name: &str, map: &RegisterMap) -> Result<()> {
    map.validate().map_err(|e| {
        tracing::warn!(instrument = name, error = %e, "refused a Modbus register map");
        DriverError::usage(name, e.to_string())
    })
}

impl ModbusPositioner {
    /// Connect over Modbus TCP to `addr` (`"10.0.0.5:502"`), unit
    /// `map.unit_id`, within `timeouts.connect`.
    pub async fn connect_tcp(
        addr: impl ToSocketAddrs + fmt::Display,
        map: RegisterMap,
        timeouts: ModbusTimeouts,
    ) -> Result<Self> {
        let name = format!("modbus-tcp {addr}");
        check_map(&name, &map)?;
        let stream = match tokio::time::timeout(timeouts.connect, TcpStream::connect(&addr)).await {
            Err(_) => {
                tracing::warn!(instrument = %name, after = ?timeouts.connect, "Modbus TCP connect timed out");
                return Err(DriverError::timeout(name, "connect", timeouts.connect));
            }
            Ok(Err(e)) => {
                tracing::warn!(instrument = %name, error = %e, "Modbus TCP connect failed");
                return Err(DriverError::new(ErrorKind::Disconnected, name, e.to_string()));
            }
            Ok(Ok(s)) => s,
        };
        // Small requests: send them at once.
        let _ = stream.set_nodelay(true);
        Ok(Self::attach_tcp(stream, map, timeouts)?.named(name))
    }

    /// Open the serial port `path` at `baud` (8 data bits, no parity, 1 stop
    /// bit) and talk Modbus RTU to slave `slave`, which replaces
    /// `map.unit_id`. Opening a port does not wait on the device, so
    /// `timeouts.connect` does not apply; a port that cannot be opened is
    /// `Disconnected`.
    pub async fn connect_rtu(
        path: &str,
        baud: u32,
        slave: u8,
        mut map: RegisterMap,
        timeouts: ModbusTimeouts,
    ) -> Result<Self> {
        let name = format!("modbus-rtu {path}#{slave}");
        map.unit_id = slave;
        check_map(&name, &map)?;
        let port = tokio_serial::new(path, baud).open_native_async().map_err(|e| {
            tracing::warn!(instrument = %name, error = %e, "cannot open the serial port");
            DriverError::new(ErrorKind::Disconnected, name.clone(), format!("cannot open {path}: {e}"))
        })?;
        Ok(Self::attach_rtu(port, map, timeouts)?.named(name))
    }

    /// Modbus TCP framing over an open byte stream (a socket, an in-memory
    /// pipe), unit `map.unit_id`.
    pub fn attach_tcp<T>(transport: T, map: RegisterMap, timeouts: ModbusTimeouts) -> Result<Self>
    where
        T: AsyncRead + AsyncWrite + Send + Unpin + fmt::Debug + 'static,
    {
        check_map("modbus-tcp", &map)?;
        let ctx = tokio_modbus::client::tcp::attach_slave(transport, Slave(map.unit_id));
        Ok(Self { name: "modbus-tcp".into(), map, timeouts, ctx: Some(ctx), late: None, dead: None })
    }

    /// Modbus RTU framing over an open byte stream (a serial port, a pty),
    /// slave `map.unit_id`. RTU has no transaction id: a reply that does not
    /// answer the request just sent (slave, function, byte count, echo) is
    /// discarded, and after a timeout the line is drained for half the
    /// request deadline again, as long as the device may still answer.
    pub fn attach_rtu<T>(transport: T, map: RegisterMap, timeouts: ModbusTimeouts) -> Result<Self>
    where
        T: AsyncRead + AsyncWrite + Send + Unpin + 'static,
    {
        check_map("modbus-rtu", &map)?;
        let (line, late) = line(transport);
        let ctx = tokio_modbus::client::rtu::attach_slave(line, Slave(map.unit_id));
        Ok(Self { name: "modbus-rtu".into(), map, timeouts, ctx: Some(ctx), late: Some(late), dead: None })
    }

    /// The same driver under another name (logs and errors).
    pub fn named(mut self, name: impl Into<String>) -> Self {
        self.name = name.into();
        self
    }

    /// The register map.
    pub fn map(&self) -> &RegisterMap {
        &self.map
    }

    /// The deadlines.
    pub fn timeouts(&self) -> ModbusTimeouts {
        self.timeouts
    }

    /// False after a link fault: every call then fails with `Disconnected`;
    /// build a new driver to reconnect.
    pub fn is_connected(&self) -> bool {
        self.ctx.is_some()
    }

    fn fail(&self, kind: ErrorKind, code: Option<i64>, message: String) -> DriverError {
        DriverError { kind, instrument: self.name.clone(), code, message }
    }

    /// A link fault: log it, drop the context, fail every later call.
    fn link_fault(&mut self, kind: ErrorKind, what: &str, message: String) -> DriverError {
        tracing::warn!(instrument = %self.name, request = what, %kind, %message, "Modbus link fault: the session is closed");
        self.ctx = None;
        self.late = None;
        self.dead = Some(format!("{kind} during {what}: {message}"));
        self.fail(kind, None, message)
    }

    /// One request under the request deadline, every failure classified.
    async fn call(&mut self, what: &str, request: Request<'_>) -> Result<Response> {
        let Some(ctx) = self.ctx.as_mut() else {
            let why = self.dead.clone().unwrap_or_else(|| "not connected".into());
            return Err(self.fail(
                ErrorKind::Disconnected,
                None,
                format!("the Modbus session is closed after an earlier fault ({why}); rebuild the driver"),
            ));
        };
        let limit = self.timeouts.request;
        match tokio::time::timeout(limit, ctx.call(request)).await {
            Err(_) => {
                if let Some(late) = &self.late {
                    let window = self.timeouts.late_window();
                    let dropped = late.drain_until(tokio::time::Instant::now() + window).await;
                    tracing::warn!(instrument = %self.name, request = what, ?window, dropped, "drained the line after a timeout");
                }
                Err(self.link_fault(ErrorKind::Timeout, what, format!("no reply to {what} within {limit:?}")))
            }
            Ok(Err(e)) => {
                let kind = link_error_kind(&e);
                Err(self.link_fault(kind, what, format!("{what}: {}", link_error_words(&e))))
            }
            Ok(Ok(Err(exc))) => {
                let kind = exception_kind(exc);
                let code = u8::from(exc);
                let message = format!("{what}: Modbus exception {code:#04x} ({})", exception_name(exc));
                tracing::warn!(instrument = %self.name, request = what, %kind, code, "Modbus exception");
                if kind.is_link() {
                    // A gateway that cannot reach the device: rebuild like any link fault.
                    let mut e = self.link_fault(kind, what, message);
                    e.code = Some(i64::from(code));
                    return Err(e);
                }
                Err(self.fail(kind, Some(i64::from(code)), message))
            }
            Ok(Ok(Ok(rsp))) => Ok(rsp),
        }
    }

    fn garbled(&mut self, what: &str, message: String) -> DriverError {
        self.link_fault(ErrorKind::Garbled, what, message)
    }

    async fn read(&mut self, what: &str, loc: Location, count: u16) -> Result<Vec<u16>> {
        debug_assert!((1..=MAX_READ_REGISTERS).contains(&count));
        let (request, rsp) = match loc.table {
            RegisterTable::Holding => {
                let rsp = self.call(what, Request::ReadHoldingRegisters(loc.address, count)).await?;
                ("read holding registers", rsp)
            }
            RegisterTable::Input => {
                let rsp = self.call(what, Request::ReadInputRegisters(loc.address, count)).await?;
                ("read input registers", rsp)
            }
        };
        let words = match (loc.table, rsp) {
            (RegisterTable::Holding, Response::ReadHoldingRegisters(w)) => w,
            (RegisterTable::Input, Response::ReadInputRegisters(w)) => w,
            (_, other) => return Err(self.garbled(what, format!("{request} answered with {other:?}"))),
        };
        if words.len() != usize::from(count) {
            return Err(self.garbled(what, format!("{request}: asked for {count} registers, got {}", words.len())));
        }
        Ok(words)
    }

    async fn write(&mut self, what: &str, address: u16, words: &[u16]) -> Result<()> {
        debug_assert!(!words.is_empty() && words.len() <= usize::from(MAX_WRITE_REGISTERS));
        let rsp = self.call(what, Request::WriteMultipleRegisters(address, Cow::Borrowed(words))).await?;
        match rsp {
            Response::WriteMultipleRegisters(a, n) if a == address && usize::from(n) == words.len() => Ok(()),
            other => {
                Err(self
                    .garbled(what, format!("write of {} registers at {address} answered with {other:?}", words.len())))
            }
        }
    }

    async fn command(&mut self, what: &str, code: u16) -> Result<()> {
        let address = self.map.command;
        let rsp = self.call(what, Request::WriteSingleRegister(address, code)).await?;
        match rsp {
            Response::WriteSingleRegister(a, v) if a == address && v == code => Ok(()),
            other => Err(self.garbled(what, format!("command {code} at {address} answered with {other:?}"))),
        }
    }

    fn usage(&self, message: String) -> DriverError {
        tracing::warn!(instrument = %self.name, %message, "refused a request");
        self.fail(ErrorKind::Usage, None, message)
    }
}

#[async_trait]
impl Positioner for ModbusPositioner {
    fn name(&self) -> &str {
        &self.name
    }

    /// Read Device Identification (0x2B / MEI 0x0E), the regular objects by
    /// stream access (vendor name, product code, revision, URL, product
    /// and model name), following "more follows" for at most
    /// [`MAX_ID_REQUESTS`] requests. A device without it (exception 0x01
    /// illegal function, 0x02 illegal data address) has none to say.
    async fn identification(&mut self) -> Result<Option<String>> {
        let what = "identification (read device identification)";
        let mut objects: Vec<(u8, String)> = Vec::new();
        let mut next = 0u8;
        for _ in 0..MAX_ID_REQUESTS {
            let request = Request::ReadDeviceIdentification(tokio_modbus::prelude::ReadCode::Regular, next);
            let rsp = match self.call(what, request).await {
                Ok(rsp) => rsp,
                Err(e) if !e.kind.is_link() && matches!(e.code, Some(1 | 2)) => return Ok(None),
                Err(e) => return Err(e),
            };
            let Response::ReadDeviceIdentification(r) = rsp else {
                return Err(self.garbled(what, format!("answered with {rsp:?}")));
            };
            for o in &r.device_id_objects {
                let text = o.value_as_str().map(str::trim).filter(|t| !t.is_empty());
                if let Some(t) = text.filter(|_| !objects.iter().any(|(id, _)| *id == o.id)) {
                    objects.push((o.id, t.to_string()));
                }
            }
            if !r.more_follows || r.next_object_id <= next {
                break;
            }
            next = r.next_object_id;
        }
        objects.sort_by_key(|(id, _)| *id);
        let words: Vec<String> = objects
            .iter()
            .map(|(id, text)| match ID_OBJECT_NAMES.get(usize::from(*id)) {
                Some(name) => format!("{name} {text}"),
                None => format!("object {id:#04x} {text}"),
            })
            .collect();
        Ok((!words.is_empty()).then(|| words.join(", ")))
    }

    /// Write the commanded position (one write of both registers), then the
    /// move command.
    async fn move_to(&mut self, target_deg: f64) -> Result<()> {
        let words =
            self.map.encode_position(target_deg).map_err(|e| self.usage(format!("target {target_deg} deg: {e}")))?;
        self.write("move_to (command position)", self.map.command_position, &words).await?;
        self.command("move_to (move command)", self.map.command_codes.move_absolute).await
    }

    async fn readout(&mut self) -> Result<f64> {
        let w = self.read("readout", self.map.actual_position, 2).await?;
        match self.map.decode_position([w[0], w[1]]) {
            Ok(deg) => Ok(deg),
            Err(e) => Err(self.garbled("readout", format!("actual position registers {w:04x?}: {e}"))),
        }
    }

    /// The status register, and the fault code register when the fault bit
    /// is set.
    async fn status(&mut self) -> Result<PositionerStatus> {
        let word = self.read("status", self.map.status, 1).await?[0];
        let fault_code = if word & (1 << self.map.status_bits.fault) != 0 {
            Some(self.read("status (fault code)", self.map.fault_code, 1).await?[0])
        } else {
            None
        };
        Ok(self.map.decode_status(word, fault_code))
    }

    async fn stop(&mut self) -> Result<()> {
        self.command("stop", self.map.command_codes.stop).await
    }

    /// Write the velocity registers (one write). The controller judges the
    /// value (a refusal is an exception); only what cannot be encoded is
    /// refused here.
    async fn set_velocity(&mut self, deg_per_s: f64) -> Result<()> {
        let words =
            self.map.encode_velocity(deg_per_s).map_err(|e| self.usage(format!("velocity {deg_per_s} deg/s: {e}")))?;
        self.write("set_velocity", self.map.velocity, &words).await
    }

    async fn clear_fault(&mut self) -> Result<()> {
        self.command("clear_fault", self.map.command_codes.clear_fault).await
    }

    /// Header, chunks, checksum read back and compared, then the load
    /// command. Directional tables are sent as two columns.
    async fn load_correction_table(&mut self, table: &CorrectionTable) -> Result<()> {
        let prepared = self
            .map
            .table_header(table)
            .and_then(|h| Ok((h, self.map.table_chunks(table)?, self.map.table_words(table)?)));
        let (header, chunks, words) = prepared.map_err(|e| self.usage(format!("correction table: {e}")))?;
        self.write("load_correction_table (header)", self.map.table.header, &header).await?;
        for chunk in &chunks {
            self.write("load_correction_table (chunk)", self.map.table.window, chunk).await?;
        }
        let want = table_checksum(&words);
        let got = self.read("load_correction_table (checksum)", self.map.table.checksum, 1).await?[0];
        if got != want {
            return Err(self.garbled(
                "load_correction_table",
                format!("table checksum {got:#06x} read back, {want:#06x} sent: rows were lost or changed on the way"),
            ));
        }
        tracing::debug!(instrument = %self.name, rows = table.len(), directional = table.is_directional(), chunks = chunks.len(), "correction table staged, loading");
        self.command("load_correction_table (load command)", self.map.command_codes.load_table).await
    }

    async fn enable_correction(&mut self, enabled: bool) -> Result<()> {
        let codes = self.map.command_codes;
        let code = if enabled { codes.correction_enable } else { codes.correction_disable };
        self.command("enable_correction", code).await
    }

    /// The status register's `correction_enabled` bit.
    async fn correction_state(&mut self) -> Result<Option<bool>> {
        let word = self.read("correction state (status)", self.map.status, 1).await?[0];
        Ok(Some(word & (1 << self.map.status_bits.correction_enabled) != 0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::modbus::map::PositionEncoding;

    #[test]
    fn exceptions_are_classified() {
        use ExceptionCode::*;
        for (code, kind) in [
            (IllegalFunction, ErrorKind::Usage),
            (IllegalDataAddress, ErrorKind::Usage),
            (IllegalDataValue, ErrorKind::Usage),
            (ServerDeviceFailure, ErrorKind::Device),
            (Acknowledge, ErrorKind::Device),
            (ServerDeviceBusy, ErrorKind::Device),
            (MemoryParityError, ErrorKind::Device),
            (GatewayPathUnavailable, ErrorKind::Disconnected),
            (GatewayTargetDevice, ErrorKind::Timeout),
            (Custom(0x42), ErrorKind::Device),
        ] {
            assert_eq!(exception_kind(code), kind, "{code:?}");
            assert!(!exception_name(code).is_empty());
        }
        let io = |k| tokio_modbus::Error::Transport(std::io::Error::from(k));
        assert_eq!(link_error_kind(&io(std::io::ErrorKind::InvalidData)), ErrorKind::Garbled);
        assert_eq!(link_error_kind(&io(std::io::ErrorKind::BrokenPipe)), ErrorKind::Disconnected);
        assert_eq!(link_error_kind(&io(std::io::ErrorKind::UnexpectedEof)), ErrorKind::Disconnected);
        // In words, not in Rust's debug notation.
        let mismatch = tokio_modbus::Error::Protocol(tokio_modbus::ProtocolError::FunctionCodeMismatch {
            request: tokio_modbus::FunctionCode::new(4),
            result: Ok(tokio_modbus::Response::Custom(94, vec![4, 0].into())),
        });
        let words = link_error_words(&mismatch);
        assert_eq!(words, "the reply is to another function: asked function 4, got function 94");
        assert!(!words.contains("Ok(") && !words.contains("Custom"));
    }

    #[tokio::test]
    async fn bad_maps_and_values_are_usage_errors_before_any_request() {
        let (a, _b) = tokio::io::duplex(64);
        let bad = RegisterMap { velocity: 1, ..RegisterMap::default() };
        assert_eq!(ModbusPositioner::attach_tcp(a, bad, ModbusTimeouts::default()).unwrap_err().kind, ErrorKind::Usage);
        let (a, _b) = tokio::io::duplex(64);
        let mut drv = ModbusPositioner::attach_tcp(a, RegisterMap::default(), ModbusTimeouts::default()).unwrap();
        for target in [f64::NAN, f64::INFINITY, 1e9] {
            assert_eq!(drv.move_to(target).await.unwrap_err().kind, ErrorKind::Usage, "{target}");
        }
        assert_eq!(drv.set_velocity(f64::NAN).await.unwrap_err().kind, ErrorKind::Usage);
        let long = CorrectionTable::new(vec![0.0; 70_000]).unwrap();
        assert_eq!(drv.load_correction_table(&long).await.unwrap_err().kind, ErrorKind::Usage);
        assert!(drv.is_connected(), "local refusals leave the session open");
        let f = RegisterMap { position_encoding: PositionEncoding::Float32, ..RegisterMap::default() };
        let (a, _b) = tokio::io::duplex(64);
        let mut drv = ModbusPositioner::attach_rtu(a, f, ModbusTimeouts::default()).unwrap();
        assert_eq!(drv.move_to(1e40).await.unwrap_err().kind, ErrorKind::Usage);
    }

    #[tokio::test(start_paused = true)]
    async fn a_silent_peer_times_out_and_the_session_is_closed() {
        let (a, _peer) = tokio::io::duplex(1024);
        let t = ModbusTimeouts { request: Duration::from_millis(200), ..ModbusTimeouts::default() };
        let mut drv = ModbusPositioner::attach_tcp(a, RegisterMap::default(), t).unwrap().named("test");
        let e = drv.readout().await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Timeout, "{e}");
        assert!(!drv.is_connected());
        let e = drv.status().await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
        assert!(e.message.contains("rebuild"), "{e}");
    }

    #[tokio::test]
    async fn a_closed_peer_is_disconnected() {
        let (a, peer) = tokio::io::duplex(1024);
        drop(peer);
        let mut drv = ModbusPositioner::attach_rtu(a, RegisterMap::default(), ModbusTimeouts::default()).unwrap();
        assert_eq!(drv.stop().await.unwrap_err().kind, ErrorKind::Disconnected);
    }

    #[tokio::test]
    async fn opening_a_missing_port_or_host_is_a_disconnection() {
        let e = ModbusPositioner::connect_rtu(
            "/dev/does-not-exist-modbus",
            19_200,
            3,
            RegisterMap::default(),
            ModbusTimeouts::default(),
        )
        .await
        .unwrap_err();
        assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
        // A port nobody listens on (bound, then closed).
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = l.local_addr().unwrap();
        drop(l);
        let e =
            ModbusPositioner::connect_tcp(addr, RegisterMap::default(), ModbusTimeouts::default()).await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
    }

    #[test]
    fn timeouts_default_and_deserialize_from_milliseconds() {
        use serde::de::value::{Error, MapDeserializer};
        let t = ModbusTimeouts::default();
        assert_eq!((t.connect, t.request), (Duration::from_secs(3), Duration::from_secs(1)));
        let given = MapDeserializer::<_, Error>::new([("request_ms", 250u64)].into_iter());
        let t = ModbusTimeouts::deserialize(given).unwrap();
        assert_eq!((t.connect, t.request), (Duration::from_secs(3), Duration::from_millis(250)));
        let unknown = MapDeserializer::<_, Error>::new([("request", 250u64)].into_iter());
        assert!(ModbusTimeouts::deserialize(unknown).is_err());
    }
}
