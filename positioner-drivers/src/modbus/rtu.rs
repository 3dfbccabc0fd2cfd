//! Modbus RTU has no transaction id: a reply is tied to its request only by
//! what it carries. What the driver and the simulators' relay share, sans-IO:
//! where a response frame ends ([`rtu_response_len`]: the function code and,
//! for reads, the byte count tell) and whether a response answers a request
//! ([`Expected`]: slave, function code, and the byte count of a read or the
//! address and value or quantity a write echoes).

use super::map::crc16_modbus_bytes;

/// The length of the RTU response frame at the start of `b` (slave address,
/// function code, data, CRC), once enough of it is there to tell; `None`
/// before. For a function this project never sends (not 1-6, 15, 16, nor
/// an exception), the bytes held: no framing to follow.
pub fn rtu_response_len(b: &[u8]) -> Option<usize> {
    let function = *b.get(1)?;
    Some(match function {
        f if f & 0x80 != 0 => 5,
        1..=4 => 5 + usize::from(*b.get(2)?),
        5 | 6 | 15 | 16 => 8,
        _ => b.len(),
    })
}

/// What the response to one RTU request must carry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Expected {
    slave: u8,
    function: u8,
    /// Bytes 2..6 of a write's echo (address and value or quantity), or the
    /// byte count of a read's data.
    echo: Echo,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Echo {
    ByteCount(usize),
    Words([u8; 4]),
    Nothing,
}

impl Expected {
    /// What answers the request frame `request` (slave, function, address
    /// and quantity or value, ...), if it is one (6 bytes at least).
    pub fn of_request(request: &[u8]) -> Option<Expected> {
        let &[slave, function, a0, a1, q0, q1, ..] = request else { return None };
        let echo = match function {
            3 | 4 => Echo::ByteCount(2 * usize::from(u16::from_be_bytes([q0, q1]))),
            1 | 2 => Echo::ByteCount(usize::from(u16::from_be_bytes([q0, q1])).div_ceil(8)),
            5 | 6 | 15 | 16 => Echo::Words([a0, a1, q0, q1]),
            _ => Echo::Nothing,
        };
        Some(Expected { slave, function, echo })
    }

    /// Why the whole response frame `frame` (CRC included) does not answer
    /// the request, or `None` when it does. An exception answers when it
    /// names the request's function; a frame whose CRC does not hold is left
    /// to the client (a garbled reply, not another request's).
    pub fn mismatch(&self, frame: &[u8]) -> Option<String> {
        let (Some(&slave), Some(&function)) = (frame.first(), frame.get(1)) else {
            return Some("an empty frame".into());
        };
        let n = frame.len();
        if n < 4 || crc16_modbus_bytes(&frame[..n - 2]).to_le_bytes() != frame[n - 2..] {
            return None;
        }
        if slave != self.slave {
            return Some(format!("slave {slave}, not {}", self.slave));
        }
        if function & 0x7F != self.function {
            return Some(format!("function {function:#04x}, not {:#04x}", self.function));
        }
        if function & 0x80 != 0 {
            return None;
        }
        match self.echo {
            Echo::ByteCount(count) if usize::from(frame[2]) != count => {
                Some(format!("{} data bytes, not {count}", frame[2]))
            }
            Echo::Words(words) if frame.get(2..6) != Some(&words[..]) => {
                Some(format!("echo {:02x?}, not {words:02x?}", frame.get(2..6).unwrap_or_default()))
            }
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn framed(body: &[u8]) -> Vec<u8> {
        let mut f = body.to_vec();
        f.extend(crc16_modbus_bytes(body).to_le_bytes());
        f
    }

    #[test]
    fn response_lengths() {
        assert_eq!(rtu_response_len(&[1]), None);
        assert_eq!(rtu_response_len(&[1, 3]), None, "a read needs its byte count");
        assert_eq!(rtu_response_len(&[1, 3, 4]), Some(9));
        assert_eq!(rtu_response_len(&[1, 0x83]), Some(5));
        assert_eq!(rtu_response_len(&[1, 6]), Some(8));
        assert_eq!(rtu_response_len(&[1, 16, 0]), Some(8));
        assert_eq!(rtu_response_len(&[1, 0x2B, 9, 9]), Some(4));
    }

    /// A reply is matched by slave, function, the byte count of a read and
    /// the echo of a write; an exception for the function answers; a frame
    /// whose CRC fails is left to the client.
    #[test]
    fn replies_are_matched_to_their_request() {
        let read = Expected::of_request(&framed(&[1, 3, 0, 20, 0, 2])).unwrap();
        assert_eq!(read.mismatch(&framed(&[1, 3, 4, 0, 1, 0, 2])), None);
        assert!(read.mismatch(&framed(&[1, 3, 2, 0, 1])).unwrap().contains("2 data bytes, not 4"));
        assert!(read.mismatch(&framed(&[1, 4, 4, 0, 1, 0, 2])).unwrap().contains("function 0x04"));
        assert!(read.mismatch(&framed(&[2, 3, 4, 0, 1, 0, 2])).unwrap().contains("slave 2"));
        assert!(read.mismatch(&framed(&[1, 6, 0, 4, 0, 1])).is_some(), "a write's echo");
        assert_eq!(read.mismatch(&framed(&[1, 0x83, 2])), None, "its exception");
        assert!(read.mismatch(&framed(&[1, 0x86, 2])).is_some(), "another function's exception");
        let mut bad = framed(&[1, 6, 0, 4, 0, 1]);
        bad[3] ^= 0x5a;
        assert_eq!(read.mismatch(&bad), None, "a failed CRC is the client's to report");
        let write = Expected::of_request(&framed(&[1, 6, 0, 4, 0, 1])).unwrap();
        assert_eq!(write.mismatch(&framed(&[1, 6, 0, 4, 0, 1])), None);
        assert!(write.mismatch(&framed(&[1, 6, 0, 4, 0, 6])).is_some(), "another command's echo");
        let many = Expected::of_request(&framed(&[1, 16, 0, 0, 0, 5, 10, 0, 0])).unwrap();
        assert_eq!(many.mismatch(&framed(&[1, 16, 0, 0, 0, 5])), None);
        assert!(many.mismatch(&framed(&[1, 16, 0, 0, 0, 4])).is_some());
    }
}
