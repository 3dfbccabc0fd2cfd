//! The CiA 402 profile as data, sans-IO: object indexes, controlword and
//! statusword bits, the drive state machine's states and commands, error-code
//! texts, unit conversion, and the byte layout of the correction-table domain
//! (this project's manufacturer-specific object `0x2100`).

use serde::{Deserialize, Serialize};
use std::fmt;
use survey_processing::table::CorrectionTable;

/// Object indexes used by the driver and served by the simulated node.
pub mod index {
    /// Device type (`u32`, ro).
    pub const DEVICE_TYPE: u16 = 0x1000;
    /// Error register (`u8`, ro).
    pub const ERROR_REGISTER: u16 = 0x1001;
    /// Manufacturer device name (visible string, ro).
    pub const DEVICE_NAME: u16 = 0x1008;
    /// Correction table (domain, rw; manufacturer-specific, this project's layout).
    pub const CORRECTION_TABLE: u16 = 0x2100;
    /// Correction applied in the feedback path (`u8` 0/1, rw; manufacturer-specific).
    pub const CORRECTION_ENABLE: u16 = 0x2101;
    /// Text of the latched fault (visible string, ro; manufacturer-specific).
    pub const FAULT_TEXT: u16 = 0x2102;
    /// Error code of the last fault (`u16`, ro).
    pub const ERROR_CODE: u16 = 0x603F;
    /// Controlword (`u16`, rw).
    pub const CONTROLWORD: u16 = 0x6040;
    /// Statusword (`u16`, ro).
    pub const STATUSWORD: u16 = 0x6041;
    /// Modes of operation (`i8`, rw).
    pub const MODES_OF_OPERATION: u16 = 0x6060;
    /// Modes of operation display (`i8`, ro).
    pub const MODES_OF_OPERATION_DISPLAY: u16 = 0x6061;
    /// Position actual value (`i32` counts, ro).
    pub const POSITION_ACTUAL: u16 = 0x6064;
    /// Target position (`i32` counts, rw).
    pub const TARGET_POSITION: u16 = 0x607A;
    /// Profile velocity (`u32` counts per second, rw).
    pub const PROFILE_VELOCITY: u16 = 0x6081;
    /// Digital inputs (`u32`, ro): bit 0 negative limit switch, bit 1 positive
    /// limit switch, bit 2 home switch.
    pub const DIGITAL_INPUTS: u16 = 0x60FD;
}

/// Modes of operation value of profile position mode.
pub const PROFILE_POSITION_MODE: i8 = 1;
/// Device type of a CiA 402 servo drive: profile 402 (0x0192) in the low word,
/// 0x0002 (servo drive) in the high word.
pub const DEVICE_TYPE_SERVO_DRIVE: u32 = 0x0002_0192;

/// Controlword bits and commands (CiA 402).
pub mod cw {
    /// Bit 0: switch on.
    pub const SWITCH_ON: u16 = 1 << 0;
    /// Bit 1: enable voltage.
    pub const ENABLE_VOLTAGE: u16 = 1 << 1;
    /// Bit 2: quick stop (active low).
    pub const QUICK_STOP: u16 = 1 << 2;
    /// Bit 3: enable operation.
    pub const ENABLE_OPERATION: u16 = 1 << 3;
    /// Bit 4 (profile position): new set-point, taken on the rising edge.
    pub const NEW_SET_POINT: u16 = 1 << 4;
    /// Bit 5 (profile position): change set immediately.
    pub const CHANGE_SET_IMMEDIATELY: u16 = 1 << 5;
    /// Bit 6 (profile position): target is relative.
    pub const RELATIVE: u16 = 1 << 6;
    /// Bit 7: fault reset, on the rising edge.
    pub const FAULT_RESET: u16 = 1 << 7;
    /// Bit 8: halt.
    pub const HALT: u16 = 1 << 8;
    /// Command "shutdown" (0x06).
    pub const SHUTDOWN: u16 = 0x06;
    /// Command "switch on" / "disable operation" (0x07).
    pub const SWITCH_ON_CMD: u16 = 0x07;
    /// Command "switch on + enable operation" / "enable operation" (0x0F).
    pub const ENABLE_OPERATION_CMD: u16 = 0x0F;
    /// Command "disable voltage" (0x00).
    pub const DISABLE_VOLTAGE: u16 = 0x00;
    /// Command "quick stop" (0x02).
    pub const QUICK_STOP_CMD: u16 = 0x02;
}

/// Statusword bits (CiA 402).
pub mod sw {
    /// Bit 0: ready to switch on.
    pub const READY_TO_SWITCH_ON: u16 = 1 << 0;
    /// Bit 1: switched on.
    pub const SWITCHED_ON: u16 = 1 << 1;
    /// Bit 2: operation enabled.
    pub const OPERATION_ENABLED: u16 = 1 << 2;
    /// Bit 3: fault.
    pub const FAULT: u16 = 1 << 3;
    /// Bit 4: voltage enabled.
    pub const VOLTAGE_ENABLED: u16 = 1 << 4;
    /// Bit 5: quick stop (active low: 0 = quick stop active).
    pub const QUICK_STOP: u16 = 1 << 5;
    /// Bit 6: switch on disabled.
    pub const SWITCH_ON_DISABLED: u16 = 1 << 6;
    /// Bit 7: warning.
    pub const WARNING: u16 = 1 << 7;
    /// Bit 9: remote (the controlword is processed).
    pub const REMOTE: u16 = 1 << 9;
    /// Bit 10: target reached.
    pub const TARGET_REACHED: u16 = 1 << 10;
    /// Bit 11: internal limit active.
    pub const INTERNAL_LIMIT: u16 = 1 << 11;
    /// Bit 12 (profile position): set-point acknowledge.
    pub const SET_POINT_ACK: u16 = 1 << 12;
    /// Bit 13 (profile position): following error.
    pub const FOLLOWING_ERROR: u16 = 1 << 13;
}

/// Digital input bits of 0x60FD.
pub mod di {
    /// Bit 0: negative limit switch.
    pub const NEGATIVE_LIMIT: u32 = 1 << 0;
    /// Bit 1: positive limit switch.
    pub const POSITIVE_LIMIT: u32 = 1 << 1;
    /// Bit 2: home switch.
    pub const HOME_SWITCH: u32 = 1 << 2;
}

/// A state of the CiA 402 drive state machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum DriveState {
    /// Not ready to switch on (initialising).
    NotReadyToSwitchOn,
    /// Switch on disabled.
    SwitchOnDisabled,
    /// Ready to switch on.
    ReadyToSwitchOn,
    /// Switched on.
    SwitchedOn,
    /// Operation enabled: the drive follows set-points.
    OperationEnabled,
    /// Quick stop active.
    QuickStopActive,
    /// Fault reaction active.
    FaultReactionActive,
    /// Fault.
    Fault,
}

impl DriveState {
    /// The state a statusword shows (masks of CiA 402: bits 0-3, 5, 6).
    pub fn from_statusword(word: u16) -> Option<Self> {
        Some(match (word & 0x4F, word & 0x6F) {
            (0x00, _) => DriveState::NotReadyToSwitchOn,
            (0x40, _) => DriveState::SwitchOnDisabled,
            (0x0F, _) => DriveState::FaultReactionActive,
            (0x08, _) => DriveState::Fault,
            (_, 0x21) => DriveState::ReadyToSwitchOn,
            (_, 0x23) => DriveState::SwitchedOn,
            (_, 0x27) => DriveState::OperationEnabled,
            (_, 0x07) => DriveState::QuickStopActive,
            _ => return None,
        })
    }

    /// The state bits of the statusword in this state (with "voltage
    /// enabled" set where the power stage is on).
    pub fn statusword_bits(self) -> u16 {
        match self {
            DriveState::NotReadyToSwitchOn => 0x00,
            DriveState::SwitchOnDisabled => 0x40,
            DriveState::ReadyToSwitchOn => 0x21 | sw::VOLTAGE_ENABLED,
            DriveState::SwitchedOn => 0x23 | sw::VOLTAGE_ENABLED,
            DriveState::OperationEnabled => 0x27 | sw::VOLTAGE_ENABLED,
            DriveState::QuickStopActive => 0x07 | sw::VOLTAGE_ENABLED,
            DriveState::FaultReactionActive => 0x0F,
            DriveState::Fault => 0x08,
        }
    }
}

impl fmt::Display for DriveState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            DriveState::NotReadyToSwitchOn => "not ready to switch on",
            DriveState::SwitchOnDisabled => "switch on disabled",
            DriveState::ReadyToSwitchOn => "ready to switch on",
            DriveState::SwitchedOn => "switched on",
            DriveState::OperationEnabled => "operation enabled",
            DriveState::QuickStopActive => "quick stop active",
            DriveState::FaultReactionActive => "fault reaction active",
            DriveState::Fault => "fault",
        })
    }
}

/// The device-control command in a controlword (bits 0-3 and 7).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DriveCommand {
    /// `0xxx xx0x`.
    DisableVoltage,
    /// `0xxx x01x`.
    QuickStop,
    /// `0xxx x110`.
    Shutdown,
    /// `0xxx 0111` (also "disable operation").
    SwitchOn,
    /// `0xxx 1111` ("switch on + enable operation", "enable operation").
    EnableOperation,
    /// Bit 7 set: fault reset (acts on its rising edge).
    FaultReset,
}

impl DriveCommand {
    /// The command a controlword carries.
    pub fn of(word: u16) -> Self {
        if word & cw::FAULT_RESET != 0 {
            DriveCommand::FaultReset
        } else if word & cw::ENABLE_VOLTAGE == 0 {
            DriveCommand::DisableVoltage
        } else if word & cw::QUICK_STOP == 0 {
            DriveCommand::QuickStop
        } else if word & cw::SWITCH_ON == 0 {
            DriveCommand::Shutdown
        } else if word & cw::ENABLE_OPERATION == 0 {
            DriveCommand::SwitchOn
        } else {
            DriveCommand::EnableOperation
        }
    }
}

/// A statusword, decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Statusword(pub u16);

impl Statusword {
    /// Whether `bit` (one of [`sw`]) is set.
    pub fn has(self, bit: u16) -> bool {
        self.0 & bit != 0
    }

    /// The drive state, if the state bits form one.
    pub fn state(self) -> Option<DriveState> {
        DriveState::from_statusword(self.0)
    }

    /// Fault bit 3.
    pub fn fault(self) -> bool {
        self.has(sw::FAULT)
    }

    /// In state "operation enabled".
    pub fn operation_enabled(self) -> bool {
        self.state() == Some(DriveState::OperationEnabled)
    }

    /// Target reached bit 10.
    pub fn target_reached(self) -> bool {
        self.has(sw::TARGET_REACHED)
    }

    /// Internal limit active bit 11.
    pub fn internal_limit(self) -> bool {
        self.has(sw::INTERNAL_LIMIT)
    }

    /// Set-point acknowledge bit 12.
    pub fn set_point_acknowledged(self) -> bool {
        self.has(sw::SET_POINT_ACK)
    }
}

impl fmt::Display for Statusword {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.state() {
            Some(s) => write!(f, "0x{:04X} ({s})", self.0),
            None => write!(f, "0x{:04X} (no valid state)", self.0),
        }
    }
}

/// The standard text of a CiA 402 / CiA 301 error code (0x603F), for the
/// codes a positioner is likely to report; `None` for others.
pub fn error_code_text(code: u16) -> Option<&'static str> {
    Some(match code {
        0x0000 => "No error",
        0x1000 => "Generic error",
        0x2310 => "Continuous over current",
        0x3210 => "DC link over-voltage",
        0x3220 => "DC link under-voltage",
        0x4210 => "Excess temperature device",
        0x5530 => "Data storage",
        0x6010 => "Software reset (watchdog)",
        0x7121 => "Motor blocked",
        0x7300 => "Sensor",
        0x7305 => "Incremental sensor 1 fault",
        0x7320 => "Position",
        0x7500 => "Communication",
        0x8500 => "Position controller",
        0x8611 => "Following error",
        0x8612 => "Reference limit",
        0xFF00 => "Device specific",
        _ => return None,
    })
}

/// Degrees to position counts, rounded; `None` when not finite or outside `i32`.
pub fn degrees_to_counts(deg: f64, counts_per_degree: f64) -> Option<i32> {
    let c = (deg * counts_per_degree).round();
    (c.is_finite() && c >= f64::from(i32::MIN) && c <= f64::from(i32::MAX)).then_some(c as i32)
}

/// Position counts to degrees.
pub fn counts_to_degrees(counts: i32, counts_per_degree: f64) -> f64 {
    f64::from(counts) / counts_per_degree
}

/// Most rows of a correction table in the domain.
pub const MAX_TABLE_ROWS: usize = 8192;
/// Bytes of the domain header.
pub const TABLE_HEADER: usize = 4;

/// Why correction-table bytes do not form a table (and the abort code a node
/// answers with).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TableDomainError {
    /// Shorter than the header, or not the length the header announces.
    #[error("{got} bytes where the header announces {expected}")]
    Length {
        /// Bytes received.
        got: usize,
        /// Bytes the header announces.
        expected: usize,
    },
    /// Fewer than 2 rows, more than [`MAX_TABLE_ROWS`], or unknown flags.
    #[error("bad header: {0}")]
    Header(String),
    /// A value is not a finite `f32`.
    #[error("row {row} is not a finite f32")]
    NotFinite {
        /// The row (0-based, reverse column rows continue after the forward ones).
        row: usize,
    },
}

impl TableDomainError {
    /// The CiA 301 abort code for this refusal.
    pub fn abort_code(&self) -> u32 {
        match self {
            TableDomainError::Length { .. } => super::sdo::abort::LENGTH_MISMATCH,
            _ => super::sdo::abort::VALUE_RANGE,
        }
    }
}

/// The bytes of a correction table in the 0x2100 domain: `u16` row count,
/// `u8` flags (bit 0: directional), `u8` 0, then the forward column and (for
/// a directional table) the reverse column as `f32`, all little-endian.
pub fn encode_table(table: &CorrectionTable) -> Result<Vec<u8>, TableDomainError> {
    let n = table.len();
    if !(2..=MAX_TABLE_ROWS).contains(&n) {
        return Err(TableDomainError::Header(format!("{n} rows (2..={MAX_TABLE_ROWS})")));
    }
    let columns: Vec<&Vec<f64>> = std::iter::once(&table.forward).chain(table.reverse.as_ref()).collect();
    let mut out = Vec::with_capacity(TABLE_HEADER + 4 * n * columns.len());
    out.extend_from_slice(&(n as u16).to_le_bytes());
    out.push(u8::from(table.reverse.is_some()));
    out.push(0);
    for (row, v) in columns.iter().flat_map(|c| c.iter()).enumerate() {
        let f = *v as f32;
        if !f.is_finite() {
            return Err(TableDomainError::NotFinite { row });
        }
        out.extend_from_slice(&f.to_le_bytes());
    }
    Ok(out)
}

/// A correction table from the 0x2100 domain bytes (see [`encode_table`]).
pub fn decode_table(bytes: &[u8]) -> Result<CorrectionTable, TableDomainError> {
    if bytes.len() < TABLE_HEADER {
        return Err(TableDomainError::Length { got: bytes.len(), expected: TABLE_HEADER });
    }
    let n = usize::from(u16::from_le_bytes([bytes[0], bytes[1]]));
    let (flags, reserved) = (bytes[2], bytes[3]);
    if flags > 1 || reserved != 0 {
        return Err(TableDomainError::Header(format!("flags 0x{flags:02X}, reserved byte 0x{reserved:02X}")));
    }
    if !(2..=MAX_TABLE_ROWS).contains(&n) {
        return Err(TableDomainError::Header(format!("{n} rows (2..={MAX_TABLE_ROWS})")));
    }
    let columns = 1 + usize::from(flags);
    let expected = TABLE_HEADER + 4 * n * columns;
    if bytes.len() != expected {
        return Err(TableDomainError::Length { got: bytes.len(), expected });
    }
    let mut values = Vec::with_capacity(n * columns);
    for (row, chunk) in bytes[TABLE_HEADER..].chunks_exact(4).enumerate() {
        let f = f32::from_le_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]);
        if !f.is_finite() {
            return Err(TableDomainError::NotFinite { row });
        }
        values.push(f64::from(f));
    }
    let reverse = (columns == 2).then(|| values.split_off(n));
    let built = match reverse {
        Some(r) => CorrectionTable::directional(values, r),
        None => CorrectionTable::new(values),
    };
    built.map_err(|e| TableDomainError::Header(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn states_round_trip_through_the_statusword() {
        for s in [
            DriveState::NotReadyToSwitchOn,
            DriveState::SwitchOnDisabled,
            DriveState::ReadyToSwitchOn,
            DriveState::SwitchedOn,
            DriveState::OperationEnabled,
            DriveState::QuickStopActive,
            DriveState::FaultReactionActive,
            DriveState::Fault,
        ] {
            let word = s.statusword_bits() | sw::REMOTE | sw::TARGET_REACHED;
            assert_eq!(DriveState::from_statusword(word), Some(s), "{word:04X}");
        }
        // Typical words seen on drives: 0x0250 switch on disabled, 0x0637 operation enabled + target reached.
        assert_eq!(Statusword(0x0250).state(), Some(DriveState::SwitchOnDisabled));
        let w = Statusword(0x1637);
        assert!(w.operation_enabled() && w.target_reached() && w.set_point_acknowledged() && !w.fault());
        assert_eq!(Statusword(0x0001).state(), None);
        assert_eq!(Statusword(0x0637).to_string(), "0x0637 (operation enabled)");
    }

    #[test]
    fn controlword_commands_as_in_cia_402() {
        assert_eq!(DriveCommand::of(cw::SHUTDOWN), DriveCommand::Shutdown);
        assert_eq!(DriveCommand::of(cw::SWITCH_ON_CMD), DriveCommand::SwitchOn);
        assert_eq!(DriveCommand::of(cw::ENABLE_OPERATION_CMD), DriveCommand::EnableOperation);
        assert_eq!(DriveCommand::of(0x3F), DriveCommand::EnableOperation);
        assert_eq!(DriveCommand::of(0x010F), DriveCommand::EnableOperation);
        assert_eq!(DriveCommand::of(cw::DISABLE_VOLTAGE), DriveCommand::DisableVoltage);
        assert_eq!(DriveCommand::of(0x0D), DriveCommand::DisableVoltage);
        assert_eq!(DriveCommand::of(cw::QUICK_STOP_CMD), DriveCommand::QuickStop);
        assert_eq!(DriveCommand::of(0x0B), DriveCommand::QuickStop);
        assert_eq!(DriveCommand::of(0x80), DriveCommand::FaultReset);
        assert_eq!(error_code_text(0x8611), Some("Following error"));
        assert_eq!(error_code_text(0x1234), None);
    }

    #[test]
    fn counts_and_degrees() {
        assert_eq!(degrees_to_counts(12.345_67, 100_000.0), Some(1_234_567));
        assert_eq!(degrees_to_counts(-0.000_004, 100_000.0), Some(0));
        assert_eq!(degrees_to_counts(1e9, 100_000.0), None);
        assert_eq!(degrees_to_counts(f64::NAN, 1.0), None);
        assert_eq!(counts_to_degrees(-4_500_000, 100_000.0), -45.0);
    }

    #[test]
    fn table_domain_layout_and_refusals() {
        let t = CorrectionTable::new(vec![0.5, -0.25]).unwrap();
        let b = encode_table(&t).unwrap();
        assert_eq!(b, [2, 0, 0, 0, 0, 0, 0, 0x3F, 0, 0, 0x80, 0xBE]);
        assert_eq!(decode_table(&b).unwrap(), t);
        assert!(matches!(decode_table(&b[..11]), Err(TableDomainError::Length { got: 11, expected: 12 })));
        assert!(matches!(decode_table(&[1, 0, 0, 0, 0, 0, 0, 0]), Err(TableDomainError::Header(_))));
        assert!(matches!(decode_table(&[2, 0, 2, 0]), Err(TableDomainError::Header(_))));
        let mut nan = b.clone();
        nan[8..12].copy_from_slice(&f32::NAN.to_le_bytes());
        assert_eq!(decode_table(&nan), Err(TableDomainError::NotFinite { row: 1 }));
        assert_eq!(TableDomainError::NotFinite { row: 1 }.abort_code(), 0x0609_0030);
        assert_eq!(TableDomainError::Length { got: 1, expected: 4 }.abort_code(), 0x0607_0010);
        let huge = CorrectionTable::new(vec![1e300, 0.0]).unwrap();
        assert_eq!(encode_table(&huge), Err(TableDomainError::NotFinite { row: 0 }));
    }

    proptest! {
        #[test]
        fn tables_round_trip_to_f32(fwd in proptest::collection::vec(-1.0f64..1.0, 2..200), directional in any::<bool>()) {
            let rev: Vec<f64> = fwd.iter().map(|v| -v / 2.0).collect();
            let t = if directional { CorrectionTable::directional(fwd.clone(), rev).unwrap() } else { CorrectionTable::new(fwd.clone()).unwrap() };
            let bytes = encode_table(&t).unwrap();
            prop_assert_eq!(bytes.len(), TABLE_HEADER + 4 * fwd.len() * (1 + usize::from(directional)));
            let back = decode_table(&bytes).unwrap();
            prop_assert_eq!(back.len(), t.len());
            prop_assert_eq!(back.is_directional(), directional);
            for (a, b) in back.forward.iter().zip(&t.forward) {
                prop_assert_eq!(*a, f64::from(*b as f32));
            }
            // Encoding the decoded table gives the same bytes.
            prop_assert_eq!(encode_table(&back).unwrap(), bytes);
        }

        #[test]
        fn arbitrary_domain_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
            let _ = decode_table(&bytes);
        }

        #[test]
        fn any_statusword_decodes_or_not_without_panic(word in any::<u16>()) {
            if let Some(s) = Statusword(word).state() {
                prop_assert_eq!(DriveState::from_statusword(s.statusword_bits()), Some(s));
            }
            let _ = DriveCommand::of(word);
        }
    }
}
