//! A simulated CiA 402 servo drive on a CAN bus, serving a [`SimPositioner`].
//!
//! [`serve`] speaks the protocol of [`survey_positioner_drivers::canopen`] (see its module
//! documentation for the frames, the objects and what was looked up versus
//! chosen) over any [`CanBus`]: an endpoint of a
//! [`MemoryBus`](survey_positioner_drivers::canopen::MemoryBus) in tests, a
//! [`SocketCanBus`](survey_positioner_drivers::canopen::SocketCanBus) where the kernel
//! has CAN. It shares the driver's sans-IO codecs (SDO frames, segmenting,
//! NMT frames, the object constants and the table layout); the object
//! dictionary, the SDO server's transfer handling and the drive state machine
//! are written here from the standard's tables, independently of the driver.
//! Physics, clock and the sim's own faults are the positioner's.
//!
//! # Behaviour
//!
//! - NMT: boot-up frame (`0x700 + node`, `[0x00]`) when serving starts, then
//!   pre-operational. Start, stop, enter pre-operational, reset node and
//!   reset communication (to this node or to all) are served; each state
//!   change is announced with one heartbeat frame (a real node sends them
//!   periodically per 0x1017; one per change keeps tests deterministic).
//!   In Stopped, SDO requests get no answer. Reset node also disables the
//!   drive (switch on disabled, motion halted).
//! - SDO server: expedited and segmented upload and download of the objects
//!   below, one transfer at a time (a new initiate drops an open one; a
//!   client abort drops it silently). Unknown object `0x0602_0000`, unknown
//!   sub-index `0x0609_0011`, write to a read-only object `0x0601_0002`,
//!   wrong length `0x0607_0012`/`0x0607_0013` (fixed-size objects) or
//!   `0x0607_0010` (the table), segment without a transfer `0x0504_0001`,
//!   toggle not alternated `0x0503_0000`, unknown or block specifier
//!   `0x0504_0001`.
//! - Drive state machine (CiA 402): starts in switch on disabled; shutdown,
//!   switch on, enable operation (3 + 4 from ready to switch on in one
//!   write), disable operation, disable voltage, quick stop, and fault reset
//!   on the rising edge of bit 7. Each transition is carried out
//!   [`NodeConfig::transition_time`] after the controlword asks for it (20 ms
//!   by default, real time), as a drive takes time: the statusword shows the
//!   old state until then, and a command meanwhile applies to the state the
//!   drive is going to. A mode written to 0x6060 shows in 0x6061 after the
//!   same time. Entering operation enabled needs NMT
//!   operational (else abort `0x0800_0022`). Leaving operation enabled, or a
//!   rising halt bit 8, stops the sim.
//! - Profile position: the rising edge of controlword bit 4 starts a move to
//!   0x607A, and sets set-point acknowledge (bit 12) until bit 4 falls. A
//!   rising bit 4 outside operation enabled, with halt set, or with modes of
//!   operation not 1 is refused with `0x0800_0022` (nothing is applied).
//!   0x607A outside the sim's travel is refused with `0x0609_0030`; 0x6081
//!   of 0 with `0x0609_0032`, above [`NodeConfig::max_velocity_deg_s`] with
//!   `0x0609_0031`; 0x6060 other than 1 with `0x0609_0030`.
//! - Statusword: state bits, remote (9), target reached (10) = the sim's
//!   `in_position`, internal limit (11) = the sim's `limit`, set-point
//!   acknowledge (12). 0x60FD bit 0/1 = lower/upper limit.
//! - Faults: when the sim reports a fault (or refuses a move with one) the
//!   drive goes to fault, 0x603F holds the code (codes above 0xFFFF become
//!   0xFF00 "device specific", the original in the text), 0x2102 the text,
//!   0x1001 bit 0 is set. Fault reset calls the sim's `clear_fault`.
//! - This project's own objects, 0x2100-0x2102, exist only with
//!   [`NodeConfig::correction_objects`] (else abort `0x0602_0000`, as on a
//!   drive with the standard objects only).
//! - Correction: 0x2100 download installs the table in the sim (refused
//!   while moving with `0x0800_0022`; bad layout with the
//!   [`TableDomainError`](survey_positioner_drivers::canopen::objects::TableDomainError)
//!   code); upload returns the bytes held, or `0x0800_0024` when none.
//!   0x2101 = 1 without a table is `0x0800_0024`.
//! - A sim call that fails with a link fault of its own becomes the same
//!   fault on the bus: `Timeout` and `Disconnected` = no response (a CAN
//!   node has no connection to drop), `Garbled` = a garbled response.
//!
//! # Faults ([`Faults`])
//!
//! The node is a [`Service`] on a CAN bus, served by
//! [`serve_can`](crate::serve::serve_can); link faults are the
//! [`relay_can`](crate::relay::relay_can)'s in front of it ([`garbled`]: the
//! SDO ways to garble a response, [`Garble`]). A device fault armed in its
//! [`Faults`], [`Fault::Refuse`], answers the next SDO request with that
//! abort code (`None`: 0x06060000, access failed due to a hardware error),
//! not executing it.

use crate::serve::{self, Service};
use async_trait::async_trait;
use survey_drivers::error::{DriverError, ErrorKind};
use survey_drivers::traits::{DeviceFault, Limit, Positioner, PositionerStatus};
use survey_positioner_drivers::canopen::DEFAULT_COUNTS_PER_DEGREE;
use survey_positioner_drivers::canopen::frame::{CanBus, CanFrame};
use survey_positioner_drivers::canopen::nmt::{self, NmtCommand, NmtState};
use survey_positioner_drivers::canopen::objects::{
    DriveCommand, DriveState, MAX_TABLE_ROWS, PROFILE_POSITION_MODE, TABLE_HEADER, counts_to_degrees, cw,
    degrees_to_counts, di, sw,
};
use survey_positioner_drivers::canopen::sdo::{
    InitData, Reassembler, SDO_REQUEST_BASE, SDO_RESPONSE_BASE, SdoRequest, SdoResponse, Segmenter, abort,
};
use survey_sims::faults::{Fault, Faults};
use survey_sims::positioner::SimPositioner;

mod od;

/// Fastest profile velocity 0x6081 accepts, degrees per second.
pub const MAX_VELOCITY_DEG_S: f64 = 100.0;
/// The default device name (0x1008).
pub const DEVICE_NAME: &str = "survey-sims CiA 402 positioner (simulated)";

/// Settings of the simulated node.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeConfig {
    /// Node-ID, 1..=127 (default 1).
    pub node_id: u8,
    /// Counts per degree of 0x607A / 0x6064 (default the driver's default).
    pub counts_per_degree: f64,
    /// 0x1008 (default [`DEVICE_NAME`]).
    pub device_name: String,
    /// Fastest profile velocity accepted (default [`MAX_VELOCITY_DEG_S`]).
    pub max_velocity_deg_s: f64,
    /// How long the drive takes, in real time, to carry out a state
    /// transition the controlword asks for (and to show a new mode of
    /// operation in 0x6061). Default [`TRANSITION_TIME`].
    pub transition_time: std::time::Duration,
    /// Whether the drive has this project's own objects (0x2100 the
    /// correction table, 0x2101 correction on/off, 0x2102 the fault's text:
    /// manufacturer-specific); without them (the default) it has the CiA
    /// 301/402 objects only and aborts those with 0x06020000, as a standard
    /// drive does.
    pub correction_objects: bool,
}

/// Default time of one drive state transition: 20 ms. Our own choice (real
/// drives take milliseconds to tens of milliseconds; the reference client
/// python-canopen allows about 0.4 s per transition): long enough that a
/// client that polls the statusword a few times at once, instead of waiting,
/// fails the way it would on hardware.
pub const TRANSITION_TIME: std::time::Duration = std::time::Duration::from_millis(20);

impl NodeConfig {
    /// Defaults for node `node_id`.
    pub fn new(node_id: u8) -> Self {
        Self {
            node_id,
            counts_per_degree: DEFAULT_COUNTS_PER_DEGREE,
            device_name: DEVICE_NAME.into(),
            max_velocity_deg_s: MAX_VELOCITY_DEG_S,
            transition_time: TRANSITION_TIME,
            correction_objects: false,
        }
    }
}

impl Default for NodeConfig {
    fn default() -> Self {
        Self::new(1)
    }
}

/// The SDO ways to garble a response ([`garbled`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Garble {
    /// Only the first 4 of the 8 bytes are sent (any response).
    Truncated,
    /// Command specifier 7 (any response).
    BadSpecifier,
    /// The index echoed plus one (initiate responses).
    WrongIndex,
    /// The toggle bit flipped (segment responses).
    FlipToggle,
}

/// The default abort code of [`Fault::Refuse`]`(None)`: 0x06060000 (CiA
/// 301: access failed due to a hardware error), the SDO counterpart of
/// Modbus exception 4. Not 0x08000022 (refused in the present device state):
/// the driver reads that as a wrong request (`Usage`), never retried.
pub const DEVICE_FAULT_ABORT: u32 = 0x0606_0000;

/// A link fault for the relay in front of the node: the next SDO response
/// `how` fits, garbled (the data bytes of its frame).
pub fn garbled(how: Garble) -> Fault {
    Fault::Garble(survey_sims::faults::Garble::edit("SDO response garbled", move |data: &[u8]| {
        let resp = SdoResponse::decode(data).ok()?;
        if !garble_fits(how, &resp) {
            return None;
        }
        let mut bytes = data.to_vec();
        match how {
            Garble::Truncated => bytes.truncate(4),
            Garble::BadSpecifier => bytes[0] = 0xE0,
            Garble::WrongIndex => {
                let i = u16::from_le_bytes([bytes[1], bytes[2]]).wrapping_add(1);
                bytes[1..3].copy_from_slice(&i.to_le_bytes());
            }
            Garble::FlipToggle => bytes[0] ^= 0x10,
        }
        Some(bytes)
    }))
}

/// What [`serve`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct NodeReport {
    /// SDO requests received (served or not).
    pub sdo_requests: usize,
    /// SDO responses sent (including garbled ones).
    pub sdo_responses: usize,
    /// NMT commands addressed to this node.
    pub nmt_commands: usize,
    /// Aborts received from the client.
    pub client_aborts: usize,
}

/// Why a request gets no normal response.
enum Refusal {
    Abort(u32),
    Silent,
    Garble,
}

impl From<u32> for Refusal {
    fn from(code: u32) -> Self {
        Refusal::Abort(code)
    }
}

/// A sim link fault, as it shows on the bus.
fn link(e: DriverError) -> Refusal {
    match e.kind {
        ErrorKind::Timeout | ErrorKind::Disconnected => Refusal::Silent,
        ErrorKind::Garbled => Refusal::Garble,
        ErrorKind::Device | ErrorKind::Usage => Refusal::Abort(abort::GENERAL),
    }
}

enum Transfer {
    Upload { mux: (u16, u8), segments: Segmenter },
    Download { mux: (u16, u8), joined: Reassembler },
}

/// What to put on the bus for a request.
enum Answer {
    Respond(SdoResponse),
    GarbleIt,
    Nothing,
}

struct Node {
    sim: SimPositioner,
    cfg: NodeConfig,
    faults: Faults,
    /// The boot-up frame is still to be sent.
    boot: bool,
    nmt: NmtState,
    drive: DriveState,
    /// A transition asked for and not yet carried out: the state, and when.
    pending: Option<(DriveState, tokio::time::Instant)>,
    controlword: u16,
    mode: i8,
    /// 0x6061: the mode the drive runs in (0x6060 after the transition time).
    mode_display: i8,
    mode_due: Option<tokio::time::Instant>,
    target: i32,
    velocity: u32,
    ack: bool,
    fault: Option<DeviceFault>,
    table: Option<Vec<u8>>,
    transfer: Option<Transfer>,
    report: NodeReport,
}

/// Serve `sim` as node `cfg.node_id` on `bus` until the bus fails (shut
/// down, interface gone). Returns what was served.
pub async fn serve<B: CanBus>(bus: B, sim: SimPositioner, cfg: NodeConfig, faults: Faults) -> NodeReport {
    let velocity = (sim.config().velocity_deg_s * cfg.counts_per_degree).round() as u32;
    let mut node = Node {
        sim,
        cfg,
        faults,
        boot: true,
        nmt: NmtState::PreOperational,
        drive: DriveState::SwitchOnDisabled,
        pending: None,
        controlword: 0,
        mode: 0,
        mode_display: 0,
        mode_due: None,
        target: 0,
        velocity,
        ack: false,
        fault: None,
        table: None,
        transfer: None,
        report: NodeReport::default(),
    };
    serve::serve_can(bus, &mut node).await;
    node.report
}

#[async_trait]
impl Service for Node {
    type Request = CanFrame;
    type Reply = Vec<CanFrame>;

    async fn call(&mut self, frame: CanFrame) -> serve::Answer<Vec<CanFrame>> {
        match self.handle(frame).await {
            Some(frame) => serve::Answer::Send(vec![frame]),
            None => serve::Answer::Nothing,
        }
    }

    /// The boot-up frame (`0x700 + node`, `[0x00]`) when serving starts.
    async fn unsolicited(&mut self) -> serve::Answer<Vec<CanFrame>> {
        if !std::mem::take(&mut self.boot) {
            return std::future::pending().await;
        }
        serve::Answer::Send(vec![self.heartbeat(NmtState::BootUp)])
    }
}

impl Node {
    fn heartbeat(&self, state: NmtState) -> CanFrame {
        nmt::encode_heartbeat(self.cfg.node_id, state)
    }

    /// The frame a frame on the bus gets, if any.
    async fn handle(&mut self, frame: CanFrame) -> Option<CanFrame> {
        if frame.id() == nmt::NMT_COB_ID {
            return self.nmt_command(&frame).await;
        }
        if frame.id() != SDO_REQUEST_BASE + u16::from(self.cfg.node_id) {
            return None;
        }
        self.report.sdo_requests += 1;
        if self.nmt == NmtState::Stopped {
            tracing::debug!(%frame, "CANopen node: stopped, SDO ignored");
            return None;
        }
        let answer = match SdoRequest::decode(frame.data()) {
            Ok(req) => self.sdo(req).await,
            Err(e) => {
                tracing::debug!(%frame, error = %e, "CANopen node: undecodable SDO request");
                self.transfer = None;
                Answer::Respond(SdoResponse::Abort { index: 0, subindex: 0, code: abort::COMMAND_SPECIFIER })
            }
        };
        self.respond(answer)
    }

    async fn nmt_command(&mut self, frame: &CanFrame) -> Option<CanFrame> {
        let (cmd, target) = match nmt::decode_command(frame) {
            Ok(c) => c,
            Err(e) => {
                tracing::debug!(%frame, error = %e, "CANopen node: bad NMT frame ignored");
                return None;
            }
        };
        if target != 0 && target != self.cfg.node_id {
            return None;
        }
        self.report.nmt_commands += 1;
        tracing::debug!(?cmd, "CANopen node: NMT");
        let state = match cmd {
            NmtCommand::Start => NmtState::Operational,
            NmtCommand::Stop => NmtState::Stopped,
            NmtCommand::EnterPreOperational => NmtState::PreOperational,
            NmtCommand::ResetNode | NmtCommand::ResetCommunication => {
                self.transfer = None;
                if cmd == NmtCommand::ResetNode {
                    if self.drive == DriveState::OperationEnabled {
                        let _ = self.sim.stop().await;
                    }
                    self.drive = if self.fault.is_some() { DriveState::Fault } else { DriveState::SwitchOnDisabled };
                    self.pending = None;
                    self.controlword = 0;
                    self.mode = 0;
                    self.mode_display = 0;
                    self.mode_due = None;
                    self.ack = false;
                }
                self.nmt = NmtState::PreOperational;
                return Some(self.heartbeat(NmtState::BootUp));
            }
        };
        self.nmt = state;
        Some(self.heartbeat(state))
    }

    /// Serve one SDO request.
    async fn sdo(&mut self, req: SdoRequest) -> Answer {
        let refused = self.faults.take_device(|f| matches!(f, Fault::Refuse(_) | Fault::RefuseWithError(_)));
        if let Some(fault) = refused {
            let code = match fault {
                Fault::Refuse(Some(d)) | Fault::RefuseWithError(d) => {
                    u32::try_from(d.code).unwrap_or(DEVICE_FAULT_ABORT)
                }
                _ => DEVICE_FAULT_ABORT,
            };
            let (index, subindex) = self.request_mux(&req);
            tracing::debug!(code = format_args!("0x{code:08X}"), "CANopen node: injected abort");
            self.transfer = None;
            return Answer::Respond(SdoResponse::Abort { index, subindex, code });
        }
        let mux = self.request_mux(&req);
        let result = match req {
            SdoRequest::Abort { code, .. } => {
                self.report.client_aborts += 1;
                tracing::debug!(code = format_args!("0x{code:08X}"), "CANopen node: client aborted");
                self.transfer = None;
                return Answer::Nothing;
            }
            SdoRequest::InitiateUpload { index, subindex } => {
                self.begin();
                self.initiate_upload(index, subindex).await
            }
            SdoRequest::InitiateDownload { index, subindex, data } => {
                self.begin();
                self.initiate_download(index, subindex, data).await
            }
            SdoRequest::UploadSegment { toggle } => self.upload_segment(toggle),
            SdoRequest::DownloadSegment { toggle, data, last } => self.download_segment(toggle, &data, last).await,
        };
        match result {
            Ok(r) => Answer::Respond(r),
            Err(Refusal::Abort(code)) => {
                self.transfer = None;
                Answer::Respond(SdoResponse::Abort { index: mux.0, subindex: mux.1, code })
            }
            Err(Refusal::Silent) => Answer::Nothing,
            Err(Refusal::Garble) => Answer::GarbleIt,
        }
    }

    /// The object a request is about (the open transfer's for segments).
    fn request_mux(&self, req: &SdoRequest) -> (u16, u8) {
        match req {
            SdoRequest::InitiateDownload { index, subindex, .. }
            | SdoRequest::InitiateUpload { index, subindex }
            | SdoRequest::Abort { index, subindex, .. } => (*index, *subindex),
            _ => match &self.transfer {
                Some(Transfer::Upload { mux, .. } | Transfer::Download { mux, .. }) => *mux,
                None => (0, 0),
            },
        }
    }

    /// A new transfer starts: drop the old one.
    fn begin(&mut self) {
        self.transfer = None;
    }

    async fn initiate_upload(&mut self, index: u16, subindex: u8) -> Result<SdoResponse, Refusal> {
        let data = self.read(index, subindex).await?;
        if (1..=4).contains(&data.len()) {
            return Ok(SdoResponse::InitiateUpload {
                index,
                subindex,
                data: InitData::Expedited { data, size_indicated: true },
            });
        }
        let size = data.len() as u32;
        self.transfer = Some(Transfer::Upload { mux: (index, subindex), segments: Segmenter::new(data) });
        Ok(SdoResponse::InitiateUpload { index, subindex, data: InitData::Segmented { size: Some(size) } })
    }

    fn upload_segment(&mut self, toggle: bool) -> Result<SdoResponse, Refusal> {
        let Some(Transfer::Upload { segments, .. }) = self.transfer.as_mut() else {
            return Err(abort::COMMAND_SPECIFIER.into());
        };
        if toggle != segments.toggle() {
            return Err(abort::TOGGLE_BIT.into());
        }
        let Some(seg) = segments.next_segment() else {
            return Err(abort::COMMAND_SPECIFIER.into());
        };
        if seg.last {
            self.transfer = None;
        }
        Ok(SdoResponse::UploadSegment { toggle: seg.toggle, data: seg.data, last: seg.last })
    }

    async fn initiate_download(&mut self, index: u16, subindex: u8, data: InitData) -> Result<SdoResponse, Refusal> {
        let entry = od::writable(index, subindex, self.cfg.correction_objects)?;
        match data {
            InitData::Expedited { data, size_indicated } => {
                let bytes = match (size_indicated, entry.size()) {
                    // Size not indicated: the object's own size of the 4 bytes.
                    (false, Some(n)) if n <= data.len() => data[..n].to_vec(),
                    _ => data,
                };
                self.write(index, &bytes).await?;
            }
            InitData::Segmented { size } => {
                let joined = Reassembler::new(size, entry.max_len()).map_err(|e| Refusal::Abort(e.abort_code()))?;
                self.transfer = Some(Transfer::Download { mux: (index, subindex), joined });
            }
        }
        Ok(SdoResponse::InitiateDownload { index, subindex })
    }

    async fn download_segment(&mut self, toggle: bool, data: &[u8], last: bool) -> Result<SdoResponse, Refusal> {
        let Some(Transfer::Download { mux, joined }) = self.transfer.as_mut() else {
            return Err(abort::COMMAND_SPECIFIER.into());
        };
        let mux = *mux;
        joined.push(toggle, data, last).map_err(|e| Refusal::Abort(e.abort_code()))?;
        if last {
            let Some(Transfer::Download { joined, .. }) = self.transfer.take() else {
                unreachable!("the transfer was a download a moment ago");
            };
            self.write(mux.0, &joined.into_data()).await?;
        }
        Ok(SdoResponse::DownloadSegment { toggle })
    }

    /// The frame a request gets.
    fn respond(&mut self, answer: Answer) -> Option<CanFrame> {
        let bytes = match answer {
            Answer::Nothing => return None,
            // The simulated positioner garbled its answer.
            Answer::GarbleIt => vec![0xE0, 0, 0, 0, 0, 0, 0, 0],
            Answer::Respond(r) => r.encode().to_vec(),
        };
        let id = SDO_RESPONSE_BASE + u16::from(self.cfg.node_id);
        match CanFrame::new(id, &bytes) {
            Ok(frame) => {
                self.report.sdo_responses += 1;
                Some(frame)
            }
            Err(e) => {
                tracing::warn!(error = %e, "CANopen node: response not sent");
                None
            }
        }
    }

    // -- the drive ------------------------------------------------------------

    /// The sim's status; latches a fault the sim reports.
    async fn poll(&mut self) -> Result<PositionerStatus, Refusal> {
        let s = self.sim.status().await.map_err(link)?;
        if let Some(f) = &s.fault
            && self.drive != DriveState::Fault
        {
            self.latch(f.clone());
        }
        Ok(s)
    }

    fn latch(&mut self, fault: DeviceFault) {
        tracing::debug!(?fault, "CANopen node: drive fault");
        self.drive = DriveState::Fault;
        self.pending = None;
        self.ack = false;
        self.fault = Some(fault);
    }

    fn error_code(&self) -> u16 {
        match &self.fault {
            None => 0,
            Some(f) => u16::try_from(f.code).unwrap_or(0xFF00),
        }
    }

    fn fault_text(&self) -> String {
        match &self.fault {
            None => String::new(),
            Some(f) if u16::try_from(f.code).is_ok() => f.text.clone(),
            Some(f) => format!("code {}: {}", f.code, f.text),
        }
    }

    /// Carry out the transitions whose time has come.
    fn settle(&mut self) {
        let now = tokio::time::Instant::now();
        if let Some((state, due)) = self.pending
            && now >= due
        {
            tracing::debug!(from = %self.drive, to = %state, "CANopen node: drive state");
            self.drive = state;
            self.pending = None;
        }
        if self.mode_due.is_some_and(|due| now >= due) {
            self.mode_display = self.mode;
            self.mode_due = None;
        }
    }

    /// Ask for a transition to `state`, carried out after the transition time.
    fn schedule(&mut self, state: DriveState) {
        let t = self.cfg.transition_time;
        if t.is_zero() {
            self.drive = state;
            self.pending = None;
        } else {
            self.pending = Some((state, tokio::time::Instant::now() + t));
        }
    }

    /// 0x6061, the mode of operation the drive runs in.
    pub(super) fn mode_display(&mut self) -> i8 {
        self.settle();
        self.mode_display
    }

    /// A write of 0x6060: shown in 0x6061 after the transition time.
    pub(super) fn set_mode(&mut self, mode: i8) {
        self.mode = mode;
        if self.cfg.transition_time.is_zero() {
            self.mode_display = mode;
        } else {
            self.mode_due = Some(tokio::time::Instant::now() + self.cfg.transition_time);
        }
    }

    async fn statusword(&mut self) -> Result<u16, Refusal> {
        self.settle();
        let s = self.poll().await?;
        let mut w = self.drive.statusword_bits() | sw::REMOTE;
        if s.in_position {
            w |= sw::TARGET_REACHED;
        }
        if s.limit.is_some() {
            w |= sw::INTERNAL_LIMIT;
        }
        if self.ack {
            w |= sw::SET_POINT_ACK;
        }
        Ok(w)
    }

    async fn digital_inputs(&mut self) -> Result<u32, Refusal> {
        Ok(match self.poll().await?.limit {
            Some(Limit::Lower) => di::NEGATIVE_LIMIT,
            Some(Limit::Upper) => di::POSITIVE_LIMIT,
            None => 0,
        })
    }

    async fn position(&mut self) -> Result<i32, Refusal> {
        let deg = self.sim.readout().await.map_err(link)?;
        degrees_to_counts(deg, self.cfg.counts_per_degree).ok_or(Refusal::Abort(abort::CANNOT_STORE))
    }

    /// A controlword write: the state machine (each transition carried out
    /// after the transition time), halt and the set-point.
    async fn controlword(&mut self, new: u16) -> Result<(), Refusal> {
        self.settle();
        let old = self.controlword;
        let cmd = DriveCommand::of(new);
        if self.drive == DriveState::Fault {
            if cmd == DriveCommand::FaultReset && old & cw::FAULT_RESET == 0 {
                self.sim.clear_fault().await.map_err(link)?;
                if self.sim.status().await.map_err(link)?.fault.is_none() {
                    tracing::debug!("CANopen node: fault reset");
                    self.fault = None;
                    self.schedule(DriveState::SwitchOnDisabled);
                }
            }
            self.controlword = new;
            return Ok(());
        }
        use DriveState as S;
        // A command while a transition is under way applies to where it goes.
        let base = self.pending.map_or(self.drive, |(state, _)| state);
        let next = match (base, cmd) {
            (S::SwitchOnDisabled, DriveCommand::Shutdown) => S::ReadyToSwitchOn,
            (S::ReadyToSwitchOn, DriveCommand::SwitchOn) => S::SwitchedOn,
            (S::ReadyToSwitchOn | S::SwitchedOn | S::QuickStopActive, DriveCommand::EnableOperation) => {
                S::OperationEnabled
            }
            (S::SwitchedOn | S::OperationEnabled, DriveCommand::Shutdown) => S::ReadyToSwitchOn,
            (S::OperationEnabled, DriveCommand::SwitchOn) => S::SwitchedOn,
            (S::OperationEnabled, DriveCommand::QuickStop) => S::QuickStopActive,
            (S::ReadyToSwitchOn | S::SwitchedOn, DriveCommand::QuickStop) => S::SwitchOnDisabled,
            (
                S::ReadyToSwitchOn | S::SwitchedOn | S::OperationEnabled | S::QuickStopActive,
                DriveCommand::DisableVoltage,
            ) => S::SwitchOnDisabled,
            (s, _) => s,
        };
        if next == S::OperationEnabled && base != S::OperationEnabled && self.nmt != NmtState::Operational {
            return Err(abort::DEVICE_STATE.into());
        }
        let enabled = self.drive == S::OperationEnabled && next == S::OperationEnabled;
        let set_point = new & cw::NEW_SET_POINT != 0 && old & cw::NEW_SET_POINT == 0;
        let halt = new & cw::HALT != 0;
        if set_point && (!enabled || halt || self.mode != PROFILE_POSITION_MODE) {
            return Err(abort::DEVICE_STATE.into());
        }
        if self.drive == S::OperationEnabled && next != S::OperationEnabled {
            // Leaving operation: the axis stops at once.
            self.sim.stop().await.map_err(link)?;
        }
        if next != base {
            self.schedule(next);
        }
        self.controlword = new;
        if new & cw::NEW_SET_POINT == 0 {
            self.ack = false;
        }
        if !enabled {
            return Ok(());
        }
        if halt && old & cw::HALT == 0 {
            self.sim.stop().await.map_err(link)?;
        }
        if set_point {
            let deg = counts_to_degrees(self.target, self.cfg.counts_per_degree);
            match self.sim.move_to(deg).await {
                Ok(()) => self.ack = true,
                Err(e) if e.kind == ErrorKind::Device => {
                    self.latch(DeviceFault { code: e.code.unwrap_or(0xFF00), text: e.message });
                }
                Err(e) if e.kind == ErrorKind::Usage => return Err(abort::VALUE_RANGE.into()),
                Err(e) => return Err(link(e)),
            }
        }
        Ok(())
    }
}

/// Whether garbling `g` applies to `resp`.
fn garble_fits(g: Garble, resp: &SdoResponse) -> bool {
    match g {
        Garble::Truncated | Garble::BadSpecifier => true,
        Garble::WrongIndex => matches!(resp, SdoResponse::InitiateUpload { .. } | SdoResponse::InitiateDownload { .. }),
        Garble::FlipToggle => matches!(resp, SdoResponse::UploadSegment { .. } | SdoResponse::DownloadSegment { .. }),
    }
}

/// Largest correction-table domain accepted, bytes.
const MAX_TABLE_BYTES: usize = TABLE_HEADER + 8 * MAX_TABLE_ROWS;

#[cfg(test)]
mod tests;
