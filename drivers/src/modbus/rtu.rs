//! Modbus RTU framing the driver and the simulators' relay share: where a
//! response frame ends (RTU has no length field: the function code and, for
//! reads, the byte count tell), sans-IO.

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

#[cfg(test)]
mod tests {
    use super::*;

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
}
