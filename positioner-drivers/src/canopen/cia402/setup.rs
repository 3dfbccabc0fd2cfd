//! A connection's set-up, request by request, and what a survey's
//! connections know of the drive across reconnects ([`DriveMemory`]).
//!
//! Bringing a CiA 402 drive up takes about ten SDO exchanges (NMT start,
//! 0x6060 written and 0x6061 read back, then the controlword steps of the
//! state machine, each followed by statusword reads). At a few faults in a
//! hundred replies a set-up redone in full on every reconnect fails more
//! often than not. So:
//!
//! - every request of a set-up is asked again in place on a link fault the
//!   bus survives (no reply, a garbled reply) or a refusal of the drive (an
//!   SDO abort classed as a device fault), up to [`SETUP_REQUEST_TRIES`]
//!   times, each logged; a lost port (the adapter closed it) ends the
//!   set-up at once, as no request can be asked on it again;
//! - the set-up is done in full once; a reconnect after it only sends NMT
//!   start (no reply is awaited) and reads the statusword: a drive that
//!   shows a state this host brought it to (or a fault, or a step of the
//!   enable sequence: the next move enables it, a fault is cleared by the
//!   engine's recovery) is taken as it is; one that shows "switch on
//!   disabled" or no valid state was reset meanwhile, and gets the full
//!   set-up again;
//! - a drive found in fault during the set-up is not refused: the
//!   connection is open, the fault is the next request's (a move refused
//!   with its code), and clearing it is the engine's recovery. Refusing the
//!   connection would leave nothing to send the fault reset on.

use super::{Cia402Positioner, DriveState, NmtCommand, Statusword, index};
use crate::canopen::frame::CanBus;
use std::sync::Mutex;
use survey_drivers::error::{DriverError, ErrorKind, Result};

/// How many times one request of a set-up is asked before its fault is the set-up's.
pub const SETUP_REQUEST_TRIES: u32 = 3;

/// What the connections to one drive know of it: whether this host has
/// selected profile position mode and walked the state machine (the full
/// set-up). Shared by the connector across reconnects (one per survey
/// process: a new process sets the drive up in full once).
#[derive(Debug, Default)]
pub struct DriveMemory {
    set_up: Mutex<bool>,
}

impl DriveMemory {
    /// Nothing known yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Whether the drive was set up in full by an earlier connection.
    pub fn is_set_up(&self) -> bool {
        *self.set_up.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn remember(&self, set_up: bool) {
        *self.set_up.lock().unwrap_or_else(|e| e.into_inner()) = set_up;
    }
}

/// How a connection was set up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SetUp {
    /// In full: mode selected, state machine walked to operation enabled.
    Full,
    /// In full, but the drive is in fault (the mode is selected; clearing
    /// the fault enables it).
    Faulted,
    /// The drive's state was known: only NMT start and the statusword.
    Rechecked,
}

/// Whether a set-up request that failed with `e` is asked again: a link
/// fault the bus survives or the drive's refusal, not bad usage and not a
/// lost port.
fn asked_again(e: &DriverError) -> bool {
    matches!(e.kind, ErrorKind::Timeout | ErrorKind::Garbled | ErrorKind::Device)
}

impl<B: CanBus> Cia402Positioner<B> {
    /// Set the connection up, in full or (with the drive's state known from
    /// an earlier connection of `memory`) by re-checking the statusword
    /// only; each request asked again on a link fault or a refusal (module
    /// documentation).
    pub async fn set_up(&mut self, memory: &DriveMemory) -> Result<SetUp> {
        self.nmt(NmtCommand::Start).await?;
        if memory.is_set_up() {
            let word = self.setup_statusword().await?;
            match word.state() {
                Some(DriveState::SwitchOnDisabled | DriveState::NotReadyToSwitchOn) | None => {
                    tracing::info!(
                        instrument = %self.name, %word,
                        "the drive was reset since the last connection: setting it up in full"
                    );
                    memory.remember(false);
                }
                Some(_) => {
                    tracing::debug!(instrument = %self.name, %word, "reconnected: the drive's state is known");
                    return Ok(SetUp::Rechecked);
                }
            }
        }
        self.select_profile_position().await?;
        let word = self.setup_statusword().await?;
        if word.fault() {
            tracing::warn!(
                instrument = %self.name, %word,
                "the drive is in fault: connected, the fault is reported by the next request and cleared by the \
                 engine's recovery"
            );
            memory.remember(true);
            return Ok(SetUp::Faulted);
        }
        self.enable_state_machine().await?;
        memory.remember(true);
        tracing::info!(instrument = %self.name, "set up in full: profile position mode, operation enabled");
        Ok(SetUp::Full)
    }

    /// One request of a set-up: asked again up to [`SETUP_REQUEST_TRIES`]
    /// times while it fails with a link fault the bus survives or a refusal.
    async fn setup_request(&mut self, index: u16, write: Option<&[u8]>, len: usize) -> Result<Vec<u8>> {
        let mut tries = 1;
        loop {
            let result = match write {
                Some(data) => self.sdo.download(&mut self.bus, index, 0, data).await.map(|()| Vec::new()),
                None => self.sdo.upload_exact(&mut self.bus, index, 0, len).await,
            };
            match result {
                Err(e) if tries < SETUP_REQUEST_TRIES && asked_again(&e) => {
                    tracing::warn!(
                        instrument = %self.name, error = %e, kind = %e.kind, tries,
                        "a set-up request failed: asked again"
                    );
                    tries += 1;
                }
                result => return result,
            }
        }
    }

    /// Read an object of `len` bytes as a set-up request.
    pub(super) async fn setup_read(&mut self, index: u16, len: usize) -> Result<Vec<u8>> {
        self.setup_request(index, None, len).await
    }

    /// Write an object as a set-up request.
    pub(super) async fn setup_write(&mut self, index: u16, data: &[u8]) -> Result<()> {
        self.setup_request(index, Some(data), data.len()).await.map(drop)
    }

    /// The statusword as a set-up request.
    pub(super) async fn setup_statusword(&mut self) -> Result<Statusword> {
        let bytes = self.setup_read(index::STATUSWORD, 2).await?;
        Ok(Statusword(u16::from_le_bytes([bytes[0], bytes[1]])))
    }

    /// Write the controlword as a set-up request (writing the same word
    /// twice is no new edge: asking again is safe).
    pub(super) async fn setup_controlword(&mut self, word: u16) -> Result<()> {
        self.setup_write(index::CONTROLWORD, &word.to_le_bytes()).await?;
        self.controlword = Some(word);
        Ok(())
    }
}

#[cfg(test)]
mod tests;
