//! The simulated node's object dictionary: which objects exist, their access
//! and size, and what reading and writing them does.

use super::{MAX_TABLE_BYTES, Node, Refusal, link};
use survey_drivers::error::ErrorKind;
use survey_drivers::traits::Positioner;
use survey_positioner_drivers::canopen::objects::{
    DEVICE_TYPE_SERVO_DRIVE, PROFILE_POSITION_MODE, counts_to_degrees, decode_table, index,
};
use survey_positioner_drivers::canopen::sdo::abort;

/// The data type of an object.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Kind {
    U8,
    I8,
    U16,
    U32,
    I32,
    Text,
    Domain,
}

/// One object (all have sub-index 0 only).
#[derive(Debug, Clone, Copy)]
pub(super) struct Entry {
    pub index: u16,
    pub writable: bool,
    pub kind: Kind,
}

impl Entry {
    /// The fixed size of the object, bytes (`None` for strings and domains).
    pub fn size(&self) -> Option<usize> {
        match self.kind {
            Kind::U8 | Kind::I8 => Some(1),
            Kind::U16 => Some(2),
            Kind::U32 | Kind::I32 => Some(4),
            Kind::Text | Kind::Domain => None,
        }
    }

    /// Most bytes a download may carry.
    pub fn max_len(&self) -> usize {
        self.size().unwrap_or(MAX_TABLE_BYTES)
    }
}

const fn ro(index: u16, kind: Kind) -> Entry {
    Entry { index, writable: false, kind }
}

const fn rw(index: u16, kind: Kind) -> Entry {
    Entry { index, writable: true, kind }
}

/// The object dictionary.
pub(super) const OD: [Entry; 16] = [
    ro(index::DEVICE_TYPE, Kind::U32),
    ro(index::ERROR_REGISTER, Kind::U8),
    ro(index::DEVICE_NAME, Kind::Text),
    rw(index::CORRECTION_TABLE, Kind::Domain),
    rw(index::CORRECTION_ENABLE, Kind::U8),
    ro(index::FAULT_TEXT, Kind::Text),
    ro(index::ERROR_CODE, Kind::U16),
    rw(index::CONTROLWORD, Kind::U16),
    ro(index::STATUSWORD, Kind::U16),
    rw(index::MODES_OF_OPERATION, Kind::I8),
    ro(index::MODES_OF_OPERATION_DISPLAY, Kind::I8),
    ro(index::POSITION_ACTUAL, Kind::I32),
    rw(index::TARGET_POSITION, Kind::I32),
    rw(index::PROFILE_VELOCITY, Kind::U32),
    ro(index::DIGITAL_INPUTS, Kind::U32),
    // 0x6502 supported drive modes (CiA 402): bit 0, profile position, only.
    ro(SUPPORTED_DRIVE_MODES, Kind::U32),
];

/// 0x6502 "Supported drive modes" (CiA 402), read by CiA 402 clients such as
/// python-canopen's `BaseNode402` before they switch the mode.
pub(super) const SUPPORTED_DRIVE_MODES: u16 = 0x6502;

/// This project's own objects (manufacturer-specific, not CiA 402): a drive
/// with only the standard objects lacks them.
const OWN: [u16; 3] = [index::CORRECTION_TABLE, index::CORRECTION_ENABLE, index::FAULT_TEXT];

/// The entry of `index:subindex` (this project's own objects only when the
/// drive has them), or the abort code for a missing one.
pub(super) fn entry(index: u16, subindex: u8, own: bool) -> Result<Entry, Refusal> {
    let e = OD
        .iter()
        .find(|e| e.index == index && (own || !OWN.contains(&e.index)))
        .ok_or(Refusal::Abort(abort::NO_OBJECT))?;
    if subindex != 0 {
        return Err(abort::NO_SUBINDEX.into());
    }
    Ok(*e)
}

/// The entry of a download target, or the abort code.
pub(super) fn writable(index: u16, subindex: u8, own: bool) -> Result<Entry, Refusal> {
    let e = entry(index, subindex, own)?;
    if !e.writable {
        return Err(abort::READ_ONLY.into());
    }
    Ok(e)
}

/// The value bytes, checked against the entry's size.
fn sized<const N: usize>(data: &[u8]) -> Result<[u8; N], Refusal> {
    match data.len() {
        n if n > N => Err(abort::LENGTH_TOO_HIGH.into()),
        n if n < N => Err(abort::LENGTH_TOO_LOW.into()),
        _ => Ok(<[u8; N]>::try_from(data).unwrap_or([0; N])),
    }
}

impl Node {
    /// The value of `index:subindex`.
    pub(super) async fn read(&mut self, index: u16, subindex: u8) -> Result<Vec<u8>, Refusal> {
        entry(index, subindex, self.cfg.correction_objects)?;
        Ok(match index {
            index::DEVICE_TYPE => DEVICE_TYPE_SERVO_DRIVE.to_le_bytes().to_vec(),
            index::ERROR_REGISTER => {
                self.poll().await?;
                vec![u8::from(self.fault.is_some())]
            }
            index::DEVICE_NAME => self.cfg.device_name.clone().into_bytes(),
            index::CORRECTION_TABLE => self.table.clone().ok_or(Refusal::Abort(abort::NO_DATA))?,
            index::CORRECTION_ENABLE => vec![u8::from(self.poll().await?.correction_enabled)],
            index::FAULT_TEXT => {
                self.poll().await?;
                self.fault_text().into_bytes()
            }
            index::ERROR_CODE => {
                self.poll().await?;
                self.error_code().to_le_bytes().to_vec()
            }
            index::CONTROLWORD => self.controlword.to_le_bytes().to_vec(),
            index::STATUSWORD => self.statusword().await?.to_le_bytes().to_vec(),
            index::MODES_OF_OPERATION => self.mode.to_le_bytes().to_vec(),
            index::MODES_OF_OPERATION_DISPLAY => self.mode_display().to_le_bytes().to_vec(),
            index::POSITION_ACTUAL => self.position().await?.to_le_bytes().to_vec(),
            index::TARGET_POSITION => self.target.to_le_bytes().to_vec(),
            index::PROFILE_VELOCITY => self.velocity.to_le_bytes().to_vec(),
            index::DIGITAL_INPUTS => self.digital_inputs().await?.to_le_bytes().to_vec(),
            SUPPORTED_DRIVE_MODES => 1u32.to_le_bytes().to_vec(),
            _ => return Err(abort::NO_OBJECT.into()),
        })
    }

    /// Store `data` in `index` (sub-index 0; access already checked for
    /// segmented transfers, checked again here).
    pub(super) async fn write(&mut self, index: u16, data: &[u8]) -> Result<(), Refusal> {
        writable(index, 0, self.cfg.correction_objects)?;
        match index {
            index::CONTROLWORD => self.controlword(u16::from_le_bytes(sized(data)?)).await,
            index::MODES_OF_OPERATION => {
                let [m] = sized::<1>(data)?;
                if m as i8 != PROFILE_POSITION_MODE {
                    return Err(abort::VALUE_RANGE.into());
                }
                self.set_mode(m as i8);
                Ok(())
            }
            index::TARGET_POSITION => {
                let counts = i32::from_le_bytes(sized(data)?);
                let deg = counts_to_degrees(counts, self.cfg.counts_per_degree);
                if let Some((lo, hi)) = self.sim.config().travel
                    && !(lo..=hi).contains(&deg)
                {
                    tracing::debug!(deg, lo, hi, "CANopen node: target outside the travel");
                    return Err(abort::VALUE_RANGE.into());
                }
                self.target = counts;
                Ok(())
            }
            index::PROFILE_VELOCITY => {
                let v = u32::from_le_bytes(sized(data)?);
                let deg_s = f64::from(v) / self.cfg.counts_per_degree;
                if v == 0 {
                    return Err(abort::VALUE_TOO_LOW.into());
                }
                if deg_s > self.cfg.max_velocity_deg_s {
                    return Err(abort::VALUE_TOO_HIGH.into());
                }
                match self.sim.set_velocity(deg_s).await {
                    Ok(()) => {
                        self.velocity = v;
                        Ok(())
                    }
                    Err(e) if e.kind == ErrorKind::Usage => Err(abort::VALUE_RANGE.into()),
                    Err(e) => Err(link(e)),
                }
            }
            index::CORRECTION_TABLE => {
                let table = decode_table(data).map_err(|e| {
                    tracing::debug!(error = %e, "CANopen node: bad correction table");
                    Refusal::Abort(e.abort_code())
                })?;
                match self.sim.load_correction_table(&table).await {
                    Ok(()) => {
                        self.table = Some(data.to_vec());
                        Ok(())
                    }
                    Err(e) if e.kind == ErrorKind::Usage => Err(abort::DEVICE_STATE.into()),
                    Err(e) => Err(link(e)),
                }
            }
            index::CORRECTION_ENABLE => {
                let [v] = sized::<1>(data)?;
                if v > 1 {
                    return Err(abort::VALUE_RANGE.into());
                }
                if v == 1 && self.table.is_none() {
                    return Err(abort::NO_DATA.into());
                }
                match self.sim.enable_correction(v == 1).await {
                    Ok(()) => Ok(()),
                    Err(e) if e.kind == ErrorKind::Usage => Err(abort::DEVICE_STATE.into()),
                    Err(e) => Err(link(e)),
                }
            }
            _ => Err(abort::READ_ONLY.into()),
        }
    }
}
