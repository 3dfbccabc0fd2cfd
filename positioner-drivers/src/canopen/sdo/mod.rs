//! The SDO protocol of CiA 301, sans-IO: frame codec (expedited and segmented
//! transfers, abort), the abort codes with their standard texts, and the two
//! halves of a segmented transfer ([`Segmenter`] splits, [`Reassembler`]
//! joins and checks the toggle bit and the size). Bytes in, values out: no
//! bus, no clock. The layouts are in the [module documentation](super).

use std::fmt;
use survey_drivers::error::ErrorKind;

/// COB-ID base of SDO requests (client to server): `0x600 + node`.
pub const SDO_REQUEST_BASE: u16 = 0x600;
/// COB-ID base of SDO responses (server to client): `0x580 + node`.
pub const SDO_RESPONSE_BASE: u16 = 0x580;

/// Most data bytes of one segment.
pub const SEGMENT_BYTES: usize = 7;
/// Most data bytes of an expedited transfer.
pub const EXPEDITED_BYTES: usize = 4;

// Command specifiers (bits 5..7 of byte 0).
const CCS_DOWNLOAD_SEGMENT: u8 = 0;
const CCS_INITIATE_DOWNLOAD: u8 = 1;
const CCS_INITIATE_UPLOAD: u8 = 2;
const CCS_UPLOAD_SEGMENT: u8 = 3;
const CS_ABORT: u8 = 4;
const CS_BLOCK_UPLOAD: u8 = 5;
const CS_BLOCK_DOWNLOAD: u8 = 6;
const SCS_UPLOAD_SEGMENT: u8 = 0;
const SCS_DOWNLOAD_SEGMENT: u8 = 1;
const SCS_INITIATE_UPLOAD: u8 = 2;
const SCS_INITIATE_DOWNLOAD: u8 = 3;

const TOGGLE: u8 = 0x10;
const EXPEDITED: u8 = 0x02;
const SIZE_INDICATED: u8 = 0x01;
const LAST_SEGMENT: u8 = 0x01;

/// Abort codes of CiA 301 (the ones this driver and its simulator use; any
/// other code is carried through unchanged).
pub mod abort {
    /// Toggle bit not alternated.
    pub const TOGGLE_BIT: u32 = 0x0503_0000;
    /// SDO protocol timed out.
    pub const TIMEOUT: u32 = 0x0504_0000;
    /// Client/server command specifier not valid or unknown.
    pub const COMMAND_SPECIFIER: u32 = 0x0504_0001;
    /// Out of memory.
    pub const OUT_OF_MEMORY: u32 = 0x0504_0005;
    /// Unsupported access to an object.
    pub const UNSUPPORTED_ACCESS: u32 = 0x0601_0000;
    /// Attempt to read a write-only object.
    pub const WRITE_ONLY: u32 = 0x0601_0001;
    /// Attempt to write a read-only object.
    pub const READ_ONLY: u32 = 0x0601_0002;
    /// Object does not exist in the object dictionary.
    pub const NO_OBJECT: u32 = 0x0602_0000;
    /// Data type does not match, length of service parameter does not match.
    pub const LENGTH_MISMATCH: u32 = 0x0607_0010;
    /// Data type does not match, length of service parameter too high.
    pub const LENGTH_TOO_HIGH: u32 = 0x0607_0012;
    /// Data type does not match, length of service parameter too low.
    pub const LENGTH_TOO_LOW: u32 = 0x0607_0013;
    /// Sub-index does not exist.
    pub const NO_SUBINDEX: u32 = 0x0609_0011;
    /// Value range of parameter exceeded (only for write access).
    pub const VALUE_RANGE: u32 = 0x0609_0030;
    /// Value of parameter written too high.
    pub const VALUE_TOO_HIGH: u32 = 0x0609_0031;
    /// Value of parameter written too low.
    pub const VALUE_TOO_LOW: u32 = 0x0609_0032;
    /// Maximum value is less than minimum value.
    pub const MAX_LESS_THAN_MIN: u32 = 0x0609_0036;
    /// General error.
    pub const GENERAL: u32 = 0x0800_0000;
    /// Data cannot be transferred or stored to the application.
    pub const CANNOT_STORE: u32 = 0x0800_0020;
    /// Data cannot be transferred or stored because of local control.
    pub const LOCAL_CONTROL: u32 = 0x0800_0021;
    /// Data cannot be transferred or stored because of the present device state.
    pub const DEVICE_STATE: u32 = 0x0800_0022;
    /// No data available.
    pub const NO_DATA: u32 = 0x0800_0024;
}

/// The standard text of an abort code (CiA 301), or `"unknown abort code"`.
pub fn abort_text(code: u32) -> &'static str {
    match code {
        0x0503_0000 => "Toggle bit not alternated",
        0x0504_0000 => "SDO protocol timed out",
        0x0504_0001 => "Client/server command specifier not valid or unknown",
        0x0504_0002 => "Invalid block size",
        0x0504_0003 => "Invalid sequence number",
        0x0504_0004 => "CRC error",
        0x0504_0005 => "Out of memory",
        0x0601_0000 => "Unsupported access to an object",
        0x0601_0001 => "Attempt to read a write only object",
        0x0601_0002 => "Attempt to write a read only object",
        0x0602_0000 => "Object does not exist in the object dictionary",
        0x0604_0041 => "Object cannot be mapped to the PDO",
        0x0604_0042 => "The number and length of the objects to be mapped would exceed PDO length",
        0x0604_0043 => "General parameter incompatibility reason",
        0x0604_0047 => "General internal incompatibility in the device",
        0x0606_0000 => "Access failed due to a hardware error",
        0x0607_0010 => "Data type does not match, length of service parameter does not match",
        0x0607_0012 => "Data type does not match, length of service parameter too high",
        0x0607_0013 => "Data type does not match, length of service parameter too low",
        0x0609_0011 => "Sub-index does not exist",
        0x0609_0030 => "Value range of parameter exceeded (only for write access)",
        0x0609_0031 => "Value of parameter written too high",
        0x0609_0032 => "Value of parameter written too low",
        0x0609_0036 => "Maximum value is less than minimum value",
        0x060A_0023 => "Resource not available: SDO connection",
        0x0800_0000 => "General error",
        0x0800_0020 => "Data cannot be transferred or stored to the application",
        0x0800_0021 => "Data cannot be transferred or stored to the application because of local control",
        0x0800_0022 => "Data cannot be transferred or stored to the application because of the present device state",
        0x0800_0023 => "Object dictionary dynamic generation fails or no object dictionary is present",
        0x0800_0024 => "No data available",
        _ => "unknown abort code",
    }
}

/// How the driver classifies a node's abort code.
///
/// [`ErrorKind::Usage`] (the request's value or timing is wrong; a different
/// request would succeed): the value-range codes `0x0609_0030`,
/// `0x0609_0031`, `0x0609_0032`, `0x0609_0036` (a target outside the travel,
/// a velocity of 0 or above the maximum, a table with bad values), `0x0800_0022`
/// (refused in the present device state: a set-point while not operation
/// enabled, a table loaded while moving) and `0x0800_0024` (no data: the
/// correction enabled with no table loaded). Every other code is
/// [`ErrorKind::Device`]: among them the codes that mean the driver and the
/// node disagree on the object dictionary (object or sub-index missing,
/// read-only, wrong length), which no retry of the same driver fixes.
pub fn abort_kind(code: u32) -> ErrorKind {
    match code {
        abort::VALUE_RANGE
        | abort::VALUE_TOO_HIGH
        | abort::VALUE_TOO_LOW
        | abort::MAX_LESS_THAN_MIN
        | abort::DEVICE_STATE
        | abort::NO_DATA => ErrorKind::Usage,
        _ => ErrorKind::Device,
    }
}

/// The data part of an initiate frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum InitData {
    /// Expedited: the data (1 to 4 bytes) is in the frame. Without
    /// `size_indicated` the size is not given and all 4 bytes are data (the
    /// encoder pads shorter data with zeros).
    Expedited {
        /// The data bytes.
        data: Vec<u8>,
        /// Whether the frame gives the size (bit s, with n = 4 - size).
        size_indicated: bool,
    },
    /// Segmented: segments follow; the total size when indicated.
    Segmented {
        /// The total size in bytes, when indicated.
        size: Option<u32>,
    },
}

/// A request from the SDO client (COB-ID `0x600 + node`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SdoRequest {
    /// Initiate a download (write) of `index:subindex`.
    InitiateDownload {
        /// Object index.
        index: u16,
        /// Sub-index.
        subindex: u8,
        /// Expedited data or the segmented size.
        data: InitData,
    },
    /// One segment of a segmented download.
    DownloadSegment {
        /// Toggle bit (0 on the first segment, alternating).
        toggle: bool,
        /// 0 to 7 data bytes.
        data: Vec<u8>,
        /// Bit c: no more segments.
        last: bool,
    },
    /// Initiate an upload (read) of `index:subindex`.
    InitiateUpload {
        /// Object index.
        index: u16,
        /// Sub-index.
        subindex: u8,
    },
    /// Ask for the next segment of a segmented upload.
    UploadSegment {
        /// Toggle bit (0 on the first request, alternating).
        toggle: bool,
    },
    /// Abort the transfer.
    Abort {
        /// Object index of the transfer.
        index: u16,
        /// Sub-index of the transfer.
        subindex: u8,
        /// Abort code.
        code: u32,
    },
}

/// A response from the SDO server (COB-ID `0x580 + node`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SdoResponse {
    /// The upload of `index:subindex` starts: expedited data or the segmented size.
    InitiateUpload {
        /// Object index echoed.
        index: u16,
        /// Sub-index echoed.
        subindex: u8,
        /// Expedited data or the segmented size.
        data: InitData,
    },
    /// One segment of a segmented upload.
    UploadSegment {
        /// Toggle bit, equal to the request's.
        toggle: bool,
        /// 0 to 7 data bytes.
        data: Vec<u8>,
        /// Bit c: no more segments.
        last: bool,
    },
    /// The download of `index:subindex` is accepted (expedited: done;
    /// segmented: send the segments).
    InitiateDownload {
        /// Object index echoed.
        index: u16,
        /// Sub-index echoed.
        subindex: u8,
    },
    /// One download segment is accepted.
    DownloadSegment {
        /// Toggle bit, equal to the request's.
        toggle: bool,
    },
    /// The server aborts the transfer.
    Abort {
        /// Object index of the transfer.
        index: u16,
        /// Sub-index of the transfer.
        subindex: u8,
        /// Abort code.
        code: u32,
    },
}

/// A frame that is not a valid SDO frame.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SdoDecodeError {
    /// SDO frames carry exactly 8 data bytes.
    #[error("SDO frame with {0} data bytes (expected 8)")]
    Length(usize),
    /// Block transfer (specifier 5 or 6) is not supported here.
    #[error("block transfer (command specifier {0}) is not supported")]
    BlockTransfer(u8),
    /// Command specifier 7 (or a server specifier in a request or the reverse).
    #[error("unknown command specifier {0}")]
    Specifier(u8),
}

fn put_multiplexer(b: &mut [u8; 8], index: u16, subindex: u8) {
    b[1..3].copy_from_slice(&index.to_le_bytes());
    b[3] = subindex;
}

fn multiplexer(b: &[u8]) -> (u16, u8) {
    (u16::from_le_bytes([b[1], b[2]]), b[3])
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Byte 0 and bytes 4..8 of an initiate frame with specifier `cs`.
fn encode_init(cs: u8, index: u16, subindex: u8, data: &InitData) -> [u8; 8] {
    let mut b = [0u8; 8];
    put_multiplexer(&mut b, index, subindex);
    b[0] = cs << 5;
    match data {
        InitData::Expedited { data, size_indicated } => {
            let n = data.len().min(EXPEDITED_BYTES);
            b[4..4 + n].copy_from_slice(&data[..n]);
            b[0] |= EXPEDITED;
            if *size_indicated {
                b[0] |= SIZE_INDICATED | (((EXPEDITED_BYTES - n) as u8) << 2);
            }
        }
        InitData::Segmented { size } => {
            if let Some(size) = size {
                b[0] |= SIZE_INDICATED;
                b[4..8].copy_from_slice(&size.to_le_bytes());
            }
        }
    }
    b
}

fn decode_init(b: &[u8]) -> InitData {
    let cmd = b[0];
    if cmd & EXPEDITED != 0 {
        if cmd & SIZE_INDICATED != 0 {
            let n = usize::from((cmd >> 2) & 0x3);
            InitData::Expedited { data: b[4..8 - n].to_vec(), size_indicated: true }
        } else {
            InitData::Expedited { data: b[4..8].to_vec(), size_indicated: false }
        }
    } else if cmd & SIZE_INDICATED != 0 {
        InitData::Segmented { size: Some(u32_at(b, 4)) }
    } else {
        InitData::Segmented { size: None }
    }
}

/// Byte 0 and data of a segment frame with specifier `cs`.
fn encode_segment(cs: u8, toggle: bool, data: &[u8], last: bool) -> [u8; 8] {
    let mut b = [0u8; 8];
    let n = data.len().min(SEGMENT_BYTES);
    b[1..1 + n].copy_from_slice(&data[..n]);
    b[0] = (cs << 5) | (((SEGMENT_BYTES - n) as u8) << 1);
    if toggle {
        b[0] |= TOGGLE;
    }
    if last {
        b[0] |= LAST_SEGMENT;
    }
    b
}

fn decode_segment(b: &[u8]) -> (bool, Vec<u8>, bool) {
    let n = usize::from((b[0] >> 1) & 0x7);
    (b[0] & TOGGLE != 0, b[1..8 - n].to_vec(), b[0] & LAST_SEGMENT != 0)
}

fn encode_abort(index: u16, subindex: u8, code: u32) -> [u8; 8] {
    let mut b = [0u8; 8];
    b[0] = CS_ABORT << 5;
    put_multiplexer(&mut b, index, subindex);
    b[4..8].copy_from_slice(&code.to_le_bytes());
    b
}

fn check_length(b: &[u8]) -> Result<(), SdoDecodeError> {
    if b.len() == 8 { Ok(()) } else { Err(SdoDecodeError::Length(b.len())) }
}

impl SdoRequest {
    /// The 8 data bytes of the request frame. Data longer than a frame holds
    /// is cut (build requests with at most 4 expedited or 7 segment bytes).
    pub fn encode(&self) -> [u8; 8] {
        match self {
            SdoRequest::InitiateDownload { index, subindex, data } => {
                encode_init(CCS_INITIATE_DOWNLOAD, *index, *subindex, data)
            }
            SdoRequest::DownloadSegment { toggle, data, last } => {
                encode_segment(CCS_DOWNLOAD_SEGMENT, *toggle, data, *last)
            }
            SdoRequest::InitiateUpload { index, subindex } => {
                let mut b = [0u8; 8];
                b[0] = CCS_INITIATE_UPLOAD << 5;
                put_multiplexer(&mut b, *index, *subindex);
                b
            }
            SdoRequest::UploadSegment { toggle } => {
                [(CCS_UPLOAD_SEGMENT << 5) | if *toggle { TOGGLE } else { 0 }, 0, 0, 0, 0, 0, 0, 0]
            }
            SdoRequest::Abort { index, subindex, code } => encode_abort(*index, *subindex, *code),
        }
    }

    /// Decode a request frame's data bytes. Reserved bits are ignored.
    pub fn decode(b: &[u8]) -> Result<Self, SdoDecodeError> {
        check_length(b)?;
        let (index, subindex) = multiplexer(b);
        Ok(match b[0] >> 5 {
            CCS_DOWNLOAD_SEGMENT => {
                let (toggle, data, last) = decode_segment(b);
                SdoRequest::DownloadSegment { toggle, data, last }
            }
            CCS_INITIATE_DOWNLOAD => SdoRequest::InitiateDownload { index, subindex, data: decode_init(b) },
            CCS_INITIATE_UPLOAD => SdoRequest::InitiateUpload { index, subindex },
            CCS_UPLOAD_SEGMENT => SdoRequest::UploadSegment { toggle: b[0] & TOGGLE != 0 },
            CS_ABORT => SdoRequest::Abort { index, subindex, code: u32_at(b, 4) },
            cs @ (CS_BLOCK_UPLOAD | CS_BLOCK_DOWNLOAD) => return Err(SdoDecodeError::BlockTransfer(cs)),
            cs => return Err(SdoDecodeError::Specifier(cs)),
        })
    }
}

impl SdoResponse {
    /// The 8 data bytes of the response frame (data cut as for requests).
    pub fn encode(&self) -> [u8; 8] {
        match self {
            SdoResponse::InitiateUpload { index, subindex, data } => {
                encode_init(SCS_INITIATE_UPLOAD, *index, *subindex, data)
            }
            SdoResponse::UploadSegment { toggle, data, last } => {
                encode_segment(SCS_UPLOAD_SEGMENT, *toggle, data, *last)
            }
            SdoResponse::InitiateDownload { index, subindex } => {
                let mut b = [0u8; 8];
                b[0] = SCS_INITIATE_DOWNLOAD << 5;
                put_multiplexer(&mut b, *index, *subindex);
                b
            }
            SdoResponse::DownloadSegment { toggle } => {
                [(SCS_DOWNLOAD_SEGMENT << 5) | if *toggle { TOGGLE } else { 0 }, 0, 0, 0, 0, 0, 0, 0]
            }
            SdoResponse::Abort { index, subindex, code } => encode_abort(*index, *subindex, *code),
        }
    }

    /// Decode a response frame's data bytes. Reserved bits are ignored.
    pub fn decode(b: &[u8]) -> Result<Self, SdoDecodeError> {
        check_length(b)?;
        let (index, subindex) = multiplexer(b);
        Ok(match b[0] >> 5 {
            SCS_UPLOAD_SEGMENT => {
                let (toggle, data, last) = decode_segment(b);
                SdoResponse::UploadSegment { toggle, data, last }
            }
            SCS_DOWNLOAD_SEGMENT => SdoResponse::DownloadSegment { toggle: b[0] & TOGGLE != 0 },
            SCS_INITIATE_UPLOAD => SdoResponse::InitiateUpload { index, subindex, data: decode_init(b) },
            SCS_INITIATE_DOWNLOAD => SdoResponse::InitiateDownload { index, subindex },
            CS_ABORT => SdoResponse::Abort { index, subindex, code: u32_at(b, 4) },
            cs @ (CS_BLOCK_UPLOAD | CS_BLOCK_DOWNLOAD) => return Err(SdoDecodeError::BlockTransfer(cs)),
            cs => return Err(SdoDecodeError::Specifier(cs)),
        })
    }
}

/// One segment of a segmented transfer, either direction.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Segment {
    /// Toggle bit.
    pub toggle: bool,
    /// 0 to 7 data bytes.
    pub data: Vec<u8>,
    /// No more segments.
    pub last: bool,
}

/// The sending half of a segmented transfer: cuts the data into segments of
/// 7 bytes with alternating toggle bits, starting at 0. Empty data gives one
/// empty last segment.
#[derive(Debug, Clone)]
pub struct Segmenter {
    data: Vec<u8>,
    pos: usize,
    toggle: bool,
    done: bool,
}

impl Segmenter {
    /// Segments of `data`.
    pub fn new(data: Vec<u8>) -> Self {
        Self { data, pos: 0, toggle: false, done: false }
    }

    /// Total bytes to send.
    pub fn total(&self) -> usize {
        self.data.len()
    }

    /// The toggle bit the next segment carries.
    pub fn toggle(&self) -> bool {
        self.toggle
    }

    /// Whether the last segment was given out.
    pub fn is_done(&self) -> bool {
        self.done
    }

    /// The next segment, or `None` after the last.
    pub fn next_segment(&mut self) -> Option<Segment> {
        if self.done {
            return None;
        }
        let end = (self.pos + SEGMENT_BYTES).min(self.data.len());
        let seg =
            Segment { toggle: self.toggle, data: self.data[self.pos..end].to_vec(), last: end == self.data.len() };
        self.pos = end;
        self.toggle = !self.toggle;
        self.done = seg.last;
        Some(seg)
    }
}

/// Why a segment was refused; each maps to the abort code the receiver sends.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SegmentError {
    /// The toggle bit did not alternate.
    #[error("toggle bit {got} where {expected} was expected")]
    Toggle {
        /// The toggle bit expected.
        expected: bool,
        /// The toggle bit received.
        got: bool,
    },
    /// More data than the receiver accepts.
    #[error("more than {max} bytes")]
    TooLong {
        /// The limit.
        max: usize,
    },
    /// The data received does not add up to the size indicated.
    #[error("{received} bytes received where {indicated} were indicated")]
    Size {
        /// The size the initiate frame indicated.
        indicated: u32,
        /// The bytes received so far (or in total).
        received: usize,
    },
    /// A segment after the last one.
    #[error("segment after the last one")]
    AfterEnd,
}

impl SegmentError {
    /// The CiA 301 abort code for this refusal.
    pub fn abort_code(&self) -> u32 {
        match self {
            SegmentError::Toggle { .. } => abort::TOGGLE_BIT,
            SegmentError::TooLong { .. } => abort::OUT_OF_MEMORY,
            SegmentError::Size { indicated, received } if *received > *indicated as usize => abort::LENGTH_TOO_HIGH,
            SegmentError::Size { .. } => abort::LENGTH_TOO_LOW,
            SegmentError::AfterEnd => abort::COMMAND_SPECIFIER,
        }
    }
}

/// The receiving half of a segmented transfer: joins segments, checks the
/// toggle bit (0 first, then alternating), the size limit and the size
/// indicated by the initiate frame.
#[derive(Debug, Clone)]
pub struct Reassembler {
    indicated: Option<u32>,
    max: usize,
    data: Vec<u8>,
    toggle: bool,
    done: bool,
}

impl Reassembler {
    /// A transfer of `indicated` bytes (when the initiate frame said), at
    /// most `max` bytes in any case.
    pub fn new(indicated: Option<u32>, max: usize) -> Result<Self, SegmentError> {
        if let Some(n) = indicated
            && n as usize > max
        {
            return Err(SegmentError::TooLong { max });
        }
        Ok(Self { indicated, max, data: Vec::new(), toggle: false, done: false })
    }

    /// The toggle bit the next segment must carry.
    pub fn toggle(&self) -> bool {
        self.toggle
    }

    /// Bytes received so far.
    pub fn received(&self) -> usize {
        self.data.len()
    }

    /// Take one segment: `Ok(true)` when it was the last.
    pub fn push(&mut self, toggle: bool, data: &[u8], last: bool) -> Result<bool, SegmentError> {
        if self.done {
            return Err(SegmentError::AfterEnd);
        }
        if toggle != self.toggle {
            return Err(SegmentError::Toggle { expected: self.toggle, got: toggle });
        }
        let received = self.data.len() + data.len();
        if received > self.max {
            return Err(SegmentError::TooLong { max: self.max });
        }
        if let Some(n) = self.indicated
            && (received > n as usize || (last && received != n as usize))
        {
            return Err(SegmentError::Size { indicated: n, received });
        }
        self.data.extend_from_slice(data);
        self.toggle = !self.toggle;
        self.done = last;
        Ok(last)
    }

    /// Whether the last segment arrived.
    pub fn is_done(&self) -> bool {
        self.done
    }

    /// The data joined so far.
    pub fn into_data(self) -> Vec<u8> {
        self.data
    }
}

/// `index:subindex` as CANopen tools print it: `0x6041:00`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Multiplexer(pub u16, pub u8);

impl fmt::Display for Multiplexer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "0x{:04X}:{:02X}", self.0, self.1)
    }
}

#[cfg(test)]
mod tests;
