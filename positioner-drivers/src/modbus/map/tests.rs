//! Tests of the register map: fixed cases and property tests of the
//! encoders and decoders.

use super::*;
use proptest::prelude::*;

fn order() -> impl Strategy<Value = WordOrder> {
    prop_oneof![Just(WordOrder::HighFirst), Just(WordOrder::LowFirst)]
}

fn map_with(enc: PositionEncoding, order: WordOrder) -> RegisterMap {
    RegisterMap { position_encoding: enc, word_order: order, ..RegisterMap::default() }
}

#[test]
fn the_default_map_is_valid_and_as_documented() {
    let m = RegisterMap::default();
    m.validate().unwrap();
    assert_eq!(m.unit_id, 1);
    assert_eq!(m.position_encoding, PositionEncoding::Counts { counts_per_degree: 100_000.0 });
    assert_eq!(m.word_order, WordOrder::HighFirst);
    assert_eq!((m.command_position, m.velocity, m.command), (0, 2, 4));
    assert_eq!(
        (m.actual_position, m.status, m.fault_code),
        (Location::input(0), Location::input(2), Location::input(3))
    );
    assert_eq!(
        (m.table.header, m.table.window, m.table.chunk_rows, m.table.checksum),
        (10, 100, 60, Location::input(4))
    );
    assert_eq!(m.span_of(Item::TableWindow).len, 122);
    assert_eq!(m.span_at(RegisterTable::Holding, 221).map(|s| s.item), Some(Item::TableWindow));
    assert_eq!(m.span_at(RegisterTable::Holding, 222), None);
    assert_eq!(m.span_at(RegisterTable::Input, 1).map(|s| s.item), Some(Item::ActualPosition));
    assert_eq!(m.span_at(RegisterTable::Holding, 3).map(|s| (s.item, s.address)), Some((Item::Velocity, 2)));
    // Known words: 45.12345 deg = 4512345 counts = 0x0044_DA59.
    assert_eq!(m.encode_position(45.12345).unwrap(), [0x0044, 0xDA59]);
    assert_eq!(m.encode_position(-1e-5).unwrap(), [0xFFFF, 0xFFFF]);
    let lo = map_with(PositionEncoding::Float32, WordOrder::LowFirst);
    // 123.45f32 = 0x42F6E666 (the byte-order example of the tutorials).
    assert_eq!(lo.encode_position(123.45).unwrap(), [0xE666, 0x42F6]);
}

#[test]
fn bad_maps_are_refused() {
    let bad = |f: &dyn Fn(&mut RegisterMap)| {
        let mut m = RegisterMap::default();
        f(&mut m);
        m.validate().unwrap_err()
    };
    assert!(bad(&|m| m.velocity = 1).0.contains("overlaps"));
    assert!(bad(&|m| m.status = Location::input(1)).0.contains("overlaps"));
    bad(&|m| m.position_encoding = PositionEncoding::Counts { counts_per_degree: 0.0 });
    bad(&|m| m.position_encoding = PositionEncoding::Counts { counts_per_degree: f64::NAN });
    // Found by fuzzing: a subnormal scale is positive and finite, and every
    // position it decoded was infinite.
    let e = bad(&|m| m.position_encoding = PositionEncoding::Counts { counts_per_degree: 1e-310 });
    assert!(e.0.contains("not within 0.001 to 1000000000"), "{e:?}");
    bad(&|m| m.position_encoding = PositionEncoding::Counts { counts_per_degree: 1e12 });
    bad(&|m| m.status_bits.fault = 16);
    bad(&|m| m.status_bits.fault = m.status_bits.moving);
    bad(&|m| m.command_codes.stop = 0);
    bad(&|m| m.command_codes.stop = m.command_codes.load_table);
    bad(&|m| m.table.chunk_rows = 61);
    bad(&|m| m.table.chunk_rows = 0);
    bad(&|m| m.table.window = 65_500);
    // The same address in different tables is fine.
    let m =
        RegisterMap { actual_position: Location::holding(20), status: Location::input(0), ..RegisterMap::default() };
    m.validate().unwrap();
}

#[test]
fn out_of_range_and_non_finite_values_are_refused() {
    let m = RegisterMap::default();
    assert!(matches!(m.encode_position(30_000.0), Err(ValueError::OutOfRange { .. })));
    assert!(matches!(m.encode_position(f64::NAN), Err(ValueError::NotFinite(_))));
    let f = map_with(PositionEncoding::Float32, WordOrder::HighFirst);
    assert!(matches!(f.encode_position(1e39), Err(ValueError::NotFinite(_))));
    assert!(matches!(f.decode_position(WordOrder::HighFirst.split(f32::NAN.to_bits())), Err(ValueError::NotFinite(_))));
    assert!(matches!(
        f.decode_position(WordOrder::HighFirst.split(f32::INFINITY.to_bits())),
        Err(ValueError::NotFinite(_))
    ));
}

#[test]
fn crc_check_values() {
    assert_eq!(crc16_modbus_bytes(b"123456789"), 0x4B37);
    // The request 01 03 00 00 00 0A of the Modbus serial-line examples: CRC C5CD (sent CD C5).
    assert_eq!(crc16_modbus_bytes(&[0x01, 0x03, 0x00, 0x00, 0x00, 0x0A]), 0xCDC5);
    assert_eq!(table_checksum(&[0x0103, 0x0000, 0x000A]), 0xCDC5);
    assert_eq!(table_checksum(&[]), 0xFFFF);
}

#[test]
fn status_words_decode_per_bit() {
    let m = RegisterMap::default();
    let s = m.decode_status(0b10_0101, Some(0x8611));
    assert!(s.moving && !s.in_position && s.correction_enabled);
    assert_eq!(s.fault, Some(DeviceFault { code: 0x8611, text: "controller fault 0x8611: following error".into() }));
    assert_eq!(m.decode_status(0b1_0000, None).limit, Some(Limit::Upper));
    assert_eq!(m.decode_status(0b1_1000, None).limit, Some(Limit::Lower));
    assert_eq!(m.decode_status(0b100, None).fault.unwrap().code, 0);
    assert_eq!(m.decode_status(0xFFC0, Some(7)), PositionerStatus::default());
}

fn status_strategy() -> impl Strategy<Value = PositionerStatus> {
    let limit = prop_oneof![Just(None), Just(Some(Limit::Lower)), Just(Some(Limit::Upper))];
    (any::<bool>(), any::<bool>(), proptest::option::of(any::<u16>()), limit, any::<bool>()).prop_map(
        |(moving, in_position, code, limit, correction_enabled)| PositionerStatus {
            moving,
            in_position,
            fault: code.map(|c| DeviceFault { code: i64::from(c), text: fault_text(c) }),
            limit,
            correction_enabled,
        },
    )
}

fn bits_strategy() -> impl Strategy<Value = StatusBits> {
    Just((0u8..16).collect::<Vec<_>>()).prop_shuffle().prop_map(|b| StatusBits {
        moving: b[0],
        in_position: b[1],
        fault: b[2],
        lower_limit: b[3],
        upper_limit: b[4],
        correction_enabled: b[5],
    })
}

fn table_strategy() -> impl Strategy<Value = CorrectionTable> {
    (2usize..200, any::<bool>(), any::<u64>()).prop_map(|(n, directional, seed)| {
        let v = |i: usize, k: u64| ((i as f64 + 1.0) * (seed % 97 + k) as f64).sin() * 0.05;
        let fwd: Vec<f64> = (0..n).map(|i| v(i, 1)).collect();
        if directional {
            CorrectionTable::directional(fwd, (0..n).map(|i| v(i, 2)).collect()).unwrap()
        } else {
            CorrectionTable::new(fwd).unwrap()
        }
    })
}

proptest! {
    #[test]
    fn words_round_trip_in_every_order(v in any::<u32>(), order in order()) {
        let w = order.split(v);
        prop_assert_eq!(order.join(w), v);
        let other = if order == WordOrder::HighFirst { WordOrder::LowFirst } else { WordOrder::HighFirst };
        prop_assert_eq!(other.split(v), [w[1], w[0]]);
    }

    #[test]
    fn counts_round_trip_within_one_count(
        cpd in prop_oneof![Just(1.0), Just(2_913.777_777), Just(100_000.0), Just(1.0e6), 0.5f64..2.0e6],
        frac in -1.0f64..1.0,
        order in order(),
    ) {
        let m = map_with(PositionEncoding::Counts { counts_per_degree: cpd }, order);
        let deg = frac * (f64::from(i32::MAX) - 1.0) / cpd;
        let w = m.encode_position(deg).unwrap();
        let back = m.decode_position(w).unwrap();
        prop_assert!((back - deg).abs() <= 0.5 / cpd * (1.0 + 1e-9), "{} -> {}", deg, back);
        // Re-encoding the decoded value gives the same registers.
        prop_assert_eq!(m.encode_position(back).unwrap(), w);
        prop_assert_eq!(m.encode_velocity(deg).unwrap(), w);
    }

    #[test]
    fn every_count_decodes_and_re_encodes(w0 in any::<u16>(), w1 in any::<u16>(), order in order()) {
        let m = map_with(PositionEncoding::Counts { counts_per_degree: 100_000.0 }, order);
        let deg = m.decode_position([w0, w1]).unwrap();
        prop_assert_eq!(m.encode_position(deg).unwrap(), [w0, w1]);
    }

    #[test]
    fn float32_round_trips_within_its_precision(deg in -1.0e6f64..1.0e6, order in order()) {
        let m = map_with(PositionEncoding::Float32, order);
        let back = m.decode_position(m.encode_position(deg).unwrap()).unwrap();
        prop_assert!((back - deg).abs() <= deg.abs() * f64::from(f32::EPSILON) / 2.0 + f64::MIN_POSITIVE);
        prop_assert_eq!(back, f64::from(deg as f32));
    }

    #[test]
    fn finite_float32_words_re_encode_exactly(bits in any::<u32>(), order in order()) {
        let m = map_with(PositionEncoding::Float32, order);
        let w = order.split(bits);
        match m.decode_position(w) {
            Ok(deg) => prop_assert_eq!(m.encode_position(deg).unwrap(), w),
            Err(_) => prop_assert!(!f32::from_bits(bits).is_finite()),
        }
    }

    #[test]
    fn status_round_trips_under_any_bit_assignment(s in status_strategy(), bits in bits_strategy()) {
        let m = RegisterMap { status_bits: bits, ..RegisterMap::default() };
        m.validate().unwrap();
        let word = m.encode_status(&s);
        prop_assert_eq!(word & !m.status_bits.mask(), 0);
        prop_assert_eq!(m.decode_status(word, Some(fault_code_register(&s))), s);
    }

    #[test]
    fn status_decode_reads_only_mapped_bits(word in any::<u16>(), code in any::<u16>(), bits in bits_strategy()) {
        let m = RegisterMap { status_bits: bits, ..RegisterMap::default() };
        let a = m.decode_status(word, Some(code));
        prop_assert_eq!(&a, &m.decode_status(word & m.status_bits.mask(), Some(code)));
        // Encoding what was decoded gives the word back, except that a
        // word with both limits reads as the lower limit.
        let both = bit(m.status_bits.lower_limit) | bit(m.status_bits.upper_limit);
        let expect = if word & both == both { word & m.status_bits.mask() & !bit(m.status_bits.upper_limit) } else { word & m.status_bits.mask() };
        prop_assert_eq!(m.encode_status(&a), expect);
    }

    #[test]
    fn table_chunks_rebuild_the_table(t in table_strategy(), chunk_rows in 1u16..=60, order in order()) {
        let m = RegisterMap { word_order: order, table: TableBlock { chunk_rows, ..TableBlock::default() }, ..RegisterMap::default() };
        let header = m.table_header(&t).unwrap();
        prop_assert_eq!(usize::from(header[0]), t.len());
        let mut cols = vec![vec![f64::NAN; t.len()]; usize::from(header[1])];
        let mut words = vec![Vec::new(); cols.len()];
        for chunk in m.table_chunks(&t).unwrap() {
            prop_assert!(chunk.len() <= usize::from(MAX_WRITE_REGISTERS));
            prop_assert!(chunk.len() <= usize::from(m.span_of(Item::TableWindow).len));
            let (col, first) = (usize::from(chunk[0]), usize::from(chunk[1]));
            for (k, pair) in chunk[2..].chunks(2).enumerate() {
                cols[col][first + k] = m.decode_table_value([pair[0], pair[1]]).unwrap();
            }
            words[col].extend_from_slice(&chunk[2..]);
        }
        let f32s = |c: &Vec<f64>| c.iter().map(|v| f64::from(*v as f32)).collect::<Vec<_>>();
        prop_assert_eq!(&cols[0], &f32s(&t.forward));
        if let Some(r) = &t.reverse {
            prop_assert_eq!(&cols[1], &f32s(r));
        }
        prop_assert_eq!(words.concat(), m.table_words(&t).unwrap());
    }
}

#[test]
fn configuration_fields_default_and_encodings_are_tagged() {
    use serde::Deserialize as _;
    use serde::de::value::{Error, MapDeserializer};
    let only_unit = MapDeserializer::<_, Error>::new([("unit_id", 7u8)].into_iter());
    let m = RegisterMap::deserialize(only_unit).unwrap();
    assert_eq!(m, RegisterMap { unit_id: 7, ..RegisterMap::default() });
    let typo = MapDeserializer::<_, Error>::new([("unit", 7u8)].into_iter());
    assert!(RegisterMap::deserialize(typo).is_err());
    let float = MapDeserializer::<_, Error>::new([("kind", "float32")].into_iter());
    assert_eq!(PositionEncoding::deserialize(float).unwrap(), PositionEncoding::Float32);
    let order = serde::de::value::StrDeserializer::<Error>::new("low_first");
    assert_eq!(WordOrder::deserialize(order).unwrap(), WordOrder::LowFirst);
    let table = serde::de::value::StrDeserializer::<Error>::new("holding");
    assert_eq!(RegisterTable::deserialize(table).unwrap(), RegisterTable::Holding);
}
