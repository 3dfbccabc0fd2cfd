//! NMT (network management, CiA 301), sans-IO: the node-control frame on
//! COB-ID 0x000 and the heartbeat / boot-up frame on `0x700 + node`.

use super::frame::CanFrame;

/// COB-ID of NMT node control.
pub const NMT_COB_ID: u16 = 0x000;
/// COB-ID base of heartbeat and boot-up frames: `0x700 + node`.
pub const HEARTBEAT_BASE: u16 = 0x700;

/// An NMT node-control command (byte 0 of the NMT frame).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum NmtCommand {
    /// Start remote node: to Operational (0x01).
    Start,
    /// Stop remote node: to Stopped (0x02).
    Stop,
    /// Enter Pre-operational (0x80).
    EnterPreOperational,
    /// Reset node (0x81).
    ResetNode,
    /// Reset communication (0x82).
    ResetCommunication,
}

impl NmtCommand {
    /// The command specifier byte.
    pub fn specifier(self) -> u8 {
        match self {
            NmtCommand::Start => 0x01,
            NmtCommand::Stop => 0x02,
            NmtCommand::EnterPreOperational => 0x80,
            NmtCommand::ResetNode => 0x81,
            NmtCommand::ResetCommunication => 0x82,
        }
    }

    /// The command of a specifier byte.
    pub fn from_specifier(cs: u8) -> Option<Self> {
        Some(match cs {
            0x01 => NmtCommand::Start,
            0x02 => NmtCommand::Stop,
            0x80 => NmtCommand::EnterPreOperational,
            0x81 => NmtCommand::ResetNode,
            0x82 => NmtCommand::ResetCommunication,
            _ => return None,
        })
    }
}

/// The NMT state a node reports in its heartbeat.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum NmtState {
    /// Boot-up message (0x00), sent once after initialisation.
    BootUp,
    /// Stopped (0x04): only NMT is served.
    Stopped,
    /// Operational (0x05).
    Operational,
    /// Pre-operational (0x7F): SDO works, PDO does not.
    PreOperational,
}

impl NmtState {
    /// The state byte of a heartbeat.
    pub fn byte(self) -> u8 {
        match self {
            NmtState::BootUp => 0x00,
            NmtState::Stopped => 0x04,
            NmtState::Operational => 0x05,
            NmtState::PreOperational => 0x7F,
        }
    }

    /// The state of a heartbeat byte (the toggle bit 7 of node guarding is ignored).
    pub fn from_byte(b: u8) -> Option<Self> {
        Some(match b & 0x7F {
            0x00 => NmtState::BootUp,
            0x04 => NmtState::Stopped,
            0x05 => NmtState::Operational,
            0x7F => NmtState::PreOperational,
            _ => return None,
        })
    }
}

/// A frame that is not the NMT or heartbeat frame expected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum NmtDecodeError {
    /// Not the COB-ID of this kind of frame.
    #[error("COB-ID 0x{0:03X} is not an NMT or heartbeat COB-ID")]
    CobId(u16),
    /// Wrong number of data bytes.
    #[error("{got} data bytes (expected {expected})")]
    Length {
        /// Received.
        got: usize,
        /// Expected.
        expected: usize,
    },
    /// Unknown command specifier or state byte.
    #[error("unknown NMT byte 0x{0:02X}")]
    Unknown(u8),
}

/// The NMT frame commanding `node` (0 = all nodes): `000#<cs><node>`.
pub fn encode_command(cmd: NmtCommand, node: u8) -> CanFrame {
    CanFrame::new(NMT_COB_ID, &[cmd.specifier(), node]).unwrap_or_else(|_| unreachable!("2 bytes on COB-ID 0"))
}

/// Decode an NMT frame: the command and the node it addresses (0 = all).
pub fn decode_command(frame: &CanFrame) -> Result<(NmtCommand, u8), NmtDecodeError> {
    if frame.id() != NMT_COB_ID {
        return Err(NmtDecodeError::CobId(frame.id()));
    }
    let d = frame.data();
    if d.len() != 2 {
        return Err(NmtDecodeError::Length { got: d.len(), expected: 2 });
    }
    let cmd = NmtCommand::from_specifier(d[0]).ok_or(NmtDecodeError::Unknown(d[0]))?;
    Ok((cmd, d[1]))
}

/// The heartbeat (or boot-up) frame of `node` (1..=127) in `state`.
pub fn encode_heartbeat(node: u8, state: NmtState) -> CanFrame {
    CanFrame::new(HEARTBEAT_BASE + u16::from(node & 0x7F), &[state.byte()])
        .unwrap_or_else(|_| unreachable!("node & 0x7F keeps the COB-ID in 11 bits"))
}

/// Decode a heartbeat frame: the node and its state.
pub fn decode_heartbeat(frame: &CanFrame) -> Result<(u8, NmtState), NmtDecodeError> {
    let id = frame.id();
    if !(HEARTBEAT_BASE + 1..=HEARTBEAT_BASE + 0x7F).contains(&id) {
        return Err(NmtDecodeError::CobId(id));
    }
    let d = frame.data();
    if d.len() != 1 {
        return Err(NmtDecodeError::Length { got: d.len(), expected: 1 });
    }
    let state = NmtState::from_byte(d[0]).ok_or(NmtDecodeError::Unknown(d[0]))?;
    Ok(((id - HEARTBEAT_BASE) as u8, state))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn frames_as_documented() {
        assert_eq!(encode_command(NmtCommand::Start, 5).to_string(), "000#0105");
        assert_eq!(encode_command(NmtCommand::ResetNode, 0).to_string(), "000#8100");
        assert_eq!(encode_heartbeat(5, NmtState::Operational).to_string(), "705#05");
        assert_eq!(encode_heartbeat(127, NmtState::BootUp).to_string(), "77F#00");
        assert_eq!(decode_heartbeat(&encode_heartbeat(9, NmtState::PreOperational)), Ok((9, NmtState::PreOperational)));
        assert_eq!(decode_command(&CanFrame::new(0, &[0x03, 1]).unwrap()), Err(NmtDecodeError::Unknown(3)));
        assert_eq!(
            decode_command(&CanFrame::new(0, &[0x01]).unwrap()),
            Err(NmtDecodeError::Length { got: 1, expected: 2 })
        );
        assert_eq!(decode_heartbeat(&CanFrame::new(0x700, &[0]).unwrap()), Err(NmtDecodeError::CobId(0x700)));
        // Node guarding sets the toggle bit 7: still the state.
        assert_eq!(NmtState::from_byte(0x85), Some(NmtState::Operational));
    }

    proptest! {
        #[test]
        fn round_trips_and_arbitrary_frames(node in 0u8..=127, cs in any::<u8>(), id in 0u16..=0x7FF, data in proptest::collection::vec(any::<u8>(), 0..=8)) {
            if let Some(cmd) = NmtCommand::from_specifier(cs) {
                prop_assert_eq!(decode_command(&encode_command(cmd, node)), Ok((cmd, node)));
                prop_assert_eq!(cmd.specifier(), cs);
            }
            if node > 0 {
                for state in [NmtState::BootUp, NmtState::Stopped, NmtState::Operational, NmtState::PreOperational] {
                    prop_assert_eq!(decode_heartbeat(&encode_heartbeat(node, state)), Ok((node, state)));
                }
            }
            let f = CanFrame::new(id, &data).unwrap();
            let _ = decode_command(&f);
            let _ = decode_heartbeat(&f);
        }
    }
}
