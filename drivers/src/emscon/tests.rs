use super::codes::{command as cmd, data_type as dt, status, status_change};
use super::frame::*;
use super::packets::*;
use super::stream::{ContinuousTimeModeData, MAX_POINTS_PER_PACKET, MeasValue, MultiMeasResult};
use super::*;
use crate::error::ErrorKind;
use crate::traits::{Tracker, TrackerState};
use proptest::prelude::*;
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt, DuplexStream, duplex};

fn le(words: &[i32]) -> Vec<u8> {
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}

fn result(status: i32, x: f64) -> SingleMeasResult {
    SingleMeasResult {
        status,
        meas_mode: 0,
        is_try_mode: false,
        val: [x, -2.5, 3.25],
        std: [0.01, 0.02, 0.03],
        std_total: 0.04,
        pointing_error: [0.0; 3],
        apriori_std: [0.011, 0.012, 0.013],
        apriori_std_total: 0.02,
        temperature: 20.5,
        pressure: 1013.25,
        humidity: 45.0,
    }
}

#[test]
fn requests_have_the_header_layouts() {
    assert_eq!(Request::Initialize.encode(), le(&[12, 0, 7]));
    assert_eq!(Request::StartMeasurement.encode(), le(&[12, 0, 49]));
    assert_eq!(Request::GetMeasurementStatusInfo.encode(), le(&[12, 0, 122]));
    assert_eq!(Request::SetUnits(SystemUnits::SURVEY).encode(), le(&[32, 0, 5, 1, 1, 0, 0, 0]));
    assert_eq!(Request::SetMeasurementMode(0).encode(), le(&[16, 0, 24, 0]));
    assert_eq!(Request::SetCoordinateSystemType(0).encode(), le(&[16, 0, 26, 0]));
    let p = StationaryModeData { meas_time_ms: 1000, use_adm: true };
    assert_eq!(Request::SetStationaryModeParams(p).encode(), le(&[20, 0, 28, 1000, 1]));
    let mut find = le(&[20, 0, 63]);
    find.extend(2500.5f64.to_le_bytes());
    assert_eq!(Request::FindReflector { approx_distance: 2500.5 }.encode(), find);
    // GoPositionCT, 40 bytes: the three doubles right after the command (pack(4)), then bUseADM.
    // The bytes cesapi 1.1.3 sends for GoPosition(0, 3500, 1000, -250) (captured from it).
    let go = Request::GoPosition { position: [3500.0, 1000.0, -250.0], use_adm: false }.encode();
    let captured = "280000000000000037000000000000000058ab400000000000408f400000000000406fc000000000";
    let hex: String = go.iter().map(|b| format!("{b:02x}")).collect();
    assert_eq!(hex, captured);
    assert_eq!(go.len(), GO_POSITION_CT_LEN);
}

#[test]
fn replies_have_the_header_layouts() {
    let bytes = Reply::SingleMeas(result(0, 1234.5)).encode();
    assert_eq!(bytes.len(), 156);
    assert_eq!(&bytes[..20], &le(&[156, 2, 0, 0, 0])[..]);
    let f = |at: usize| f64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
    // #pragma pack(4): dVal1 right after bIsTryMode, no padding.
    assert_eq!((f(20), f(28), f(36)), (1234.5, -2.5, 3.25));
    assert_eq!((f(44), f(68), f(100), f(124)), (0.01, 0.04, 0.011, 0.02));
    assert_eq!((f(132), f(140), f(148)), (20.5, 1013.25, 45.0));

    assert_eq!(Reply::answer(cmd::INITIALIZE, 0).encode(), le(&[16, 0, 7, 0]));
    assert_eq!(Reply::Error { command: 49, status: 10012 }.encode(), le(&[16, 1, 49, 10012]));
    assert_eq!(Reply::StatusChange(25).encode(), le(&[12, 8, 25]));
    let s = SystemStatus {
        last_result_status: 0,
        tracker_processor_status: 5,
        laser_status: 3,
        adm_status: 2,
        version: [3, 6, 1],
        weather_monitor_status: 1,
        flags: 0,
        tracker_serial_number: 390_001,
    };
    let a = Reply::Answer(Answer { command: 1, status: 0, body: AnswerBody::SystemStatus(s) });
    assert_eq!(a.encode(), le(&[56, 0, 1, 0, 0, 5, 3, 2, 3, 6, 1, 1, 0, 390_001]));
    let m = MeasurementStatusInfo { last_result_status: 0, info: 2048 };
    let a = Reply::Answer(Answer { command: 122, status: 0, body: AnswerBody::MeasurementStatusInfo(m) });
    assert_eq!(a.encode(), le(&[24, 0, 122, 0, 0, 2048]));
}

#[test]
fn answers_decode_by_command_and_status() {
    // A failed GetSystemStatus may be a bare BasicCommandRT...
    let bare = Reply::decode(&le(&[16, 0, 1, 10012])).unwrap();
    assert_eq!(bare, Reply::answer(1, 10012));
    // ...a successful one may not.
    assert!(matches!(Reply::decode(&le(&[16, 0, 1, 0])), Err(DecodeError::WrongLength { .. })));
    // An answer to a command not modelled here is kept raw.
    let units = Reply::decode(&le(&[36, 0, 6, 0, 1, 1, 0, 0, 0])).unwrap();
    assert_eq!(units, Reply::Answer(Answer { command: 6, status: 0, body: AnswerBody::Other(le(&[1, 1, 0, 0, 0])) }));
    assert_eq!(Reply::decode(&le(&[16, 0, 141, 0])), Err(DecodeError::UnsupportedCommand { command: 141 }));
    assert_eq!(Reply::decode(&le(&[12, 12, 0])), Err(DecodeError::UnknownType { data_type: 12 }));
    assert_eq!(Reply::decode(&le(&[12, -1, 0])), Err(DecodeError::UnknownType { data_type: -1 }));
    assert!(matches!(Reply::decode(&le(&[16, 2, 0, 0])), Err(DecodeError::WrongLength { .. })));
    assert!(matches!(Reply::decode(&le(&[16, 8, 25, 0])), Err(DecodeError::WrongLength { .. })));
    assert_eq!(Reply::decode(&le(&[20, 7, 0, 1, 2])), Ok(Reply::Other { data_type: 7, body: le(&[0, 1, 2]) }));
    assert!(matches!(Reply::decode(&le(&[13, 8, 25])), Err(DecodeError::SizeMismatch { .. })));
    // Requests: only commands, only the modelled ones, exact sizes.
    assert_eq!(Request::decode(&le(&[12, 1, 7])), Err(DecodeError::UnexpectedType { data_type: 1 }));
    assert_eq!(Request::decode(&le(&[12, 0, 6])), Err(DecodeError::UnsupportedCommand { command: 6 }));
    assert!(matches!(Request::decode(&le(&[16, 0, 7, 0])), Err(DecodeError::WrongLength { .. })));
    assert_eq!(Request::command_of(&le(&[16, 0, 7, 0])), Some(7));
}

#[test]
fn absurd_sizes_lose_the_framing_until_cleared() {
    for size in [0, 11, 4097, -1, i32::MAX] {
        let mut d = ReplyDecoder::new();
        d.push(&le(&[size]));
        assert_eq!(d.next_reply(), Some(Err(DecodeError::AbsurdSize { size: i64::from(size) })), "{size}");
        assert!(d.is_lost());
        d.push(&Reply::StatusChange(25).encode());
        assert_eq!(d.next_reply(), None);
        d.clear();
        d.push(&Reply::StatusChange(25).encode());
        assert_eq!(d.next_reply(), Some(Ok(Reply::StatusChange(25))));
    }
}

#[test]
fn codes_are_named_as_in_the_header() {
    assert_eq!(status::describe(10012), "ES_RS_SensorNotWarmedUp");
    assert_eq!(status::describe(39), "ES_RS_TrackerNotInitialized");
    assert_eq!(status::describe(99), "ES_RS_NoTriggerBoard");
    assert_eq!(status::describe(10021), "ES_RS_ATRHardwareProblem");
    assert_eq!(status::describe(100), "ES_ResultStatus 100");
    assert_eq!(status_change::describe(25), "ES_SSC_MeasStatus_NotReady");
    assert_eq!(status_change::describe(151), "ES_SCC_InitializationStatusChanged");
    assert_eq!(status_change::describe(999), "ES_SSC_ServerStarted");
    assert_eq!(cmd::describe(49), "ES_C_StartMeasurement");
    assert!(cmd::is_known(142) && !cmd::is_known(141) && !cmd::is_known(50));
}

/// The status field of an answer with one byte changed as the simulator's
/// relay changes it (XOR 0x5a): the header defines 0..=99 and
/// 10001..=10021, so a change of the status's second, third or fourth byte
/// reads as no status at all (`ES_RS_AllOK` becomes 23040, 5898240,
/// 1509949440), while its first byte reads as another defined status.
#[test]
fn a_garbled_status_field_is_no_status_of_the_header() {
    for code in [0, 1, 3, 36, 99, 10_001, 10_013, 10_021] {
        assert!(status::is_defined(code), "{code}");
    }
    for code in [-1, 100, 9_999, 10_000, 10_022, 23_040, i32::MIN, i32::MAX] {
        assert!(!status::is_defined(code), "{code}");
    }
    let frame = Reply::answer(cmd::START_MEASUREMENT, status::ALL_OK).encode();
    let at = 12; // header (8), command (4), then `enum ES_ResultStatus status`
    let mut read = Vec::new();
    for byte in 0..4 {
        let mut garbled = frame.clone();
        garbled[at + byte] ^= 0x5a;
        let Ok(Reply::Answer(a)) = Reply::decode(&garbled) else { panic!("byte {byte}: still an answer") };
        read.push((a.status, status::is_defined(a.status)));
    }
    assert_eq!(read, [(90, true), (23_040, false), (5_898_240, false), (1_509_949_440, false)]);
    assert_eq!(status::describe(23_040), "ES_ResultStatus 23040");
}

// ---------------------------------------------------------------------------
// Property tests
// ---------------------------------------------------------------------------

fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![-1e5f64..1e5, any::<f64>().prop_filter("finite", |v| v.is_finite())]
}

fn arb_request() -> impl Strategy<Value = Request> {
    let units = (0..6, 0..3, 0..2, 0..7, 0..1).prop_map(|(length, angle, temperature, pressure, humidity)| {
        SystemUnits { length, angle, temperature, pressure, humidity }
    });
    prop_oneof![
        Just(Request::Initialize),
        units.prop_map(Request::SetUnits),
        any::<i32>().prop_map(Request::SetCoordinateSystemType),
        any::<i32>().prop_map(Request::SetMeasurementMode),
        (any::<i32>(), any::<bool>()).prop_map(|(meas_time_ms, use_adm)| Request::SetStationaryModeParams(
            StationaryModeData { meas_time_ms, use_adm }
        )),
        Just(Request::StartMeasurement),
        Just(Request::GetSystemStatus),
        Just(Request::GetMeasurementStatusInfo),
        Just(Request::GoLastMeasuredPoint),
        finite().prop_map(|approx_distance| Request::FindReflector { approx_distance }),
        ([finite(), finite(), finite()], any::<bool>())
            .prop_map(|(position, use_adm)| Request::GoPosition { position, use_adm }),
        (any::<i32>(), any::<i32>())
            .prop_map(|(stationary, continuous)| Request::SetStatisticMode { stationary, continuous }),
        (any::<i32>(), any::<i32>(), any::<bool>(), any::<i32>()).prop_map(
            |(time_separation_ms, number_of_points, use_region, region_type)| {
                Request::SetContinuousTimeModeParams(ContinuousTimeModeData {
                    time_separation_ms,
                    number_of_points,
                    use_region,
                    region_type,
                })
            }
        ),
        Just(Request::StopMeasurement),
    ]
}

fn arb_multi() -> impl Strategy<Value = MultiMeasResult> {
    let point = (any::<i32>(), any::<i32>(), any::<i32>(), [finite(), finite(), finite()])
        .prop_map(|(status, time1, time2, val)| MeasValue { status, time1, time2, val });
    (
        any::<i32>(),
        any::<i32>(),
        any::<bool>(),
        [finite(), finite(), finite()],
        proptest::collection::vec(point, 0..=MAX_POINTS_PER_PACKET),
    )
        .prop_map(|(status, meas_mode, is_try_mode, env, points)| MultiMeasResult {
            status,
            meas_mode,
            is_try_mode,
            temperature: env[0],
            pressure: env[1],
            humidity: env[2],
            points,
        })
}

fn arb_result() -> impl Strategy<Value = SingleMeasResult> {
    let f3 = || [finite(), finite(), finite()];
    (
        any::<i32>(),
        any::<i32>(),
        any::<bool>(),
        f3(),
        f3(),
        f3(),
        f3(),
        [finite(), finite(), finite(), finite(), finite()],
    )
        .prop_map(|(status, meas_mode, is_try_mode, val, std, pointing_error, apriori_std, e)| SingleMeasResult {
            status,
            meas_mode,
            is_try_mode,
            val,
            std,
            std_total: e[0],
            pointing_error,
            apriori_std,
            apriori_std_total: e[1],
            temperature: e[2],
            pressure: e[3],
            humidity: e[4],
        })
}

/// An extended result: a standard one with drawn covariances.
fn arb_result2() -> impl Strategy<Value = SingleMeasResult2> {
    (arb_result(), [finite(), finite(), finite()], [finite(), finite(), finite()]).prop_map(|(m, covar, apriori)| {
        SingleMeasResult2 {
            status: m.status,
            meas_mode: m.meas_mode,
            is_try_mode: m.is_try_mode,
            val: m.val,
            std: m.std,
            std_total: m.std_total,
            covar,
            pointing_error: m.pointing_error,
            apriori_std: m.apriori_std,
            apriori_std_total: m.apriori_std_total,
            apriori_covar: apriori,
            temperature: m.temperature,
            pressure: m.pressure,
            humidity: m.humidity,
        }
    })
}

fn arb_answer() -> impl Strategy<Value = Answer> {
    let bare_cmd =
        prop_oneof![Just(7), Just(5), Just(24), Just(26), Just(28), Just(49), Just(62), Just(63), Just(30), Just(52)];
    let status_body =
        (any::<i32>(), any::<i32>(), any::<[i32; 3]>(), any::<[i32; 5]>()).prop_map(|(a, b, version, r)| {
            SystemStatus {
                last_result_status: a,
                tracker_processor_status: b,
                laser_status: r[0],
                adm_status: r[1],
                version,
                weather_monitor_status: r[2],
                flags: r[3],
                tracker_serial_number: r[4],
            }
        });
    let other_cmd = (0..=142i32).prop_filter("unmodelled", |c| {
        cmd::is_known(*c) && ![1, 5, 7, 24, 26, 28, 49, 62, 63, 30, 52, 122].contains(c)
    });
    prop_oneof![
        (bare_cmd, any::<i32>()).prop_map(|(command, status)| Answer { command, status, body: AnswerBody::Empty }),
        (any::<i32>(), status_body).prop_map(|(status, s)| Answer {
            command: 1,
            status,
            body: AnswerBody::SystemStatus(s)
        }),
        (any::<i32>(), any::<i32>(), any::<i32>()).prop_map(|(status, last_result_status, info)| Answer {
            command: 122,
            status,
            body: AnswerBody::MeasurementStatusInfo(MeasurementStatusInfo { last_result_status, info }),
        }),
        (prop_oneof![Just(1), Just(122)], (1..i32::MAX)).prop_map(|(command, status)| Answer {
            command,
            status,
            body: AnswerBody::Empty
        }),
        (other_cmd, any::<i32>(), proptest::collection::vec(any::<u8>(), 0..64))
            .prop_map(|(command, status, raw)| Answer { command, status, body: AnswerBody::Other(raw) }),
    ]
}

fn arb_reply() -> impl Strategy<Value = Reply> {
    prop_oneof![
        arb_answer().prop_map(Reply::Answer),
        (any::<i32>(), any::<i32>()).prop_map(|(command, status)| Reply::Error { command, status }),
        arb_result().prop_map(Reply::SingleMeas),
        arb_result2().prop_map(Reply::SingleMeas2),
        any::<i32>().prop_map(Reply::StatusChange),
        arb_multi().prop_map(Reply::MultiMeas),
        (prop_oneof![4..=7i32, 10..=11i32], proptest::collection::vec(any::<u8>(), 4..200))
            .prop_map(|(data_type, body)| Reply::Other { data_type, body }),
    ]
}

fn decode_replies(chunks: &[&[u8]]) -> Vec<Result<Reply, DecodeError>> {
    let mut d = ReplyDecoder::new();
    let mut out = Vec::new();
    for c in chunks {
        d.push(c);
        out.extend(std::iter::from_fn(|| d.next_reply()));
    }
    out
}

fn decode_requests(chunks: &[&[u8]]) -> Vec<Result<Request, (DecodeError, Option<i32>)>> {
    let mut d = RequestDecoder::new();
    let mut out = Vec::new();
    for c in chunks {
        d.push(c);
        out.extend(std::iter::from_fn(|| d.next_request()));
    }
    out
}

fn chunked<'a>(bytes: &'a [u8], sizes: &[usize]) -> Vec<&'a [u8]> {
    let mut out = Vec::new();
    let mut rest = bytes;
    for s in sizes.iter().cycle() {
        if rest.is_empty() {
            break;
        }
        let (a, b) = rest.split_at((*s).min(rest.len()));
        out.push(a);
        rest = b;
    }
    out
}

proptest! {
    #[test]
    fn every_request_round_trips(req in arb_request()) {
        let bytes = req.encode();
        prop_assert_eq!(bytes.len(), i32::from_le_bytes(bytes[..4].try_into().unwrap()) as usize);
        prop_assert_eq!(Request::decode(&bytes), Ok(req));
        prop_assert_eq!(decode_requests(&[&bytes]), vec![Ok(req)]);
    }

    #[test]
    fn every_reply_round_trips(reply in arb_reply()) {
        let bytes = reply.encode();
        prop_assert!(bytes.len() <= MAX_PACKET_LEN);
        prop_assert_eq!(Reply::decode(&bytes), Ok(reply.clone()));
    }

    #[test]
    fn packets_split_anywhere_decode_the_same(replies in proptest::collection::vec(arb_reply(), 1..4), req in arb_request()) {
        let stream: Vec<u8> = replies.iter().flat_map(Reply::encode).collect();
        let whole = decode_replies(&[&stream]);
        prop_assert_eq!(whole, replies.into_iter().map(Ok).collect::<Vec<_>>());
        let whole = decode_replies(&[&stream]);
        for at in 0..=stream.len() {
            prop_assert_eq!(&decode_replies(&[&stream[..at], &stream[at..]]), &whole);
        }
        let singles: Vec<&[u8]> = stream.chunks(1).collect();
        prop_assert_eq!(&decode_replies(&singles), &whole);
        let bytes = req.encode();
        for at in 0..=bytes.len() {
            prop_assert_eq!(decode_requests(&[&bytes[..at], &bytes[at..]]), vec![Ok(req)]);
        }
    }

    #[test]
    fn arbitrary_bytes_never_panic_and_chunking_does_not_matter(
        bytes in proptest::collection::vec(any::<u8>(), 0..600),
        sizes in proptest::collection::vec(1usize..40, 1..20),
        header in prop_oneof![Just(None), (12i32..300, -2i32..14).prop_map(Some)],
    ) {
        // Half the cases start with a plausible header so decoding goes deep.
        let mut bytes = bytes;
        if let Some((size, ty)) = header {
            let mut h = le(&[size, ty]);
            h.extend(bytes);
            bytes = h;
        }
        let chunks = chunked(&bytes, &sizes);
        prop_assert_eq!(decode_replies(&chunks), decode_replies(&[&bytes]));
        prop_assert_eq!(decode_requests(&chunks), decode_requests(&[&bytes]));
        let _ = Reply::decode(&bytes);
        let _ = Request::decode(&bytes);
        let _ = Request::command_of(&bytes);
    }
}

// ---------------------------------------------------------------------------
// The driver over an in-memory stream, against a scripted peer
// ---------------------------------------------------------------------------

fn quick() -> EmsconConfig {
    EmsconConfig {
        measurement_time_ms: 20,
        timeouts: EmsconTimeouts {
            request_ms: 300,
            measurement_margin_ms: 300,
            resync_grace_ms: 30,
            ..Default::default()
        },
        ..EmsconConfig::default()
    }
}

/// Read one request from the peer's side.
async fn next_request(io: &mut DuplexStream, d: &mut RequestDecoder) -> Option<Request> {
    let mut buf = [0u8; 256];
    loop {
        if let Some(r) = d.next_request() {
            return Some(r.unwrap());
        }
        let n = io.read(&mut buf).await.ok()?;
        if n == 0 {
            return None;
        }
        d.push(&buf[..n]);
    }
}

/// A driver whose set-up was answered, and the peer's end.
async fn set_up() -> (EmsconTracker<DuplexStream>, DuplexStream, RequestDecoder) {
    let (ours, mut theirs) = duplex(4096);
    let peer = tokio::spawn(async move {
        let mut d = RequestDecoder::new();
        let mut seen = Vec::new();
        for _ in 0..6 {
            let r = next_request(&mut theirs, &mut d).await.unwrap();
            theirs.write_all(&Reply::answer(r.command(), 0).encode()).await.unwrap();
            seen.push(r);
        }
        (theirs, d, seen)
    });
    let t = EmsconTracker::open(ours, quick()).await.unwrap();
    let (theirs, d, seen) = peer.await.unwrap();
    let params = StationaryModeData { meas_time_ms: 20, use_adm: false };
    let want = [
        Request::Initialize,
        Request::SetUnits(SystemUnits::SURVEY),
        Request::SetCoordinateSystemType(0),
        Request::SetMeasurementMode(0),
        Request::SetStatisticMode { stationary: 0, continuous: 0 },
        Request::SetStationaryModeParams(params),
    ];
    assert_eq!(seen, want);
    (t, theirs, d)
}

#[tokio::test]
async fn status_changes_and_stale_packets_around_an_answer() {
    let (mut t, mut peer, mut d) = set_up().await;
    let script = tokio::spawn(async move {
        assert_eq!(next_request(&mut peer, &mut d).await, Some(Request::StartMeasurement));
        let mut out = Reply::StatusChange(status_change::MEAS_STATUS_NOT_READY).encode();
        out.extend(Reply::answer(cmd::SET_UNITS, 0).encode()); // stale: another command's answer
        out.extend(Reply::Other { data_type: dt::REFLECTOR_POS_RESULT, body: vec![0; 28] }.encode());
        out.extend(Reply::answer(cmd::START_MEASUREMENT, 0).encode()); // continuous-mode acknowledgement
        out.extend(Reply::SingleMeas(result(0, 1500.0)).encode());
        // Arrives while idle: applied before the next request.
        out.extend(Reply::StatusChange(status_change::MEAS_STATUS_READY).encode());
        peer.write_all(&out).await.unwrap();
        assert_eq!(next_request(&mut peer, &mut d).await, Some(Request::StartMeasurement));
        let mut out = Reply::StatusChange(status_change::MEAS_STATUS_NOT_READY).encode();
        out.extend(Reply::answer(cmd::START_MEASUREMENT, status::NO_STATIONARY_RESULT).encode());
        peer.write_all(&out).await.unwrap();
        peer
    });
    let m = t.measure().await.unwrap();
    assert_eq!((m.x_mm, m.y_mm, m.z_mm), (1500.0, -2.5, 3.25));
    assert_eq!(m.std_dev_mm, [0.01, 0.02, 0.03]);
    assert_eq!(m.measurement_time_s, 0.02);
    // The weather station's air, kept with the measurement (dTemperature, dPressure, dHumidity).
    let air = m.environment.expect("the air the result carries");
    assert_eq!((air.temperature_c, air.pressure_hpa, air.humidity_pct), (20.5, 1013.25, 45.0));
    assert_eq!(t.state(), TrackerState::TargetLocked);
    assert_eq!(t.status_changes_seen(), 1);
    let e = t.measure().await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(10_009)), "{e}");
    assert!(e.message.contains("ES_RS_NoStationaryResult"), "{e}");
    assert_eq!(t.status_changes_seen(), 3);
    assert_eq!(t.last_status_change(), Some(status_change::MEAS_STATUS_NOT_READY));
    assert_eq!(t.state(), TrackerState::BeamBroken);
    drop(script.await.unwrap());
}

#[tokio::test]
async fn absurd_size_is_garbled_and_the_next_request_resynchronises() {
    let (mut t, mut peer, mut d) = set_up().await;
    let script = tokio::spawn(async move {
        assert_eq!(next_request(&mut peer, &mut d).await, Some(Request::GetMeasurementStatusInfo));
        // A size field of 1 GB, then the rest of "its" bytes.
        peer.write_all(&le(&[1 << 30, 0, 122, 0, 0, 2048])).await.unwrap();
        let r = next_request(&mut peer, &mut d).await.unwrap();
        let m = MeasurementStatusInfo { last_result_status: 0, info: 2048 };
        let a = Answer { command: r.command(), status: 0, body: AnswerBody::MeasurementStatusInfo(m) };
        peer.write_all(&Reply::Answer(a).encode()).await.unwrap();
        // A truncated packet, then the end of the stream.
        assert_eq!(next_request(&mut peer, &mut d).await, Some(Request::StartMeasurement));
        peer.write_all(&Reply::SingleMeas(result(0, 1.0)).encode()[..100]).await.unwrap();
    });
    let e = t.measurement_status_info().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Garbled, "{e}");
    assert!(e.message.contains("absurd packet size"), "{e}");
    assert_eq!(t.measurement_status_info().await.unwrap().info, 2048);
    let e = t.measure().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
    assert!(e.message.contains("after 100 bytes"), "{e}");
    script.await.unwrap();
    let started = tokio::time::Instant::now();
    assert_eq!(t.status().await.unwrap_err().kind, ErrorKind::Disconnected);
    assert!(started.elapsed() < Duration::from_millis(100));
    assert!(!t.is_connected());
}

/// A status the header does not define, in an answer, an error packet or a
/// measurement result, is a garbled packet (a link fault: the connection is
/// rebuilt); a defined one stays the tracker's device fault with its code.
#[tokio::test]
async fn an_undefined_status_is_a_garbled_packet_and_a_defined_one_a_device_fault() {
    let (mut t, mut peer, mut d) = set_up().await;
    let script = tokio::spawn(async move {
        let r = next_request(&mut peer, &mut d).await.unwrap();
        peer.write_all(&Reply::answer(r.command(), 23_040).encode()).await.unwrap();
        let r = next_request(&mut peer, &mut d).await.unwrap();
        peer.write_all(&Reply::Error { command: r.command(), status: 10_000 }.encode()).await.unwrap();
        assert_eq!(next_request(&mut peer, &mut d).await, Some(Request::StartMeasurement));
        peer.write_all(&Reply::SingleMeas(result(-7, 1.0)).encode()).await.unwrap();
        assert_eq!(next_request(&mut peer, &mut d).await, Some(Request::StartMeasurement));
        peer.write_all(&Reply::SingleMeas(result(status::SENSOR_NOT_STABLE, 1.0)).encode()).await.unwrap();
        assert_eq!(next_request(&mut peer, &mut d).await, Some(Request::StartMeasurement));
        peer.write_all(&Reply::SingleMeas(result(0, 2.0)).encode()).await.unwrap();
        peer
    });
    let before = t.state();
    let e = t.measurement_status_info().await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Garbled, None), "{e}");
    assert!(e.message.contains("ES_ResultStatus 23040 is no status of the emScon header"), "{e}");
    let e = t.measurement_status_info().await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Garbled, None), "{e}");
    assert!(e.message.contains("ES_ResultStatus 10000"), "{e}");
    let e = t.measure().await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Garbled, None), "{e}");
    assert!(e.message.contains("ES_ResultStatus -7"), "{e}");
    assert_eq!(t.state(), before, "a garbled status says nothing of the tracker");
    let e = t.measure().await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(10_013)), "{e}");
    assert!(e.message.contains("ES_RS_SensorNotStable"), "{e}");
    assert_eq!(t.measure().await.unwrap().x_mm, 2.0);
    drop(script.await.unwrap());
}

#[tokio::test]
async fn bad_configuration_is_usage() {
    let (ours, _theirs) = duplex(64);
    let cfg = EmsconConfig { measurement_time_ms: 0, ..quick() };
    assert_eq!(EmsconTracker::open(ours, cfg).await.unwrap_err().kind, ErrorKind::Usage);
    let (ours, _theirs) = duplex(64);
    let cfg = EmsconConfig { approx_distance_mm: f64::NAN, ..quick() };
    assert_eq!(EmsconTracker::open(ours, cfg).await.unwrap_err().kind, ErrorKind::Usage);
}

#[test]
fn config_serde_names_and_defaults() {
    let cfg: EmsconConfig = config_from_pairs();
    assert_eq!(cfg.measurement_time_ms, 500);
    assert_eq!(cfg.timeouts.request_ms, 3000);
    assert!(cfg.initialize && !cfg.use_adm);
}

/// Deserialize from key/value pairs (no serde_json in this crate).
fn config_from_pairs() -> EmsconConfig {
    use serde::Deserialize;
    use serde::de::value::{Error, MapDeserializer};
    let pairs = vec![("measurement_time_ms", 500u32)];
    EmsconConfig::deserialize(MapDeserializer::<_, Error>::new(pairs.into_iter())).unwrap()
}

/// A tracker that answers a stationary measurement with the extended result
/// (left in `ES_SM_Extended` by other software): decoded, the standard fields
/// kept.
#[tokio::test]
async fn an_extended_result_is_decoded_like_a_standard_one() {
    let (mut t, mut peer, mut d) = set_up().await;
    let standard = result(0, 1500.25);
    let extended = SingleMeasResult2 {
        status: 0,
        meas_mode: standard.meas_mode,
        is_try_mode: false,
        val: standard.val,
        std: standard.std,
        std_total: standard.std_total,
        covar: [1e-6, -2e-6, 3e-6],
        pointing_error: standard.pointing_error,
        apriori_std: standard.apriori_std,
        apriori_std_total: standard.apriori_std_total,
        apriori_covar: [0.0; 3],
        temperature: standard.temperature,
        pressure: standard.pressure,
        humidity: standard.humidity,
    };
    let bytes = Reply::SingleMeas2(extended).encode();
    assert_eq!(bytes.len(), SINGLE_MEAS_RESULT2_LEN);
    let f = |at: usize| f64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
    // dVal1 at 20, dCovar12 after dStdTotal (20 + 7 * 8), dTemperature at 20 + 20 * 8.
    assert_eq!((f(20), f(76), f(180)), (1500.25, 1e-6, standard.temperature));
    let script = tokio::spawn(async move {
        let r = next_request(&mut peer, &mut d).await.unwrap();
        assert_eq!(r, Request::StartMeasurement);
        peer.write_all(&bytes).await.unwrap();
        peer
    });
    let got = t.measure_result().await.unwrap();
    assert_eq!(got, SingleMeasResult::from(extended));
    assert_eq!(got.val, standard.val);
    script.await.unwrap();
}

/// `point_at`: GoPosition with the position, FindReflector at its distance,
/// then whether a reflector is locked; each refusal or a search that locks
/// nothing is a device fault naming the position.
#[tokio::test]
async fn pointing_goes_to_the_position_searches_and_checks_the_lock() {
    let (mut t, mut peer, mut d) = set_up().await;
    let p = [2500.0, 800.0, -300.0];
    let distance = (2500f64.powi(2) + 800f64.powi(2) + 300f64.powi(2)).sqrt();
    let info = |found: bool| {
        let info = if found { super::codes::measurement_status_info::REFLECTOR_FOUND } else { 0 };
        Reply::Answer(Answer {
            command: cmd::GET_MEASUREMENT_STATUS_INFO,
            status: 0,
            body: AnswerBody::MeasurementStatusInfo(MeasurementStatusInfo { last_result_status: 0, info }),
        })
        .encode()
    };
    let script = tokio::spawn(async move {
        // Locked.
        assert_eq!(next_request(&mut peer, &mut d).await, Some(Request::GoPosition { position: p, use_adm: false }));
        peer.write_all(&Reply::answer(cmd::GO_POSITION, 0).encode()).await.unwrap();
        assert_eq!(next_request(&mut peer, &mut d).await, Some(Request::FindReflector { approx_distance: distance }));
        peer.write_all(&Reply::answer(cmd::FIND_REFLECTOR, 0).encode()).await.unwrap();
        assert_eq!(next_request(&mut peer, &mut d).await, Some(Request::GetMeasurementStatusInfo));
        peer.write_all(&info(true)).await.unwrap();
        // The search answers AllOK but nothing is locked.
        for (r, answer) in [(cmd::GO_POSITION, 0), (cmd::FIND_REFLECTOR, 0)] {
            assert_eq!(next_request(&mut peer, &mut d).await.map(|q| q.command()), Some(r));
            peer.write_all(&Reply::answer(r, answer).encode()).await.unwrap();
        }
        assert_eq!(next_request(&mut peer, &mut d).await, Some(Request::GetMeasurementStatusInfo));
        peer.write_all(&info(false)).await.unwrap();
        // The turn refused (a position out of the tracker's range).
        assert_eq!(next_request(&mut peer, &mut d).await.map(|q| q.command()), Some(cmd::GO_POSITION));
        peer.write_all(&Reply::answer(cmd::GO_POSITION, status::PARAMETER1_OUT_OF_RANGE_NOK).encode()).await.unwrap();
        peer
    });
    t.point_at(p).await.unwrap();
    assert_eq!(t.state(), TrackerState::TargetLocked);
    let e = t.point_at(p).await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(i64::from(status::MEASUREMENT_STATUS_NOT_READY))), "{e}");
    assert!(e.message.contains("no reflector locked at (2500.0, 800.0, -300.0) mm"), "{e}");
    assert_eq!(t.state(), TrackerState::BeamBroken);
    let e = t.point_at(p).await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Device, "{e}");
    assert!(
        e.message.contains("ES_C_GoPosition") && e.message.contains("(pointing at (2500.0, 800.0, -300.0) mm)"),
        "{e}"
    );
    assert!(t.can_point());
    drop(script.await.unwrap());
}
