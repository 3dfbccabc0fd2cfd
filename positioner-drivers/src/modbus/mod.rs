//! Positioner controllers on Modbus TCP and Modbus RTU: a register map given
//! in configuration ([`RegisterMap`]), its pure encoders and decoders, and a
//! [`Positioner`](survey_drivers::traits::Positioner) driver ([`ModbusPositioner`])
//! over the tokio-modbus 0.17 client.
//!
//! # The default register map
//!
//! Addresses are protocol addresses (0-based, as on the wire: holding
//! register 0 is "40001" in the 1-based convention). Every 32-bit value is
//! two consecutive registers in the map's word order (default: high word
//! first), bytes big-endian inside each register.
//!
//! | quantity | table | address | registers | encoding | access |
//! |---|---|---|---|---|---|
//! | commanded position | holding | 0 | 2 | i32 counts, 100000 per degree | write (read back) |
//! | velocity of the following moves | holding | 2 | 2 | i32 counts per second | write (read back) |
//! | command | holding | 4 | 1 | command code (below) | write |
//! | table header: rows, columns | holding | 10 | 2 | u16 rows (2..), u16 columns (1 or 2) | write |
//! | table window | holding | 100 | 2 + 2 x 60 | u16 column (0 forward, 1 reverse), u16 first row, then float32 degrees per row | write |
//! | actual position (the readout) | input | 0 | 2 | as the commanded position | read |
//! | status | input | 2 | 1 | bits (below) | read |
//! | fault code | input | 3 | 1 | u16, valid while the fault bit is set | read |
//! | table checksum | input | 4 | 1 | CRC-16/MODBUS of the staged values | read |
//!
//! | command code | meaning |
//! |---|---|
//! | 1 | move to the commanded position |
//! | 2 | stop |
//! | 3 | clear a latched fault |
//! | 4 | apply the correction table |
//! | 5 | stop applying the correction table |
//! | 6 | load: install the staged table (not yet applied) |
//!
//! | status bit | meaning |
//! |---|---|
//! | 0 | moving |
//! | 1 | in position (settled at the commanded position) |
//! | 2 | fault latched (the fault code register says which) |
//! | 3 | lower travel limit |
//! | 4 | upper travel limit |
//! | 5 | correction table applied |
//!
//! Everything is configurable: the unit id, the encoding
//! ([`PositionEncoding::Counts`] with its counts per degree, or
//! [`PositionEncoding::Float32`] degrees), the [`WordOrder`], every address,
//! the table (input or holding) of the read-only registers, the command codes
//! and the status bit numbers. [`RegisterMap::validate`] refuses maps whose
//! items overlap or whose bits or codes collide. In configuration files
//! (serde, every field optional):
//!
//! ```toml
//! unit_id = 1
//! word_order = "high_first"          # or "low_first"
//! command_position = 0
//! velocity = 2
//! command = 4
//! position_encoding = { kind = "counts", counts_per_degree = 100000.0 }   # or { kind = "float32" }
//! actual_position = { table = "input", address = 0 }                     # or "holding"
//! status = { table = "input", address = 2 }
//! fault_code = { table = "input", address = 3 }
//! [command_codes]
//! move_absolute = 1
//! stop = 2
//! clear_fault = 3
//! correction_enable = 4
//! correction_disable = 5
//! load_table = 6
//! [status_bits]
//! moving = 0
//! in_position = 1
//! fault = 2
//! lower_limit = 3
//! upper_limit = 4
//! correction_enabled = 5
//! [table]
//! header = 10
//! window = 100
//! chunk_rows = 60
//! checksum = { table = "input", address = 4 }
//! ```
//!
//! The velocity uses the position encoding: counts per second with counts,
//! float32 degrees per second with float32. Correction-table values are
//! always float32 degrees (the table's errors, the
//! [`CorrectionTable`](survey_processing::table::CorrectionTable)
//! convention: rows at `i * 360 / n`).
//!
//! # The requests the driver sends
//!
//! | trait method | requests |
//! |---|---|
//! | `move_to(t)` | write multiple (16) of both commanded-position registers; write single (6) of the command register = move |
//! | `readout()` | read (3 or 4) of the two actual-position registers |
//! | `status()` | read of the status register; when the fault bit is set, read of the fault code register |
//! | `stop()`, `clear_fault()`, `enable_correction(b)` | write single (6) of the command register |
//! | `set_velocity(v)` | write multiple (16) of both velocity registers |
//! | `load_correction_table(t)` | write multiple of the header `[rows, columns]`; one write multiple per chunk `[column, first row, values...]` at the window (at most 60 rows, 122 registers, under the 123 a request may carry); read of the checksum register, compared with the CRC computed here; write single of the command register = load |
//!
//! A 32-bit value is always written in one request (a device may refuse a
//! write that covers half of one, and the simulator does).
//!
//! Directional tables are supported: the header says 2 columns and the
//! reverse column follows the forward one. The checksum is CRC-16/MODBUS
//! ([`table_checksum`]) over the value registers in that order (forward rows,
//! then reverse rows), each register high byte first. A checksum that differs
//! is [`ErrorKind::Garbled`](survey_drivers::error::ErrorKind::Garbled): values were
//! lost or changed on the way, loading again may succeed.
//!
//! Status: both limit bits set read as the lower limit. A fault without a
//! code (register 0) is still a fault. The fault's text is built here from
//! the code ([`fault_text`]); the map carries no text.
//!
//! # Errors
//!
//! A Modbus exception is the device's own answer; the error keeps the
//! exception code as [`DriverError::code`](survey_drivers::error::DriverError):
//!
//! | exception | kind | why |
//! |---|---|---|
//! | 0x01 illegal function | Usage | the device lacks a function the map needs |
//! | 0x02 illegal data address | Usage | the map does not match the device |
//! | 0x03 illegal data value | Usage | the value was refused: a target outside the travel, a velocity that is not positive, a table that does not fit, a command in the wrong state (loading while moving, applying without a table) |
//! | 0x04 server device failure | Device | the device failed to execute: a move refused while a fault is latched; `status()` gives the fault code |
//! | 0x05, 0x06, 0x08, others | Device | acknowledge, busy, memory parity, non-standard codes |
//! | 0x0A gateway path unavailable | Disconnected | the gateway cannot reach the device (a link fault) |
//! | 0x0B gateway target failed to respond | Timeout | the device behind the gateway did not answer (a link fault) |
//!
//! The specification says 0x03 is about the structure of a request, not the
//! meaning of a register's value; in practice servo drives use it for
//! out-of-range values, and so does the simulator. Using it for usage errors
//! keeps a refused target apart from a drive fault.
//!
//! Link faults: tokio-modbus client calls have no timeout, so every request
//! runs under [`ModbusTimeouts::request`] (default 1 s); no reply by then is
//! [`ErrorKind::Timeout`](survey_drivers::error::ErrorKind::Timeout). An I/O error or
//! end of stream (also in the middle of a reply) is `Disconnected`; a reply
//! that does not decode, does not match the request (function code, TCP
//! transaction or unit, RTU slave or CRC) or has the wrong length or a
//! non-finite float is `Garbled`. After any link fault the client context is
//! in an unknown state (a reply may still be on its way, a frame half read),
//! so the driver drops it and answers every later call at once with
//! `Disconnected`: the owner builds a new driver to reconnect
//! ([`ModbusPositioner::connect_tcp`], [`ModbusPositioner::connect_rtu`]).
//! Values that cannot be encoded (a non-finite target, a target beyond the
//! 32-bit count range, a table over 65535 rows) are refused before any request
//! with `Usage`, and the session stays open.
//!
//! # What was looked up and what was chosen
//!
//! Looked up:
//!
//! - tokio-modbus 0.17.0 (`slowtec/tokio-modbus`, read in its crate source:
//!   `src/client/mod.rs`, `src/service/{tcp,rtu}.rs`, `src/error.rs`,
//!   `src/frame/mod.rs`, `src/codec/{tcp,rtu}.rs`; and `examples/tcp-server.rs`
//!   found by code search): `Client::call` returns `Result<Result<Response,
//!   ExceptionCode>, Error>`; `Error` is `Transport(io::Error)` or
//!   `Protocol(HeaderMismatch | FunctionCodeMismatch)`; the codecs report a
//!   bad CRC, a bad MBAP protocol id or an undecodable PDU as
//!   `io::ErrorKind::InvalidData`; a stream that ends gives `BrokenPipe` (or
//!   "bytes remaining on stream" when it ends inside a frame); the RTU client
//!   clears its read buffer before each request.
//! - Modbus Application Protocol V1.1b3 (as quoted by the Kepware, CODESYS and
//!   rodbus documentation found by search): the exception codes and their
//!   meanings, at most 125 registers per read and 123 per write-multiple.
//! - 32-bit values in two registers: vendors differ in word order ("ABCD"
//!   big-endian versus "CDAB" word swap; Vaisala documents the low word first
//!   as the "Modicon" order and asks that a 32-bit value be read and written
//!   in one transaction; modbus.maxenergic.com's float32 byte-order notes),
//!   hence a configurable word order and whole-value writes.
//! - CRC-16/MODBUS (polynomial 0xA001 reflected, initial 0xFFFF; check value
//!   0x4B37), the same CRC tokio-modbus uses for RTU frames.
//! - CiA 402 error code 0x8611 "following error" (the code the simulated
//!   positioner trips with, see `survey_sims`).
//!
//! Chosen (no public positioner register map was found; this is the
//! project's own, in the style of servo drives): every address, the command
//! codes, the status bits, counts at 100000 per degree, velocity in the
//! position's encoding, the table block (header, window with column and first
//! row, checksum register, load command), and the exception classes above.

mod driver;
mod line;
mod map;
mod rtu;

pub use driver::{ModbusPositioner, ModbusTimeouts, exception_kind, exception_name, link_error_kind};
pub use map::{
    CommandCodes, DEFAULT_COUNTS_PER_DEGREE, Item, Location, MAX_CHUNK_ROWS, MAX_READ_REGISTERS, MAX_WRITE_REGISTERS,
    MapError, PositionEncoding, RegisterMap, RegisterTable, Span, StatusBits, TableBlock, ValueError,
    WINDOW_HEADER_WORDS, WordOrder, crc16_modbus_bytes, fault_code_register, fault_text, table_checksum,
};
pub use rtu::rtu_response_len;
/// The tokio-modbus types the simulator and tests share with the driver.
pub use tokio_modbus::{ExceptionCode, Request, Response};
