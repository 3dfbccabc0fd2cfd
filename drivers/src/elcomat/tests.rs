//! Tests of the codec (property-tested) and of the driver against a scripted
//! unit over an in-memory duplex. The driver against the simulator over a pty
//! is tested in `survey_sim_servers::elcomat_server`.

use super::*;
use crate::error::ErrorKind;
use crate::traits::{AcReading, AcState, Autocollimator};
use proptest::prelude::*;
use std::time::Duration;
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader, DuplexStream, duplex};

fn decode_all(bytes: &[u8]) -> Vec<Result<Reply, DecodeError>> {
    let mut d = Decoder::new();
    d.push(bytes);
    std::iter::from_fn(|| d.next_reply()).collect()
}

#[test]
fn commands_encode_and_decode() {
    assert_eq!(encode_command(Command::Absolute), b"a\r\n");
    assert_eq!(encode_command(Command::Relative), b"r\r\n");
    let mut d = CommandDecoder::new();
    d.push(b"a\r\nr\nx\r\n a \rA\r\n");
    let got: Vec<_> = std::iter::from_fn(|| d.next_command()).collect();
    assert_eq!(got.len(), 5);
    assert_eq!(got[0], Ok(Command::Absolute));
    assert_eq!(got[1], Ok(Command::Relative));
    assert!(matches!(got[2], Err(DecodeError::UnknownCommand { .. })));
    assert_eq!(got[3], Ok(Command::Absolute));
    // Upper-case `A` starts streaming on a real unit: not served here.
    assert!(matches!(got[4], Err(DecodeError::UnknownCommand { .. })));
}

#[test]
fn replies_of_every_form_decode() {
    assert_eq!(decode_reply(b"4 003 -12.35 3.20"), Ok(Reply::absolute(-12.35, 3.2)));
    assert_eq!(decode_reply(b"2 103 0.00 -0.01"), Ok(Reply::relative(0.0, -0.01)));
    assert_eq!(decode_reply(b"4 000"), Ok(Reply::no_reflection(ReplyKind::Absolute)));
    assert_eq!(decode_reply(b"2 100"), Ok(Reply::no_reflection(ReplyKind::Relative)));
    // DLS test data: six decimals and tab separators are fine.
    assert_eq!(decode_reply(b"4\t003  4.500000 2.300000"), Ok(Reply::absolute(4.5, 2.3)));
    // An invalid status with values (a real unit may send them).
    let r = decode_reply(b"4 001 12.00 0.00").unwrap();
    assert_eq!((r.validity(), r.reading()), (1, None));
    assert_eq!(Reply::no_reflection(ReplyKind::Absolute).reading(), None);
    assert_eq!(encode_reply(&Reply::absolute(-12.345, 3.2)), b"4 003 -12.35 3.20\r\n".to_vec());
    assert_eq!(encode_reply(&Reply::no_reflection(ReplyKind::Relative)), b"2 100\r\n".to_vec());
}

#[test]
fn garbled_lines_are_errors() {
    let bad: [&[u8]; 9] = [
        b"4 003 1.0",
        b"4 003 1.0 2.0 3.0",
        b"5 003 1.0 2.0",
        b"4 03 1.0 2.0",
        b"4 0x3 1.0 2.0",
        b"4 003 1.0 abc",
        b"4 003 inf 2.0",
        b"4 003",
        b"4 003 \xff 2.0",
    ];
    for line in bad {
        assert!(decode_reply(line).is_err(), "{:?}", String::from_utf8_lossy(line));
    }
    assert!(matches!(decode_reply(b"4 003"), Err(DecodeError::MissingValues { .. })));
    assert!(matches!(decode_reply(b"4 003 \xff 2.0"), Err(DecodeError::NotAscii { .. })));
}

#[test]
fn line_ends_and_blank_lines() {
    let got = decode_all(b"4 003 1.00 2.00\r\n2 103 3.00 4.00\n4 000\r\r\n  \r\n2 100\r");
    assert_eq!(
        got,
        vec![
            Ok(Reply::absolute(1.0, 2.0)),
            Ok(Reply::relative(3.0, 4.0)),
            Ok(Reply::no_reflection(ReplyKind::Absolute)),
            Ok(Reply::no_reflection(ReplyKind::Relative)),
        ]
    );
}

#[test]
fn an_overlong_line_is_one_error_then_decoding_resumes() {
    let mut bytes = vec![b'7'; 3 * MAX_LINE];
    bytes.extend_from_slice(b"\r\n4 003 1.00 2.00\r\n");
    let got = decode_all(&bytes);
    assert_eq!(got, vec![Err(DecodeError::LineTooLong), Ok(Reply::absolute(1.0, 2.0))]);
    // Exactly MAX_LINE bytes is still a line (garbled, but not too long).
    let mut exact = vec![b' '; MAX_LINE - 5];
    exact.extend_from_slice(b"4 000\r\n");
    assert_eq!(decode_all(&exact), vec![Ok(Reply::no_reflection(ReplyKind::Absolute))]);
}

#[test]
fn discard_pending_skips_the_rest_of_a_cut_line() {
    let mut d = Decoder::new();
    d.push(b"4 003 1.00 2.00\r\n4 003 5.0");
    assert_eq!(d.discard_pending(), Discarded { lines: 1, partial_bytes: 9 });
    d.push(b"0 6.00\r\n2 103 7.00 8.00\r\n");
    assert_eq!(d.next_reply(), Some(Ok(Reply::relative(7.0, 8.0))));
    assert_eq!(d.next_reply(), None);
    // Nothing partial: nothing skipped.
    d.push(b"4 000\r\n");
    assert_eq!(d.discard_pending(), Discarded { lines: 1, partial_bytes: 0 });
    d.push(b"4 000\r\n");
    assert_eq!(d.next_reply(), Some(Ok(Reply::no_reflection(ReplyKind::Absolute))));
}

fn reply_strategy() -> impl Strategy<Value = Reply> {
    let kind = prop_oneof![Just(ReplyKind::Absolute), Just(ReplyKind::Relative)];
    (kind, 0u16..1000, proptest::option::of((-1.0e5..1.0e5f64, -1.0e5..1.0e5f64))).prop_map(|(kind, status, values)| {
        // A valid status needs values.
        let status = if values.is_none() && status % 10 == 3 { status - 3 } else { status };
        Reply { kind, status, values }
    })
}

fn same_within_print(a: &Reply, b: &Reply) -> bool {
    let tol = 0.5 * 10f64.powi(-(REPLY_DECIMALS as i32)) + 1e-9;
    a.kind == b.kind
        && a.status == b.status
        && match (a.values, b.values) {
            (None, None) => true,
            (Some((x, y)), Some((x2, y2))) => (x - x2).abs() <= tol && (y - y2).abs() <= tol,
            _ => false,
        }
}

/// A stream of lines: valid replies, garbled lines and an overlong one.
fn stream_strategy() -> impl Strategy<Value = Vec<u8>> {
    let line = prop_oneof![
        4 => reply_strategy().prop_map(|r| encode_reply(&r)),
        1 => proptest::collection::vec(any::<u8>(), 0..20).prop_map(|mut v| { v.extend_from_slice(b"\r\n"); v }),
        1 => Just(vec![b'9'; MAX_LINE + 10]),
        1 => prop_oneof![Just(b"\n".to_vec()), Just(b"\r".to_vec()), Just(b"\r\n".to_vec())],
    ];
    proptest::collection::vec(line, 0..8).prop_map(|v| v.concat())
}

proptest! {
    #[test]
    fn every_reply_form_round_trips(r in reply_strategy()) {
        let got = decode_all(&encode_reply(&r));
        prop_assert_eq!(got.len(), 1);
        let back = got[0].clone().unwrap();
        prop_assert!(same_within_print(&r, &back), "{:?} -> {:?}", r, back);
        // Printing a decoded reply again gives the same bytes.
        prop_assert_eq!(encode_reply(&back), encode_reply(&r));
    }

    #[test]
    fn chunk_boundaries_do_not_matter(bytes in stream_strategy(), cuts in proptest::collection::vec(any::<prop::sample::Index>(), 0..6)) {
        let whole = decode_all(&bytes);
        // Every single boundary.
        for i in 0..=bytes.len() {
            let mut d = Decoder::new();
            d.push(&bytes[..i]);
            d.push(&bytes[i..]);
            let split: Vec<_> = std::iter::from_fn(|| d.next_reply()).collect();
            prop_assert_eq!(&split, &whole, "split at {}", i);
        }
        // Several boundaries at once.
        let mut at: Vec<usize> = cuts.iter().map(|c| c.index(bytes.len() + 1)).collect();
        at.sort_unstable();
        let mut d = Decoder::new();
        let mut start = 0;
        for &c in &at {
            d.push(&bytes[start..c]);
            start = c;
        }
        d.push(&bytes[start..]);
        let split: Vec<_> = std::iter::from_fn(|| d.next_reply()).collect();
        prop_assert_eq!(&split, &whole);
    }

    #[test]
    fn arbitrary_bytes_never_panic(chunks in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..400), 0..6)) {
        let mut d = Decoder::new();
        let mut c = CommandDecoder::new();
        for chunk in &chunks {
            d.push(chunk);
            c.push(chunk);
            prop_assert!(d.buffered_len() <= MAX_LINE);
            while d.next_reply().is_some() {}
            while c.next_command().is_some() {}
        }
        d.discard_pending();
        prop_assert_eq!(d.buffered_len(), 0);
    }
}

/// A scripted instrument on the far end of a duplex: reads one command
/// line, then the test writes what it wants.
struct FakeUnit {
    lines: BufReader<tokio::io::ReadHalf<DuplexStream>>,
    tx: tokio::io::WriteHalf<DuplexStream>,
}

impl FakeUnit {
    async fn expect(&mut self, cmd: &str) {
        let mut line = String::new();
        self.lines.read_line(&mut line).await.unwrap();
        assert_eq!(line, format!("{cmd}\r\n"));
    }
    async fn send(&mut self, bytes: &[u8]) {
        self.tx.write_all(bytes).await.unwrap();
    }
}

fn rig(timeout: Duration) -> (ElcomatDriver<DuplexStream>, FakeUnit) {
    let (a, b) = duplex(4096);
    let (rx, tx) = tokio::io::split(b);
    (ElcomatDriver::new(a).with_timeout(timeout), FakeUnit { lines: BufReader::new(rx), tx })
}

#[tokio::test(start_paused = true)]
async fn a_late_reply_is_not_the_answer_to_the_next_request() {
    let (mut drv, mut unit) = rig(Duration::from_secs(2));
    let first = tokio::spawn(async move {
        let e = drv.read().await.unwrap_err();
        (drv, e)
    });
    unit.expect("a").await;
    // No answer: the driver times out (virtual time).
    let (mut drv, e) = first.await.unwrap();
    assert_eq!(e.kind, ErrorKind::Timeout);
    // The late answer arrives, part of another line too.
    unit.send(b"4 003 1.00 1.00\r\n4 003 9.").await;
    let second = tokio::spawn(async move { (drv.read().await, drv) });
    unit.expect("a").await;
    unit.send(b"99 9.99\r\n4 003 2.00 -2.00\r\n").await;
    let (r, _drv) = second.await.unwrap();
    assert_eq!(r.unwrap(), AcReading { x_arcsec: 2.0, y_arcsec: -2.0 });
}

#[tokio::test(start_paused = true)]
async fn a_reply_of_the_other_type_is_skipped_and_faults_are_classified() {
    let (mut drv, mut unit) = rig(Duration::from_millis(500));
    let task = tokio::spawn(async move {
        let rel = drv.read_relative().await;
        let dev = drv.read().await;
        let st = drv.status().await;
        let garbled = drv.read().await;
        let ok = drv.read().await;
        let closed = drv.read().await;
        (rel, dev, st, garbled, ok, closed)
    });
    unit.expect("r").await;
    unit.send(b"4 003 1.00 1.00\r\n2 103 0.50 -0.25\r\n").await;
    unit.expect("a").await;
    unit.send(b"4 000\r\n").await;
    unit.expect("a").await;
    unit.send(b"4 000\r\n").await;
    unit.expect("a").await;
    unit.send(b"4 0\xff3 ### 1.00\r\n").await;
    unit.expect("a").await;
    unit.send(b"4 003 3.00 4.00\r\n").await;
    unit.expect("a").await;
    unit.send(b"4 003 1.2").await;
    drop(unit);
    let (rel, dev, st, garbled, ok, closed) = task.await.unwrap();
    assert_eq!(rel.unwrap(), AcReading { x_arcsec: 0.5, y_arcsec: -0.25 });
    let dev = dev.unwrap_err();
    assert_eq!((dev.kind, dev.code), (ErrorKind::Device, Some(0)));
    assert!(dev.message.contains("no reflection"), "{dev}");
    assert_eq!(st.unwrap(), AcState::NoReflection);
    assert_eq!(garbled.unwrap_err().kind, ErrorKind::Garbled);
    assert_eq!(ok.unwrap(), AcReading { x_arcsec: 3.0, y_arcsec: 4.0 });
    let closed = closed.unwrap_err();
    assert_eq!(closed.kind, ErrorKind::Disconnected);
    assert!(closed.message.contains("unterminated"), "{closed}");
}

#[tokio::test]
async fn opening_a_missing_port_is_a_disconnection() {
    let e = ElcomatDriver::open_serial("/dev/does-not-exist-elcomat", 9600).unwrap_err();
    assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
}

/// Exchanges seen in public code that drives real ELCOMAT 3000s
/// (`dls-controls/elcomat3000`: `elcomat3000App/src/elcomat3000.cpp` writes
/// `a` (absolute) with LF and reads up to CR; its serial simulator
/// `etc/simulations/elcomat3000.py` answers `4 003 %f %f` CR to `a` and
/// `2 103 %f %f` CR to `r`; the status's last digit is 1 X valid, 2 Y valid,
/// 3 both). Our codec reads them as that code does.
#[test]
fn the_public_record_decodes_as_the_epics_driver_reads_it() {
    let mut d = Decoder::new();
    d.push(b"4 003 4.500000 2.300000\r2 103 4.500000 2.300000\r4 001 12.000000 0.000000\r");
    let abs = d.next_reply().unwrap().unwrap();
    assert_eq!((abs.kind, abs.reading()), (ReplyKind::Absolute, Some(AcReading { x_arcsec: 4.5, y_arcsec: 2.3 })));
    let rel = d.next_reply().unwrap().unwrap();
    assert_eq!((rel.kind, rel.reading()), (ReplyKind::Relative, Some(AcReading { x_arcsec: 4.5, y_arcsec: 2.3 })));
    let partial = d.next_reply().unwrap().unwrap();
    assert_eq!((partial.validity(), partial.reading()), (1, None), "only X valid: no reading");
    assert_eq!(partial.validity_text(), "only X valid");
    // We send what that code sends: the letter, then a line end it accepts (LF ends it).
    let a = encode_command(Command::Absolute);
    assert_eq!(a.first(), Some(&b'a'));
    assert_eq!(a.last(), Some(&b'\n'));
    assert_eq!(decode_command(b"a"), Ok(Command::Absolute));
}
