use super::*;
use survey_sims::faults::FaultKind;
use tokio::io::duplex;

/// An echo "device" on one end of a duplex pipe.
async fn echo(mut device: tokio::io::DuplexStream) {
    let mut buf = [0u8; 64];
    while let Ok(n) = device.read(&mut buf).await {
        if n == 0 || device.write_all(&buf[..n]).await.is_err() {
            return;
        }
    }
}

async fn ask(client: &mut tokio::io::DuplexStream, line: &[u8]) -> Option<Vec<u8>> {
    client.write_all(line).await.ok()?;
    let mut buf = vec![0u8; line.len()];
    match tokio::time::timeout(Duration::from_millis(200), client.read_exact(&mut buf)).await {
        Ok(Ok(_)) => Some(buf),
        _ => None,
    }
}

/// A relay with `rates` (stalls held `stall_for`) in front of an echo
/// device; the client's end.
fn echoed(rates: FaultRates, stall_for: Duration, seed: u64, faults: &Faults) -> tokio::io::DuplexStream {
    let (client, relay_client) = duplex(256);
    let (relay_device, device) = duplex(256);
    tokio::spawn(echo(device));
    let r = Relay { faults: faults.clone(), rates, stall_for, framing: Framing::Chunks, seed };
    tokio::spawn(async move { relay(relay_client, relay_device, &r).await });
    client
}

#[tokio::test]
async fn without_faults_every_reply_passes_unchanged() {
    let faults = Faults::new();
    let mut client = echoed(FaultRates::default(), Duration::ZERO, 1, &faults);
    for k in 0..20u8 {
        assert_eq!(ask(&mut client, &[b'a' + k, b'\n']).await, Some(vec![b'a' + k, b'\n']));
    }
    assert_eq!(faults.injected().replies(), 20);
    assert_eq!(faults.injected().get(FaultKind::Timeout), 0);
}

#[tokio::test]
async fn each_kind_of_fault_does_what_it_says() {
    let faults = Faults::new();
    // Only drops: the client gets no reply.
    let drops = FaultRates { timeout: 1.0, ..FaultRates::default() };
    let mut client = echoed(drops, Duration::ZERO, 2, &faults);
    assert_eq!(ask(&mut client, b"x\n").await, None);
    assert_eq!(faults.injected().get(FaultKind::Timeout), 1);

    // Only garbles: a reply of the right length, not the one sent.
    let garbles = FaultRates { garbled: 1.0, ..FaultRates::default() };
    let mut client = echoed(garbles, Duration::ZERO, 3, &faults);
    let reply = ask(&mut client, b"hello\n").await.expect("a reply");
    assert_ne!(reply, b"hello\n");

    // Only disconnects: the link closes after half the reply.
    let cuts = FaultRates { disconnect: 1.0, ..FaultRates::default() };
    let mut client = echoed(cuts, Duration::ZERO, 4, &faults);
    client.write_all(b"abcd\n").await.unwrap();
    let mut got = Vec::new();
    client.read_to_end(&mut got).await.unwrap();
    assert_eq!(got, b"ab");

    // Only stalls: the reply comes, late.
    let stalls = FaultRates { stall: 1.0, ..FaultRates::default() };
    let mut client = echoed(stalls, Duration::from_millis(400), 5, &faults);
    assert_eq!(ask(&mut client, b"q\n").await, None, "not within the client's 200 ms");
    let mut late = [0u8; 2];
    client.read_exact(&mut late).await.unwrap();
    assert_eq!(&late, b"q\n", "then delivered");
    let i = faults.injected();
    assert_eq!((i.get(FaultKind::Garbled), i.get(FaultKind::Disconnect), i.get(FaultKind::Stall)), (1, 1, 1));
}

/// Armed faults apply in order, one reply each, and are counted; a
/// device fault drawn at its rate is armed for the simulator.
#[tokio::test]
async fn armed_faults_apply_in_order_and_device_faults_are_armed_behind() {
    let faults = Faults::new();
    let mut client = echoed(FaultRates::default(), Duration::ZERO, 6, &faults);
    faults.arm(Fault::Pass);
    faults.arm(Fault::Drop);
    faults.arm(Fault::Trailing(b"9\n".to_vec()));
    faults.arm(Fault::Garble(Garble::edit("only b", |r: &[u8]| (r[0] == b'b').then(|| b"B\n".to_vec()))));
    assert_eq!(ask(&mut client, b"1\n").await, Some(b"1\n".to_vec()), "passes");
    assert_eq!(ask(&mut client, b"2\n").await, None, "dropped");
    assert_eq!(ask(&mut client, b"3\n").await, Some(b"3\n".to_vec()));
    let mut stale = [0u8; 2];
    client.read_exact(&mut stale).await.unwrap();
    assert_eq!(&stale, b"9\n", "the stale line came after it");
    assert_eq!(ask(&mut client, b"a\n").await, Some(b"a\n".to_vec()), "the edit does not fit: it waits");
    assert_eq!(ask(&mut client, b"b\n").await, Some(b"B\n".to_vec()));
    let i = faults.injected();
    assert_eq!((i.get(FaultKind::Timeout), i.get(FaultKind::Stall), i.get(FaultKind::Garbled)), (1, 1, 1));

    let refusals = FaultRates { device: 1.0, ..FaultRates::default() };
    let mut client = echoed(refusals, Duration::ZERO, 7, &faults);
    assert_eq!(ask(&mut client, b"r\n").await, Some(b"r\n".to_vec()));
    assert!(matches!(faults.take_device(|_| true), Some(Fault::Refuse(None))));
    assert_eq!(faults.injected().get(FaultKind::Device), 1, "counted where the simulator takes it");
}

/// An SLCAN adapter's stream: at a drop rate of 1, every reply (command
/// answers, SDO responses) is dropped and counted, while transmit
/// acknowledgements and a heartbeat pass, however the stream is cut into
/// chunks; a garble lands in a reply, never in an acknowledgement.
#[tokio::test]
async fn slcan_framing_faults_the_replies_only() {
    let stream: &[u8] = b"\rz\rt58584B41600037120000\rt705105\r\x07V1013\rz\r";
    for cut in [1usize, 5, 17, stream.len()] {
        let (mut client, relay_client) = duplex(256);
        let (relay_device, mut device) = duplex(256);
        let faults = Faults::new();
        let drops = FaultRates { timeout: 1.0, ..FaultRates::default() };
        let r = Relay {
            rates: drops,
            framing: Framing::SlcanCanopen,
            seed: 6,
            ..Relay::armed(faults.clone(), Framing::Chunks)
        };
        tokio::spawn(async move { relay(relay_client, relay_device, &r).await });
        for part in stream.chunks(cut) {
            device.write_all(part).await.unwrap();
            device.flush().await.unwrap();
            tokio::task::yield_now().await;
        }
        drop(device);
        let mut got = Vec::new();
        client.read_to_end(&mut got).await.unwrap();
        assert_eq!(got, b"z\rt705105\rz\r", "cut every {cut} bytes");
        let i = faults.injected();
        assert_eq!((i.replies(), i.get(FaultKind::Timeout)), (4, 4), "cut every {cut} bytes");
    }

    let (mut client, relay_client) = duplex(256);
    let (relay_device, mut device) = duplex(256);
    let faults = Faults::new();
    let garbles = FaultRates { garbled: 1.0, ..FaultRates::default() };
    let r = Relay {
        rates: garbles,
        framing: Framing::SlcanCanopen,
        seed: 7,
        ..Relay::armed(faults.clone(), Framing::Chunks)
    };
    tokio::spawn(async move { relay(relay_client, relay_device, &r).await });
    device.write_all(b"z\rt58580000000000000000\rz\r").await.unwrap();
    drop(device);
    let mut got = Vec::new();
    client.read_to_end(&mut got).await.unwrap();
    assert_eq!(got.len(), 26);
    assert_eq!((&got[..2], &got[24..]), (&b"z\r"[..], &b"z\r"[..]), "the acknowledgements pass");
    assert_ne!(&got[2..24], b"t58580000000000000000\r", "the SDO response is garbled");
    assert_eq!(faults.injected().get(FaultKind::Garbled), 1);
}

#[test]
fn slcan_replies_are_answers_and_sdo_responses() {
    for (message, reply) in [
        (&b"\r"[..], true),
        (b"\x07", true),
        (b"V1013\r", true),
        (b"t58586000000000000000\r", true),
        (b"t58186000000000000000\r", true),
        (b"t58086000000000000000\r", false),
        (b"z\r", false),
        (b"Z\r", false),
        (b"t705105\r", false),
        (b"t08580000000000000000\r", false),
        (b"T123456781AB\r", false),
        (b"?#\r", true),
    ] {
        assert_eq!(slcan_reply(message), reply, "{:?}", String::from_utf8_lossy(message));
    }
}

/// Each framing cuts whole messages, whatever the chunks, and tells the
/// replies from what no request waits for.
#[test]
fn framings_cut_whole_messages() {
    // (framing, bytes, the messages' lengths and whether each is a reply)
    type Case = (Framing, Vec<u8>, Vec<(usize, bool)>);
    let cases: [Case; 4] = [
        (Framing::Lines, b"12\n-1,\"x\"\r\n".to_vec(), vec![(3, true), (8, true)]),
        (
            Framing::Emscon,
            [
                &12i32.to_le_bytes()[..],
                &8i32.to_le_bytes(),
                &[0; 4],
                &12i32.to_le_bytes(),
                &0i32.to_le_bytes(),
                &[1; 4],
            ]
            .concat(),
            vec![(12, false), (12, true)],
        ),
        (
            Framing::ModbusTcp,
            vec![0, 1, 0, 0, 0, 3, 1, 6, 0, 0, 1, 0, 0, 0, 5, 1, 3, 2, 0, 5],
            vec![(9, true), (11, true)],
        ),
        (Framing::ModbusRtu, vec![1, 3, 2, 0, 5, 0xAA, 0xBB, 1, 0x83, 2, 0xCC, 0xDD], vec![(7, true), (5, true)]),
    ];
    for (framing, bytes, want) in cases {
        for cut in 1..=bytes.len() {
            let mut pending = Vec::new();
            let mut got = Vec::new();
            for part in bytes.chunks(cut) {
                pending.extend_from_slice(part);
                got.extend(framing.take(&mut pending).into_iter().map(|(m, r)| (m.len(), r)));
            }
            assert_eq!((got, pending.len()), (want.clone(), 0), "{framing:?} cut every {cut}");
        }
    }
}
