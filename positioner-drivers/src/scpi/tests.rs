//! Tests of the codec (property-tested) and of the driver over an in-memory
//! stream. The driver against the simulator over TCP is tested in
//! `survey_sim_servers::scpi_server`.

use super::*;
use proptest::prelude::*;
use survey_drivers::error::ErrorKind;
use survey_drivers::traits::{Limit, Positioner};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

fn decode_all(chunks: &[&[u8]], max: usize) -> Vec<Result<String, CodecError>> {
    let mut d = Decoder::new(max);
    let mut out = Vec::new();
    for c in chunks {
        d.push(c);
        while let Some(l) = d.next_line() {
            out.push(l);
        }
    }
    out
}

#[test]
fn commands_encode_as_documented() {
    let a = Address::default();
    let line = |c: Command| String::from_utf8(c.encode(a)).unwrap();
    assert_eq!(line(Command::SetTarget(-90.0)), "CONT1:AXIS(1):POS:COMM -90\n");
    assert_eq!(line(Command::SetTarget(45.125)), "CONT1:AXIS(1):POS:COMM 45.125\n");
    assert_eq!(line(Command::Start), "CONT1:AXIS(1):MOT:STAR\n");
    assert_eq!(line(Command::Stop), "CONT1:AXIS(1):MOT:STOP\n");
    assert_eq!(line(Command::PositionQuery), "CONT1:AXIS(1):POS:CURR?\n");
    assert_eq!(line(Command::StatusQuery), "CONT1:AXIS(1):STAT?\n");
    assert_eq!(line(Command::SetVelocity(2.5)), "CONT1:AXIS(1):VEL:COMM 2.5\n");
    assert_eq!(line(Command::ErrorQuery), "SYST:ERR?\n");
    assert_eq!(line(Command::ClearStatus), "*CLS\n");
    assert_eq!(
        line(Command::TableData { column: Column::Reverse, start: 32, values: vec![0.001, -0.5] }),
        "CONT1:AXIS(1):CORR:TABL:REV 32,0.001,-0.5\n"
    );
    assert_eq!(line(Command::TablePointsQuery(Column::Forward)), "CONT1:AXIS(1):CORR:TABL:POIN?\n");
    assert_eq!(line(Command::SetCorrection(true)), "CONT1:AXIS(1):CORR:STAT ON\n");
    let other = Address { controller: 2, axis: 3 };
    assert_eq!(Command::Start.to_line(other), "CONT2:AXIS(3):MOT:STAR");
    // Extreme magnitudes keep lines short and exact.
    assert_eq!(format_number(1e-300), "1E-300");
    assert_eq!(parse_number(&format_number(f64::MAX)).unwrap(), f64::MAX);
}

#[test]
fn parse_accepts_long_forms_and_any_case() {
    let p = Command::parse(":controller2:axis(4):position:command 12.5").unwrap();
    assert_eq!(p.address, Some(Address { controller: 2, axis: 4 }));
    assert_eq!(p.command, Command::SetTarget(12.5));
    let p = Command::parse("CONT:AXIS:MOT:STAR").unwrap();
    assert_eq!(p, Parsed { address: Some(Address::default()), command: Command::Start });
    assert_eq!(Command::parse("syst:err:next?").unwrap().command, Command::ErrorQuery);
    for bad in [
        "CONT1:AXIS(1):POS:COMM",
        "CONT1:AXIS(1):POS:COMM abc",
        "CONT1:AXIS():STAT?",
        "FOO?",
        "*CLS 1",
        "CONT1:AXIS(1):STAT? 3",
    ] {
        assert!(Command::parse(bad).is_err(), "{bad}");
    }
}

#[test]
fn replies_parse_and_refuse_garbage() {
    assert_eq!(parse_number(" -89.95 ").unwrap(), -89.95);
    assert_eq!(parse_number("1.5E-3").unwrap(), 1.5e-3);
    for bad in ["", "abc", "inf", "NaN", "1e999", "12,5", "0x10", "1 2"] {
        assert!(parse_number(bad).is_err(), "{bad}");
    }
    assert_eq!(parse_status("4865").unwrap(), StatusWord(4865));
    for bad in ["70000", "-1", "12.0", "", "0x10"] {
        assert!(parse_status(bad).is_err(), "{bad}");
    }
    assert_eq!(ErrorEntry::parse("0,\"No error\"").unwrap(), ErrorEntry::none());
    assert_eq!(
        ErrorEntry::parse("-222, \"Data out of range;said \"\"no\"\"\"").unwrap(),
        ErrorEntry::new(-222, "Data out of range;said \"no\"")
    );
    for bad in ["-222", "x,\"a\"", "-222,a", "-222,\"a\"b\"", "-222,\"a"] {
        assert!(ErrorEntry::parse(bad).is_err(), "{bad}");
    }
    assert!(parse_bool("on").unwrap());
    assert!(!parse_bool("0").unwrap());
    assert_eq!(parse_count("720").unwrap(), 720);
    assert!(parse_count("-1").is_err());
}

/// Exchanges seen in public code that drives real MI-4190/4192 controllers:
/// `csun-rf-lab/antennameasure`, `+MotionController/MI4190.m` (the commands,
/// `UNIT:POS?` with 6 = degree, `SYST:ERR:ALL?` answered `0, "No error"`),
/// and `Ugikie/PositionControl`, `Docs/testcomms.txt`
/// (`CONT1:AXIS(1):POS:COMM -90.000000`).
#[test]
fn the_public_record_parses_as_our_codec_reads_it() {
    let seen = Command::parse("CONT1:AXIS(1):POS:COMM -90.000000").unwrap();
    assert_eq!(seen.command, Command::SetTarget(-90.0));
    for (line, command) in [
        ("CONT1:AXIS(2):MOT:STAR", Command::Start),
        ("CONT1:AXIS(2):MOT:STOP", Command::Stop),
        ("CONT1:AXIS(2):POS:CURR?", Command::PositionQuery),
        ("CONT1:AXIS(2):VEL:CURR?", Command::VelocityQuery),
        ("CONT1:AXIS(2):STAT?", Command::StatusQuery),
        ("CONT1:AXIS(2):UNIT:POS?", Command::UnitsQuery),
    ] {
        let parsed = Command::parse(line).unwrap();
        assert_eq!(parsed.command, command, "{line}");
        assert_eq!(parsed.command.to_line(Address { controller: 1, axis: 2 }), line, "we send what they send");
    }
    assert_eq!(Command::parse("SYST:ERR:ALL?").unwrap().command, Command::ErrorQueryAll);
    assert_eq!(Command::ErrorQueryAll.to_line(Address::default()), "SYST:ERR:ALL?");
    assert_eq!(ErrorEntry::parse_list("0, \"No error\"").unwrap(), vec![ErrorEntry::new(0, "No error")]);
    let two = ErrorEntry::parse_list("-222, \"Data out of range\", -113,\"Undefined header;say \"\"hi\"\"\"").unwrap();
    assert_eq!(
        two,
        vec![ErrorEntry::new(-222, "Data out of range"), ErrorEntry::new(-113, "Undefined header;say \"hi\"")]
    );
    for bad in ["", "0", "0, \"No error\",", "0, \"a\" x", "0 \"a\""] {
        assert!(ErrorEntry::parse_list(bad).is_err(), "{bad:?}");
    }
}

#[test]
fn status_bits_as_documented() {
    // The logged MI-4192 at rest: latch, active, indexed, status changed.
    let w = StatusWord(4865);
    assert!(!w.moving() && !w.fault() && w.limit().is_none());
    // The word carries no in-position or correction bit: the driver decides those.
    let s = StatusWord(bits::IN_MOTION | bits::FORWARD_LIMIT | bits::UNUSED).to_status(None, false, true);
    assert!(s.moving && s.correction_enabled && !s.in_position);
    assert_eq!(s.limit, Some(Limit::Upper));
    assert_eq!(StatusWord(bits::REVERSE_LIMIT).limit(), Some(Limit::Lower));
    assert!(StatusWord(1 << 4).fault() && StatusWord(1 << 6).fault());
    assert!(!StatusWord(bits::UNUSED).fault() && !StatusWord(bits::UNUSED).moving());
    assert_eq!(StatusWord(bits::ERROR_LIMIT).fault_names(), "error limit active");
    assert_eq!(bits::UNUSED, 0xE000, "bits 13-15");
}

#[test]
fn error_codes_classify() {
    for usage in [
        COMMAND_ERROR,
        SYNTAX_ERROR,
        UNDEFINED_HEADER,
        HEADER_SUFFIX_OUT_OF_RANGE,
        SETTINGS_CONFLICT,
        DATA_OUT_OF_RANGE,
        TOO_MUCH_DATA,
    ] {
        assert_eq!(ErrorEntry::new(usage, "x").kind(), Some(ErrorKind::Usage), "{usage}");
    }
    for device in [EXECUTION_ERROR, -240, DEVICE_SPECIFIC_ERROR, QUEUE_OVERFLOW, 305, 0x8611] {
        assert_eq!(ErrorEntry::new(device, "x").kind(), Some(ErrorKind::Device), "{device}");
    }
    assert_eq!(ErrorEntry::none().kind(), None);
}

#[test]
fn decoder_handles_crlf_garbage_and_long_lines() {
    let out = decode_all(&[b"12.5\r\n\xff\xfe\n4865\n", b"abcdefghijk\nok\n"], 8);
    assert_eq!(
        out,
        vec![
            Ok("12.5".into()),
            Err(CodecError::NonAscii),
            Ok("4865".into()),
            Err(CodecError::LineTooLong(8)),
            Ok("ok".into())
        ]
    );
    // A control byte is garbage too; TAB is not.
    assert_eq!(decode_all(&[b"a\x07b\n\tx\n"], 64), vec![Err(CodecError::NonAscii), Ok("\tx".into())]);
    // Clearing a partial line skips its tail.
    let mut d = Decoder::default();
    d.push(b"12.");
    assert_eq!(d.clear(), 3);
    d.push(b"5\n7\n");
    assert_eq!(d.next_line(), Some(Ok("7".into())));
    assert!(d.is_empty());
}

#[tokio::test]
async fn driver_over_an_in_memory_stream() {
    // A scripted peer: answers the position query, then one stale line
    // arrives before the status query and must not be taken for its answer.
    let (ours, mut theirs) = tokio::io::duplex(4096);
    let mut p = ScpiPositioner::from_stream(ours).named("duplex");
    let peer = tokio::spawn(async move {
        let mut d = Decoder::default();
        let mut buf = [0u8; 256];
        let mut seen = Vec::new();
        while seen.len() < 3 {
            let n = theirs.read(&mut buf).await.unwrap();
            d.push(&buf[..n]);
            while let Some(l) = d.next_line() {
                let l = l.unwrap();
                let reply = if l.ends_with("UNIT:POS?") {
                    "6\n"
                } else if l.ends_with("POS:CURR?") {
                    "12.5\n1234\n"
                } else {
                    "8992\n"
                };
                theirs.write_all(reply.as_bytes()).await.unwrap();
                seen.push(l);
            }
        }
        seen
    });
    assert_eq!(p.readout().await.unwrap(), 12.5);
    // Let the stale line land in our buffer.
    tokio::task::yield_now().await;
    let s = p.status().await.unwrap();
    assert!(s.in_position && !s.correction_enabled && !s.moving && s.fault.is_none(), "{s:?}");
    let seen = peer.await.unwrap();
    // The units are checked once, before the first request that uses a position.
    assert_eq!(seen, vec!["CONT1:AXIS(1):UNIT:POS?", "CONT1:AXIS(1):POS:CURR?", "CONT1:AXIS(1):STAT?"]);
    // The peer is gone: end of stream.
    let e = p.readout().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
    assert!(!p.is_connected());
}

/// `correction_state`: `CORR:STAT?` only with the unverified commands (else
/// unknown, and nothing is sent); `1`/`0` read as on/off, anything else is
/// a garbled reply.
#[tokio::test]
async fn the_correction_state_is_asked_only_with_the_unverified_commands() {
    let (ours, mut theirs) = tokio::io::duplex(4096);
    let cfg = ScpiConfig { unverified_commands: true, ..ScpiConfig::default() };
    let mut p = ScpiPositioner::with_config(ours, cfg).named("duplex");
    let peer = tokio::spawn(async move {
        let mut d = Decoder::default();
        let mut buf = [0u8; 256];
        let mut seen = Vec::new();
        for reply in ["1\n", "OFF\n", "maybe\n"] {
            let line = loop {
                if let Some(l) = d.next_line() {
                    break l.unwrap();
                }
                let n = theirs.read(&mut buf).await.unwrap();
                d.push(&buf[..n]);
            };
            theirs.write_all(reply.as_bytes()).await.unwrap();
            seen.push(line);
        }
        seen
    });
    assert_eq!(p.correction_state().await.unwrap(), Some(true));
    assert_eq!(p.correction_state().await.unwrap(), Some(false));
    let e = p.correction_state().await.unwrap_err();
    assert!(e.kind == ErrorKind::Garbled && e.message.contains("CORR:STAT?"), "{e}");
    assert_eq!(peer.await.unwrap(), vec!["CONT1:AXIS(1):CORR:STAT?"; 3]);

    // Without them: unknown, and the line stays silent.
    let (ours, mut theirs) = tokio::io::duplex(4096);
    let mut p = ScpiPositioner::from_stream(ours).named("duplex");
    assert_eq!(p.correction_state().await.unwrap(), None);
    drop(p);
    let mut rest = Vec::new();
    theirs.read_to_end(&mut rest).await.unwrap();
    assert!(rest.is_empty(), "sent {rest:?}");
}

fn arb_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        -1e4f64..1e4,
        any::<f64>().prop_filter("finite", |v| v.is_finite()),
        (-1000i64..1000).prop_map(|i| i as f64 / 8.0),
    ]
}

fn arb_command() -> impl Strategy<Value = Command> {
    let column = prop_oneof![Just(Column::Forward), Just(Column::Reverse)];
    prop_oneof![
        arb_f64().prop_map(Command::SetTarget),
        Just(Command::TargetQuery),
        Just(Command::Start),
        Just(Command::Stop),
        Just(Command::PositionQuery),
        Just(Command::StatusQuery),
        arb_f64().prop_map(Command::SetVelocity),
        Just(Command::VelocityQuery),
        Just(Command::UnitsQuery),
        Just(Command::ErrorQueryAll),
        Just(Command::ClearFault),
        Just(Command::TableClear),
        (column.clone(), 0usize..100_000, proptest::collection::vec(arb_f64(), 0..40))
            .prop_map(|(column, start, values)| Command::TableData { column, start, values }),
        column.prop_map(Command::TablePointsQuery),
        Just(Command::TableLoad),
        any::<bool>().prop_map(Command::SetCorrection),
        Just(Command::CorrectionQuery),
        Just(Command::ErrorQuery),
        Just(Command::ClearStatus),
        Just(Command::Identify),
    ]
}

proptest! {
    #[test]
    fn command_round_trip(cmd in arb_command(), controller in 1u32..100, axis in 1u32..100) {
        let address = Address { controller, axis };
        let bytes = cmd.encode(address);
        prop_assert!(bytes.len() < 2048);
        let mut d = Decoder::default();
        d.push(&bytes);
        let line = d.next_line().unwrap().unwrap();
        prop_assert!(d.next_line().is_none());
        let parsed = Command::parse(&line).unwrap();
        prop_assert_eq!(parsed.address, cmd.is_axis_command().then_some(address));
        prop_assert_eq!(parsed.command, cmd);
    }

    #[test]
    fn number_round_trip(v in arb_f64()) {
        let s = format_number(v);
        prop_assert!(s.len() <= 24, "{}", s);
        prop_assert_eq!(parse_number(&s).unwrap(), v);
    }

    #[test]
    fn error_entry_round_trip(code in any::<i32>(), text in "[ -~]{0,80}") {
        let e = ErrorEntry::new(code as i64, text);
        prop_assert_eq!(ErrorEntry::parse(&e.to_line()).unwrap(), e);
    }

    #[test]
    fn error_lists_round_trip(entries in proptest::collection::vec((any::<i32>(), "[ -~]{0,40}"), 1..5)) {
        let entries: Vec<ErrorEntry> = entries.into_iter().map(|(c, t)| ErrorEntry::new(c as i64, t)).collect();
        let line = entries.iter().map(ErrorEntry::to_line).collect::<Vec<_>>().join(", ");
        prop_assert_eq!(ErrorEntry::parse_list(&line).unwrap(), entries);
    }

    #[test]
    fn a_line_split_anywhere_decodes_the_same(cmd in arb_command()) {
        let bytes = cmd.encode(Address::default());
        let whole = decode_all(&[&bytes], Decoder::DEFAULT_MAX_LINE);
        prop_assert_eq!(whole.len(), 1);
        // Split at every boundary, and byte by byte.
        for at in 0..=bytes.len() {
            prop_assert_eq!(&decode_all(&[&bytes[..at], &bytes[at..]], Decoder::DEFAULT_MAX_LINE), &whole);
        }
        let singles: Vec<&[u8]> = bytes.chunks(1).collect();
        prop_assert_eq!(&decode_all(&singles, Decoder::DEFAULT_MAX_LINE), &whole);
    }

    #[test]
    fn arbitrary_bytes_never_panic_and_chunking_does_not_matter(
        bytes in proptest::collection::vec(any::<u8>(), 0..600),
        sizes in proptest::collection::vec(1usize..40, 1..20),
        max in 1usize..64,
    ) {
        let whole = decode_all(&[&bytes], max);
        let mut chunks = Vec::new();
        let mut rest = &bytes[..];
        for s in sizes.iter().cycle() {
            if rest.is_empty() { break; }
            let (a, b) = rest.split_at((*s).min(rest.len()));
            chunks.push(a);
            rest = b;
        }
        prop_assert_eq!(decode_all(&chunks, max), whole.clone());
        for line in whole.into_iter().flatten() {
            prop_assert!(line.len() <= max);
            let _ = Command::parse(&line);
            let _ = parse_number(&line);
            let _ = parse_status(&line);
            let _ = ErrorEntry::parse(&line);
            let _ = ErrorEntry::parse_list(&line);
        }
    }
}
