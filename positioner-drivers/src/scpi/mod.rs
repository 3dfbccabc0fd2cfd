//! SCPI-style positioner controllers (MI Technologies MI-4190 / MI-4192 style):
//! a sans-IO codec and a [`Positioner`] driver over any byte stream (TCP,
//! serial through `tokio-serial`, an in-memory pipe).
//!
//! # The protocol as implemented
//!
//! ASCII lines. The driver ends every line with LF; it accepts replies ended
//! by LF or CR LF. `<c>` is the controller number and `<a>` the axis number
//! (both 1 by default, see [`Address`]). Numbers go out as the shortest
//! decimal that reads back to the same `f64` (`-90`, `45.125`, or with an
//! exponent, `1.5E-300`, when the plain form would be longer than 24
//! characters), so a target read back is bit-for-bit the target sent.
//!
//! | request | reply | meaning | source |
//! |---|---|---|---|
//! | `CONT<c>:AXIS(<a>):POS:COMM <deg>` | none | commanded (target) position | looked up |
//! | `CONT<c>:AXIS(<a>):POS:COMM?` | `<deg>` | the commanded position | looked up |
//! | `CONT<c>:AXIS(<a>):MOT:STAR` | none | start the move to the commanded position | looked up |
//! | `CONT<c>:AXIS(<a>):MOT:STOP` | none | stop the axis | looked up |
//! | `CONT<c>:AXIS(<a>):POS:CURR?` | `<deg>` | current position (the readout) | looked up |
//! | `CONT<c>:AXIS(<a>):VEL:CURR?` | `<deg/s>` | current velocity (0 at rest) | looked up |
//! | `CONT<c>:AXIS(<a>):STAT?` | `<integer>` | the axis status word (bits below) | looked up |
//! | `CONT<c>:AXIS(<a>):UNIT:POS?` | `<code>` | position units (6 = degree; checked once per connection) | looked up |
//! | `CONT<c>:AXIS(<a>):VEL:COMM <deg/s>` | none | velocity of the following moves | chosen (unverified) |
//! | `CONT<c>:AXIS(<a>):FAUL:CLE` | none | clear a latched axis fault | chosen (unverified) |
//! | `CONT<c>:AXIS(<a>):CORR:TABL:CLE` | none | empty the table being loaded | chosen |
//! | `CONT<c>:AXIS(<a>):CORR:TABL <n>,<v>,<v>...` | none | write forward-column values from row `n` (0-based) on | chosen |
//! | `CONT<c>:AXIS(<a>):CORR:TABL:REV <n>,<v>...` | none | the same for the reverse column of a directional table | chosen |
//! | `CONT<c>:AXIS(<a>):CORR:TABL:POIN?` | `<count>` | rows held in the forward column (`:REV:POIN?` for reverse) | chosen |
//! | `CONT<c>:AXIS(<a>):CORR:TABL:LOAD` | none | install the rows as the correction table (not yet applied) | chosen |
//! | `CONT<c>:AXIS(<a>):CORR:STAT ON\|OFF` | none | apply (or stop applying) the table in the feedback path | chosen |
//! | `CONT<c>:AXIS(<a>):CORR:STAT?` | `1\|0` | whether the table is applied | chosen |
//! | `SYST:ERR:ALL?` | `<code>, "<text>"[, ...]` | every entry of the error queue; `0, "No error"` when empty (the default error query) | looked up |
//! | `SYST:ERR?` | `<code>,"<text>"` | pop the oldest entry of the error queue (`error_query = "next"`) | SCPI-99 |
//! | `*CLS` | none | clear the error queue | IEEE 488.2, seen in use |
//! | `*IDN?` | `<maker>,<model>,<serial>,<firmware>` | identification | IEEE 488.2, seen in use |
//!
//! Table rows are correction-table errors in degrees at the readouts
//! `i * 360 / n` (the [`CorrectionTable`] convention); a row `n` beyond the
//! rows already held is refused (`-222`). `CORR:TABL:LOAD` refuses a table of
//! fewer than 2 rows or with columns of different lengths (`-221`).
//!
//! ## The status word (`STAT?`)
//!
//! | bit | meaning | used by the driver | source |
//! |---|---|---|---|
//! | 0 | latch set | no | looked up |
//! | 1 | home switch active | no | looked up |
//! | 2 | reverse limit active | [`Limit::Lower`] | looked up |
//! | 3 | forward limit active | [`Limit::Upper`] | looked up |
//! | 4 | PAU (power amplifier) fault | fault | looked up |
//! | 5 | axis enabled | no | looked up |
//! | 6 | error limit active (following-error limit) | fault | looked up |
//! | 7 | axis in motion | `moving` | looked up |
//! | 8 | axis active | no | looked up |
//! | 9 | axis indexed | no | looked up |
//! | 10 | position trigger active | no | looked up |
//! | 11 | property changed | no | looked up |
//! | 12 | status changed | no | looked up |
//! | 13-15 | unused | no | looked up |
//!
//! The word has no in-position bit (an earlier version of this driver read
//! bit 13, which the manual lists as unused: every move on a real controller
//! would have timed out). The driver decides: in position when bit 7 (in
//! motion) is clear, no fault bit is set, and `POS:CURR?` is within
//! [`ScpiConfig::in_position_window_deg`] (0.01 deg by default) of the
//! position last commanded; after `MOT:STOP`, or before any move, at rest is
//! in position. Public code waits for `VEL:CURR?` = 0 instead; both end a move
//! at the same moment on the simulator. `correction_enabled` is what the
//! driver last set with `CORR:STAT`.
//!
//! ## Commands the public record does not show
//!
//! `VEL:COMM`, `FAUL:CLE` and the `CORR:` subsystem are this project's
//! guesses, implemented by the simulator and unverified on hardware. They
//! are sent only with [`ScpiConfig::unverified_commands`] (configuration key
//! `unverified_commands = true`); otherwise `set_velocity`,
//! `load_correction_table` and `enable_correction` are usage errors that say
//! what to do instead (load the table the controller's own way from the files
//! `survey process` writes), and `clear_fault` only sends `*CLS`.
//!
//! ## Errors
//!
//! Commands have no reply, so after every command the driver asks the error
//! query (`SYST:ERR:ALL?` by default, as public code for MI controllers does;
//! `SYST:ERR?` with `error_query = "next"`). It sends `*CLS` in the same write
//! before the command, so the entries read back are the command's own and
//! never stale ones. A non-zero code
//! becomes a [`DriverError`] carrying the code, with the controller's text as
//! the message. The class follows the SCPI-99 code ranges:
//!
//! - [`ErrorKind::Usage`] (the request itself is wrong, retrying fails the same
//!   way): `-100..=-199` (command errors: syntax, undefined header, wrong
//!   axis suffix `-114`, missing parameter...) and `-220..=-229` (parameter
//!   errors: `-221` settings conflict, e.g. loading a table while moving;
//!   `-222` data out of range, e.g. a target outside the travel or a velocity
//!   that is not positive; `-223` too much data; `-224` illegal value).
//! - [`ErrorKind::Device`] for every other code: `-200` execution error,
//!   `-24x` hardware errors, `-3xx` device-specific errors and the
//!   controller's own positive codes (drive faults).
//!
//! When `STAT?` shows a fault bit (4 or 6), the driver reads the error queue
//! until it answers 0 and reports the newest device-class entry as
//! [`PositionerStatus::fault`]. The entry is remembered while the fault bit
//! stays set, because the queue gives each entry out only once; if it was
//! never seen (another client read it), the fault carries code
//! [`DEVICE_SPECIFIC_ERROR`] (`-300`) and a text naming the status bits.
//!
//! ## Link faults
//!
//! Every request (one write of its lines and, for a query, one reply line)
//! runs under its own deadline, [`ScpiTimeouts::request`] (2 s by default):
//!
//! - no reply by then: [`ErrorKind::Timeout`];
//! - end of stream or an I/O error: [`ErrorKind::Disconnected`]. The driver
//!   then fails every later call at once with `Disconnected`: build a new
//!   one to reconnect;
//! - a reply line with a non-ASCII or control byte, longer than
//!   [`Decoder::DEFAULT_MAX_LINE`], or not the number, status word or error
//!   entry expected: [`ErrorKind::Garbled`]. The line is consumed, so the
//!   next request is in step again.
//!
//! Before each request the driver drops whatever input is already waiting
//! (lines and partial lines), so a late reply is never taken for the next
//! request's answer. After a timeout it drains the line for as long as the
//! controller may still answer ([`ScpiTimeouts::late_window`]) before it
//! reports the timeout. A partial
//! line dropped this way makes the decoder skip everything up to the next LF,
//! so its tail cannot pass for a reply either.
//!
//! A correction table is sent in chunks of [`ScpiConfig::table_chunk`] rows
//! after `CORR:TABL:CLE`, all in one write followed by one `SYST:ERR?`, then
//! the driver reads `CORR:TABL:POIN?` (and `:REV:POIN?`) back: a count other
//! than the rows sent means rows were lost on the way ([`ErrorKind::Garbled`],
//! a link fault: loading again may succeed), and only then sends
//! `CORR:TABL:LOAD`.
//!
//! # What was looked up and what was chosen
//!
//! Looked up (no MI Technologies manual is public; these come from two public
//! MATLAB programs that drive real MI-4190/4192 controllers over GPIB):
//!
//! - `github.com/csun-rf-lab/antennameasure`, `+MotionController/MI4190.m`:
//!   `CONT1:AXIS(%d):POS:COMM %f` then `CONT1:AXIS(%d):MOT:STAR` to move,
//!   `POS:COMM?` read back, `POS:INCR`, `MOT:STOP`, `POS:CURR?`, `VEL:CURR?`,
//!   `STAT?` (a 16-bit integer; its comment copies the bit table of "page
//!   3-42 of the MI-4192 manual": the bits 0 to 12 above, 13 to 15 unused),
//!   `UNIT:POS?` (6 = degrees), `POS:LIM:FORW?`/`REV?`, `SYST:ERR:COUN`,
//!   `SYST:ERR:ALL?` (comment: `0, "No error"`), `*CLS`, `*IDN?`,
//!   `CONT1:ABORT`, and its PAU-fault test on bit 4.
//! - `github.com/Ugikie/PositionControl`: the same move, stop and position
//!   commands, and a logged session: `*IDN?` answered
//!   `M. I. Technologies,Model 4192/4195,0,4.2.1`, and `STAT?` at rest
//!   answered `4865` (bits 0, 8, 9, 12: latch, active, indexed, status
//!   changed), through a Prologix GPIB adapter that ends replies with CR LF.
//! - SCPI-99 (the standard error queue `SYST:ERR?`, `<code>,"<text>"`, and the
//!   standard codes -100 to -350 used here; also as listed by the `scpi`
//!   crate's `ErrorCode` on docs.rs).
//!
//! - `github.com/csun-rf-lab/antennameasure`, `+MotionController/MI4190.m`:
//!   the status-bit table "from page 3-42 of the MI-4192 manual" (bits 13-15
//!   unused), `UNIT:POS?` (6 = degree), `SYST:ERR:ALL?` answered
//!   `0, "No error"`, `SYST:ERR:COUN`, `*CLS`, `VEL:CURR?`, `MOT:STOP`,
//!   `CONT1:ABORT` (the recorded-exchange test
//!   `the_public_record_parses_as_our_codec_reads_it` replays them).
//!
//! Chosen (no public documentation found, designed in the same style, sent
//! only with `unverified_commands`): `VEL:COMM`, `FAUL:CLE`, the whole `CORR:`
//! subsystem; also LF as the terminator sent, which codes mean usage, and the
//! drain/`*CLS`/error-query discipline above.
//!
//! # Layout
//!
//! - `codes`: the controller's error codes and the `STAT?` status word;
//! - `codec`: the sans-IO codec (numbers, the status word, error entries,
//!   commands, the line [`Decoder`]);
//! - `driver`: [`ScpiPositioner`], the [`Positioner`] driver over a byte
//!   stream.
//!
//! Everything public is re-exported here: use `survey_positioner_drivers::scpi::...`.

// Names the documentation above links to.
#[cfg(doc)]
use survey_drivers::error::{DriverError, ErrorKind};
#[cfg(doc)]
use survey_drivers::traits::{Limit, Positioner, PositionerStatus};
#[cfg(doc)]
use survey_processing::table::CorrectionTable;

mod codec;
mod codes;
mod driver;
#[cfg(test)]
mod tests;

pub use codec::*;
pub use codes::*;
pub use driver::*;
