//! The positioner controllers' codecs under arbitrary bytes: one function per wire codec (the tracker's and the autocollimator's are in `survey_drivers::fuzz_targets`), shared by
//! the cargo-fuzz harnesses (`fuzz/fuzz_targets/`, run on nightly) and the
//! bounded replay on stable (`positioner-drivers/tests/codec_fuzz.rs`, in CI).
//!
//! Each function feeds `data` to every decoder of its codec, whole and cut
//! into chunks at sizes drawn from the data itself, and checks what must hold
//! for any input: no panic (the harness catches one), every buffer bounded,
//! and whatever decodes encodes to bytes that decode to the same thing again
//! (a round trip on the decoded value, so NaN fields compare by their bytes).

use crate::canopen::frame::CanFrame;
use crate::canopen::{nmt, objects, sdo, slcan};
use crate::modbus::{PositionEncoding, RegisterMap, WordOrder};
use crate::scpi;
use survey_drivers::fuzz_targets::chunks;

/// The Modbus register map: a map built from the first bytes (word order,
/// encoding, scale, status bits), checked, then every 2-register value and
/// status word of the rest decoded and encoded again.
pub fn modbus_map(data: &[u8]) {
    if data.len() < 16 {
        return;
    }
    let scale = f64::from_le_bytes(data[1..9].try_into().expect("8 bytes"));
    let map = RegisterMap {
        word_order: if data[0] & 1 == 0 { WordOrder::HighFirst } else { WordOrder::LowFirst },
        position_encoding: if data[0] & 2 == 0 {
            PositionEncoding::Counts { counts_per_degree: scale }
        } else {
            PositionEncoding::Float32
        },
        status_bits: crate::modbus::StatusBits {
            moving: data[9] % 20,
            in_position: data[10] % 20,
            fault: data[11] % 20,
            lower_limit: data[12] % 20,
            upper_limit: data[13] % 20,
            correction_enabled: data[14] % 20,
        },
        ..RegisterMap::default()
    };
    if map.validate().is_err() {
        return;
    }
    for w in data[15..].chunks_exact(4) {
        let words = [u16::from_be_bytes([w[0], w[1]]), u16::from_be_bytes([w[2], w[3]])];
        for (decode, encode) in [
            (
                RegisterMap::decode_position as fn(&RegisterMap, [u16; 2]) -> _,
                RegisterMap::encode_position as fn(&RegisterMap, f64) -> _,
            ),
            (RegisterMap::decode_velocity, RegisterMap::encode_velocity),
            (RegisterMap::decode_table_value, RegisterMap::encode_table_value),
        ] {
            if let Ok(v) = decode(&map, words) {
                assert!(v.is_finite(), "a decoded value is finite: {v}");
                let again = encode(&map, v).expect("a decoded value encodes");
                let back = decode(&map, again).expect("and decodes again");
                assert_eq!(back.to_bits(), v.to_bits(), "{words:?} -> {v} -> {again:?} -> {back}");
            }
        }
        let fault = Some(words[1]);
        let status = map.decode_status(words[0], fault);
        let word = map.encode_status(&status);
        assert_eq!(map.decode_status(word, fault), status, "status {:#06x}", words[0]);
    }
    let _ = crate::modbus::table_checksum(
        &data.chunks_exact(2).map(|b| u16::from_be_bytes([b[0], b[1]])).collect::<Vec<_>>(),
    );
}

/// CANopen: SDO requests and responses (each 8-byte window), NMT commands and
/// heartbeats, CiA 402 statuswords and controlwords, the correction-table
/// domain, and segmented reassembly driven by the bytes.
pub fn canopen(data: &[u8]) {
    for w in data.windows(8).step_by(3) {
        if let Ok(r) = sdo::SdoRequest::decode(w) {
            assert_eq!(sdo::SdoRequest::decode(&r.encode()).as_ref(), Ok(&r), "{w:02x?}");
        }
        if let Ok(r) = sdo::SdoResponse::decode(w) {
            assert_eq!(sdo::SdoResponse::decode(&r.encode()).as_ref(), Ok(&r), "{w:02x?}");
        }
    }
    let _ = sdo::SdoRequest::decode(data);
    let _ = sdo::SdoResponse::decode(data);
    if data.len() >= 2 {
        let id = u16::from_le_bytes([data[0], data[1]]) & 0x7ff;
        let payload = &data[2..data.len().min(10)];
        if let Ok(frame) = CanFrame::new(id, payload) {
            if let Ok((cmd, node)) = nmt::decode_command(&frame) {
                assert_eq!(nmt::decode_command(&nmt::encode_command(cmd, node)), Ok((cmd, node)));
            }
            if let Ok((node, state)) = nmt::decode_heartbeat(&frame) {
                assert_eq!(nmt::decode_heartbeat(&nmt::encode_heartbeat(node, state)), Ok((node, state)));
            }
        }
        let word = u16::from_le_bytes([data[0], data[1]]);
        let sw = objects::Statusword(word);
        let _ = (sw.state(), sw.fault(), sw.target_reached(), sw.to_string(), objects::DriveCommand::of(word));
        if let Some(state) = objects::DriveState::from_statusword(word) {
            assert_eq!(objects::DriveState::from_statusword(state.statusword_bits()), Some(state));
        }
        let _ = objects::error_code_text(word);
    }
    if let Ok(table) = objects::decode_table(data) {
        let bytes = objects::encode_table(&table).expect("a decoded table encodes");
        assert_eq!(objects::decode_table(&bytes).map(|t| objects::encode_table(&t).ok()), Ok(Some(bytes)));
    }
    // A segmented upload: the indicated size and the segments from the data.
    if data.len() >= 4 {
        let indicated = (data[0] & 1 == 1).then(|| u32::from_le_bytes([data[1], data[2], data[3], 0]));
        if let Ok(mut r) = sdo::Reassembler::new(indicated, 4096) {
            for seg in data[4..].chunks(8) {
                let toggle = seg[0] & 0x10 != 0;
                let last = seg[0] & 1 == 1;
                let body = &seg[1..];
                match r.push(toggle, body, last) {
                    Ok(done) => {
                        assert!(r.received() <= 4096, "the reassembler is bounded");
                        if done {
                            break;
                        }
                    }
                    Err(e) => {
                        let _ = e.abort_code();
                        break;
                    }
                }
            }
        }
    }
}

/// SLCAN (Lawicel): the line decoder over chunks, every line parsed, every
/// parsed message encoded and parsed again to itself.
pub fn slcan(data: &[u8]) {
    let mut decoder = slcan::LineDecoder::new();
    for chunk in chunks(data) {
        decoder.push(chunk);
        while let Some(line) = decoder.next_line() {
            let Ok(line) = line else { continue };
            if let Ok(m) = slcan::Message::parse(&line) {
                let bytes = m.encode();
                let mut again = slcan::LineDecoder::new();
                again.push(&bytes);
                let l = again.next_line().expect("an encoded message is a line").expect("a good line");
                assert_eq!(slcan::Message::parse(&l), Ok(m), "{line:02x?}");
            }
        }
    }
    let _ = slcan::Message::parse(data);
}

/// SCPI: the line decoder over chunks (bounded lines), every line parsed as
/// a command, a number, a count, a status word and error-queue entries; a
/// parsed command printed and parsed again to itself.
pub fn scpi(data: &[u8]) {
    let mut decoder = scpi::Decoder::new(256);
    for chunk in chunks(data) {
        decoder.push(chunk);
        while let Some(line) = decoder.next_line() {
            let Ok(line) = line else { continue };
            assert!(line.len() <= 256, "a line within the limit");
            scpi_line(&line);
        }
    }
    if let Ok(s) = std::str::from_utf8(data) {
        scpi_line(s);
    }
}

fn scpi_line(line: &str) {
    if let Ok(p) = scpi::Command::parse(line) {
        let address = p.address.unwrap_or_default();
        let printed = p.command.to_line(address);
        let again = scpi::Command::parse(&printed).expect("a printed command parses");
        assert_eq!(again.command, p.command, "{line:?} -> {printed:?}");
    }
    let _ = scpi::parse_number(line);
    let _ = scpi::parse_count(line);
    let _ = scpi::parse_bool(line);
    let _ = scpi::parse_status(line);
    if let Ok(list) = scpi::ErrorEntry::parse_list(line) {
        for e in list {
            let _ = (e.kind(), e.to_line());
        }
    }
    if let Ok(e) = scpi::ErrorEntry::parse(line) {
        // Printing replaces what is not printable by '?': after one print the
        // entry prints and parses to itself.
        let printed = scpi::ErrorEntry::parse(&e.to_line()).expect("a printed entry parses");
        assert_eq!(scpi::ErrorEntry::parse(&printed.to_line()).as_ref(), Ok(&printed), "{line:?}");
    }
}
