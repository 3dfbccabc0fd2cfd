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
//! - `STAT?` follows the driver's bit table. A latched fault sets bit 6 (error
//!   limit) for the sim's following error
//!   ([`FAULT_FOLLOWING_ERROR`]) and
//!   bit 4 (PAU fault) for any other code, clears bit 5 (enabled) and bit 13
//!   (in position), and the first `STAT?` that shows a newly latched fault
//!   pushes its code and text on the error queue.
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
use survey_drivers::scpi::{Decoder, bits};
use survey_drivers::traits::{DeviceFault, Limit, Positioner};
use survey_processing::table::CorrectionTable;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};

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

    /// Latch a device fault at the next request.
    pub fn trip(&self, code: i64, text: impl Into<String>) {
        self.plan.lock().trip = Some(DeviceFault { code, text: text.into() });
    }
}

/// Serve the controller on `listener`, one client at a time, until the task
/// running this future is dropped or aborted.
pub async fn serve_tcp(listener: TcpListener, positioner: SimPositioner, faults: ScpiFaults) {
    let mut controller = Controller::new(positioner, faults);
    loop {
        match listener.accept().await {
            Ok((stream, peer)) => {
                tracing::debug!(%peer, "scpi simulator: client connected");
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
    async fn serve(&mut self, mut stream: TcpStream) {
        stream.set_nodelay(true).ok();
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
    async fn respond(&mut self, stream: &mut TcpStream, outcome: Outcome) -> bool {
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
            _ => {}
        }
        let Some((controller, axis, tail)) = axis_header(&header) else {
            self.push_error(-113, format!("Undefined header;{header}"));
            return Outcome::Nothing;
        };
        if (controller, axis) != (1, 1) {
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
        let mut w = bits::ACTIVE | bits::INDEXED;
        match &fault {
            None => w |= bits::ENABLED,
            Some(f) if f.code == FAULT_FOLLOWING_ERROR => w |= bits::ERROR_LIMIT,
            Some(_) => w |= bits::PAU_FAULT,
        }
        if s.moving {
            w |= bits::IN_MOTION;
        }
        if s.in_position && fault.is_none() {
            w |= bits::IN_POSITION;
        }
        if s.correction_enabled {
            w |= bits::CORRECTION;
        }
        w |= match s.limit {
            Some(Limit::Lower) => bits::REVERSE_LIMIT,
            Some(Limit::Upper) => bits::FORWARD_LIMIT,
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
mod tests {
    use super::*;
    use crate::positioner::{PositionerConfig, PositionerFaults};
    use crate::presets::{Preset, without_noise};
    use crate::turntable::Turntable;
    use std::net::SocketAddr;
    use std::sync::Arc;
    use std::time::{Duration, Instant};
    use survey_drivers::VirtualClock;
    use survey_drivers::clock::Clock;
    use survey_drivers::scpi::{Address, ScpiPositioner, ScpiTimeouts};
    use survey_drivers::traits::PositionerStatus;
    use survey_processing::Direction;
    use survey_processing::model::Model;
    use tokio::task::JoinHandle;

    const TIMEOUTS: ScpiTimeouts = ScpiTimeouts {
        request: Duration::from_millis(200),
        connect: Duration::from_secs(2),
        resync_grace: Duration::from_millis(20),
    };

    type Wire = ScpiPositioner<TcpStream>;

    fn fig8() -> Model {
        Preset::by_name("fig8").unwrap().model
    }

    /// A simulator on a loopback port; the server task is aborted on drop.
    struct Rig {
        clock: VirtualClock,
        truth: Turntable,
        faults: ScpiFaults,
        addr: SocketAddr,
        server: JoinHandle<()>,
    }

    impl Drop for Rig {
        fn drop(&mut self) {
            self.server.abort();
        }
    }

    impl Rig {
        async fn new(cfg: PositionerConfig) -> Rig {
            let clock = VirtualClock::new();
            let sim = SimPositioner::new(cfg, Arc::new(clock.clone()));
            let truth = sim.truth();
            let faults = ScpiFaults::new();
            let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
            let addr = listener.local_addr().unwrap();
            let server = tokio::spawn(serve_tcp(listener, sim, faults.clone()));
            Rig { clock, truth, faults, addr, server }
        }

        async fn connect(&self) -> Wire {
            ScpiPositioner::connect_tcp(self.addr, TIMEOUTS).await.unwrap()
        }

        fn actual(&self) -> f64 {
            self.truth.actual_deg(self.clock.now())
        }
    }

    /// Poll until in position or faulted, 250 ms of clock time between polls.
    async fn settle(p: &mut impl Positioner, clock: &VirtualClock) -> PositionerStatus {
        for _ in 0..2_000 {
            let s = p.status().await.unwrap();
            if s.in_position || s.fault.is_some() {
                return s;
            }
            clock.advance(Duration::from_millis(250));
        }
        panic!("never settled");
    }

    #[tokio::test]
    async fn move_poll_readout_stop_and_velocity() {
        let rig = Rig::new(PositionerConfig::new(fig8())).await;
        let mut p = rig.connect().await;
        assert!(p.name().starts_with("scpi-tcp 127.0.0.1:"), "{}", p.name());
        assert_eq!(p.identify().await.unwrap(), IDN);

        p.move_to(45.0).await.unwrap();
        assert_eq!(p.commanded_position().await.unwrap(), 45.0);
        let s = p.status().await.unwrap();
        assert!(s.moving && !s.in_position, "{s:?}");
        let s = settle(&mut p, &rig.clock).await;
        assert!(s.in_position && !s.moving && s.fault.is_none() && s.limit.is_none(), "{s:?}");
        assert_eq!(p.readout().await.unwrap(), 45.0, "readout at rest equals the target");

        // Velocity: accepted, and a move at 20 deg/s takes half the time.
        p.set_velocity(20.0).await.unwrap();
        let t0 = rig.clock.now();
        p.move_to(145.0).await.unwrap();
        settle(&mut p, &rig.clock).await;
        let took = (rig.clock.now() - t0).as_secs_f64();
        assert!(took < 100.0 / 20.0 + 2.0, "took {took} s");
        for bad in [-1.0, 0.0, 1e6] {
            let e = p.set_velocity(bad).await.unwrap_err();
            assert_eq!((e.kind, e.code), (ErrorKind::Usage, Some(-222)), "{bad}: {e}");
            assert!(e.message.contains("Data out of range"), "{e}");
        }
        let e = p.set_velocity(f64::NAN).await.unwrap_err();
        assert_eq!((e.kind, e.code), (ErrorKind::Usage, None));

        // Stop mid-move: the axis halts between start and target.
        p.set_velocity(10.0).await.unwrap();
        p.move_to(345.0).await.unwrap();
        rig.clock.advance(Duration::from_secs(5));
        assert!(p.status().await.unwrap().moving);
        p.stop().await.unwrap();
        let s = settle(&mut p, &rig.clock).await;
        assert!(!s.moving && s.in_position, "{s:?}");
        let r = p.readout().await.unwrap();
        assert!(r > 160.0 && r < 345.0, "stopped at {r}");
        assert!((r - rig.actual()).abs() < 0.1, "readout {r} vs actual {}", rig.actual());
        // Stopped: it stays put.
        rig.clock.advance(Duration::from_secs(10));
        assert_eq!(p.readout().await.unwrap(), r);
    }

    #[tokio::test]
    async fn usage_errors_carry_the_controllers_code() {
        let cfg = PositionerConfig { travel: Some((-10.0, 90.0)), ..PositionerConfig::new(without_noise(&fig8())) };
        let rig = Rig::new(cfg).await;
        let mut p = rig.connect().await;
        let e = p.move_to(95.0).await.unwrap_err();
        assert_eq!((e.kind, e.code), (ErrorKind::Usage, Some(-222)), "{e}");
        assert!(e.message.contains("outside the travel -10..90 deg"), "{e}");
        // Nothing moved, and the commanded position is still the old one.
        assert_eq!(p.commanded_position().await.unwrap(), 0.0);
        let s = p.status().await.unwrap();
        assert!(!s.moving && s.in_position, "{s:?}");
        // Inside the travel it moves; at the end it reports the limit.
        p.move_to(90.0).await.unwrap();
        let s = settle(&mut p, &rig.clock).await;
        assert_eq!(s.limit, Some(Limit::Upper));
        // A correction table with nothing loaded: settings conflict.
        let e = p.enable_correction(true).await.unwrap_err();
        assert_eq!((e.kind, e.code), (ErrorKind::Usage, Some(-221)), "{e}");
        // An axis the controller does not have (one client at a time: the
        // first one leaves).
        drop(p);
        let mut other = rig.connect().await.with_address(Address { controller: 1, axis: 2 });
        let e = other.move_to(10.0).await.unwrap_err();
        assert_eq!((e.kind, e.code), (ErrorKind::Usage, Some(-114)), "{e}");
    }

    #[tokio::test]
    async fn correction_over_the_wire_moves_the_axis_as_the_simulators_own() {
        let cfg = PositionerConfig { seed: 7, ..PositionerConfig::new(fig8()) };
        let model = cfg.model.clone();
        let n = 360;
        let rows = |d| (0..n).map(|i| model.repeatable_error_deg(i as f64 * 360.0 / n as f64, d)).collect::<Vec<_>>();
        let table = CorrectionTable::directional(rows(Direction::Forward), rows(Direction::Reverse)).unwrap();

        let rig = Rig::new(cfg.clone()).await;
        let mut wire = rig.connect().await;
        let direct_clock = VirtualClock::new();
        let mut direct = SimPositioner::new(cfg, Arc::new(direct_clock.clone()));

        // Same moves on both, natively first.
        let target = 123.4;
        wire.move_to(target).await.unwrap();
        settle(&mut wire, &rig.clock).await;
        direct.move_to(target).await.unwrap();
        settle(&mut direct, &direct_clock).await;
        let native = rig.actual();
        assert_eq!(native, direct.truth().actual_deg(direct_clock.now()));

        // Load (12 chunks per column) and enable, on both.
        wire.load_correction_table(&table).await.unwrap();
        assert!(!wire.status().await.unwrap().correction_enabled, "loaded, not yet applied");
        wire.enable_correction(true).await.unwrap();
        assert!(wire.status().await.unwrap().correction_enabled);
        direct.load_correction_table(&table).await.unwrap();
        direct.enable_correction(true).await.unwrap();

        for t in [10.0, target, 300.25, 47.3] {
            wire.move_to(t).await.unwrap();
            settle(&mut wire, &rig.clock).await;
            direct.move_to(t).await.unwrap();
            settle(&mut direct, &direct_clock).await;
            assert_eq!(wire.readout().await.unwrap(), t);
            let (a, b) = (rig.actual(), direct.truth().actual_deg(direct_clock.now()));
            assert!((a - b).abs() < 1e-12, "at {t}: over the wire {a}, direct {b}");
            if t == target {
                assert!((a - native).abs() > 1e-3, "the table moved the axis: {a} vs native {native}");
                assert!((a - t).abs() < (native - t).abs(), "closer to the target: {a} vs native {native}");
            }
        }
        wire.enable_correction(false).await.unwrap();
        assert!(!wire.status().await.unwrap().correction_enabled);
    }

    /// Send raw lines, then `*IDN?`; the replies before the identification.
    async fn raw(addr: SocketAddr, lines: &[&[u8]]) -> Vec<String> {
        let mut s = TcpStream::connect(addr).await.unwrap();
        let mut out = Vec::new();
        for l in lines {
            out.extend_from_slice(l);
            out.push(b'\n');
        }
        out.extend_from_slice(b"*IDN?\n");
        s.write_all(&out).await.unwrap();
        let mut d = Decoder::default();
        let mut buf = [0u8; 4096];
        let mut replies = Vec::new();
        loop {
            let n = s.read(&mut buf).await.unwrap();
            assert!(n > 0, "closed; got {replies:?}");
            d.push(&buf[..n]);
            while let Some(l) = d.next_line() {
                let l = l.unwrap();
                if l == IDN {
                    return replies;
                }
                replies.push(l);
            }
        }
    }

    #[tokio::test]
    async fn the_documented_protocol_on_a_raw_socket() {
        let rig = Rig::new(PositionerConfig::new(fig8())).await;
        let replies = raw(
            rig.addr,
            &[
                b"cont1:axis(1):pos:curr?",
                b"CONT1:AXIS(1):STAT?",
                b"CONTROLLER1:AXIS(1):POSITION:CURRENT?",
                b"SYST:ERR?",
                b"CONT1:AXIS(1):CORR:TABL 5,1.0",
                b"SYST:ERR?",
                b"CONT1:AXIS(1):CORR:TABL 0,1.0,x",
                b"SYST:ERR?",
                b"CONT1:AXIS(1):MOT:STAR 5",
                b"SYST:ERR?",
                b"CONT1:AXIS(1):POS:COMM",
                b"CONT1:AXIS(1):POS:COMM 1e999",
                b"\xffbad",
                b"CONT1:AXIS(1):CORR:TABL 0,0.5,0.25",
                b"CONT1:AXIS(1):CORR:TABL 1,0.125",
                b"CONT1:AXIS(1):CORR:TABL:POIN?",
                b"SYST:ERR?",
                b"SYST:ERR?",
                b"SYST:ERR?",
                b"SYST:ERR?",
            ],
        )
        .await;
        let expect_prefix = [
            "0",
            "8992",
            "-113,\"Undefined header",
            "-222,\"Data out of range;rows from 5",
            "-104,\"Data type error",
            "-108,\"Parameter not allowed",
            "2",
            "-109,\"Missing parameter",
            "-222,\"Data out of range",
            "-102,\"Syntax error;non-ASCII",
            "0,\"No error\"",
        ];
        assert_eq!(replies.len(), expect_prefix.len(), "{replies:#?}");
        for (r, e) in replies.iter().zip(expect_prefix) {
            assert!(r.starts_with(e), "{r:?} should start with {e:?}; all: {replies:#?}");
        }
        // The queue holds 16 entries; the newest becomes -350 on overflow.
        let mut lines: Vec<&[u8]> = vec![b"FOO"; 20];
        lines.extend([b"SYST:ERR?".as_slice(); 17]);
        let replies = raw(rig.addr, &lines).await;
        assert!(replies[..15].iter().all(|r| r.starts_with("-113,")), "{replies:#?}");
        assert_eq!(replies[15], "-350,\"Queue overflow\"");
        assert_eq!(replies[16], "0,\"No error\"");
    }

    #[tokio::test]
    async fn dropped_reply_times_out_and_the_next_request_succeeds() {
        let rig = Rig::new(PositionerConfig::new(fig8())).await;
        let mut p = rig.connect().await;
        let r0 = p.readout().await.unwrap();
        rig.faults.drop_next_replies(1);
        let t = Instant::now();
        let e = p.readout().await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Timeout, "{e}");
        assert!(t.elapsed() >= TIMEOUTS.request, "{:?}", t.elapsed());
        assert_eq!(p.readout().await.unwrap(), r0);
        // A dropped SYST:ERR? after a command times out the command too.
        rig.faults.drop_next_replies(1);
        assert_eq!(p.stop().await.unwrap_err().kind, ErrorKind::Timeout);
        p.stop().await.unwrap();
    }

    #[tokio::test]
    async fn a_stale_line_is_never_taken_for_the_next_answer() {
        let rig = Rig::new(PositionerConfig::new(fig8())).await;
        let mut p = rig.connect().await;
        // "4865" would pass for a readout (and for a status word).
        rig.faults.stale_line_after_next_reply("4865");
        let s = p.status().await.unwrap();
        assert!(s.in_position, "{s:?}");
        assert_eq!(p.readout().await.unwrap(), 0.0);
    }

    #[tokio::test]
    async fn garbled_reply_then_the_next_request_succeeds() {
        let rig = Rig::new(PositionerConfig::new(fig8())).await;
        let mut p = rig.connect().await;
        rig.faults.garble_next_replies(1);
        let e = p.readout().await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Garbled, "{e}");
        assert!(e.is_link());
        assert_eq!(p.readout().await.unwrap(), 0.0);
        rig.faults.garble_next_replies(1);
        assert_eq!(p.status().await.unwrap_err().kind, ErrorKind::Garbled);
        assert!(p.status().await.unwrap().in_position);
    }

    #[tokio::test]
    async fn closed_connection_is_disconnected_and_a_new_client_is_served() {
        let rig = Rig::new(PositionerConfig::new(fig8())).await;
        let mut p = rig.connect().await;
        p.move_to(30.0).await.unwrap();
        rig.faults.close_during_next_reply();
        let e = p.readout().await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
        assert!(!p.is_connected());
        // Every later call fails at once.
        let t = Instant::now();
        assert_eq!(p.status().await.unwrap_err().kind, ErrorKind::Disconnected);
        assert!(t.elapsed() < TIMEOUTS.request);
        drop(p);
        // The controller kept its state for the next client.
        let mut q = rig.connect().await;
        let s = settle(&mut q, &rig.clock).await;
        assert!(s.in_position);
        assert_eq!(q.readout().await.unwrap(), 30.0);
    }

    #[tokio::test]
    async fn injected_device_fault_with_code_and_text() {
        let rig = Rig::new(PositionerConfig::new(fig8())).await;
        let mut p = rig.connect().await;
        let text = "PAU fault: amplifier over temperature";
        rig.faults.trip(305, text);
        let s = p.status().await.unwrap();
        let fault = s.fault.clone().expect("fault");
        assert_eq!((fault.code, fault.text.as_str()), (305, text));
        assert!(!s.in_position);
        // The queue gave the entry out once; the driver keeps it while the bit is set.
        assert_eq!(p.status().await.unwrap().fault, Some(fault.clone()));
        let e = p.move_to(10.0).await.unwrap_err();
        assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(305)), "{e}");
        assert!(e.message.contains(text), "{e}");
        p.clear_fault().await.unwrap();
        let s = p.status().await.unwrap();
        assert!(s.fault.is_none() && s.in_position, "{s:?}");
        p.move_to(10.0).await.unwrap();
        assert!(settle(&mut p, &rig.clock).await.in_position);
    }

    #[tokio::test]
    async fn a_trip_of_the_simulated_drive_is_an_error_limit_fault() {
        let faults = PositionerFaults { fault_on_move: Some(1), ..PositionerFaults::default() };
        let rig = Rig::new(PositionerConfig { faults, ..PositionerConfig::new(fig8()) }).await;
        let mut p = rig.connect().await;
        p.move_to(90.0).await.unwrap();
        let s = settle(&mut p, &rig.clock).await;
        let fault = s.fault.expect("the drive tripped");
        assert_eq!(fault.code, FAULT_FOLLOWING_ERROR);
        assert!(fault.text.contains("following error"), "{}", fault.text);
        let e = p.move_to(0.0).await.unwrap_err();
        assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(FAULT_FOLLOWING_ERROR)), "{e}");
        p.clear_fault().await.unwrap();
        assert!(p.status().await.unwrap().fault.is_none());
        p.move_to(0.0).await.unwrap();
        assert!(settle(&mut p, &rig.clock).await.in_position);
    }

    #[tokio::test]
    async fn a_rejected_command_carries_code_and_text() {
        let rig = Rig::new(PositionerConfig::new(fig8())).await;
        let mut p = rig.connect().await;
        rig.faults.reject_next_command(-200, "Execution error;brake engaged");
        let e = p.move_to(20.0).await.unwrap_err();
        assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(-200)), "{e}");
        assert!(e.message.contains("brake engaged"), "{e}");
        rig.faults.reject_next_command(-224, "Illegal parameter value");
        assert_eq!(p.stop().await.unwrap_err().kind, ErrorKind::Usage);
        p.move_to(20.0).await.unwrap();
        assert!(settle(&mut p, &rig.clock).await.in_position);
        assert_eq!(p.readout().await.unwrap(), 20.0);
    }
}
