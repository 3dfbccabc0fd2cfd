//! A simulated MI-4190-style positioner controller on a TCP port.
//!
//! [`serve_tcp`] speaks the protocol of [`survey_drivers::scpi`] (see its module
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
//!   ([`PositionerFaults`](crate::positioner::PositionerFaults)) becomes the
//!   same fault on the wire: `Timeout` = no reply, `Disconnected` = the
//!   connection is closed, `Garbled` = a garbled reply (for a command without
//!   reply, the command is lost).
//!
//! # Fault injection ([`ScpiFaults`])
//!
//! A [`ScpiFaults`] is a handle shared with the test (clone it before passing
//! it in). What is armed applies to the next requests as they come, so a test
//! arms a fault right before the driver call that should meet it:
//!
//! - [`drop_next_replies`](ScpiFaults::drop_next_replies): the next replies
//!   are not sent (the query is still executed);
//! - [`garble_next_replies`](ScpiFaults::garble_next_replies): the next
//!   replies are sent with the high bit set on every byte (then LF);
//! - [`close_during_next_reply`](ScpiFaults::close_during_next_reply): the
//!   first half of the next reply is sent, without its LF, then the
//!   connection is closed;
//! - [`stale_line_after_next_reply`](ScpiFaults::stale_line_after_next_reply):
//!   an extra line follows the next reply in the same write (a late or
//!   duplicated answer the driver must not take for its next reply);
//! - [`reject_next_command`](ScpiFaults::reject_next_command): the next axis
//!   command (not a query, not `*CLS`) is not executed and pushes the given
//!   code and text instead;
//! - [`trip`](ScpiFaults::trip): at the next request the axis latches a device
//!   fault with that code and text (the sim is stopped), reported by `STAT?`
//!   and `SYST:ERR?` and refusing moves until `FAUL:CLE`.

use crate::faults::{Countdown, FaultPlan};
use crate::positioner::{FAULT_FOLLOWING_ERROR, SimPositioner};
use std::collections::VecDeque;
use survey_drivers::error::{DriverError, ErrorKind};
use survey_drivers::scpi::Decoder;

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
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
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

/// Faults armed by a test; a cheap handle, shared by clones. See the module
/// documentation.
#[derive(Debug, Clone, Default)]
pub struct ScpiFaults {
    plan: FaultPlan<Plan>,
}

#[derive(Debug, Default)]
struct Plan {
    drop_replies: Countdown,
    garble_replies: Countdown,
    close_in_reply: bool,
    stale_line: Option<String>,
    reject: VecDeque<(i64, String)>,
    trip: Option<DeviceFault>,
    units: Option<i64>,
}

impl ScpiFaults {
    /// No faults armed.
    pub fn new() -> Self {
        Self::default()
    }

    /// Do not send the next `n` replies.
    pub fn drop_next_replies(&self, n: usize) {
        self.plan.lock().drop_replies.add(n);
    }

    /// Garble the next `n` replies.
    pub fn garble_next_replies(&self, n: usize) {
        self.plan.lock().garble_replies.add(n);
    }

    /// Send half of the next reply, then close the connection.
    pub fn close_during_next_reply(&self) {
        self.plan.lock().close_in_reply = true;
    }

    /// Send `line` right after the next reply.
    pub fn stale_line_after_next_reply(&self, line: impl Into<String>) {
        self.plan.lock().stale_line = Some(line.into());
    }

    /// Refuse the next axis command with `code` and `text`.
    pub fn reject_next_command(&self, code: i64, text: impl Into<String>) {
        self.plan.lock().reject.push_back((code, text.into()));
    }

    /// Answer `UNIT:POS?` with `code` (default 6, degree).
    pub fn report_position_units(&self, code: i64) {
        self.plan.lock().units = Some(code);
    }

    /// Latch a device fault at the next request.
    pub fn trip(&self, code: i64, text: impl Into<String>) {
        self.plan.lock().trip = Some(DeviceFault { code, text: text.into() });
    }
}

/// Serve the controller on `listener`, one client at a time, until the task
/// running this future is dropped or aborted.
pub async fn serve_tcp(listener: TcpListener, positioner: SimPositioner, faults: ScpiFaults) {
    serve_tcp_at(listener, positioner, faults, (1, 1)).await;
}

/// [`serve_tcp`] for the axis at `(controller, axis)` (`CONT<c>:AXIS(<a>)`):
/// requests to any other address are answered with error -114, as to an
/// axis the controller does not have.
pub async fn serve_tcp_at(listener: TcpListener, positioner: SimPositioner, faults: ScpiFaults, address: (u32, u32)) {
    let mut controller = Controller::new(positioner, faults);
    controller.address = address;
    loop {
        match listener.accept().await {
            Ok((stream, peer)) => {
                tracing::debug!(%peer, "scpi simulator: client connected");
                stream.set_nodelay(true).ok();
                controller.serve(stream).await;
                tracing::debug!(%peer, "scpi simulator: client gone");
            }
            Err(e) => {
                tracing::warn!(error = %e, "scpi simulator: accept failed");
                tokio::task::yield_now().await;
            }
        }
    }
}

/// Serve the controller's axis at `(controller, axis)` on one byte stream (a
/// serial line: a pty's master end) until the stream closes.
pub async fn serve_stream<S>(stream: S, positioner: SimPositioner, faults: ScpiFaults, address: (u32, u32))
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    let mut controller = Controller::new(positioner, faults);
    controller.address = address;
    controller.serve(stream).await;
}

/// What to do after a request.
enum Outcome {
    /// No reply (a command, or a query that failed into the error queue).
    Nothing,
    /// Send this line.
    Reply(String),
    /// The sim lost the request: no reply.
    Lost,
    /// The sim garbled its answer.
    Garble,
    /// The sim dropped the link.
    Close,
}

/// The armed fault a reply meets.
enum ReplyFault {
    Drop,
    Garble,
    CloseHalfway,
    None { stale: Option<String> },
}

struct Controller {
    /// The `(controller, axis)` this simulator is (default `(1, 1)`).
    address: (u32, u32),
    sim: SimPositioner,
    faults: ScpiFaults,
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
    fn new(sim: SimPositioner, faults: ScpiFaults) -> Self {
        let commanded = match sim.config().travel {
            Some((lo, hi)) => 0.0f64.clamp(lo, hi),
            None => 0.0,
        };
        let velocity = sim.config().velocity_deg_s;
        Self {
            address: (1, 1),
            sim,
            faults,
            commanded,
            velocity,
            queue: VecDeque::new(),
            forward: Vec::new(),
            reverse: Vec::new(),
            injected: None,
            reported: None,
        }
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

    /// Serve one connection until it closes (or a fault closes it).
    async fn serve<S: AsyncRead + AsyncWrite + Unpin>(&mut self, mut stream: S) {
        let mut decoder = Decoder::new(MAX_REQUEST_LINE);
        let mut buf = vec![0u8; 4096];
        loop {
            let n = match stream.read(&mut buf).await {
                Ok(0) | Err(_) => return,
                Ok(n) => n,
            };
            decoder.push(&buf[..n]);
            while let Some(line) = decoder.next_line() {
                let outcome = match line {
                    Ok(line) => self.handle(&line).await,
                    Err(e) => {
                        self.push_error(-102, format!("Syntax error;{e}"));
                        Outcome::Nothing
                    }
                };
                if !self.respond(&mut stream, outcome).await {
                    return;
                }
            }
        }
    }

    /// Send the outcome, applying the armed reply faults. False: close.
    async fn respond<S: AsyncWrite + Unpin>(&mut self, stream: &mut S, outcome: Outcome) -> bool {
        let (bytes, close_after) = match outcome {
            Outcome::Nothing | Outcome::Lost => return true,
            Outcome::Close => return false,
            Outcome::Garble => (garble("#?"), false),
            Outcome::Reply(r) => match self.reply_fault() {
                ReplyFault::Drop => {
                    tracing::debug!(%r, "scpi simulator: reply dropped (injected)");
                    return true;
                }
                ReplyFault::Garble => (garble(&r), false),
                ReplyFault::CloseHalfway => {
                    tracing::debug!(%r, "scpi simulator: closing mid-reply (injected)");
                    (r.as_bytes()[..r.len() / 2].to_vec(), true)
                }
                ReplyFault::None { stale } => {
                    let mut bytes = r.into_bytes();
                    bytes.push(b'\n');
                    if let Some(stale) = stale {
                        bytes.extend(stale.into_bytes());
                        bytes.push(b'\n');
                    }
                    (bytes, false)
                }
            },
        };
        let sent = stream.write_all(&bytes).await.is_ok() && stream.flush().await.is_ok();
        sent && !close_after
    }

    /// Take the armed fault for the next reply.
    fn reply_fault(&self) -> ReplyFault {
        let mut plan = self.faults.plan.lock();
        if plan.drop_replies.take() {
            ReplyFault::Drop
        } else if plan.garble_replies.take() {
            ReplyFault::Garble
        } else if std::mem::take(&mut plan.close_in_reply) {
            ReplyFault::CloseHalfway
        } else {
            ReplyFault::None { stale: plan.stale_line.take() }
        }
    }

    /// Map a sim failure: link faults to the wire, refusals to the queue.
    fn sim_failed(&mut self, e: DriverError, usage_code: i64) -> Outcome {
        match e.kind {
            ErrorKind::Timeout => Outcome::Lost,
            ErrorKind::Disconnected => Outcome::Close,
            ErrorKind::Garbled => Outcome::Garble,
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

    async fn handle(&mut self, line: &str) -> Outcome {
        let trip = self.faults.plan.lock().trip.take();
        if let Some(fault) = trip {
            tracing::debug!(?fault, "scpi simulator: device fault latched (injected)");
            self.injected = Some(fault);
            if let Err(e) = self.sim.stop().await {
                return self.sim_failed(e, -221);
            }
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
        match header.as_str() {
            "*IDN?" => return Outcome::Reply(IDN.into()),
            "*CLS" => {
                self.queue.clear();
                return Outcome::Nothing;
            }
            "SYST:ERR?" | "SYST:ERR:NEXT?" => {
                let (code, text) = self.queue.pop_front().unwrap_or((0, "No error".into()));
                return Outcome::Reply(error_line(code, &text));
            }
            "SYST:ERR:ALL?" => {
                if self.queue.is_empty() {
                    return Outcome::Reply("0, \"No error\"".into());
                }
                let all: Vec<String> = self.queue.drain(..).map(|(code, text)| error_line(code, &text)).collect();
                return Outcome::Reply(all.join(", "));
            }
            "SYST:ERR:COUN?" | "SYST:ERR:COUN" => return Outcome::Reply(self.queue.len().to_string()),
            _ => {}
        }
        let Some((controller, axis, tail)) = axis_header(&header) else {
            self.push_error(-113, format!("Undefined header;{header}"));
            return Outcome::Nothing;
        };
        if (controller, axis) != self.address {
            self.push_error(-114, format!("Header suffix out of range;no controller {controller} axis {axis}"));
            return Outcome::Nothing;
        }
        let query = tail.ends_with('?');
        if !query {
            let rejected = self.faults.plan.lock().reject.pop_front();
            if let Some((code, text)) = rejected {
                tracing::debug!(%line, code, "scpi simulator: command refused (injected)");
                self.push_error(code, text);
                return Outcome::Nothing;
            }
        }
        let takes_params = matches!(tail, "POS:COMM" | "VEL:COMM" | "CORR:TABL" | "CORR:TABL:REV" | "CORR:STAT");
        if !takes_params && !params.is_empty() {
            self.push_error(-108, format!("Parameter not allowed;{params}"));
            return Outcome::Nothing;
        }
        if takes_params && params.is_empty() {
            self.push_error(-109, "Missing parameter");
            return Outcome::Nothing;
        }
        match tail {
            "POS:COMM" => {
                let Some(v) = self.number(params) else { return Outcome::Nothing };
                if let Some((lo, hi)) = self.sim.config().travel
                    && !(lo..=hi).contains(&v)
                {
                    self.push_error(
                        -222,
                        format!("Data out of range;target {v} deg is outside the travel {lo}..{hi} deg"),
                    );
                    return Outcome::Nothing;
                }
                self.commanded = v;
                Outcome::Nothing
            }
            "POS:COMM?" => Outcome::Reply(format!("{}", self.commanded)),
            "UNIT:POS?" => Outcome::Reply(self.faults.plan.lock().units.unwrap_or(6).to_string()),
            "MOT:STAR" => {
                if let Some(f) = &self.injected {
                    let (code, text) = (f.code, format!("{} (clear the fault first)", f.text));
                    self.push_error(code, text);
                    return Outcome::Nothing;
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
            "POS:CURR?" => match self.sim.readout().await {
                Ok(v) => Outcome::Reply(format!("{v}")),
                Err(e) => self.sim_failed(e, -221),
            },
            "STAT?" => match self.status_word().await {
                Ok(w) => Outcome::Reply(w.to_string()),
                Err(e) => self.sim_failed(e, -221),
            },
            "VEL:COMM" => {
                let Some(v) = self.number(params) else { return Outcome::Nothing };
                if !(v > 0.0 && v <= MAX_VELOCITY_DEG_S) {
                    self.push_error(
                        -222,
                        format!("Data out of range;velocity {v} deg/s is not in (0, {MAX_VELOCITY_DEG_S}]"),
                    );
                    return Outcome::Nothing;
                }
                match self.sim.set_velocity(v).await {
                    Ok(()) => {
                        self.velocity = v;
                        Outcome::Nothing
                    }
                    Err(e) => self.sim_failed(e, -222),
                }
            }
            "VEL:COMM?" => Outcome::Reply(format!("{}", self.velocity)),
            "VEL:CURR?" => match self.sim.status().await {
                Ok(s) => Outcome::Reply(format!("{}", if s.moving { self.velocity } else { 0.0 })),
                Err(e) => self.sim_failed(e, -221),
            },
            "FAUL:CLE" => {
                self.injected = None;
                self.reported = None;
                match self.sim.clear_fault().await {
                    Ok(()) => Outcome::Nothing,
                    Err(e) => self.sim_failed(e, -221),
                }
            }
            "CORR:TABL:CLE" => {
                self.forward.clear();
                self.reverse.clear();
                Outcome::Nothing
            }
            "CORR:TABL" | "CORR:TABL:REV" => {
                self.table_rows(tail == "CORR:TABL:REV", params);
                Outcome::Nothing
            }
            "CORR:TABL:POIN?" => Outcome::Reply(self.forward.len().to_string()),
            "CORR:TABL:REV:POIN?" => Outcome::Reply(self.reverse.len().to_string()),
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
                        return Outcome::Nothing;
                    }
                };
                match self.sim.enable_correction(on).await {
                    Ok(()) => Outcome::Nothing,
                    Err(e) => self.sim_failed(e, -221),
                }
            }
            "CORR:STAT?" => match self.sim.status().await {
                Ok(s) => Outcome::Reply(if s.correction_enabled { "1" } else { "0" }.into()),
                Err(e) => self.sim_failed(e, -221),
            },
            _ => {
                self.push_error(-113, format!("Undefined header;{header}"));
                Outcome::Nothing
            }
        }
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
fn garble(line: &str) -> Vec<u8> {
    let mut b: Vec<u8> = line.bytes().map(|b| b | 0x80).collect();
    b.push(b'\n');
    b
}

#[cfg(test)]
mod tests;
