//! [`Cia402Positioner`]: the [`Positioner`] trait over SDO, in CiA 402
//! profile position mode. The object usage is tabulated in the
//! [module documentation](super).

use super::client::{SdoClient, SdoTimeouts};
use super::frame::CanBus;
use super::nmt::{NmtCommand, encode_command};
use super::objects::{
    DriveState, PROFILE_POSITION_MODE, Statusword, counts_to_degrees, cw, decode_table, degrees_to_counts, di,
    encode_table, error_code_text, index,
};
use async_trait::async_trait;
use serde::{Deserialize, Serialize};
use std::time::Duration;
use survey_drivers::error::{DriverError, ErrorKind, Result};
use survey_drivers::traits::{DeviceFault, Limit, Positioner, PositionerStatus};
use survey_processing::table::CorrectionTable;

/// Default position counts per degree (1e-5 degree per count; `i32` covers
/// ±21474 degrees).
pub const DEFAULT_COUNTS_PER_DEGREE: f64 = 100_000.0;

/// The controlword the driver leaves the drive in between moves: enable
/// operation with "change set immediately" (0x2F).
pub const CW_OPERATE: u16 = cw::ENABLE_OPERATION_CMD | cw::CHANGE_SET_IMMEDIATELY;

/// How many controlword steps [`Cia402Positioner::enable`] takes at most
/// (switch on disabled -> ready -> switched on -> operation enabled, plus
/// slack for transient states).
const MAX_ENABLE_STEPS: usize = 6;

/// Between two statusword reads while a transition is awaited.
const TRANSITION_POLL: Duration = Duration::from_millis(2);

/// Configuration of a [`Cia402Positioner`] (serde: all fields optional).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CanopenConfig {
    /// Node-ID of the drive, 1..=127. Default 1.
    pub node_id: u8,
    /// Position counts (of 0x607A / 0x6064) per degree; velocity units
    /// (0x6081) are counts per second. Default [`DEFAULT_COUNTS_PER_DEGREE`].
    pub counts_per_degree: f64,
    /// Deadline of each SDO response, milliseconds. Default 500.
    pub sdo_timeout_ms: u64,
    /// After a timeout, how long the SDO client drains late frames at least,
    /// milliseconds (it drains half the SDO timeout when that is longer).
    /// Default 20.
    pub resync_grace_ms: u64,
    /// Statusword reads to wait for the set-point acknowledge (bit 12) after
    /// a new set-point. Default 10.
    pub set_point_polls: u32,
    /// How long one state transition (a controlword step of the enable
    /// sequence, a fault reset) and the switch of the mode of operation
    /// (0x6061 showing 0x6060) may take, milliseconds. Default 500 (the
    /// reference client, python-canopen's `p402`, allows about 0.4 s).
    pub transition_timeout_ms: u64,
    /// Object holding the fault's text (visible string), read when the drive
    /// reports a fault; the standard text of 0x603F is used when it is `None`
    /// or the node aborts the read. Default `Some(0x2102)`.
    pub fault_text_index: Option<u16>,
    /// Whether the drive has this project's correction objects (0x2100 the
    /// table, 0x2101 correction on/off: manufacturer-specific, not CiA 402).
    /// Without them (the default) the status reads no correction, and
    /// loading or switching the table is refused as bad usage.
    pub correction_objects: bool,
}

impl Default for CanopenConfig {
    fn default() -> Self {
        Self {
            node_id: 1,
            counts_per_degree: DEFAULT_COUNTS_PER_DEGREE,
            sdo_timeout_ms: 500,
            resync_grace_ms: 20,
            set_point_polls: 10,
            transition_timeout_ms: 500,
            fault_text_index: Some(index::FAULT_TEXT),
            correction_objects: false,
        }
    }
}

impl CanopenConfig {
    /// The SDO deadlines of this configuration.
    pub fn sdo_timeouts(&self) -> SdoTimeouts {
        SdoTimeouts {
            response: Duration::from_millis(self.sdo_timeout_ms),
            resync_grace: Duration::from_millis(self.resync_grace_ms),
        }
    }

    fn check(&self) -> std::result::Result<(), String> {
        if !(1..=127).contains(&self.node_id) {
            return Err(format!("node id {} is outside 1..=127", self.node_id));
        }
        if !(self.counts_per_degree.is_finite() && self.counts_per_degree > 0.0) {
            return Err(format!("counts per degree {} is not a positive number", self.counts_per_degree));
        }
        if self.sdo_timeout_ms == 0 {
            return Err("the SDO timeout is 0 ms".into());
        }
        Ok(())
    }
}

/// A CiA 402 drive in profile position mode, over any [`CanBus`].
#[derive(Debug)]
pub struct Cia402Positioner<B> {
    bus: B,
    sdo: SdoClient,
    cfg: CanopenConfig,
    name: String,
    /// The controlword last written (for the edges of bits 4 and 7).
    controlword: Option<u16>,
}

impl<B: CanBus> Cia402Positioner<B> {
    /// A driver on `bus` (nothing is sent yet; see [`Self::connect`]).
    /// A bad configuration is [`ErrorKind::Usage`].
    pub fn new(bus: B, cfg: CanopenConfig) -> Result<Self> {
        let name = format!("canopen node {} on {}", cfg.node_id, bus.describe());
        cfg.check().map_err(|m| DriverError::usage(&name, m))?;
        let sdo = SdoClient::new(cfg.node_id, cfg.sdo_timeouts(), name.clone());
        Ok(Self { bus, sdo, cfg, name, controlword: None })
    }

    /// A driver on `bus`, with the node started (NMT) and the drive brought
    /// to "operation enabled" in profile position mode ([`Self::enable`]).
    pub async fn connect(bus: B, cfg: CanopenConfig) -> Result<Self> {
        let mut p = Self::new(bus, cfg)?;
        p.enable().await?;
        Ok(p)
    }

    /// Set the name used in logs and errors.
    pub fn named(mut self, name: impl Into<String>) -> Self {
        self.name = name.into();
        self.sdo.set_name(self.name.clone());
        self
    }

    /// The configuration.
    pub fn config(&self) -> &CanopenConfig {
        &self.cfg
    }

    /// The bus, for frames of one's own.
    pub fn bus_mut(&mut self) -> &mut B {
        &mut self.bus
    }

    /// The bus back.
    pub fn into_bus(self) -> B {
        self.bus
    }

    /// Send an NMT command to this node.
    pub async fn nmt(&mut self, cmd: NmtCommand) -> Result<()> {
        tracing::debug!(instrument = %self.name, ?cmd, "NMT");
        self.bus.send(encode_command(cmd, self.cfg.node_id)).await
    }

    /// SDO upload (read) of `index:subindex`.
    pub async fn upload(&mut self, index: u16, subindex: u8) -> Result<Vec<u8>> {
        self.sdo.upload(&mut self.bus, index, subindex).await
    }

    /// SDO download (write) of `data` to `index:subindex`.
    pub async fn download(&mut self, index: u16, subindex: u8, data: &[u8]) -> Result<()> {
        self.sdo.download(&mut self.bus, index, subindex, data).await
    }

    /// Read an object of `N` bytes (0x6041 is 2, 0x6064 is 4).
    async fn read_fixed<const N: usize>(&mut self, index: u16) -> Result<[u8; N]> {
        let bytes = self.sdo.upload_exact(&mut self.bus, index, 0, N).await?;
        let mut out = [0u8; N];
        out.copy_from_slice(&bytes);
        Ok(out)
    }

    /// Read a visible string (0x1008 and the like), trailing NULs removed.
    pub async fn read_string(&mut self, index: u16) -> Result<String> {
        let bytes = self.upload(index, 0).await?;
        let text = String::from_utf8_lossy(&bytes);
        Ok(text.trim_end_matches('\0').to_string())
    }

    /// The manufacturer device name (0x1008).
    pub async fn device_name(&mut self) -> Result<String> {
        self.read_string(index::DEVICE_NAME).await
    }

    /// The statusword (0x6041).
    pub async fn statusword(&mut self) -> Result<Statusword> {
        Ok(Statusword(u16::from_le_bytes(self.read_fixed(index::STATUSWORD).await?)))
    }

    /// Write the controlword (0x6040).
    pub async fn write_controlword(&mut self, word: u16) -> Result<()> {
        self.download(index::CONTROLWORD, 0, &word.to_le_bytes()).await?;
        self.controlword = Some(word);
        Ok(())
    }

    /// The position actual value (0x6064), counts.
    pub async fn position_counts(&mut self) -> Result<i32> {
        Ok(i32::from_le_bytes(self.read_fixed(index::POSITION_ACTUAL).await?))
    }

    /// Start the node (NMT), select profile position mode (0x6060 = 1) and
    /// wait until the drive shows it (0x6061), then walk the state machine to
    /// "operation enabled" (shutdown 0x06, switch on 0x07, enable operation
    /// 0x2F), waiting after each step until the statusword shows the next
    /// state, each within [`CanopenConfig::transition_timeout_ms`]. A drive in
    /// fault is a [`ErrorKind::Device`] error with its code.
    pub async fn enable(&mut self) -> Result<()> {
        self.nmt(NmtCommand::Start).await?;
        self.select_profile_position().await?;
        self.enable_state_machine().await
    }

    /// Write 0x6060 = profile position and read 0x6061 until it shows it,
    /// within the transition timeout; each request asked again on a link
    /// fault or a refusal ([`setup::SETUP_REQUEST_TRIES`]).
    async fn select_profile_position(&mut self) -> Result<()> {
        self.setup_write(index::MODES_OF_OPERATION, &PROFILE_POSITION_MODE.to_le_bytes()).await?;
        let deadline = tokio::time::Instant::now() + self.transition_timeout();
        loop {
            let shown = self.setup_read(index::MODES_OF_OPERATION_DISPLAY, 1).await?[0];
            if shown as i8 == PROFILE_POSITION_MODE {
                return Ok(());
            }
            if tokio::time::Instant::now() >= deadline {
                let e = DriverError::new(
                    ErrorKind::Device,
                    &self.name,
                    format!(
                        "the drive did not switch to profile position mode: 0x6061 shows {} {:?} after writing \
                         0x6060 = {PROFILE_POSITION_MODE}",
                        shown as i8,
                        self.transition_timeout()
                    ),
                );
                tracing::warn!(instrument = %self.name, error = %e, "enable failed");
                return Err(e);
            }
            tokio::time::sleep(TRANSITION_POLL).await;
        }
    }

    fn transition_timeout(&self) -> Duration {
        Duration::from_millis(self.cfg.transition_timeout_ms)
    }

    /// Read the statusword until `done` holds or the transition timeout
    /// passes; returns the last word read.
    async fn await_statusword(&mut self, done: impl Fn(Statusword) -> bool) -> Result<(Statusword, bool)> {
        let deadline = tokio::time::Instant::now() + self.transition_timeout();
        loop {
            let word = self.setup_statusword().await?;
            if done(word) {
                return Ok((word, true));
            }
            if tokio::time::Instant::now() >= deadline {
                return Ok((word, false));
            }
            tokio::time::sleep(TRANSITION_POLL).await;
        }
    }

    async fn enable_state_machine(&mut self) -> Result<()> {
        let mut word = self.setup_statusword().await?;
        for _ in 0..MAX_ENABLE_STEPS {
            let next = match word.state() {
                Some(DriveState::OperationEnabled) => return Ok(()),
                Some(DriveState::Fault | DriveState::FaultReactionActive) => {
                    return Err(self.fault_error(word, "cannot enable operation").await);
                }
                Some(DriveState::SwitchOnDisabled) => Some(cw::SHUTDOWN),
                Some(DriveState::ReadyToSwitchOn) => Some(cw::SWITCH_ON_CMD),
                Some(DriveState::SwitchedOn | DriveState::QuickStopActive) => Some(CW_OPERATE),
                // Transient (initialising) or not a valid state: wait for a state.
                Some(DriveState::NotReadyToSwitchOn) | None => None,
            };
            let from = word.state();
            if let Some(c) = next {
                tracing::debug!(instrument = %self.name, %word, controlword = format_args!("0x{c:04X}"), "enabling");
                self.setup_controlword(c).await?;
            }
            // Wait for the drive to leave the state the step was written in.
            let (now, moved) = self.await_statusword(|w| w.state() != from || w.fault()).await?;
            if !moved {
                let e = DriverError::new(
                    ErrorKind::Device,
                    &self.name,
                    format!(
                        "the drive stayed in {} for {:?} after controlword {} (statusword {now})",
                        from.map_or_else(|| "no valid state".to_string(), |s| s.to_string()),
                        self.transition_timeout(),
                        next.map_or_else(|| "none".to_string(), |c| format!("0x{c:04X}")),
                    ),
                );
                tracing::warn!(instrument = %self.name, error = %e, "enable failed");
                return Err(e);
            }
            word = now;
        }
        let e = DriverError::new(
            ErrorKind::Device,
            &self.name,
            format!("the drive did not reach operation enabled in {MAX_ENABLE_STEPS} steps (statusword {word})"),
        );
        tracing::warn!(instrument = %self.name, error = %e, "enable failed");
        Err(e)
    }

    /// The latched fault: code from 0x603F, text from the fault-text object
    /// (or the standard text of the code).
    pub async fn fault(&mut self) -> Result<DeviceFault> {
        let code = u16::from_le_bytes(self.read_fixed(index::ERROR_CODE).await?);
        let standard = || match error_code_text(code) {
            Some(t) => t.to_string(),
            None => format!("error code 0x{code:04X}"),
        };
        let text = match self.cfg.fault_text_index {
            None => standard(),
            Some(idx) => match self.read_string(idx).await {
                Ok(t) if !t.is_empty() => t,
                Ok(_) => standard(),
                Err(e) if matches!(e.kind, ErrorKind::Device | ErrorKind::Usage) => {
                    tracing::debug!(instrument = %self.name, error = %e, "no fault text object; standard text used");
                    standard()
                }
                Err(e) => return Err(e),
            },
        };
        Ok(DeviceFault { code: i64::from(code), text })
    }

    /// A device error for a drive in fault (a link failure while reading the
    /// fault is returned instead).
    async fn fault_error(&mut self, word: Statusword, what: &str) -> DriverError {
        match self.fault().await {
            Ok(f) => {
                let e = DriverError::device(
                    &self.name,
                    f.code,
                    format!("{what}: drive fault 0x{:04X}: {} (statusword {word})", f.code, f.text),
                );
                tracing::warn!(instrument = %self.name, error = %e, "drive in fault");
                e
            }
            Err(e) => e,
        }
    }

    /// Read back the correction table held in 0x2100 (segmented upload).
    pub async fn read_correction_table(&mut self) -> Result<CorrectionTable> {
        self.require_correction_objects("read the correction table")?;
        let bytes = self.upload(index::CORRECTION_TABLE, 0).await?;
        decode_table(&bytes).map_err(|e| {
            let e = DriverError::new(ErrorKind::Garbled, &self.name, format!("correction table 0x2100: {e}"));
            tracing::warn!(instrument = %self.name, error = %e, "bad table");
            e
        })
    }

    /// Refuse `what` as bad usage unless the drive has the correction objects.
    fn require_correction_objects(&self, what: &str) -> Result<()> {
        if self.cfg.correction_objects {
            return Ok(());
        }
        Err(self.usage(format!(
            "cannot {what}: the correction objects 0x2100/0x2101 are this project's own (manufacturer-specific, \
             not CiA 402) and the configuration does not say the drive has them (correction_objects = true \
             under [positioner]); load the table with the drive's own tool instead"
        )))
    }

    fn usage(&self, message: String) -> DriverError {
        tracing::warn!(instrument = %self.name, %message, "refused before sending");
        DriverError::usage(&self.name, message)
    }

    /// Write a controlword with bit 4 low first when the last one had it
    /// high, so the next write is a rising edge.
    async fn set_point_handshake(&mut self) -> Result<Statusword> {
        if self.controlword.is_none_or(|c| c & cw::NEW_SET_POINT != 0) {
            self.write_controlword(CW_OPERATE).await?;
        }
        self.write_controlword(CW_OPERATE | cw::NEW_SET_POINT).await?;
        let mut word = self.statusword().await?;
        for _ in 1..self.cfg.set_point_polls.max(1) {
            if word.set_point_acknowledged() || word.fault() {
                break;
            }
            word = self.statusword().await?;
        }
        self.write_controlword(CW_OPERATE).await?;
        Ok(word)
    }
}

#[async_trait]
impl<B: CanBus> Positioner for Cia402Positioner<B> {
    fn name(&self) -> &str {
        &self.name
    }

    /// The device name (0x1008, CiA 301).
    async fn identification(&mut self) -> Result<Option<String>> {
        Ok(Some(self.device_name().await?))
    }

    /// Statusword check (a fault refuses the move with its code; a drive not
    /// in operation enabled is enabled), 0x607A, then the set-point
    /// handshake: controlword 0x3F (new set-point, change set immediately),
    /// wait for bit 12, controlword 0x2F.
    async fn move_to(&mut self, target_deg: f64) -> Result<()> {
        let Some(counts) = degrees_to_counts(target_deg, self.cfg.counts_per_degree) else {
            return Err(self.usage(format!(
                "target {target_deg} deg is not a finite angle within the i32 position range at {} counts/deg",
                self.cfg.counts_per_degree
            )));
        };
        let word = self.statusword().await?;
        if word.fault() {
            return Err(self.fault_error(word, &format!("move to {target_deg} deg refused")).await);
        }
        if !word.operation_enabled() {
            tracing::info!(instrument = %self.name, %word, "drive not in operation enabled: enabling before the move");
            self.enable().await?;
        }
        self.download(index::TARGET_POSITION, 0, &counts.to_le_bytes()).await?;
        let word = self.set_point_handshake().await?;
        if word.fault() {
            return Err(self.fault_error(word, &format!("move to {target_deg} deg")).await);
        }
        if !word.set_point_acknowledged() {
            let e = DriverError::new(
                ErrorKind::Device,
                &self.name,
                format!("the drive did not acknowledge the set-point {counts} counts (statusword {word})"),
            );
            tracing::warn!(instrument = %self.name, error = %e, "no set-point acknowledge");
            return Err(e);
        }
        Ok(())
    }

    /// 0x6064 in degrees.
    async fn readout(&mut self) -> Result<f64> {
        Ok(counts_to_degrees(self.position_counts().await?, self.cfg.counts_per_degree))
    }

    /// The statusword (moving = operation enabled and not target reached;
    /// in position = target reached), 0x2101 for the correction (with the
    /// correction objects; else none), and when their bits say so 0x603F (+
    /// fault text) and 0x60FD for the limit.
    async fn status(&mut self) -> Result<PositionerStatus> {
        let word = self.statusword().await?;
        let correction = self.cfg.correction_objects && self.read_fixed::<1>(index::CORRECTION_ENABLE).await?[0] != 0;
        let fault = if word.fault() { Some(self.fault().await?) } else { None };
        let limit = if word.internal_limit() {
            let inputs = u32::from_le_bytes(self.read_fixed(index::DIGITAL_INPUTS).await?);
            if inputs & di::NEGATIVE_LIMIT != 0 {
                Some(Limit::Lower)
            } else if inputs & di::POSITIVE_LIMIT != 0 {
                Some(Limit::Upper)
            } else {
                None
            }
        } else {
            None
        };
        Ok(PositionerStatus {
            moving: word.operation_enabled() && !word.target_reached(),
            in_position: word.target_reached(),
            fault,
            limit,
            correction_enabled: correction,
        })
    }

    /// Halt (controlword bit 8) when the drive is in operation enabled; in
    /// any other state the drive cannot be moving and nothing is sent.
    async fn stop(&mut self) -> Result<()> {
        let word = self.statusword().await?;
        if word.operation_enabled() {
            self.write_controlword(CW_OPERATE | cw::HALT).await?;
        } else {
            tracing::debug!(instrument = %self.name, %word, "stop: drive not in operation enabled, nothing to halt");
        }
        Ok(())
    }

    /// 0x6081 in counts per second.
    async fn set_velocity(&mut self, deg_per_s: f64) -> Result<()> {
        let v = (deg_per_s * self.cfg.counts_per_degree).round();
        if !(deg_per_s.is_finite() && v >= 1.0 && v <= f64::from(u32::MAX)) {
            return Err(self.usage(format!(
                "velocity {deg_per_s} deg/s is not a positive number of counts/s within u32 at {} counts/deg",
                self.cfg.counts_per_degree
            )));
        }
        self.download(index::PROFILE_VELOCITY, 0, &(v as u32).to_le_bytes()).await
    }

    /// Fault reset (a rising edge of controlword bit 7) when the drive is in
    /// fault, then back to operation enabled. A fault that stays latched is
    /// a [`ErrorKind::Device`] error with its code.
    async fn clear_fault(&mut self) -> Result<()> {
        let word = self.statusword().await?;
        if !word.fault() {
            return Ok(());
        }
        if self.controlword.is_none_or(|c| c & cw::FAULT_RESET != 0) {
            self.write_controlword(cw::DISABLE_VOLTAGE).await?;
        }
        self.write_controlword(cw::FAULT_RESET).await?;
        let (word, cleared) = self.await_statusword(|w| !w.fault()).await?;
        if !cleared {
            return Err(self.fault_error(word, "fault reset did not clear the fault").await);
        }
        self.enable_state_machine().await
    }

    /// Segmented download of the table to 0x2100 (f32 values, see
    /// [`encode_table`]).
    async fn load_correction_table(&mut self, table: &CorrectionTable) -> Result<()> {
        self.require_correction_objects("load the correction table")?;
        let bytes = encode_table(table).map_err(|e| self.usage(format!("correction table: {e}")))?;
        self.download(index::CORRECTION_TABLE, 0, &bytes).await
    }

    /// 0x2101 = 1 or 0.
    async fn enable_correction(&mut self, enabled: bool) -> Result<()> {
        self.require_correction_objects(if enabled { "apply the correction" } else { "switch the correction off" })?;
        self.download(index::CORRECTION_ENABLE, 0, &[u8::from(enabled)]).await
    }

    /// 0x2101 with the correction objects; without them the standard
    /// objects say nothing of a correction: unknown, nothing is read.
    async fn correction_state(&mut self) -> Result<Option<bool>> {
        if !self.cfg.correction_objects {
            return Ok(None);
        }
        Ok(Some(self.read_fixed::<1>(index::CORRECTION_ENABLE).await?[0] != 0))
    }
}

mod setup;
pub use setup::{DriveMemory, SETUP_REQUEST_TRIES, SetUp};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::canopen::frame::CanFrame;
    use crate::canopen::memory_bus::{MemoryBus, MemoryEndpoint};
    use crate::canopen::sdo::{InitData, SdoRequest, SdoResponse, abort};
    use std::collections::HashMap;
    use std::sync::{Arc, Mutex};

    type Objects = Arc<Mutex<HashMap<u16, Vec<u8>>>>;

    /// A scripted node: expedited SDO only, objects from a map, every write
    /// stored and never acted on (a drive that ignores its controlword).
    /// With `no_size`, expedited responses do not indicate their size (4
    /// bytes, zero-padded), as some drives answer.
    fn scripted(bus: &MemoryBus, node: u8, objects: Objects, no_size: bool) -> tokio::task::JoinHandle<()> {
        let mut ep: MemoryEndpoint = bus.endpoint();
        tokio::spawn(async move {
            while let Ok(f) = ep.recv().await {
                if f.id() != 0x600 + u16::from(node) {
                    continue;
                }
                let resp = match SdoRequest::decode(f.data()) {
                    Ok(SdoRequest::InitiateUpload { index, subindex }) => {
                        match objects.lock().unwrap().get(&index).cloned() {
                            Some(data) => SdoResponse::InitiateUpload {
                                index,
                                subindex,
                                data: InitData::Expedited { data, size_indicated: !no_size },
                            },
                            None => SdoResponse::Abort { index, subindex, code: abort::NO_OBJECT },
                        }
                    }
                    Ok(SdoRequest::InitiateDownload { index, subindex, data: InitData::Expedited { data, .. } }) => {
                        objects.lock().unwrap().insert(index, data);
                        SdoResponse::InitiateDownload { index, subindex }
                    }
                    _ => continue,
                };
                let frame = CanFrame::full(0x580 + u16::from(node), resp.encode()).unwrap();
                if ep.send(frame).await.is_err() {
                    return;
                }
            }
        })
    }

    fn cfg() -> CanopenConfig {
        CanopenConfig { node_id: 3, sdo_timeout_ms: 200, ..CanopenConfig::default() }
    }

    fn objects(statusword: u16) -> Objects {
        let mut m = HashMap::new();
        m.insert(index::STATUSWORD, statusword.to_le_bytes().to_vec());
        m.insert(index::CORRECTION_ENABLE, vec![0]);
        // The scripted drive shows profile position mode at once.
        m.insert(index::MODES_OF_OPERATION_DISPLAY, vec![1]);
        Arc::new(Mutex::new(m))
    }

    #[test]
    fn configuration_defaults_and_checks() {
        let c = CanopenConfig::default();
        assert_eq!((c.node_id, c.counts_per_degree, c.sdo_timeout_ms), (1, 100_000.0, 500));
        assert_eq!((c.resync_grace_ms, c.set_point_polls, c.fault_text_index), (20, 10, Some(0x2102)));
        assert_eq!((c.transition_timeout_ms, c.correction_objects), (500, false));
        assert_eq!(c.sdo_timeouts().response, Duration::from_millis(500));
        let bus = MemoryBus::new();
        for bad in [
            CanopenConfig { node_id: 0, ..cfg() },
            CanopenConfig { node_id: 128, ..cfg() },
            CanopenConfig { counts_per_degree: 0.0, ..cfg() },
            CanopenConfig { counts_per_degree: f64::NAN, ..cfg() },
            CanopenConfig { sdo_timeout_ms: 0, ..cfg() },
        ] {
            let e = Cia402Positioner::new(bus.endpoint(), bad.clone()).unwrap_err();
            assert_eq!(e.kind, ErrorKind::Usage, "{bad:?}");
        }
        let p = Cia402Positioner::new(bus.endpoint(), cfg()).unwrap().named("axis 1");
        assert_eq!(p.name(), "axis 1");
        assert_eq!(p.config().node_id, 3);
    }

    #[tokio::test]
    async fn a_drive_that_ignores_the_controlword_is_a_device_error() {
        let bus = MemoryBus::new();
        let objs = objects(0x0250);
        let _node = scripted(&bus, 3, objs.clone(), false);
        let quick = CanopenConfig { transition_timeout_ms: 30, ..cfg() };
        let started = std::time::Instant::now();
        let e = Cia402Positioner::connect(bus.endpoint(), quick).await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Device, "{e}");
        assert!(e.message.contains("stayed in switch on disabled for 30ms after controlword 0x0006"), "{e}");
        assert!(started.elapsed() >= Duration::from_millis(30), "it waited the transition timeout");
        // It was asked: profile position mode, then shutdown.
        assert_eq!(objs.lock().unwrap()[&index::MODES_OF_OPERATION], [1]);
        assert_eq!(objs.lock().unwrap()[&index::CONTROLWORD], cw::SHUTDOWN.to_le_bytes());
    }

    #[tokio::test]
    async fn a_set_point_never_acknowledged_is_a_device_error_and_bit_4_is_dropped() {
        let bus = MemoryBus::new();
        let objs = objects(0x0237);
        let _node = scripted(&bus, 3, objs.clone(), true);
        let mut p = Cia402Positioner::new(bus.endpoint(), CanopenConfig { set_point_polls: 3, ..cfg() }).unwrap();
        let e = p.move_to(12.0).await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Device, "{e}");
        assert!(e.message.contains("did not acknowledge the set-point 1200000 counts"), "{e}");
        assert_eq!(objs.lock().unwrap()[&index::TARGET_POSITION], 1_200_000i32.to_le_bytes());
        assert_eq!(objs.lock().unwrap()[&index::CONTROLWORD], CW_OPERATE.to_le_bytes());
        // Status of such a drive: enabled, target not reached: moving.
        let s = p.status().await.unwrap();
        assert!(s.moving && !s.in_position && s.fault.is_none() && s.limit.is_none(), "{s:?}");
    }

    /// A drive with the standard objects only (no 0x2100-0x2102): status,
    /// its fault and its limits need nothing else; the correction table is
    /// refused before anything is sent unless the configuration says the
    /// drive has the objects.
    #[tokio::test]
    async fn a_drive_with_only_the_standard_objects_reports_its_status() {
        let bus = MemoryBus::new();
        let mut m = HashMap::new();
        m.insert(index::STATUSWORD, 0x0E37u16.to_le_bytes().to_vec());
        m.insert(index::ERROR_CODE, 0u16.to_le_bytes().to_vec());
        m.insert(index::DIGITAL_INPUTS, 2u32.to_le_bytes().to_vec());
        let objs = Arc::new(Mutex::new(m));
        let _node = scripted(&bus, 3, objs.clone(), false);
        let mut p = Cia402Positioner::new(bus.endpoint(), cfg()).unwrap();
        let s = p.status().await.unwrap();
        assert_eq!((s.limit, s.correction_enabled, s.in_position), (Some(Limit::Upper), false, true), "{s:?}");
        let f = p.fault().await.unwrap();
        assert_eq!((f.code, f.text.as_str()), (0, "No error"), "0x2102 absent: the standard text");
        let table = CorrectionTable::new(vec![0.0; 4]).unwrap();
        for e in [p.load_correction_table(&table).await.unwrap_err(), p.enable_correction(true).await.unwrap_err()] {
            assert_eq!(e.kind, ErrorKind::Usage, "{e}");
            assert!(e.message.contains("correction_objects = true"), "{e}");
        }
        assert!(!objs.lock().unwrap().contains_key(&index::CORRECTION_TABLE), "nothing was sent");
        // A drive that has them, configured so: 0x2101 is read.
        objs.lock().unwrap().insert(index::CORRECTION_ENABLE, vec![1]);
        let with = CanopenConfig { correction_objects: true, ..cfg() };
        let mut p = Cia402Positioner::new(bus.endpoint(), with).unwrap();
        assert!(p.status().await.unwrap().correction_enabled);
    }

    #[tokio::test]
    async fn an_object_of_the_wrong_size_is_garbled_and_a_limit_without_switches_is_none() {
        let bus = MemoryBus::new();
        let objs = objects(0x0A37);
        objs.lock().unwrap().insert(index::POSITION_ACTUAL, vec![1, 2]);
        objs.lock().unwrap().insert(index::DIGITAL_INPUTS, 0u32.to_le_bytes().to_vec());
        let _node = scripted(&bus, 3, objs.clone(), false);
        let mut p = Cia402Positioner::new(bus.endpoint(), cfg()).unwrap();
        let e = p.readout().await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Garbled, "{e}");
        assert!(e.message.contains("0x6064:00 came back with 2 bytes where 4 were expected"), "{e}");
        // Internal limit bit 11 with no limit switch input: no limit to name.
        let s = p.status().await.unwrap();
        assert_eq!((s.limit, s.in_position, s.moving), (None, false, true));
        // No fault-text object: the standard text (of an unknown code, its number).
        objs.lock().unwrap().insert(index::ERROR_CODE, 0x1234u16.to_le_bytes().to_vec());
        let f = p.fault().await.unwrap();
        assert_eq!((f.code, f.text.as_str()), (0x1234, "error code 0x1234"));
    }
}
