//! What every emScon TPI packet shares, whichever module decodes it
//! ([`super::packets`], [`super::stream`]): the header's layout, the limits of
//! `lPacketSize`, and why bytes did not decode.

/// `sizeof(struct PacketHeaderT)`: `long lPacketSize; enum ES_DataType type;`.
pub const PACKET_HEADER_LEN: usize = 8;
/// `sizeof(struct ReturnDataT)`: header + `status`.
pub const RETURN_DATA_LEN: usize = 12;

/// The smallest packet of the protocol (`BasicCommandCT`, `SystemStatusChangeT`).
pub const MIN_PACKET_LEN: usize = 12;
/// The largest `lPacketSize` accepted. The packets this driver reads are at
/// most 204 bytes (`SingleMeasResult2T`), or a `MultiMeasResultT` of at most
/// 112 points (4080 bytes, [`super::stream::MAX_POINTS_PER_PACKET`]); a size field
/// above this limit (or below [`MIN_PACKET_LEN`]) is taken for garbage, not
/// waited for.
pub const MAX_PACKET_LEN: usize = 4096;

/// Why bytes did not decode.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// `lPacketSize` outside `MIN_PACKET_LEN..=MAX_PACKET_LEN`: the stream's
    /// framing is lost (the decoder drops what it holds).
    #[error("absurd packet size {size} (accepted {MIN_PACKET_LEN}..={MAX_PACKET_LEN})")]
    AbsurdSize { size: i64 },
    /// `lPacketSize` differs from the bytes given (only for a frame decoded
    /// on its own, never from a [`super::packets::Framer`]).
    #[error("lPacketSize {size} but the frame has {len} bytes")]
    SizeMismatch { size: i64, len: usize },
    /// A `type` that is no `ES_DataType`.
    #[error("unknown packet type {data_type}")]
    UnknownType { data_type: i32 },
    /// A `type` that is an `ES_DataType` but not allowed in this direction.
    #[error("packet type {data_type} is not expected from this side")]
    UnexpectedType { data_type: i32 },
    /// A command that is no `ES_Command`, or one this codec does not model in
    /// this direction.
    #[error("unknown or unsupported command {command}")]
    UnsupportedCommand { command: i32 },
    /// The packet's size does not fit its type and command.
    #[error("{what}: {len} bytes, expected {expected}")]
    WrongLength { what: &'static str, len: usize, expected: usize },
}

impl DecodeError {
    /// Whether the stream's framing is lost (only an absurd size).
    pub fn loses_framing(&self) -> bool {
        matches!(self, DecodeError::AbsurdSize { .. })
    }
}
