//! The real-time corrector (the paper's section 5) and the binary table it loads.
//!
//! # Correcting in the feedback path
//!
//! The paper applies the table to the position feedback itself, in hardware,
//! so that displays, triggers and the servo loop all see the corrected angle:
//! "By using a position update rate of 20 KHz or higher and performing the
//! correction in hardware, this tight timing budget can be met" (at 6 deg/s a
//! 50 us delay costs 0.0003 deg, under 10 % of the error budget). The budget of
//! one correction is therefore **50 us per update at 20 kHz**; [`Corrector`]
//! takes a few nanoseconds (see `benches/corrector.rs` and the README).
//!
//! [`Corrector::new`] precomputes, for every row `i` of a
//! [`CorrectionTable`] of `n` rows, the pair `(e_i, e_{i+1} - e_i)` (value and
//! slope per row, the last row's slope running to row 0 across 360 deg). A
//! correction is then, with no division and no branch on the table size:
//!
//! ```text
//! p = readout * (n / 360)             row units, any turn
//! p = p - n * floor(p * (1 / n))      wrap into [0, n) by a multiply and a floor
//! i = min(trunc(p), n - 1)            (rounding can give p == n: clamped, frac = 1)
//! error = e_i + slope_i * (p - i)
//! corrected = readout - error
//! ```
//!
//! which is the contract's reading of the table (linear interpolation between
//! rows, wrapping at 360) and gives the same bits as
//! [`CorrectionTable::error_at`], the one reading of a table (both place the
//! readout with `table::row_position`; property-tested below). A direction-aware table holds a second
//! column for reverse motion; [`DirectionTracker`] derives the direction from
//! successive readouts the way LinuxCNC's compensation does (moving up uses
//! the forward column, moving down the reverse one, standing still keeps the
//! last), with a dead band against encoder jitter.
//!
//! # Binary table format (version 1)
//!
//! What a controller loads, little-endian throughout:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic, the ASCII bytes `SVCT` |
//! | 4 | 2 | format version, `u16`, 1 |
//! | 6 | 1 | bytes per value: 8 (`f64`) or 4 (`f32`) |
//! | 7 | 1 | columns: 1 (`error`) or 2 (`error_forward`, `error_reverse`) |
//! | 8 | 4 | rows `n`, `u32`, at least 2 |
//! | 12 | 4 | CRC-32 of the value bytes (IEEE 802.3 polynomial, reflected, as zlib's `crc32`), `u32` |
//! | 16 | `n * columns * size` | the values, degrees, IEEE 754, column after column (all `n` rows of the forward column, then the reverse one) |
//!
//! Row `i` is the error at readout `360 i / n` degrees (the CSV's rows). The
//! file is exactly `16 + n * columns * size` bytes. [`from_bytes`] checks every
//! field, the length, the checksum and that every value is finite, and returns
//! an error (never panics) on anything else: any single flipped bit of a valid
//! file is detected (property-tested). `f32` halves the size at a rounding of
//! about `6e-8` relative (under a nanodegree for errors of a few hundredths).

use survey_processing::table::CorrectionTable;
use survey_processing::types::Direction;

/// The first four bytes of a binary table.
pub const MAGIC: [u8; 4] = *b"SVCT";
/// The binary format version this module writes and reads.
pub const VERSION: u16 = 1;
/// Bytes before the values.
pub const HEADER_LEN: usize = 16;

/// Constant-time correction of readouts from a [`CorrectionTable`].
#[derive(Debug, Clone, PartialEq)]
pub struct Corrector {
    rows: usize,
    rows_f: f64,
    /// `rows / 360`: readout degrees to row units.
    scale: f64,
    /// `1 / rows`.
    inv_rows: f64,
    forward: Vec<[f64; 2]>,
    reverse: Option<Vec<[f64; 2]>>,
}

fn pairs(col: &[f64]) -> Vec<[f64; 2]> {
    let n = col.len();
    (0..n).map(|i| [col[i], col[(i + 1) % n] - col[i]]).collect()
}

#[inline(always)]
fn lookup(col: &[[f64; 2]], rows: usize, rows_f: f64, scale: f64, inv_rows: f64, readout_deg: f64) -> f64 {
    let (i, frac) = survey_processing::table::row_position(readout_deg, rows, rows_f, scale, inv_rows);
    let [value, slope] = col[i];
    value + slope * frac
}

impl Corrector {
    /// Precompute the rows and slopes of `table`.
    pub fn new(table: &CorrectionTable) -> Self {
        let rows = table.len();
        Self {
            rows,
            rows_f: rows as f64,
            scale: rows as f64 / 360.0,
            inv_rows: 1.0 / rows as f64,
            forward: pairs(&table.forward),
            reverse: table.reverse.as_deref().map(pairs),
        }
    }

    /// Number of table rows.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Whether the table has a reverse column.
    pub fn is_directional(&self) -> bool {
        self.reverse.is_some()
    }

    /// The error at `readout_deg` from the forward (or only) column.
    #[inline]
    pub fn error_forward(&self, readout_deg: f64) -> f64 {
        lookup(&self.forward, self.rows, self.rows_f, self.scale, self.inv_rows, readout_deg)
    }

    /// The error at `readout_deg` for motion in `direction` (the forward column
    /// when the table is not direction-aware).
    #[inline]
    pub fn error(&self, readout_deg: f64, direction: Direction) -> f64 {
        let col = match (direction, &self.reverse) {
            (Direction::Reverse, Some(r)) => r.as_slice(),
            _ => self.forward.as_slice(),
        };
        lookup(col, self.rows, self.rows_f, self.scale, self.inv_rows, readout_deg)
    }

    /// The corrected angle `readout - error(readout)`.
    #[inline]
    pub fn correct(&self, readout_deg: f64, direction: Direction) -> f64 {
        readout_deg - self.error(readout_deg, direction)
    }
}

/// Derives the direction of motion from successive readouts.
///
/// A move of more than `deadband_deg` from the reading where the direction was
/// last decided sets the direction; smaller moves (jitter, standing still)
/// keep it. Differences are taken across 0/360 the short way round.
#[derive(Debug, Clone, PartialEq)]
pub struct DirectionTracker {
    reference: Option<f64>,
    direction: Direction,
    deadband_deg: f64,
}

impl DirectionTracker {
    /// A tracker that reports `initial` until the axis has moved more than
    /// `deadband_deg` (its absolute value is used).
    pub fn new(initial: Direction, deadband_deg: f64) -> Self {
        Self { reference: None, direction: initial, deadband_deg: deadband_deg.abs() }
    }

    /// The current direction.
    pub fn direction(&self) -> Direction {
        self.direction
    }

    /// Take a new readout and return the direction of motion.
    #[inline]
    pub fn update(&mut self, readout_deg: f64) -> Direction {
        match self.reference {
            None => self.reference = Some(readout_deg),
            Some(r) => {
                let d = readout_deg - r;
                let d = d - 360.0 * (d * (1.0 / 360.0) + 0.5).floor();
                if d > self.deadband_deg {
                    self.direction = Direction::Forward;
                    self.reference = Some(readout_deg);
                } else if d < -self.deadband_deg {
                    self.direction = Direction::Reverse;
                    self.reference = Some(readout_deg);
                }
            }
        }
        self.direction
    }
}

/// How values are stored in a binary table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ValueFormat {
    /// 8-byte IEEE 754 doubles (exact).
    #[default]
    F64,
    /// 4-byte IEEE 754 singles (about 6e-8 relative rounding).
    F32,
}

impl ValueFormat {
    /// Bytes per value.
    pub fn size(self) -> usize {
        match self {
            ValueFormat::F64 => 8,
            ValueFormat::F32 => 4,
        }
    }
}

/// Why bytes are not a binary table.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BinaryError {
    /// Fewer bytes than the header.
    #[error("{len} bytes: a binary table has a {HEADER_LEN}-byte header")]
    TooShort {
        /// Bytes given.
        len: usize,
    },
    /// The first four bytes are not `SVCT`.
    #[error("not a survey correction table (magic {found:02x?}, expected \"SVCT\")")]
    BadMagic {
        /// The bytes found.
        found: [u8; 4],
    },
    /// A version this reader does not know.
    #[error("binary table version {0}; this reader knows version {VERSION}")]
    UnsupportedVersion(u16),
    /// The value size is neither 4 nor 8.
    #[error("value size {0} bytes; expected 4 (f32) or 8 (f64)")]
    BadValueSize(u8),
    /// The column count is neither 1 nor 2.
    #[error("{0} columns; expected 1 or 2")]
    BadColumns(u8),
    /// Fewer than two rows.
    #[error("{0} rows; a table needs at least 2")]
    TooFewRows(u32),
    /// The byte count does not match the header.
    #[error("{actual} bytes, but the header announces {expected}")]
    LengthMismatch {
        /// What the header implies.
        expected: u64,
        /// What was given.
        actual: u64,
    },
    /// The values do not match their checksum.
    #[error("checksum mismatch: header {expected:08x}, values {actual:08x} (the file is corrupt)")]
    Checksum {
        /// The header's CRC-32.
        expected: u32,
        /// The CRC-32 of the values.
        actual: u32,
    },
    /// A value is NaN or infinite.
    #[error("row {row} of column {column} is not a finite number")]
    NotFinite {
        /// Row (from 0).
        row: usize,
        /// Column (0 forward, 1 reverse).
        column: usize,
    },
}

const fn crc_table() -> [u32; 256] {
    let mut table = [0u32; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
            k += 1;
        }
        table[i] = c;
        i += 1;
    }
    table
}

static CRC_TABLE: [u32; 256] = crc_table();

/// CRC-32 (IEEE 802.3, reflected, initial and final XOR `0xFFFFFFFF`): zlib's `crc32`.
pub fn crc32(bytes: &[u8]) -> u32 {
    !bytes.iter().fold(!0u32, |c, &b| CRC_TABLE[((c ^ b as u32) & 0xFF) as usize] ^ (c >> 8))
}

/// Encode `table` in the binary format (see the module documentation).
pub fn to_bytes(table: &CorrectionTable, format: ValueFormat) -> Vec<u8> {
    let columns: Vec<&[f64]> = std::iter::once(table.forward.as_slice()).chain(table.reverse.as_deref()).collect();
    let mut values = Vec::with_capacity(table.len() * columns.len() * format.size());
    for v in columns.iter().flat_map(|c| c.iter()) {
        match format {
            ValueFormat::F64 => values.extend_from_slice(&v.to_le_bytes()),
            ValueFormat::F32 => values.extend_from_slice(&(*v as f32).to_le_bytes()),
        }
    }
    let rows = u32::try_from(table.len()).expect("a correction table has fewer than 2^32 rows");
    let mut out = Vec::with_capacity(HEADER_LEN + values.len());
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.push(format.size() as u8);
    out.push(columns.len() as u8);
    out.extend_from_slice(&rows.to_le_bytes());
    out.extend_from_slice(&crc32(&values).to_le_bytes());
    out.extend_from_slice(&values);
    out
}

/// Decode a binary table, checking everything (see the module documentation).
pub fn from_bytes(bytes: &[u8]) -> Result<CorrectionTable, BinaryError> {
    let Some((header, values)) = bytes.split_first_chunk::<HEADER_LEN>() else {
        return Err(BinaryError::TooShort { len: bytes.len() });
    };
    let magic = [header[0], header[1], header[2], header[3]];
    if magic != MAGIC {
        return Err(BinaryError::BadMagic { found: magic });
    }
    let version = u16::from_le_bytes([header[4], header[5]]);
    if version != VERSION {
        return Err(BinaryError::UnsupportedVersion(version));
    }
    let size = header[6];
    let format = match size {
        8 => ValueFormat::F64,
        4 => ValueFormat::F32,
        other => return Err(BinaryError::BadValueSize(other)),
    };
    let columns = header[7];
    if !(columns == 1 || columns == 2) {
        return Err(BinaryError::BadColumns(columns));
    }
    let rows = u32::from_le_bytes([header[8], header[9], header[10], header[11]]);
    if rows < 2 {
        return Err(BinaryError::TooFewRows(rows));
    }
    let expected = HEADER_LEN as u64 + rows as u64 * columns as u64 * size as u64;
    if expected != bytes.len() as u64 {
        return Err(BinaryError::LengthMismatch { expected, actual: bytes.len() as u64 });
    }
    let crc = u32::from_le_bytes([header[12], header[13], header[14], header[15]]);
    let actual = crc32(values);
    if crc != actual {
        return Err(BinaryError::Checksum { expected: crc, actual });
    }
    let rows = rows as usize;
    let decoded: Vec<f64> = match format {
        ValueFormat::F64 => {
            values.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().expect("chunks of 8"))).collect()
        }
        ValueFormat::F32 => {
            values.chunks_exact(4).map(|c| f64::from(f32::from_le_bytes(c.try_into().expect("chunks of 4")))).collect()
        }
    };
    if let Some(i) = decoded.iter().position(|v| !v.is_finite()) {
        return Err(BinaryError::NotFinite { row: i % rows, column: i / rows });
    }
    let mut decoded = decoded;
    let reverse = (columns == 2).then(|| decoded.split_off(rows));
    let table = match reverse {
        Some(r) => CorrectionTable::directional(decoded, r),
        None => CorrectionTable::new(decoded),
    };
    Ok(table.expect("rows >= 2, equal columns and finite values were checked"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use proptest::test_runner::{Config as ProptestConfig, RngSeed};

    fn sample_table(n: usize, directional: bool) -> CorrectionTable {
        let f: Vec<f64> = (0..n).map(|i| 0.01 * (0.37 * i as f64).sin() + 1e-4 * i as f64).collect();
        if directional {
            let r = f.iter().map(|v| v - 0.004).collect();
            CorrectionTable::directional(f, r).unwrap()
        } else {
            CorrectionTable::new(f).unwrap()
        }
    }

    #[test]
    fn corrector_matches_the_table_reading_and_wraps() {
        let t = sample_table(360, true);
        let c = Corrector::new(&t);
        assert_eq!((c.rows(), c.is_directional()), (360, true));
        for r in [0.0, 0.5, 1.0, 123.456, 359.0, 359.999_999, 360.0, 720.25, -0.25, -360.0, -1e-300, 1e6 + 0.3] {
            for d in [Direction::Forward, Direction::Reverse] {
                let a = c.error(r, d);
                let b = t.error_at(r, d);
                assert_eq!(a.to_bits(), b.to_bits(), "{r} {d}: {a} vs {b}");
                assert_eq!(c.correct(r, d).to_bits(), t.correct(r, d).to_bits());
            }
        }
        // Exactly on a row: the row's value; half way: the mean of two rows.
        assert!((c.error_forward(1.0) - t.forward[1]).abs() < 1e-15);
        assert!((c.error_forward(359.5) - 0.5 * (t.forward[359] + t.forward[0])).abs() < 1e-15);
        // Non-directional: both directions read the one column.
        let one = Corrector::new(&sample_table(8, false));
        assert_eq!(one.error(10.0, Direction::Reverse), one.error(10.0, Direction::Forward));
        // Garbage in, no panic.
        assert!(c.error_forward(f64::NAN).is_nan());
        let _ = c.error_forward(f64::INFINITY);
        let _ = c.error_forward(f64::MAX);
    }

    #[test]
    fn direction_tracker_keeps_the_last_direction_inside_the_deadband() {
        let mut t = DirectionTracker::new(Direction::Forward, 0.001);
        assert_eq!(t.update(10.0), Direction::Forward);
        assert_eq!(t.update(9.9995), Direction::Forward); // jitter
        assert_eq!(t.update(9.99), Direction::Reverse);
        assert_eq!(t.update(9.99), Direction::Reverse); // standing still
        assert_eq!(t.update(9.9905), Direction::Reverse);
        assert_eq!(t.update(9.995), Direction::Forward);
        // Across 360 the short way: 359.999 -> 0.001 is forward.
        let mut w = DirectionTracker::new(Direction::Reverse, 0.0001);
        w.update(359.999);
        assert_eq!(w.update(0.001), Direction::Forward);
        assert_eq!(w.update(359.99), Direction::Reverse);
        assert_eq!(w.direction(), Direction::Reverse);
    }

    #[test]
    fn binary_round_trip_f64_exact_and_f32_rounded() {
        for directional in [false, true] {
            let t = sample_table(1000, directional);
            let bytes = to_bytes(&t, ValueFormat::F64);
            assert_eq!(bytes.len(), HEADER_LEN + 1000 * 8 * if directional { 2 } else { 1 });
            assert_eq!(&bytes[..4], b"SVCT");
            assert_eq!(from_bytes(&bytes).unwrap(), t);
            let small = from_bytes(&to_bytes(&t, ValueFormat::F32)).unwrap();
            assert_eq!(small.is_directional(), directional);
            let worst = small.forward.iter().zip(&t.forward).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            assert!(worst < 1e-8, "{worst:e}");
        }
        // zlib's check value for the CRC-32.
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn corrupt_headers_are_named() {
        let good = to_bytes(&sample_table(4, false), ValueFormat::F64);
        let with = |i: usize, v: u8| {
            let mut b = good.clone();
            b[i] = v;
            from_bytes(&b)
        };
        assert_eq!(from_bytes(&good[..10]), Err(BinaryError::TooShort { len: 10 }));
        assert!(matches!(with(0, b'X'), Err(BinaryError::BadMagic { .. })));
        assert_eq!(with(4, 2), Err(BinaryError::UnsupportedVersion(2)));
        assert_eq!(with(6, 2), Err(BinaryError::BadValueSize(2)));
        assert_eq!(with(7, 3), Err(BinaryError::BadColumns(3)));
        assert_eq!(with(8, 1), Err(BinaryError::TooFewRows(1)));
        assert!(matches!(with(8, 5), Err(BinaryError::LengthMismatch { expected: 56, actual: 48 })));
        assert!(matches!(with(20, good[20] ^ 1), Err(BinaryError::Checksum { .. })));
        // A NaN with a valid checksum is still refused.
        let mut nan = CorrectionTable::new(vec![0.0; 3]).unwrap();
        nan.forward[2] = f64::NAN;
        assert_eq!(from_bytes(&to_bytes(&nan, ValueFormat::F64)), Err(BinaryError::NotFinite { row: 2, column: 0 }));
        assert!(from_bytes(&[]).unwrap_err().to_string().contains("16-byte header"));
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            cases: 128,
            rng_seed: RngSeed::Fixed(0x5eed_c022),
            failure_persistence: None,
            ..ProptestConfig::default()
        })]

        #[test]
        fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..200)) {
            let _ = from_bytes(&bytes);
        }

        #[test]
        fn arbitrary_bytes_behind_a_valid_header_never_panic(
            rows in 0u32..6, size in 0u8..10, columns in 0u8..4,
            tail in prop::collection::vec(any::<u8>(), 0..120),
        ) {
            let mut b = MAGIC.to_vec();
            b.extend_from_slice(&VERSION.to_le_bytes());
            b.extend_from_slice(&[size, columns]);
            b.extend_from_slice(&rows.to_le_bytes());
            b.extend_from_slice(&crc32(&tail).to_le_bytes());
            b.extend_from_slice(&tail);
            if let Ok(t) = from_bytes(&b) {
                prop_assert_eq!(to_bytes(&t, if size == 8 { ValueFormat::F64 } else { ValueFormat::F32 }), b);
            }
        }

        #[test]
        fn round_trip_and_every_flipped_bit_is_caught(
            values in prop::collection::vec(-1.0f64..1.0, 4..40),
            directional in any::<bool>(),
            f32_values in any::<bool>(),
            flip in any::<prop::sample::Index>(),
        ) {
            let n = values.len() / 2;
            let t = if directional {
                CorrectionTable::directional(values[..n].to_vec(), values[n..2 * n].to_vec()).unwrap()
            } else {
                CorrectionTable::new(values.clone()).unwrap()
            };
            let format = if f32_values { ValueFormat::F32 } else { ValueFormat::F64 };
            let bytes = to_bytes(&t, format);
            let back = from_bytes(&bytes).unwrap();
            if format == ValueFormat::F64 {
                prop_assert_eq!(&back, &t);
            }
            let bit = flip.index(bytes.len() * 8);
            let mut bad = bytes.clone();
            bad[bit / 8] ^= 1 << (bit % 8);
            prop_assert!(from_bytes(&bad).is_err(), "bit {} flipped was not caught", bit);
            // Truncated anywhere: an error.
            let cut = flip.index(bytes.len());
            prop_assert!(from_bytes(&bytes[..cut]).is_err());
        }

        #[test]
        fn corrector_agrees_with_the_table_everywhere(
            values in prop::collection::vec(-0.05f64..0.05, 2..300),
            readouts in prop::collection::vec(-1000.0f64..1000.0, 20),
        ) {
            let t = CorrectionTable::directional(values.clone(), values.iter().map(|v| -v).collect()).unwrap();
            let c = Corrector::new(&t);
            for r in readouts {
                for d in [Direction::Forward, Direction::Reverse] {
                    prop_assert_eq!(c.error(r, d).to_bits(), t.error_at(r, d).to_bits());
                }
            }
        }
    }
}
