//! Moeller-Wedel ELCOMAT autocollimator over RS-232: a sans-IO codec and an
//! async driver generic over its byte transport.
//!
//! # The protocol as implemented
//!
//! Link: RS-232, 8 data bits, no parity, 1 stop bit, no flow control; the baud
//! rate is the caller's (the instrument's setting).
//!
//! | direction | bytes | meaning |
//! |---|---|---|
//! | host -> instrument | `a` CR LF | one absolute measurement |
//! | host -> instrument | `r` CR LF | one relative measurement (relative to the zero stored in the instrument) |
//! | instrument -> host | `4 003 <x> <y>` CR LF | absolute reading, X and Y valid |
//! | instrument -> host | `2 103 <x> <y>` CR LF | relative reading, X and Y valid |
//! | instrument -> host | `4 000` CR LF / `2 100` CR LF | no reflection (the simulator's convention, see below) |
//!
//! A reply is `<type> <status> [<x> <y>]`: fields separated by ASCII
//! whitespace; `<type>` is `4` (absolute) or `2` (relative); `<status>` is
//! exactly three digits whose last digit tells which axes are valid (`1` X,
//! `2` Y, `3` both, `0` none); `<x>` and `<y>` are signed decimals in
//! arcseconds (`-12.35`). A reply whose validity digit is not 3 is the
//! instrument saying it has no (complete) reading: the driver reports it as a
//! [`ErrorKind::Device`] error whose code is the status field as an integer
//! (`4 000` -> code 0, `2 100` -> code 100), and [`Autocollimator::status`]
//! answers [`AcState::NoReflection`] for it.
//!
//! ## What was looked up
//!
//! No Moeller-Wedel manual or interface description was found in the searched
//! documentation. What is here comes from third-party code that talks to real
//! units:
//!
//! - LNLS (James Citadini), Python module "Elcomat communication" (several
//!   copies found by code search; the index did not name their repository):
//!   serial 8N1; commands `a` (absolute) and `r` (relative) sent with CR LF;
//!   accepted replies are exactly `4 003 <x> <y>` after `a` and `2 103 <x> <y>`
//!   after `r`, split on CR; the values are arcseconds (converted to degrees
//!   by /3600 and to radians by /206264.8).
//! - Diamond Light Source EPICS support, `dls-controls/elcomat3000`
//!   (`elcomat3000App/src/elcomat3000.cpp`, `etc/simulations/elcomat3000.py`)
//!   and `dls-controls/ADElcomat` (`ADElcomatApp/src/ADElcomat.cpp`,
//!   `etc/simulations/elcomat.py`): commands are sent with LF and replies are
//!   read up to CR; the second field is a status whose third digit means
//!   `1` = X valid, `2` = Y valid, `3` = both valid; `A` / `R` start
//!   continuous output (types `3 003` / `1 103`), `s` stops it, `d` returns a
//!   type-8 device-information line; values in arcseconds.
//!
//! ## What was chosen here (not documented by what was found)
//!
//! - The reply to a measurement with no reflection. By the DLS reading of the
//!   status digit, "nothing valid" is a validity digit of 0; the simulator
//!   answers `4 000` (after `a`) or `2 100` (after `r`) with no value fields.
//!   The decoder also accepts value fields after an invalid status (ignored,
//!   but they must be numbers), in case a real unit sends them. A partially
//!   valid reply (validity 1 or 2) is a device error too: the trait needs both
//!   axes.
//! - No zero-setting command: none was found (`s` is "stop continuous
//!   output" in the DLS code, not "set zero"), so only `a` and `r` are sent.
//!   The simulator's relative zero is part of its configuration.
//! - Line ends: commands are sent with CR LF (as LNLS does); replies may end
//!   in CR LF, a lone LF or a lone CR (DLS reads up to CR). Empty and blank
//!   lines are skipped. A line longer than [`MAX_LINE`] bytes without a line
//!   end is garbled; the rest of it, up to the next line end, is discarded.
//! - Values are printed with [`REPLY_DECIMALS`] decimals (0.01 arcsec).
//! - The streaming (`A`/`R`/`s`) and device-information (`d`) commands are
//!   not used.
//!
//! # The driver
//!
//! [`ElcomatDriver`] runs over any `AsyncRead + AsyncWrite` byte transport (a
//! [`tokio_serial::SerialStream`] from [`ElcomatDriver::open_serial`], a pty,
//! an in-memory duplex). Every request has its own deadline (default
//! [`DEFAULT_TIMEOUT`], 2 s), measured on the real clock because a real
//! instrument can hang. Before each request it discards stale input: bytes
//! already waiting on the transport, complete replies not yet taken, and (if
//! a line was cut in the middle) the rest of that line, so that a late reply
//! to a request that timed out is not taken as the answer to the next one. A
//! reply of the other type (an absolute reply while waiting for a relative
//! one) is discarded as stale too. The protocol has no sequence numbers, so a
//! late reply of the right type that arrives after the next request was sent
//! cannot be told from the answer: keep the timeout above the instrument's
//! worst reply time.
//!
//! Faults: no reply within the deadline -> [`ErrorKind::Timeout`]; end of
//! file or an I/O error -> [`ErrorKind::Disconnected`] (also when part of a
//! line had arrived: a truncated line followed by a closed port is a
//! disconnection, not a garbled frame); a line that does not decode ->
//! [`ErrorKind::Garbled`] (the receive buffer is discarded; the next request
//! works normally); an out-of-range reply -> [`ErrorKind::Device`] with the
//! device's status code.
//!
//! # Layout
//!
//! - `codec`: the sans-IO codec (commands, replies, the line framing and the
//!   incremental [`Decoder`] and [`CommandDecoder`]);
//! - `driver`: [`ElcomatDriver`], the [`Autocollimator`] driver over a byte
//!   transport.
//!
//! Everything public is re-exported here: use `survey_drivers::elcomat::...`.

// Names the documentation above links to.
#[cfg(doc)]
use crate::error::ErrorKind;
#[cfg(doc)]
use crate::traits::{AcState, Autocollimator};

mod codec;
mod driver;
#[cfg(test)]
mod tests;

pub use codec::*;
pub use driver::*;
