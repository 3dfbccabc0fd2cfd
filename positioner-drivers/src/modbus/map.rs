//! The register map: where each quantity lives and how it is encoded. Pure
//! data and arithmetic (no I/O), shared by the driver and the simulator.
//!
//! See the [module documentation](super) for the default map as a table.

use serde::{Deserialize, Serialize};
use std::fmt;
use survey_drivers::traits::{DeviceFault, Limit, PositionerStatus};
use survey_processing::table::CorrectionTable;

/// Most registers one read (function 3 or 4) may ask for (Modbus Application
/// Protocol V1.1b3, 6.3 and 6.4).
pub const MAX_READ_REGISTERS: u16 = 125;
/// Most registers one write-multiple-registers (function 16) may carry
/// (Modbus Application Protocol V1.1b3, 6.12).
pub const MAX_WRITE_REGISTERS: u16 = 123;
/// Registers at the start of the table window before the values: the column
/// (0 forward, 1 reverse) and the first row of the chunk.
pub const WINDOW_HEADER_WORDS: u16 = 2;
/// Most rows one chunk may carry with the window header and two words per
/// value in one write-multiple-registers: `(123 - 2) / 2 = 60`.
pub const MAX_CHUNK_ROWS: u16 = (MAX_WRITE_REGISTERS - WINDOW_HEADER_WORDS) / 2;

/// The order of the two 16-bit registers of a 32-bit value. Bytes inside a
/// register are always big-endian (the Modbus rule).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WordOrder {
    /// The most significant word at the lower address ("ABCD", big-endian).
    #[default]
    HighFirst,
    /// The least significant word at the lower address ("CDAB", word swap,
    /// the "Modicon" order of some devices).
    LowFirst,
}

impl WordOrder {
    /// The two registers of `v`, lower address first.
    pub fn split(self, v: u32) -> [u16; 2] {
        let (hi, lo) = ((v >> 16) as u16, v as u16);
        match self {
            WordOrder::HighFirst => [hi, lo],
            WordOrder::LowFirst => [lo, hi],
        }
    }

    /// The 32-bit value of two registers, lower address first.
    pub fn join(self, words: [u16; 2]) -> u32 {
        let (hi, lo) = match self {
            WordOrder::HighFirst => (words[0], words[1]),
            WordOrder::LowFirst => (words[1], words[0]),
        };
        (u32::from(hi) << 16) | u32::from(lo)
    }
}

/// How positions (and velocities) are encoded in two registers.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum PositionEncoding {
    /// A 32-bit signed count of encoder steps: `counts = round(deg * counts_per_degree)`.
    /// Velocities are counts per second, also 32-bit signed.
    Counts {
        /// Encoder counts per degree (finite, positive).
        counts_per_degree: f64,
    },
    /// An IEEE 754 single-precision number of degrees (velocities: degrees
    /// per second). Resolution about 3e-5 degrees near 360.
    Float32,
}

impl Default for PositionEncoding {
    fn default() -> Self {
        PositionEncoding::Counts { counts_per_degree: DEFAULT_COUNTS_PER_DEGREE }
    }
}

/// The counts per degree a map may have: from one count per 1000 degrees to
/// 1e9 per degree (a 32-bit encoder per revolution has about 1.2e7).
pub const COUNTS_PER_DEGREE_RANGE: (f64, f64) = (1e-3, 1e9);

/// Counts per degree of the default map: 1e-5 degrees (0.036 arcsec) per
/// count, a range of +/-21474 degrees.
pub const DEFAULT_COUNTS_PER_DEGREE: f64 = 100_000.0;

/// The two register tables a read-only quantity can live in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RegisterTable {
    /// Holding registers: read with function 3, written with 6 and 16.
    Holding,
    /// Input registers: read-only, read with function 4.
    Input,
}

impl fmt::Display for RegisterTable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            RegisterTable::Holding => "holding",
            RegisterTable::Input => "input",
        })
    }
}

/// A register address in one of the tables.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Location {
    /// Which table.
    pub table: RegisterTable,
    /// The protocol address (0-based, as on the wire).
    pub address: u16,
}

impl Location {
    /// An input-register location.
    pub const fn input(address: u16) -> Self {
        Self { table: RegisterTable::Input, address }
    }
    /// A holding-register location.
    pub const fn holding(address: u16) -> Self {
        Self { table: RegisterTable::Holding, address }
    }
}

/// The values written to the command register.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CommandCodes {
    /// Move to the commanded position (default 1).
    pub move_absolute: u16,
    /// Stop any motion (default 2).
    pub stop: u16,
    /// Clear a latched fault (default 3).
    pub clear_fault: u16,
    /// Apply the loaded correction table (default 4).
    pub correction_enable: u16,
    /// Stop applying the correction table (default 5).
    pub correction_disable: u16,
    /// Install the staged table as the correction table (default 6).
    pub load_table: u16,
}

impl Default for CommandCodes {
    fn default() -> Self {
        Self { move_absolute: 1, stop: 2, clear_fault: 3, correction_enable: 4, correction_disable: 5, load_table: 6 }
    }
}

impl CommandCodes {
    fn all(&self) -> [(&'static str, u16); 6] {
        [
            ("move_absolute", self.move_absolute),
            ("stop", self.stop),
            ("clear_fault", self.clear_fault),
            ("correction_enable", self.correction_enable),
            ("correction_disable", self.correction_disable),
            ("load_table", self.load_table),
        ]
    }
}

/// Bit numbers (0 = least significant) of the status register.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StatusBits {
    /// The axis is moving (default 0).
    pub moving: u8,
    /// Settled in the window at the commanded position (default 1).
    pub in_position: u8,
    /// A fault is latched; the fault code register says which (default 2).
    pub fault: u8,
    /// The lower travel limit is active (default 3).
    pub lower_limit: u8,
    /// The upper travel limit is active (default 4).
    pub upper_limit: u8,
    /// The correction table is applied (default 5).
    pub correction_enabled: u8,
}

impl Default for StatusBits {
    fn default() -> Self {
        Self { moving: 0, in_position: 1, fault: 2, lower_limit: 3, upper_limit: 4, correction_enabled: 5 }
    }
}

impl StatusBits {
    fn all(&self) -> [(&'static str, u8); 6] {
        [
            ("moving", self.moving),
            ("in_position", self.in_position),
            ("fault", self.fault),
            ("lower_limit", self.lower_limit),
            ("upper_limit", self.upper_limit),
            ("correction_enabled", self.correction_enabled),
        ]
    }

    /// The bits this map uses.
    pub fn mask(&self) -> u16 {
        self.all().iter().fold(0u16, |m, &(_, b)| m | bit(b))
    }
}

fn bit(b: u8) -> u16 {
    1u16.checked_shl(u32::from(b)).unwrap_or(0)
}

/// Where the correction table is staged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TableBlock {
    /// Holding registers `header` and `header + 1`: the number of rows and the
    /// number of columns (1, or 2 for a directional table). Writing them
    /// starts a new staged table (default 10).
    pub header: u16,
    /// Holding registers from `window`: the chunk window, `[column, first
    /// row, value 0 (2 words), value 1 (2 words), ...]` (default 100).
    pub window: u16,
    /// Most rows one chunk carries (default and maximum
    /// [`MAX_CHUNK_ROWS`], 60): the window is `2 + 2 * chunk_rows` registers.
    pub chunk_rows: u16,
    /// The checksum register: CRC-16/MODBUS over the staged value registers
    /// (see [`table_checksum`]) (default input register 4).
    pub checksum: Location,
}

impl Default for TableBlock {
    fn default() -> Self {
        Self { header: 10, window: 100, chunk_rows: MAX_CHUNK_ROWS, checksum: Location::input(4) }
    }
}

/// A register map. Every field has a default (the documented default map),
/// so a configuration names only what differs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RegisterMap {
    /// Modbus unit (TCP) or slave (RTU) address (default 1).
    pub unit_id: u8,
    /// Position and velocity encoding (default counts, 100000 per degree).
    pub position_encoding: PositionEncoding,
    /// Word order of every 32-bit value (default `high_first`).
    pub word_order: WordOrder,
    /// Holding registers of the commanded position, 2 words (default 0).
    pub command_position: u16,
    /// Holding registers of the velocity of the following moves, 2 words,
    /// counts per second or float32 degrees per second (default 2).
    pub velocity: u16,
    /// Holding register the command codes are written to (default 4).
    pub command: u16,
    /// The command codes.
    pub command_codes: CommandCodes,
    /// The actual position (the readout), 2 words (default input register 0).
    pub actual_position: Location,
    /// The status register (default input register 2).
    pub status: Location,
    /// Bit numbers of the status register.
    pub status_bits: StatusBits,
    /// The fault code register, valid while the fault bit is set (default
    /// input register 3).
    pub fault_code: Location,
    /// The correction-table block.
    pub table: TableBlock,
}

impl Default for RegisterMap {
    fn default() -> Self {
        Self {
            unit_id: 1,
            position_encoding: PositionEncoding::default(),
            word_order: WordOrder::default(),
            command_position: 0,
            velocity: 2,
            command: 4,
            command_codes: CommandCodes::default(),
            actual_position: Location::input(0),
            status: Location::input(2),
            status_bits: StatusBits::default(),
            fault_code: Location::input(3),
            table: TableBlock::default(),
        }
    }
}

/// A quantity of the map.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Item {
    /// Commanded position (holding, 2 words).
    CommandPosition,
    /// Velocity (holding, 2 words).
    Velocity,
    /// Command register (holding, 1 word).
    Command,
    /// Actual position (2 words, read-only).
    ActualPosition,
    /// Status register (read-only).
    Status,
    /// Fault code register (read-only).
    FaultCode,
    /// Table header: rows, columns (holding, 2 words).
    TableHeader,
    /// Table chunk window (holding).
    TableWindow,
    /// Table checksum (read-only).
    TableChecksum,
}

impl Item {
    /// Whether the master writes it (the others are read-only).
    pub fn is_writable(self) -> bool {
        matches!(self, Item::CommandPosition | Item::Velocity | Item::Command | Item::TableHeader | Item::TableWindow)
    }

    /// Its name in messages.
    pub fn name(self) -> &'static str {
        match self {
            Item::CommandPosition => "command position",
            Item::Velocity => "velocity",
            Item::Command => "command",
            Item::ActualPosition => "actual position",
            Item::Status => "status",
            Item::FaultCode => "fault code",
            Item::TableHeader => "table header",
            Item::TableWindow => "table window",
            Item::TableChecksum => "table checksum",
        }
    }
}

/// The registers one item occupies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Span {
    /// The item.
    pub item: Item,
    /// Its table.
    pub table: RegisterTable,
    /// Its first register.
    pub address: u16,
    /// How many registers.
    pub len: u16,
}

impl Span {
    /// Whether `address` in `table` is one of its registers.
    pub fn contains(&self, table: RegisterTable, address: u16) -> bool {
        table == self.table && address >= self.address && u32::from(address) < self.end()
    }
    /// One past its last register (may be 65536).
    pub fn end(&self) -> u32 {
        u32::from(self.address) + u32::from(self.len)
    }
}

/// A map that cannot work (overlapping items, bad bits or codes...).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("bad Modbus register map: {0}")]
pub struct MapError(pub String);

/// A value that cannot be encoded or decoded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ValueError {
    /// Not a finite number (NaN or infinite; for float32, also beyond its range).
    #[error("{0} is not a finite number in this encoding")]
    NotFinite(f64),
    /// Outside the range of 32-bit counts.
    #[error("{value} is outside the encodable range {min}..={max}")]
    OutOfRange {
        /// The value.
        value: f64,
        /// The smallest encodable value.
        min: f64,
        /// The largest encodable value.
        max: f64,
    },
    /// A table with more rows than the 16-bit header can say.
    #[error("a table of {0} rows does not fit the 16-bit row count")]
    TableTooLong(usize),
}

impl RegisterMap {
    /// Every item with its registers.
    pub fn spans(&self) -> [Span; 9] {
        let h = RegisterTable::Holding;
        let window_len = WINDOW_HEADER_WORDS + 2 * self.table.chunk_rows;
        [
            Span { item: Item::CommandPosition, table: h, address: self.command_position, len: 2 },
            Span { item: Item::Velocity, table: h, address: self.velocity, len: 2 },
            Span { item: Item::Command, table: h, address: self.command, len: 1 },
            Span {
                item: Item::ActualPosition,
                table: self.actual_position.table,
                address: self.actual_position.address,
                len: 2,
            },
            Span { item: Item::Status, table: self.status.table, address: self.status.address, len: 1 },
            Span { item: Item::FaultCode, table: self.fault_code.table, address: self.fault_code.address, len: 1 },
            Span { item: Item::TableHeader, table: h, address: self.table.header, len: 2 },
            Span { item: Item::TableWindow, table: h, address: self.table.window, len: window_len },
            Span {
                item: Item::TableChecksum,
                table: self.table.checksum.table,
                address: self.table.checksum.address,
                len: 1,
            },
        ]
    }

    /// The item a register belongs to.
    pub fn span_at(&self, table: RegisterTable, address: u16) -> Option<Span> {
        self.spans().into_iter().find(|s| s.contains(table, address))
    }

    /// The span of one item.
    pub fn span_of(&self, item: Item) -> Span {
        self.spans().into_iter().find(|s| s.item == item).unwrap_or_else(|| unreachable!("every item has a span"))
    }

    /// Check that the map can work: counts per degree finite and positive,
    /// status bits below 16 and distinct, command codes non-zero and distinct,
    /// chunk rows in `1..=60`, items inside the address space and not
    /// overlapping.
    pub fn validate(&self) -> Result<(), MapError> {
        // A scale outside this range is no encoder (found by fuzzing: a
        // subnormal scale passed as "positive and finite" and every decoded
        // position became infinite).
        if let PositionEncoding::Counts { counts_per_degree } = self.position_encoding
            && !(COUNTS_PER_DEGREE_RANGE.0..=COUNTS_PER_DEGREE_RANGE.1).contains(&counts_per_degree)
        {
            return Err(MapError(format!(
                "counts_per_degree {counts_per_degree} is not within {} to {} counts per degree",
                COUNTS_PER_DEGREE_RANGE.0, COUNTS_PER_DEGREE_RANGE.1
            )));
        }
        let bits = self.status_bits.all();
        for (i, &(name, b)) in bits.iter().enumerate() {
            if b >= 16 {
                return Err(MapError(format!("status bit {name} = {b} is not in 0..=15")));
            }
            if let Some(&(other, _)) = bits[..i].iter().find(|&&(_, o)| o == b) {
                return Err(MapError(format!("status bits {other} and {name} are both bit {b}")));
            }
        }
        let codes = self.command_codes.all();
        for (i, &(name, c)) in codes.iter().enumerate() {
            if c == 0 {
                return Err(MapError(format!("command code {name} is 0 (0 means no command)")));
            }
            if let Some(&(other, _)) = codes[..i].iter().find(|&&(_, o)| o == c) {
                return Err(MapError(format!("command codes {other} and {name} are both {c}")));
            }
        }
        if !(1..=MAX_CHUNK_ROWS).contains(&self.table.chunk_rows) {
            return Err(MapError(format!("table chunk_rows {} is not in 1..={MAX_CHUNK_ROWS}", self.table.chunk_rows)));
        }
        let spans = self.spans();
        for (i, a) in spans.iter().enumerate() {
            if a.end() > 65_536 {
                return Err(MapError(format!(
                    "{} at {} {} runs past register 65535",
                    a.item.name(),
                    a.table,
                    a.address
                )));
            }
            for b in &spans[..i] {
                let overlap = a.table == b.table && u32::from(a.address) < b.end() && u32::from(b.address) < a.end();
                if overlap {
                    return Err(MapError(format!(
                        "{} ({} {}..{}) overlaps {} ({} {}..{})",
                        a.item.name(),
                        a.table,
                        a.address,
                        a.end(),
                        b.item.name(),
                        b.table,
                        b.address,
                        b.end()
                    )));
                }
            }
        }
        Ok(())
    }

    /// The registers of a position, degrees.
    pub fn encode_position(&self, deg: f64) -> Result<[u16; 2], ValueError> {
        encode_scalar(self.position_encoding, self.word_order, deg)
    }

    /// The position in two registers, degrees.
    pub fn decode_position(&self, words: [u16; 2]) -> Result<f64, ValueError> {
        decode_scalar(self.position_encoding, self.word_order, words)
    }

    /// The registers of a velocity, degrees per second (counts per second or
    /// float32, as the positions).
    pub fn encode_velocity(&self, deg_per_s: f64) -> Result<[u16; 2], ValueError> {
        encode_scalar(self.position_encoding, self.word_order, deg_per_s)
    }

    /// The velocity in two registers, degrees per second.
    pub fn decode_velocity(&self, words: [u16; 2]) -> Result<f64, ValueError> {
        decode_scalar(self.position_encoding, self.word_order, words)
    }

    /// The registers of one correction-table value (always float32 degrees,
    /// in the map's word order).
    pub fn encode_table_value(&self, deg: f64) -> Result<[u16; 2], ValueError> {
        encode_scalar(PositionEncoding::Float32, self.word_order, deg)
    }

    /// One correction-table value from its registers.
    pub fn decode_table_value(&self, words: [u16; 2]) -> Result<f64, ValueError> {
        decode_scalar(PositionEncoding::Float32, self.word_order, words)
    }

    /// The value registers of a whole table: every row of the forward column,
    /// then (directional tables) every row of the reverse column. The
    /// checksum covers exactly these words.
    pub fn table_words(&self, table: &CorrectionTable) -> Result<Vec<u16>, ValueError> {
        if table.len() > usize::from(u16::MAX) {
            return Err(ValueError::TableTooLong(table.len()));
        }
        let columns = std::iter::once(&table.forward).chain(table.reverse.as_ref());
        let mut words = Vec::with_capacity(2 * table.len() * if table.is_directional() { 2 } else { 1 });
        for v in columns.flatten() {
            words.extend(self.encode_table_value(*v)?);
        }
        Ok(words)
    }

    /// The header registers of a table: `[rows, columns]`.
    pub fn table_header(&self, table: &CorrectionTable) -> Result<[u16; 2], ValueError> {
        let rows = u16::try_from(table.len()).map_err(|_| ValueError::TableTooLong(table.len()))?;
        Ok([rows, if table.is_directional() { 2 } else { 1 }])
    }

    /// The chunks to write at the window: `[column, first_row, value
    /// words...]`, at most `chunk_rows` rows each, forward column first.
    pub fn table_chunks(&self, table: &CorrectionTable) -> Result<Vec<Vec<u16>>, ValueError> {
        self.table_header(table)?;
        let per = usize::from(self.table.chunk_rows.max(1));
        let columns = std::iter::once(&table.forward).chain(table.reverse.as_ref());
        let mut chunks = Vec::new();
        for (column, values) in columns.enumerate() {
            for (k, rows) in values.chunks(per).enumerate() {
                let mut chunk = Vec::with_capacity(2 + 2 * rows.len());
                chunk.push(column as u16);
                chunk.push((k * per) as u16);
                for v in rows {
                    chunk.extend(self.encode_table_value(*v)?);
                }
                chunks.push(chunk);
            }
        }
        Ok(chunks)
    }

    /// Decode the status register (and the fault code register, read when
    /// the fault bit is set). Both limit bits set reads as the lower limit.
    pub fn decode_status(&self, word: u16, fault_code: Option<u16>) -> PositionerStatus {
        let b = &self.status_bits;
        let has = |n: u8| word & bit(n) != 0;
        let fault = has(b.fault).then(|| {
            let code = fault_code.unwrap_or(0);
            DeviceFault { code: i64::from(code), text: fault_text(code) }
        });
        let limit = if has(b.lower_limit) {
            Some(Limit::Lower)
        } else if has(b.upper_limit) {
            Some(Limit::Upper)
        } else {
            None
        };
        PositionerStatus {
            moving: has(b.moving),
            in_position: has(b.in_position),
            fault,
            limit,
            correction_enabled: has(b.correction_enabled),
        }
    }

    /// The status register of `status` (the fault code goes to its own
    /// register: see [`fault_code_register`]).
    pub fn encode_status(&self, status: &PositionerStatus) -> u16 {
        let b = &self.status_bits;
        let mut w = 0u16;
        let mut set = |on: bool, n: u8| {
            if on {
                w |= bit(n);
            }
        };
        set(status.moving, b.moving);
        set(status.in_position, b.in_position);
        set(status.fault.is_some(), b.fault);
        set(status.limit == Some(Limit::Lower), b.lower_limit);
        set(status.limit == Some(Limit::Upper), b.upper_limit);
        set(status.correction_enabled, b.correction_enabled);
        w
    }
}

/// The fault code register for a status: the fault's code when it fits 16
/// bits, `0xFFFF` when it does not, 0 without a fault.
pub fn fault_code_register(status: &PositionerStatus) -> u16 {
    status.fault.as_ref().map_or(0, |f| u16::try_from(f.code).unwrap_or(u16::MAX))
}

/// The text of a controller fault code. The map carries codes only; the
/// names given are the CiA 402 (IEC 61800-7-201) error codes the simulator
/// uses.
pub fn fault_text(code: u16) -> String {
    match code {
        0 => "fault bit set without a fault code".to_string(),
        0x8611 => format!("controller fault {code:#06x}: following error"),
        _ => format!("controller fault {code:#06x}"),
    }
}

/// CRC-16/MODBUS (polynomial 0xA001 reflected, initial 0xFFFF) over
/// registers, each register high byte first. Check value: the bytes
/// `"123456789"` give 0x4B37.
pub fn crc16_modbus_bytes(bytes: &[u8]) -> u16 {
    let mut crc = 0xFFFFu16;
    for &b in bytes {
        crc ^= u16::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 { (crc >> 1) ^ 0xA001 } else { crc >> 1 };
        }
    }
    crc
}

/// The table checksum: CRC-16/MODBUS over the value registers of
/// [`RegisterMap::table_words`], each register high byte first.
pub fn table_checksum(words: &[u16]) -> u16 {
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_be_bytes()).collect();
    crc16_modbus_bytes(&bytes)
}

fn encode_scalar(enc: PositionEncoding, order: WordOrder, v: f64) -> Result<[u16; 2], ValueError> {
    if !v.is_finite() {
        return Err(ValueError::NotFinite(v));
    }
    match enc {
        PositionEncoding::Counts { counts_per_degree } => {
            let counts = (v * counts_per_degree).round();
            if !(f64::from(i32::MIN)..=f64::from(i32::MAX)).contains(&counts) {
                return Err(ValueError::OutOfRange {
                    value: v,
                    min: f64::from(i32::MIN) / counts_per_degree,
                    max: f64::from(i32::MAX) / counts_per_degree,
                });
            }
            Ok(order.split(counts as i32 as u32))
        }
        PositionEncoding::Float32 => {
            let f = v as f32;
            if !f.is_finite() {
                return Err(ValueError::NotFinite(v));
            }
            Ok(order.split(f.to_bits()))
        }
    }
}

fn decode_scalar(enc: PositionEncoding, order: WordOrder, words: [u16; 2]) -> Result<f64, ValueError> {
    let raw = order.join(words);
    match enc {
        PositionEncoding::Counts { counts_per_degree } => Ok(f64::from(raw as i32) / counts_per_degree),
        PositionEncoding::Float32 => {
            let f = f32::from_bits(raw);
            if f.is_finite() { Ok(f64::from(f)) } else { Err(ValueError::NotFinite(f64::from(f))) }
        }
    }
}

#[cfg(test)]
mod tests;
