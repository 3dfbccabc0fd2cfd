//! A simulated MI-4190-style positioner controller on a TCP port.
//!
//! [`serve_tcp`] speaks the protocol of [`survey_positioner_drivers::scpi`] (see its module
//! documentation for the wire format, the status bits, the error codes, and
//! what was looked up versus chosen) and answers from a [`SimPositioner`]: the
//! physics, the clock and the sim's own injected faults are the positioner's.
//! The request parser here is written from that documentation, independently
//! of the driver's codec (it shares only the line framing, [`Decoder`], and
//! the status bit constants), so a codec that drifts from the documented
//! protocol fails the tests instead of agreeing with itself.
//!
//! # Behaviour
//!
//! - One client at a time, like the hardware: the next connection is accepted
//!   when the current one closes. The controller state (commanded position,
//!   error queue, table being loaded, latched faults) survives reconnections.
//! - Only the documented short forms are accepted, in any case:
//!   `CONT1:AXIS(1):POS:COMM 10`, `cont1:axis(1):stat?`. Other controllers or
//!   axes are refused with `-114`, unknown headers with `-113`.
//! - Refused commands push `<code>,"<text>"` on an error queue of 16 entries
//!   (`SYST:ERR?` pops the oldest; overflow turns the newest into `-350`).
//!   `POS:COMM` outside the travel of the sim, `VEL:COMM` not in
//!   `(0, MAX_VELOCITY_DEG_S]`, and table rows that leave a gap are `-222`;
//!   a sim `Usage` refusal (loading or switching the table while moving, no
//!   table) is `-221`; a sim device refusal (a move while a fault is latched)
//!   carries the fault's code and text.
//! - `STAT?` sets only the bits the MI-4192 manual documents (p. 3-42, as
//!   reproduced in public code: bits 0-12; 13-15 unused), from this module's
//!   own table ([`status`]), not the driver's: active, indexed, enabled, in
//!   motion (bit 7), the limit switches, and a latched fault as bit 6 (error
//!   limit) for the sim's following error ([`FAULT_FOLLOWING_ERROR`]) or
//!   bit 4 (PAU fault) for any other code, with bit 5 (enabled) cleared. The
//!   first `STAT?` that shows a newly latched fault pushes its code and text
//!   on the error queue. There is no in-position bit: a client decides from
//!   bit 7 and `POS:CURR?` (or `VEL:CURR?` = 0, as public code does).
//! - `SYST:ERR:ALL?` answers every queued entry, `<code>, "<text>"` joined by
//!   commas, and empties the queue (`0, "No error"` when empty, as public code
//!   shows); `SYST:ERR:COUN?` the number queued; `SYST:ERR?` the oldest.
//! - `UNIT:POS?` answers 6 (degree; public code's table), or what
//!   [`ScpiFaults::report_position_units`] set.
//! - A sim call that fails with a link fault of its own
//!   ([`PositionerFaults`](survey_sims::positioner::PositionerFaults)) becomes the
//!   same fault on the wire: `Timeout` = no reply, `Disconnected` = the
//!   connection is closed, `Garbled` = a garbled reply (for a command without
//!   reply, the command is lost).
//!
//! # Faults ([`Faults`])
//!
//! The controller is a [`Service`] served by [`crate::serve`]'s loops; link
//! faults are the [`relay`](crate::relay)'s in front of it ([`garbled`]:
//! the SCPI way to garble a reply, the high bit set on every byte). Device
//! faults armed in its [`Faults`] apply to the next requests as they come:
//!
//! - [`Fault::Refuse`]: the next axis command (not a query, not `*CLS`) is
//!   not executed and pushes the given code and text instead (`None`:
//!   -310, a device-specific error of SCPI-99's -300 class);
//! - [`Fault::Trip`]: at the next request the axis latches that device
//!   fault (the sim is stopped), reported by `STAT?` and `SYST:ERR?` and
//!   refusing moves until `FAUL:CLE`.
//!
//! [`Controller::position_units`] changes what `UNIT:POS?` answers.

use crate::serve::{Answer, Codec, Service};
use async_trait::async_trait;
use std::collections::VecDeque;
use std::sync::Arc;
use std::sync::atomic::{AtomicI64, Ordering};
use survey_drivers::error::{DriverError, ErrorKind};
use survey_positioner_drivers::scpi::{CodecError, Decoder};
use survey_sims::faults::{Fault, Faults, Garble};
use survey_sims::positioner::{FAULT_FOLLOWING_ERROR, SimPositioner};

/// The `STAT?` bits, from the MI-4192 manual's table (p. 3-42) as public code
/// reproduces it (`csun-rf-lab/antennameasure`, `MI4190.m`). Bits 13-15 are
/// unused and never set here.
pub mod status {
    /// Bit 2: reverse limit active.
    pub const REVERSE_LIMIT: u16 = 1 << 2;
    /// Bit 3: forward limit active.
    pub const FORWARD_LIMIT: u16 = 1 << 3;
    /// Bit 4: PAU fault.
    pub const PAU_FAULT: u16 = 1 << 4;
    /// Bit 5: axis enabled.
    pub const ENABLED: u16 = 1 << 5;
    /// Bit 6: error limit active.
    pub const ERROR_LIMIT: u16 = 1 << 6;
    /// Bit 7: axis in motion.
    pub const IN_MOTION: u16 = 1 << 7;
    /// Bit 8: axis is active.
    pub const ACTIVE: u16 = 1 << 8;
    /// Bit 9: axis is indexed.
    pub const INDEXED: u16 = 1 << 9;
}
use survey_drivers::traits::{DeviceFault, Limit, Positioner};
use survey_processing::table::CorrectionTable;
use tokio::io::{AsyncRead, AsyncWrite};
use tokio::net::TcpListener;

/// Fastest velocity `VEL:COMM` accepts, degrees per second.
pub const MAX_VELOCITY_DEG_S: f64 = 100.0;
/// Most rows a table column may hold.
pub const MAX_TABLE_ROWS: usize = 1 << 16;
/// Capacity of the error queue.
pub const ERROR_QUEUE_LEN: usize = 16;
/// Longest request line accepted, bytes.
pub const MAX_REQUEST_LINE: usize = 64 * 1024;
/// The `*IDN?` reply.
pub const IDN: &str = "survey-sims,MI-4190-style positioner controller (simulated),0,1.0";

/// The default device-fault code of [`Fault::Refuse`]`(None)`: -310, a
/// device-specific error of SCPI-99's -300 class.
pub const DEVICE_FAULT_CODE: i64 = -310;

/// The SCPI way to garble a reply: the high bit set on every byte but the
/// line's LF.
pub fn garbled() -> Fault {
    Fault::Garble(Garble::edit("SCPI high bit set", |reply: &[u8]| {
        let line = reply.strip_suffix(b"\n").unwrap_or(reply);
        Some(garble_bytes(line))
    }))
}

/// Serve the controller on `listener`, one client at a time, until the task
/// running this future is dropped or aborted.
pub async fn serve_tcp(listener: TcpListener, positioner: SimPositioner, faults: Faults) {
    serve_tcp_at(listener, positioner, faults, (1, 1)).await;
}

/// [`serve_tcp`] for the axis at `(controller, axis)` (`CONT<c>:AXIS(<a>)`):
/// requests to any other address are answered with error -114, as to an
/// axis the controller does not have.
pub async fn serve_tcp_at(listener: TcpListener, positioner: SimPositioner, faults: Faults, address: (u32, u32)) {
    serve_controller(listener, Controller::new(positioner, faults).at(address)).await;
}

/// Serve `controller` on `listener` (see [`serve_tcp`]).
pub async fn serve_controller(listener: TcpListener, controller: Controller) {
    crate::serve::serve_tcp(listener, request_codec, controller).await;
}

/// Serve the controller's axis at `(controller, axis)` on one byte stream (a
/// serial line: a pty's master end) until the stream closes.
pub async fn serve_stream<S>(stream: S, positioner: SimPositioner, faults: Faults, address: (u32, u32))
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    let mut controller = Controller::new(positioner, faults).at(address);
    crate::serve::serve_stream(stream, request_codec(), &mut controller).await;
}

/// The request framing: lines (the driver's [`Decoder`]).
fn request_codec() -> Decoder {
    Decoder::new(MAX_REQUEST_LINE)
}

impl Codec for Decoder {
    type Item = Result<String, CodecError>;
    fn push(&mut self, bytes: &[u8]) {
        Decoder::push(self, bytes);
    }
    fn next_item(&mut self) -> Option<Self::Item> {
        self.next_line()
    }
}

/// What to do after a request.
type Outcome = Answer<Vec<u8>>;

/// A reply line.
fn reply(line: String) -> Outcome {
    let mut bytes = line.into_bytes();
    bytes.push(b'\n');
    Answer::Send(bytes)
}

/// A simulated controller: the [`Service`] [`serve_tcp`] and
/// [`serve_stream`] serve.
#[derive(Debug)]
pub struct Controller {
    /// The `(controller, axis)` this simulator is (default `(1, 1)`).
    address: (u32, u32),
    sim: SimPositioner,
    faults: Faults,
    /// What `UNIT:POS?` answers (6, degree, unless changed).
    units: Arc<AtomicI64>,
    commanded: f64,
    velocity: f64,
    queue: VecDeque<(i64, String)>,
    forward: Vec<f64>,
    reverse: Vec<f64>,
    /// A fault latched by [`ScpiFaults::trip`].
    injected: Option<DeviceFault>,
    /// The latched fault already pushed on the error queue.
    reported: Option<DeviceFault>,
}

impl Controller {
    /// A controller of `sim`'s axis at `(1, 1)`, its device faults armed in `faults`.
    pub fn new(sim: SimPositioner, faults: Faults) -> Self {
        let commanded = match sim.config().travel {
            Some((lo, hi)) => 0.0f64.clamp(lo, hi),
            None => 0.0,
        };
        let velocity = sim.config().velocity_deg_s;
        Self {
            address: (1, 1),
            sim,
            faults,
            units: Arc::new(AtomicI64::new(6)),
            commanded,
            velocity,
            queue: VecDeque::new(),
            forward: Vec::new(),
            reverse: Vec::new(),
            injected: None,
            reported: None,
        }
    }

    /// The same controller for the axis at `(controller, axis)`.
    pub fn at(mut self, address: (u32, u32)) -> Self {
        self.address = address;
        self
    }

    /// The code `UNIT:POS?` answers (6, degree, by default), shared: set it
    /// while the controller serves.
    pub fn position_units(&self) -> Arc<AtomicI64> {
        Arc::clone(&self.units)
    }

    fn push_error(&mut self, code: i64, text: impl Into<String>) {
        let text = text.into();
        tracing::debug!(code, %text, "scpi simulator: error queued");
        if self.queue.len() >= ERROR_QUEUE_LEN {
            if let Some(last) = self.queue.back_mut() {
                *last = (-350, "Queue overflow".into());
            }
        } else {
            self.queue.push_back((code, text));
        }
    }

    /// Map a sim failure: link faults to the wire, refusals to the queue.
    fn sim_failed(&mut self, e: DriverError, usage_code: i64) -> Outcome {
        match e.kind {
            ErrorKind::Timeout => Outcome::Nothing,
            ErrorKind::Disconnected => Outcome::Close,
            ErrorKind::Garbled => Outcome::Send(garble_bytes(b"#?")),
            ErrorKind::Usage => {
                self.push_error(usage_code, format!("{};{}", text_of(usage_code), e.message));
                Outcome::Nothing
            }
            ErrorKind::Device => {
                self.push_error(e.code.unwrap_or(-300), e.message);
                Outcome::Nothing
            }
        }
    }

    /// One request line. An armed trip latches first; then the controller's
    /// own commands are answered, then a command to this axis is checked
    /// (address, injected refusal, parameters) and goes to its group: the
    /// axis queries, the motion commands, the correction table.
    async fn handle(&mut self, line: &str) -> Outcome {
        if let Some(out) = self.trip_if_armed().await {
            return out;
        }
        let line = line.trim();
        if line.is_empty() {
            return Outcome::Nothing;
        }
        let (header, params) = match line.find([' ', '\t']) {
            Some(i) => (line[..i].to_ascii_uppercase(), line[i..].trim()),
            None => (line.to_ascii_uppercase(), ""),
        };
        let header = header.strip_prefix(':').unwrap_or(&header).to_string();
        if let Some(out) = self.controller_command(&header) {
            return out;
        }
        let Some(tail) = self.axis_tail(&header) else { return Outcome::Nothing };
        if !tail.ends_with('?') && self.refused_by_fault(line) {
            return Outcome::Nothing;
        }
        if !self.parameters_fit(tail, params) {
            return Outcome::Nothing;
        }
        if let Some(out) = self.axis_query(tail).await {
            return out;
        }
        if let Some(out) = self.motion(tail, params).await {
            return out;
        }
        if let Some(out) = self.correction(tail, params).await {
            return out;
        }
        self.push_error(-113, format!("Undefined header;{header}"));
        Outcome::Nothing
    }

    /// An armed [`Fault::Trip`]: the axis latches its device fault and the
    /// sim is stopped. `Some` when the stop fails: that failure is the
    /// request's outcome.
    async fn trip_if_armed(&mut self) -> Option<Outcome> {
        if let Some(Fault::Trip(fault)) = self.faults.take_device(|f| matches!(f, Fault::Trip(_))) {
            tracing::debug!(?fault, "scpi simulator: device fault latched (injected)");
            self.injected = Some(fault);
            if let Err(e) = self.sim.stop().await {
                return Some(self.sim_failed(e, -221));
            }
        }
        None
    }

    /// The controller's own commands (no axis in the header): `*IDN?`,
    /// `*CLS` and the error queue's `SYST:ERR` family. `None` for any other
    /// header.
    fn controller_command(&mut self, header: &str) -> Option<Outcome> {
        Some(match header {
            "*IDN?" => reply(IDN.into()),
            "*CLS" => {
                self.queue.clear();
                Outcome::Nothing
            }
            "SYST:ERR?" | "SYST:ERR:NEXT?" => {
                let (code, text) = self.queue.pop_front().unwrap_or((0, "No error".into()));
                reply(error_line(code, &text))
            }
            "SYST:ERR:ALL?" => {
                if self.queue.is_empty() {
                    return Some(reply("0, \"No error\"".into()));
                }
                let all: Vec<String> = self.queue.drain(..).map(|(code, text)| error_line(code, &text)).collect();
                reply(all.join(", "))
            }
            "SYST:ERR:COUN?" | "SYST:ERR:COUN" => reply(self.queue.len().to_string()),
            _ => return None,
        })
    }

    /// The command part of an axis header addressed to this axis. `None`
    /// with `-113` queued for a header of no axis, `-114` for another
    /// controller's or axis'.
    fn axis_tail<'h>(&mut self, header: &'h str) -> Option<&'h str> {
        let Some((controller, axis, tail)) = axis_header(header) else {
            self.push_error(-113, format!("Undefined header;{header}"));
            return None;
        };
        if (controller, axis) != self.address {
            self.push_error(-114, format!("Header suffix out of range;no controller {controller} axis {axis}"));
            return None;
        }
        Some(tail)
    }

    /// Whether an armed [`Fault::Refuse`] or [`Fault::RefuseWithError`] takes
    /// this command (`line`, not a query): then it is not executed and the
    /// fault's code and text are queued instead.
    fn refused_by_fault(&mut self, line: &str) -> bool {
        let refused = |f: &mut Fault| matches!(f, Fault::Refuse(_) | Fault::RefuseWithError(_));
        let Some(fault) = self.faults.take_device(refused) else { return false };
        let (code, text) = match fault {
            Fault::Refuse(Some(d)) | Fault::RefuseWithError(d) => (d.code, d.text),
            _ => (DEVICE_FAULT_CODE, "System error; simulated device fault".into()),
        };
        tracing::debug!(%line, code, "scpi simulator: command refused (injected)");
        self.push_error(code, text);
        true
    }

    /// Whether the axis command `tail` has parameters exactly when it takes
    /// some; else `-108` (given, not taken) or `-109` (taken, missing) is queued.
    fn parameters_fit(&mut self, tail: &str, params: &str) -> bool {
        let takes_params = matches!(tail, "POS:COMM" | "VEL:COMM" | "CORR:TABL" | "CORR:TABL:REV" | "CORR:STAT");
        if !takes_params && !params.is_empty() {
            self.push_error(-108, format!("Parameter not allowed;{params}"));
            return false;
        }
        if takes_params && params.is_empty() {
            self.push_error(-109, "Missing parameter");
            return false;
        }
        true
    }

    /// The axis' queries of position, units, status and velocity (`POS:COMM?`,
    /// `UNIT:POS?`, `POS:CURR?`, `STAT?`, `VEL:COMM?`, `VEL:CURR?`). `None`
    /// for any other command.
    async fn axis_query(&mut self, tail: &str) -> Option<Outcome> {
        Some(match tail {
            "POS:COMM?" => reply(format!("{}", self.commanded)),
            "UNIT:POS?" => reply(self.units.load(Ordering::Relaxed).to_string()),
            "POS:CURR?" => match self.sim.readout().await {
                Ok(v) => reply(format!("{v}")),
                Err(e) => self.sim_failed(e, -221),
            },
            "STAT?" => match self.status_word().await {
                Ok(w) => reply(w.to_string()),
                Err(e) => self.sim_failed(e, -221),
            },
            "VEL:COMM?" => reply(format!("{}", self.velocity)),
            "VEL:CURR?" => match self.sim.status().await {
                Ok(s) => reply(format!("{}", if s.moving { self.velocity } else { 0.0 })),
                Err(e) => self.sim_failed(e, -221),
            },
            _ => return None,
        })
    }

    /// The motion commands: the commanded position (within the travel) and
    /// velocity, start, stop, and clearing a latched fault (`POS:COMM`,
    /// `VEL:COMM`, `MOT:STAR`, `MOT:STOP`, `FAUL:CLE`). A start while a fault
    /// is latched is refused with the fault. `None` for any other command.
    async fn motion(&mut self, tail: &str, params: &str) -> Option<Outcome> {
        Some(match tail {
            "POS:COMM" => {
                let Some(v) = self.number(params) else { return Some(Outcome::Nothing) };
                if let Some((lo, hi)) = self.sim.config().travel
                    && !(lo..=hi).contains(&v)
                {
                    self.push_error(
                        -222,
                        format!("Data out of range;target {v} deg is outside the travel {lo}..{hi} deg"),
                    );
                    return Some(Outcome::Nothing);
                }
                self.commanded = v;
                Outcome::Nothing
            }
            "MOT:STAR" => {
                if let Some(f) = &self.injected {
                    let (code, text) = (f.code, format!("{} (clear the fault first)", f.text));
                    self.push_error(code, text);
                    return Some(Outcome::Nothing);
                }
                match self.sim.move_to(self.commanded).await {
                    Ok(()) => Outcome::Nothing,
                    Err(e) => self.sim_failed(e, -222),
                }
            }
            "MOT:STOP" => match self.sim.stop().await {
                Ok(()) => Outcome::Nothing,
                Err(e) => self.sim_failed(e, -221),
            },
            "VEL:COMM" => {
                let Some(v) = self.number(params) else { return Some(Outcome::Nothing) };
                if !(v > 0.0 && v <= MAX_VELOCITY_DEG_S) {
                    self.push_error(
                        -222,
                        format!("Data out of range;velocity {v} deg/s is not in (0, {MAX_VELOCITY_DEG_S}]"),
                    );
                    return Some(Outcome::Nothing);
                }
                match self.sim.set_velocity(v).await {
                    Ok(()) => {
                        self.velocity = v;
                        Outcome::Nothing
                    }
                    Err(e) => self.sim_failed(e, -222),
                }
            }
            "FAUL:CLE" => {
                self.injected = None;
                self.reported = None;
                match self.sim.clear_fault().await {
                    Ok(()) => Outcome::Nothing,
                    Err(e) => self.sim_failed(e, -221),
                }
            }
            _ => return None,
        })
    }

    /// The correction table: clearing, writing and counting the forward and
    /// reverse rows, loading them into the sim, and switching the correction
    /// on or off (`CORR:TABL:CLE`, `CORR:TABL[:REV]`, `CORR:TABL[:REV]:POIN?`,
    /// `CORR:TABL:LOAD`, `CORR:STAT`, `CORR:STAT?`). `None` for any other
    /// command.
    async fn correction(&mut self, tail: &str, params: &str) -> Option<Outcome> {
        Some(match tail {
            "CORR:TABL:CLE" => {
                self.forward.clear();
                self.reverse.clear();
                Outcome::Nothing
            }
            "CORR:TABL" | "CORR:TABL:REV" => {
                self.table_rows(tail == "CORR:TABL:REV", params);
                Outcome::Nothing
            }
            "CORR:TABL:POIN?" => reply(self.forward.len().to_string()),
            "CORR:TABL:REV:POIN?" => reply(self.reverse.len().to_string()),
            "CORR:TABL:LOAD" => {
                let built = if self.reverse.is_empty() {
                    CorrectionTable::new(self.forward.clone())
                } else {
                    CorrectionTable::directional(self.forward.clone(), self.reverse.clone())
                };
                match built {
                    Err(e) => {
                        self.push_error(-221, format!("Settings conflict;{e}"));
                        Outcome::Nothing
                    }
                    Ok(table) => match self.sim.load_correction_table(&table).await {
                        Ok(()) => Outcome::Nothing,
                        Err(e) => self.sim_failed(e, -221),
                    },
                }
            }
            "CORR:STAT" => {
                let on = match params.to_ascii_uppercase().as_str() {
                    "ON" | "1" => true,
                    "OFF" | "0" => false,
                    _ => {
                        self.push_error(-104, format!("Data type error;{params}"));
                        return Some(Outcome::Nothing);
                    }
                };
                match self.sim.enable_correction(on).await {
                    Ok(()) => Outcome::Nothing,
                    Err(e) => self.sim_failed(e, -221),
                }
            }
            "CORR:STAT?" => match self.sim.status().await {
                Ok(s) => reply(if s.correction_enabled { "1" } else { "0" }.into()),
                Err(e) => self.sim_failed(e, -221),
            },
            _ => return None,
        })
    }

    /// A decimal parameter, or `-104`/`-222` on the queue.
    fn number(&mut self, text: &str) -> Option<f64> {
        let t = text.trim();
        if t.is_empty() || !t.bytes().all(|b| b.is_ascii_digit() || b"+-.eE".contains(&b)) {
            self.push_error(-104, format!("Data type error;{t}"));
            return None;
        }
        match t.parse::<f64>() {
            Ok(v) if v.is_finite() => Some(v),
            Ok(_) => {
                self.push_error(-222, format!("Data out of range;{t}"));
                None
            }
            Err(_) => {
                self.push_error(-104, format!("Data type error;{t}"));
                None
            }
        }
    }

    /// `CORR:TABL[:REV] <start>,<v>...`: write the rows from `start` on.
    fn table_rows(&mut self, reverse: bool, params: &str) {
        let mut parts = params.split(',');
        let start = parts.next().unwrap_or("").trim();
        let Ok(start) = start.parse::<usize>() else {
            self.push_error(-104, format!("Data type error;row {start}"));
            return;
        };
        let mut values = Vec::new();
        for p in parts {
            let Some(v) = self.number(p) else { return };
            values.push(v);
        }
        if values.is_empty() {
            self.push_error(-109, "Missing parameter;no rows");
            return;
        }
        let held = if reverse { self.reverse.len() } else { self.forward.len() };
        if start > held {
            self.push_error(
                -222,
                format!("Data out of range;rows from {start} would leave a gap after the {held} held"),
            );
            return;
        }
        if start + values.len() > MAX_TABLE_ROWS {
            self.push_error(-223, format!("Too much data;more than {MAX_TABLE_ROWS} rows"));
            return;
        }
        let column = if reverse { &mut self.reverse } else { &mut self.forward };
        let end = start + values.len();
        if end > held {
            column.resize(end, 0.0);
        }
        column[start..end].copy_from_slice(&values);
    }

    /// The `STAT?` word; pushes a newly latched fault on the error queue.
    async fn status_word(&mut self) -> Result<u16, DriverError> {
        let s = self.sim.status().await?;
        let fault = self.injected.clone().or(s.fault.clone());
        let mut w = status::ACTIVE | status::INDEXED;
        match &fault {
            None => w |= status::ENABLED,
            Some(f) if f.code == FAULT_FOLLOWING_ERROR => w |= status::ERROR_LIMIT,
            Some(_) => w |= status::PAU_FAULT,
        }
        if s.moving {
            w |= status::IN_MOTION;
        }
        w |= match s.limit {
            Some(Limit::Lower) => status::REVERSE_LIMIT,
            Some(Limit::Upper) => status::FORWARD_LIMIT,
            None => 0,
        };
        if fault != self.reported {
            if let Some(f) = &fault {
                self.push_error(f.code, f.text.clone());
            }
            self.reported = fault;
        }
        Ok(w)
    }
}

/// `CONT<c>:AXIS(<a>):<tail>` (uppercase) -> `(c, a, tail)`; `CONT` alone is 1.
fn axis_header(header: &str) -> Option<(u32, u32, &str)> {
    let rest = header.strip_prefix("CONT")?;
    let (c, rest) = rest.split_once(':')?;
    let c = if c.is_empty() { 1 } else { digits(c)? };
    let rest = rest.strip_prefix("AXIS(")?;
    let (a, tail) = rest.split_once("):")?;
    Some((c, digits(a)?, tail))
}

fn digits(s: &str) -> Option<u32> {
    if s.is_empty() || s.len() > 9 || !s.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    s.parse().ok()
}

/// `<code>,"<text>"` with inner quotes doubled and non-ASCII replaced.
fn error_line(code: i64, text: &str) -> String {
    let text: String = text.chars().map(|c| if c == ' ' || c.is_ascii_graphic() { c } else { '?' }).collect();
    format!("{code},\"{}\"", text.replace('"', "\"\""))
}

/// The SCPI-99 text of the codes the simulator produces itself.
fn text_of(code: i64) -> &'static str {
    match code {
        -221 => "Settings conflict",
        -222 => "Data out of range",
        _ => "Execution error",
    }
}

/// The line with the high bit set on every byte, then LF.
fn garble_bytes(line: &[u8]) -> Vec<u8> {
    let mut b: Vec<u8> = line.iter().map(|b| b | 0x80).collect();
    b.push(b'\n');
    b
}

#[async_trait]
impl Service for Controller {
    type Request = Result<String, CodecError>;
    type Reply = Vec<u8>;

    async fn call(&mut self, request: Self::Request) -> Outcome {
        match request {
            Ok(line) => self.handle(&line).await,
            Err(e) => {
                self.push_error(-102, format!("Syntax error;{e}"));
                Outcome::Nothing
            }
        }
    }
}

#[cfg(test)]
mod tests;
