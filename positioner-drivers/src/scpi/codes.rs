//! The controller's error codes (SCPI-99 ranges) and the bits of the `STAT?`
//! status word (see the module documentation of [`crate::scpi`]).

use std::fmt;
#[cfg(doc)]
use survey_drivers::error::ErrorKind;
use survey_drivers::traits::{DeviceFault, Limit, PositionerStatus};

/// `0,"No error"`.
pub const NO_ERROR: i64 = 0;
/// SCPI-99 `-100 Command error`.
pub const COMMAND_ERROR: i64 = -100;
/// SCPI-99 `-101 Invalid character`.
pub const INVALID_CHARACTER: i64 = -101;
/// SCPI-99 `-102 Syntax error`.
pub const SYNTAX_ERROR: i64 = -102;
/// SCPI-99 `-104 Data type error`.
pub const DATA_TYPE_ERROR: i64 = -104;
/// SCPI-99 `-108 Parameter not allowed`.
pub const PARAMETER_NOT_ALLOWED: i64 = -108;
/// SCPI-99 `-109 Missing parameter`.
pub const MISSING_PARAMETER: i64 = -109;
/// SCPI-99 `-113 Undefined header`.
pub const UNDEFINED_HEADER: i64 = -113;
/// SCPI-99 `-114 Header suffix out of range` (no such controller or axis).
pub const HEADER_SUFFIX_OUT_OF_RANGE: i64 = -114;
/// SCPI-99 `-200 Execution error`.
pub const EXECUTION_ERROR: i64 = -200;
/// SCPI-99 `-221 Settings conflict`.
pub const SETTINGS_CONFLICT: i64 = -221;
/// SCPI-99 `-222 Data out of range`.
pub const DATA_OUT_OF_RANGE: i64 = -222;
/// SCPI-99 `-223 Too much data`.
pub const TOO_MUCH_DATA: i64 = -223;
/// SCPI-99 `-300 Device-specific error`.
pub const DEVICE_SPECIFIC_ERROR: i64 = -300;
/// SCPI-99 `-350 Queue overflow`.
pub const QUEUE_OVERFLOW: i64 = -350;

/// Whether a controller error code means the request itself was wrong
/// ([`ErrorKind::Usage`]): SCPI command errors `-100..=-199` and parameter
/// errors `-220..=-229`. Every other non-zero code is [`ErrorKind::Device`].
pub fn is_usage_code(code: i64) -> bool {
    (-199..=-100).contains(&code) || (-229..=-220).contains(&code)
}

/// The bits of the `STAT?` word (see the module documentation).
pub mod bits {
    /// Bit 0: latch set.
    pub const LATCH: u16 = 1 << 0;
    /// Bit 1: home switch active.
    pub const HOME: u16 = 1 << 1;
    /// Bit 2: reverse limit active (lower limit).
    pub const REVERSE_LIMIT: u16 = 1 << 2;
    /// Bit 3: forward limit active (upper limit).
    pub const FORWARD_LIMIT: u16 = 1 << 3;
    /// Bit 4: PAU (power amplifier) fault.
    pub const PAU_FAULT: u16 = 1 << 4;
    /// Bit 5: axis enabled.
    pub const ENABLED: u16 = 1 << 5;
    /// Bit 6: error limit active (following-error limit exceeded).
    pub const ERROR_LIMIT: u16 = 1 << 6;
    /// Bit 7: axis in motion.
    pub const IN_MOTION: u16 = 1 << 7;
    /// Bit 8: axis active.
    pub const ACTIVE: u16 = 1 << 8;
    /// Bit 9: axis indexed.
    pub const INDEXED: u16 = 1 << 9;
    /// Bit 10: position trigger active.
    pub const POSITION_TRIGGER: u16 = 1 << 10;
    /// Bit 11: property changed.
    pub const PROPERTY_CHANGED: u16 = 1 << 11;
    /// Bit 12: status changed.
    pub const STATUS_CHANGED: u16 = 1 << 12;
    /// Bits 13-15 are unused (MI-4192 manual p. 3-42, as reproduced in public
    /// code): nothing here reads them.
    pub const UNUSED: u16 = 0b111 << 13;
    /// The bits that mean a fault.
    pub const FAULT: u16 = PAU_FAULT | ERROR_LIMIT;
}

/// A decoded `STAT?` word (parsed by [`super::parse_status`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct StatusWord(pub u16);

impl StatusWord {
    pub fn has(self, bit: u16) -> bool {
        self.0 & bit != 0
    }
    pub fn moving(self) -> bool {
        self.has(bits::IN_MOTION)
    }
    /// A fault bit (PAU fault or error limit) is set.
    pub fn fault(self) -> bool {
        self.has(bits::FAULT)
    }
    /// The active limit switch (reverse = lower wins if both are set).
    pub fn limit(self) -> Option<Limit> {
        if self.has(bits::REVERSE_LIMIT) {
            Some(Limit::Lower)
        } else if self.has(bits::FORWARD_LIMIT) {
            Some(Limit::Upper)
        } else {
            None
        }
    }

    /// The names of the fault bits that are set (for messages).
    pub fn fault_names(self) -> String {
        let mut names = Vec::new();
        if self.has(bits::PAU_FAULT) {
            names.push("PAU fault");
        }
        if self.has(bits::ERROR_LIMIT) {
            names.push("error limit active");
        }
        names.join(", ")
    }

    /// The status, with `fault` (learned from the error queue) as its fault,
    /// `in_position` as the driver decided it (bit 7 clear and the position
    /// within the window of the commanded one) and `correction_enabled` as
    /// the driver set it: the word has no bit for either.
    pub fn to_status(
        self,
        fault: Option<DeviceFault>,
        in_position: bool,
        correction_enabled: bool,
    ) -> PositionerStatus {
        PositionerStatus { moving: self.moving(), in_position, fault, limit: self.limit(), correction_enabled }
    }
}

impl fmt::Display for StatusWord {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}
