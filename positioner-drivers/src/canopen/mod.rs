//! CANopen (CiA 301) servo drives in CiA 402 profile position mode: a
//! [`Positioner`](survey_drivers::traits::Positioner) driver over a frame-bus trait,
//! with an in-memory bus for tests and a SocketCAN adapter for hardware.
//!
//! # Layers
//!
//! | module | what | I/O |
//! |---|---|---|
//! | [`frame`] | [`CanFrame`] (11-bit id, 0-8 bytes) and the [`CanBus`] trait | trait only |
//! | [`sdo`] | SDO frame codec, abort codes, segmenting and reassembly | none (sans-IO) |
//! | [`nmt`] | NMT node control and heartbeat frames | none (sans-IO) |
//! | [`objects`] | CiA 402 objects, controlword/statusword, state machine, table domain | none (sans-IO) |
//! | [`client`] | [`SdoClient`]: upload/download with deadlines, aborts, late frames drained | over [`CanBus`] |
//! | [`cia402`] | [`Cia402Positioner`]: the `Positioner` trait | over [`CanBus`] |
//! | [`memory_bus`] | [`MemoryBus`]: a broadcast bus in memory (tests, simulation) | tokio channels |
//! | [`socketcan_bus`] | [`SocketCanBus`]: Linux SocketCAN | `AF_CAN` socket |
//!
//! The simulated drive that answers all of this is
//! `survey_sim_servers::canopen_node`.
//!
//! # The protocol as implemented
//!
//! ## COB-IDs
//!
//! | COB-ID | frame |
//! |---|---|
//! | `0x000` | NMT node control: `[cs, node]`; cs `0x01` start, `0x02` stop, `0x80` enter pre-operational, `0x81` reset node, `0x82` reset communication; node 0 = all |
//! | `0x580 + node` | SDO response (server to client) |
//! | `0x600 + node` | SDO request (client to server) |
//! | `0x700 + node` | heartbeat / boot-up: `[state]`; `0x00` boot-up, `0x04` stopped, `0x05` operational, `0x7F` pre-operational |
//!
//! ## SDO frames (always 8 data bytes)
//!
//! Byte 0 is the command: bits 7-5 the command specifier, then per frame
//! kind. Bytes 1-2 are the index (little-endian), byte 3 the sub-index,
//! bytes 4-7 data, size or abort code (little-endian).
//!
//! | frame | byte 0 | bytes 1-7 |
//! |---|---|---|
//! | initiate download request | `001 0 nn e s` (ccs 1) | index, sub, expedited data (4 - n bytes) or size |
//! | initiate download response | `011 00000` (scs 3) | index, sub |
//! | download segment request | `000 t nnn c` (ccs 0) | 7 - n data bytes |
//! | download segment response | `001 t 0000` (scs 1) | - |
//! | initiate upload request | `010 00000` (ccs 2) | index, sub |
//! | initiate upload response | `010 0 nn e s` (scs 2) | index, sub, expedited data or size |
//! | upload segment request | `011 t 0000` (ccs 3) | - |
//! | upload segment response | `000 t nnn c` (scs 0) | 7 - n data bytes |
//! | abort (either way) | `100 00000` (cs 4) | index, sub, abort code (u32) |
//!
//! `e` expedited, `s` size indicated, `n` unused bytes, `t` toggle (0 on the
//! first segment, alternating; a response carries its request's), `c` last
//! segment. Data of 1 to 4 bytes goes expedited; longer (or empty) data is
//! segmented with the size indicated. Block transfer (cs 5, 6) is not used
//! and decodes as an error.
//!
//! ## Failures and how they are classified
//!
//! | what happens | [`ErrorKind`](survey_drivers::error::ErrorKind) | the client also |
//! |---|---|---|
//! | no response within [`SdoTimeouts::response`] (default 500 ms) | `Timeout` | sends abort `0x0504_0000`, drains late frames for [`SdoTimeouts::late_window`] |
//! | response not 8 bytes, unknown specifier, wrong kind | `Garbled` | sends abort `0x0504_0001` |
//! | initiate response or abort naming another object (a late response) | discarded, logged | waits on for its own |
//! | toggle bit not alternated | `Garbled` | sends abort `0x0503_0000` |
//! | segments do not add up to the indicated size | `Garbled` | sends abort `0x0607_0012` / `0x0607_0013` |
//! | abort from the node | `Device` with the code, or `Usage` (see [`sdo::abort_kind`]: value range `0x0609_003x`, device state `0x0800_0022`, no data `0x0800_0024`) | - |
//! | bus error | `Disconnected` | - |
//!
//! The message of an abort error carries the code in hex and its standard
//! text (`SDO abort 0x06090030 (Value range of parameter exceeded (only for
//! write access)) in the SDO download of 0x607A:00 (4 bytes)`); the code is
//! in [`DriverError::code`](survey_drivers::error::DriverError::code).
//!
//! ## CiA 402 objects used
//!
//! | object | type | use |
//! |---|---|---|
//! | `0x1008` | visible string | device name ([`Cia402Positioner::device_name`], segmented) |
//! | `0x603F` | u16 | error code of the fault |
//! | `0x6040` | u16 | controlword |
//! | `0x6041` | u16 | statusword |
//! | `0x6060` | i8 | modes of operation, written 1 (profile position) |
//! | `0x6064` | i32 | position actual value: the readout, counts |
//! | `0x607A` | i32 | target position, counts |
//! | `0x6081` | u32 | profile velocity, counts per second |
//! | `0x60FD` | u32 | digital inputs: bit 0 negative, bit 1 positive limit switch |
//! | `0x2100` | domain | correction table (this project's layout, below), only with [`CanopenConfig::correction_objects`] |
//! | `0x2101` | u8 | correction applied (0/1), only with [`CanopenConfig::correction_objects`] |
//! | `0x2102` | visible string | text of the latched fault, when the drive has it ([`CanopenConfig::fault_text_index`]) |
//!
//! Status, enable, moves and limits use the CiA 301/402 objects only, which
//! every CiA 402 drive has. 0x2100-0x2102 are this project's own layout in
//! the manufacturer-specific range, which a drive may lack or use otherwise
//! (SDO abort 0x06020000): the correction objects are used only when the
//! configuration says the drive has them (`correction_objects = true`;
//! without, loading and switching the correction table is refused as bad
//! usage), and a missing fault-text object falls back to the code's text.
//!
//! Counts per degree are configured ([`CanopenConfig::counts_per_degree`],
//! default 100 000); velocity units are counts per second.
//!
//! The driver walks the state machine with the controlword: shutdown `0x06`
//! (switch on disabled -> ready to switch on), switch on `0x07` (-> switched
//! on), enable operation `0x2F` (-> operation enabled; bit 5 "change set
//! immediately" rides along). A move writes 0x607A, then controlword `0x3F`
//! (the rising edge of bit 4, new set-point), reads the statusword until bit
//! 12 (set-point acknowledge), and writes `0x2F` again so the next move has
//! its own rising edge. `stop()` sets bit 8 (halt, `0x12F`), which keeps the
//! drive in operation enabled; `clear_fault()` sends the rising edge of bit 7
//! (`0x80`) and enables again.
//!
//! Status: `moving` = operation enabled and not target reached (bit 10);
//! `in_position` = target reached; `fault` = bit 3, with the code of 0x603F
//! and the text of 0x2102 (or the code's standard text); `limit` = bit 11
//! (internal limit active) refined by 0x60FD bits 0/1; `correction_enabled`
//! = 0x2101 with the correction objects, else false.
//!
//! The correction table domain (0x2100): `u16` rows `n` (2..=8192), `u8`
//! flags (bit 0: a reverse column follows), `u8` 0, then `n` forward values
//! and (directional) `n` reverse values as `f32`, all little-endian. Values
//! are rounded to `f32` (about 7 significant digits: far below the
//! hundredths of a degree being corrected).
//!
//! # What was looked up, and where
//!
//! - SDO command specifiers, bit layout, toggle and size rules:
//!   `christiansandberg/canopen` (`canopen/sdo/constants.py`,
//!   `canopen/sdo/server.py`: `REQUEST_*`/`RESPONSE_*` specifiers,
//!   `EXPEDITED = 0x2`, `SIZE_SPECIFIED = 0x1`, `TOGGLE_BIT = 0x10`,
//!   `NO_MORE_DATA = 0x1`, n in bits 2-3 / 1-3, toggle mismatch aborted with
//!   `0x05030000`); `heig-vd-iai/canopen-stack` `src/sdo/frames.md` (frame
//!   diagrams).
//! - Abort codes and texts: `christiansandberg/canopen`
//!   `canopen/sdo/exceptions.py`, `Daxbot/node-canopen` `src/protocol/SDO.js`
//!   and CANopenNode `CO_SDOserver.h` (which words 0x06090030 as "Invalid
//!   value for parameter (download only)"; CiA 301's wording, used here, is
//!   "Value range of parameter exceeded").
//! - CiA 402 state machine, statusword masks and controlword commands:
//!   `christiansandberg/canopen` `canopen/profiles/p402.py` (`SW_MASK`,
//!   `CW_*`, transition table); profile position bits 4, 5, 8, 10, 12 from
//!   drive manuals (LTi ServoOne CANopen/EtherCAT manual 9.4, Synapticon
//!   SOMANET profile position mode, ABB FECA-01); 0x60FD bits 0-2 from the
//!   Novanta Everest/Capitan object reference; error codes 0x603F from
//!   `marel-keytech/openCANopen` `inc/canopen/cia402-error-codes.h`.
//! - SocketCAN: `socketcan` 4.0 source (`src/tokio.rs`: `CanSocket::open`,
//!   `write_frame`, `read_frame`, `try_read_frame`; `src/frame.rs`:
//!   `CanFrame::{Data, Remote, Error}`) and its docs.rs example
//!   `examples/tokio_send.rs` (`CanFrame::new(StandardId::new(..), &data)`).
//!
//! # Chosen here (not from a standard)
//!
//! - The objects 0x2100-0x2102 and the table layout.
//! - Which abort codes are `Usage` (see above).
//! - A per-frame response deadline (not a whole-transfer one): each frame
//!   of a long segmented transfer gets [`SdoTimeouts::response`].
//! - `move_to` enables a drive that is not in operation enabled (not
//!   faulted) before the move; a faulted drive refuses the move with its
//!   fault as a `Device` error, as the simulated positioner does.
//! - `stop()` uses halt rather than quick stop, so the drive stays in
//!   operation enabled and reports target reached when stopped.
//! - An expedited upload response without size indication (`e = 1, s = 0`)
//!   carries 4 bytes; for an object of known size the driver takes the first
//!   bytes ([`SdoClient::upload_exact`]).
//!
//! # Not done
//!
//! PDOs, SYNC and the heartbeat consumer are not used: the status is polled
//! by SDO (a few milliseconds per read on a real 1 Mbit/s bus). Emergency
//! frames (`0x080 + node`) are ignored; the fault comes from 0x603F. Block
//! transfer is not supported: a node must serve objects over 4 bytes by
//! segmented transfer.

pub mod cia402;
pub mod client;
pub mod frame;
pub mod memory_bus;
pub mod nmt;
pub mod objects;
pub mod sdo;
pub mod slcan;
pub mod socketcan_bus;

pub use cia402::{CW_OPERATE, CanopenConfig, Cia402Positioner, DEFAULT_COUNTS_PER_DEGREE, DriveMemory, SetUp};
pub use client::{SdoClient, SdoTimeouts};
pub use frame::{CanBus, CanFrame, FrameError};
pub use memory_bus::{MemoryBus, MemoryEndpoint};
pub use nmt::{NmtCommand, NmtState};
pub use objects::{DriveCommand, DriveState, Statusword};
pub use socketcan_bus::SocketCanBus;
