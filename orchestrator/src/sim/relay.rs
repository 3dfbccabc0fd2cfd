//! Wire faults at a rate: a relay between a client's connection and a
//! simulated instrument that, for a fraction of the instrument's replies,
//! drops the reply (the client times out), garbles a byte of it, closes the
//! link halfway through it (a disconnect), or holds it past the client's
//! timeout and then delivers it (a stall: the late reply must not be taken for
//! the next request's).
//!
//! Protocol-agnostic, so every instrument gets the same four link faults
//! whatever it speaks. A device fault in the instrument's own code is armed
//! through a [`DeviceArm`]: at its rate per request, the relay asks the
//! simulator behind it to refuse the next request with its own code (a
//! Modbus exception, an SDO abort, an SCPI error, an emScon result status);
//! the drive tripping mid-move and the broken beam are the simulators' own
//! (see [`super::Served`]). Our own design, not from an instrument's
//! documentation: a link fault looks the same on every wire.
//!
//! A fault lands on a *reply*: by default each chunk the instrument writes
//! (a request-reply instrument writes each reply at once). A wire whose
//! instrument also writes what no request waits for says so with its
//! [`Framing`]: an SLCAN adapter acknowledges every transmitted frame (`z`)
//! and passes unsolicited CAN frames (a CANopen node's heartbeat), which the
//! host never awaits; a fault there would be injected and counted, yet reach
//! nothing (a dropped acknowledgement is no timeout), so those messages pass
//! unfaulted and uncounted, and each reply meets one draw whatever chunks
//! the stream arrives in.

use rand::{Rng as _, SeedableRng as _};
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncReadExt as _, AsyncWrite, AsyncWriteExt as _};

/// The link faults a relay injects, each at its own rate per reply.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkFaults {
    /// Replies dropped.
    pub drop: f64,
    /// Replies with one byte garbled.
    pub garble: f64,
    /// Links closed halfway through a reply.
    pub disconnect: f64,
    /// Replies delivered after `stall` (past the client's timeout).
    pub stall: f64,
    /// How long a stalled reply is held, real time.
    pub stall_for: Duration,
    /// Where the replies are in the instrument's byte stream.
    pub framing: Framing,
}

impl LinkFaults {
    /// No faults.
    pub const NONE: LinkFaults = LinkFaults {
        drop: 0.0,
        garble: 0.0,
        disconnect: 0.0,
        stall: 0.0,
        stall_for: Duration::ZERO,
        framing: Framing::Chunks,
    };

    /// `rate` of all replies faulted, shared evenly among the four kinds.
    pub fn at_rate(rate: f64, stall_for: Duration) -> LinkFaults {
        let each = rate / 4.0;
        LinkFaults { drop: each, garble: each, disconnect: each, stall: each, stall_for, framing: Framing::Chunks }
    }

    /// Whether any reply is faulted.
    pub fn any(&self) -> bool {
        self.drop + self.garble + self.disconnect + self.stall > 0.0
    }
}

/// Where the replies are in what an instrument writes: what a link fault
/// lands on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Framing {
    /// Each chunk read from the instrument is one reply.
    #[default]
    Chunks,
    /// An SLCAN adapter with CANopen nodes behind it: messages end at CR or
    /// BEL. The replies are the adapter's answers to the host's commands (CR,
    /// BEL, `V`/`N`/`F` lines) and the received frames that answer a request
    /// (SDO responses, COB-IDs 0x581..=0x5FF, CiA 301). The transmit
    /// acknowledgement (`z`, `Z`) and unsolicited frames (heartbeats,
    /// emergencies, PDOs, 29-bit and remote frames) are no reply.
    SlcanCanopen,
}

/// The longest message [`Framing::SlcanCanopen`] waits for its terminator
/// before passing what it holds on as one reply (an SLCAN line is at most
/// 32 bytes and its CR).
const MAX_MESSAGE: usize = 64;

impl Framing {
    /// Cut `pending` into whole messages, each with whether it is a reply;
    /// an incomplete message stays in `pending`.
    fn take(self, pending: &mut Vec<u8>) -> Vec<(Vec<u8>, bool)> {
        match self {
            Framing::Chunks => vec![(std::mem::take(pending), true)],
            Framing::SlcanCanopen => {
                let mut out = Vec::new();
                while let Some(end) = pending.iter().position(|&b| b == b'\r' || b == 0x07) {
                    let message: Vec<u8> = pending.drain(..=end).collect();
                    let reply = slcan_reply(&message);
                    out.push((message, reply));
                }
                if pending.len() > MAX_MESSAGE {
                    out.push((std::mem::take(pending), true));
                }
                out
            }
        }
    }
}

/// Whether an SLCAN message (its terminator included) answers a request of
/// the host: see [`Framing::SlcanCanopen`].
fn slcan_reply(message: &[u8]) -> bool {
    use survey_drivers::canopen::slcan::Message;
    let line = message.strip_suffix(b"\r").unwrap_or(message);
    match Message::parse(line) {
        Ok(Message::TransmitAck | Message::OtherFrame) => false,
        Ok(Message::Frame(f)) => (0x581..=0x5FF).contains(&f.id()),
        // CR, BEL, the answers to V, N, F; and what does not parse (a host
        // waiting for an answer meets it).
        _ => true,
    }
}

/// Arms a device fault in the simulator behind a relay: at `rate` per
/// request, `arm` is called before the request is passed on (it makes the
/// simulator refuse that request with its own fault code).
#[derive(Clone)]
pub struct DeviceArm {
    /// Probability per request.
    pub rate: f64,
    /// Arms the fault.
    pub arm: Arc<dyn Fn() + Send + Sync>,
}

impl std::fmt::Debug for DeviceArm {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DeviceArm").field("rate", &self.rate).finish_non_exhaustive()
    }
}

/// Counts of what the relays did, shared by all of them.
#[derive(Debug, Default)]
pub struct Counts {
    /// Replies relayed (faulted or not).
    pub replies: AtomicU64,
    /// Replies dropped.
    pub dropped: AtomicU64,
    /// Replies garbled.
    pub garbled: AtomicU64,
    /// Links closed.
    pub disconnects: AtomicU64,
    /// Replies stalled.
    pub stalls: AtomicU64,
    /// Device faults armed (requests refused with the instrument's code).
    pub device: AtomicU64,
}

impl Counts {
    /// The counts as JSON (`{"replies", "dropped", "garbled", "disconnects", "stalls", "device"}`).
    pub fn json(&self) -> serde_json::Value {
        let get = |c: &AtomicU64| c.load(Ordering::Relaxed);
        serde_json::json!({
            "replies": get(&self.replies),
            "dropped": get(&self.dropped),
            "garbled": get(&self.garbled),
            "disconnects": get(&self.disconnects),
            "stalls": get(&self.stalls),
            "device": get(&self.device),
        })
    }
}

/// Why a relay ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ended {
    /// A disconnect was injected: the client's link was closed.
    Disconnect,
    /// One side closed (or failed).
    Closed,
}

/// Relay bytes between `client` and `device` until either side closes or a
/// disconnect is injected. Requests go to the device unchanged; each chunk
/// the device sends (a reply) meets the faults.
pub async fn relay<C, D>(client: C, device: D, faults: LinkFaults, seed: u64, counts: Arc<Counts>) -> Ended
where
    C: AsyncRead + AsyncWrite + Unpin + Send,
    D: AsyncRead + AsyncWrite + Unpin + Send,
{
    relay_with(client, device, faults, None, seed, counts).await
}

/// [`relay`], with device faults armed at a rate per request.
pub async fn relay_with<C, D>(
    client: C,
    device: D,
    faults: LinkFaults,
    arm: Option<DeviceArm>,
    seed: u64,
    counts: Arc<Counts>,
) -> Ended
where
    C: AsyncRead + AsyncWrite + Unpin + Send,
    D: AsyncRead + AsyncWrite + Unpin + Send,
{
    let (mut client_rx, mut client_tx) = tokio::io::split(client);
    let (mut device_rx, mut device_tx) = tokio::io::split(device);
    let requests = async {
        let mut buf = vec![0u8; 4096];
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xdead_beef);
        loop {
            match client_rx.read(&mut buf).await {
                Ok(0) | Err(_) => return Ended::Closed,
                Ok(n) => {
                    if let Some(a) = &arm
                        && rng.random::<f64>() < a.rate
                    {
                        (a.arm)();
                        counts.device.fetch_add(1, Ordering::Relaxed);
                        tracing::info!("sim: the next request is refused with the instrument's fault code");
                    }
                    if device_tx.write_all(&buf[..n]).await.is_err() {
                        return Ended::Closed;
                    }
                }
            }
        }
    };
    let replies = async {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut buf = vec![0u8; 4096];
        let mut pending = Vec::new();
        loop {
            let n = match device_rx.read(&mut buf).await {
                Ok(0) | Err(_) => return Ended::Closed,
                Ok(n) => n,
            };
            pending.extend_from_slice(&buf[..n]);
            // What goes to the client, in order, written at once (or before
            // a stall holds the rest).
            let mut out = Vec::new();
            for (mut message, reply) in faults.framing.take(&mut pending) {
                if !reply {
                    out.extend_from_slice(&message);
                    continue;
                }
                counts.replies.fetch_add(1, Ordering::Relaxed);
                if faults.any() {
                    let x: f64 = rng.random();
                    let mut edge = faults.drop;
                    if x < edge {
                        counts.dropped.fetch_add(1, Ordering::Relaxed);
                        tracing::info!("sim: dropped a reply");
                        continue;
                    }
                    edge += faults.garble;
                    if x < edge {
                        let i = rng.random_range(0..message.len());
                        message[i] ^= 0x5a;
                        counts.garbled.fetch_add(1, Ordering::Relaxed);
                        tracing::info!("sim: garbled a reply");
                    } else if x < edge + faults.disconnect {
                        out.extend_from_slice(&message[..message.len() / 2]);
                        let _ = client_tx.write_all(&out).await;
                        counts.disconnects.fetch_add(1, Ordering::Relaxed);
                        tracing::info!("sim: closed the link halfway through a reply");
                        return Ended::Disconnect;
                    } else if x < edge + faults.disconnect + faults.stall {
                        counts.stalls.fetch_add(1, Ordering::Relaxed);
                        tracing::info!(after = ?faults.stall_for, "sim: holding a reply past the client's timeout");
                        if !out.is_empty() && client_tx.write_all(&std::mem::take(&mut out)).await.is_err() {
                            return Ended::Closed;
                        }
                        tokio::time::sleep(faults.stall_for).await;
                    }
                }
                out.extend_from_slice(&message);
            }
            if !out.is_empty() && client_tx.write_all(&out).await.is_err() {
                return Ended::Closed;
            }
        }
    };
    let ended = tokio::select! {
        e = requests => e,
        e = replies => e,
    };
    let _ = client_tx.shutdown().await;
    ended
}

#[cfg(test)]
mod tests {
    use super::*;
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

    #[tokio::test]
    async fn without_faults_every_reply_passes_unchanged() {
        let (mut client, relay_client) = duplex(256);
        let (relay_device, device) = duplex(256);
        tokio::spawn(echo(device));
        let counts = Arc::new(Counts::default());
        tokio::spawn(relay(relay_client, relay_device, LinkFaults::NONE, 1, counts.clone()));
        for k in 0..20u8 {
            assert_eq!(ask(&mut client, &[b'a' + k, b'\n']).await, Some(vec![b'a' + k, b'\n']));
        }
        assert_eq!(counts.json()["replies"], 20);
        assert_eq!(counts.json()["dropped"], 0);
    }

    #[tokio::test]
    async fn each_kind_of_fault_does_what_it_says() {
        // Only drops: the client gets no reply.
        let (mut client, relay_client) = duplex(256);
        let (relay_device, device) = duplex(256);
        tokio::spawn(echo(device));
        let counts = Arc::new(Counts::default());
        let drops = LinkFaults { drop: 1.0, ..LinkFaults::NONE };
        tokio::spawn(relay(relay_client, relay_device, drops, 2, counts.clone()));
        assert_eq!(ask(&mut client, b"x\n").await, None);
        assert_eq!(counts.json()["dropped"], 1);

        // Only garbles: a reply of the right length, not the one sent.
        let (mut client, relay_client) = duplex(256);
        let (relay_device, device) = duplex(256);
        tokio::spawn(echo(device));
        let garbles = LinkFaults { garble: 1.0, ..LinkFaults::NONE };
        tokio::spawn(relay(relay_client, relay_device, garbles, 3, counts.clone()));
        let reply = ask(&mut client, b"hello\n").await.expect("a reply");
        assert_ne!(reply, b"hello\n");

        // Only disconnects: the link closes after half the reply.
        let (mut client, relay_client) = duplex(256);
        let (relay_device, device) = duplex(256);
        tokio::spawn(echo(device));
        let cuts = LinkFaults { disconnect: 1.0, ..LinkFaults::NONE };
        tokio::spawn(relay(relay_client, relay_device, cuts, 4, counts.clone()));
        client.write_all(b"abcd\n").await.unwrap();
        let mut got = Vec::new();
        client.read_to_end(&mut got).await.unwrap();
        assert_eq!(got, b"ab");

        // Only stalls: the reply comes, late.
        let (mut client, relay_client) = duplex(256);
        let (relay_device, device) = duplex(256);
        tokio::spawn(echo(device));
        let stalls = LinkFaults { stall: 1.0, stall_for: Duration::from_millis(400), ..LinkFaults::NONE };
        tokio::spawn(relay(relay_client, relay_device, stalls, 5, counts.clone()));
        assert_eq!(ask(&mut client, b"q\n").await, None, "not within the client's 200 ms");
        let mut late = [0u8; 2];
        client.read_exact(&mut late).await.unwrap();
        assert_eq!(&late, b"q\n", "then delivered");
        let c = counts.json();
        assert_eq!(
            (c["garbled"].as_u64(), c["disconnects"].as_u64(), c["stalls"].as_u64()),
            (Some(1), Some(1), Some(1))
        );
    }
    /// An SLCAN adapter's stream: at a drop rate of 1, every reply (command
    /// answers, SDO responses) is dropped and counted, while transmit
    /// acknowledgements and a heartbeat pass, however the stream is cut
    /// into chunks; a garble lands in a reply, never in an acknowledgement.
    #[tokio::test]
    async fn slcan_framing_faults_the_replies_only() {
        let stream: &[u8] = b"\rz\rt58584B41600037120000\rt705105\r\x07V1013\rz\r";
        for cut in [1usize, 5, 17, stream.len()] {
            let (mut client, relay_client) = duplex(256);
            let (relay_device, mut device) = duplex(256);
            let counts = Arc::new(Counts::default());
            let drops = LinkFaults { drop: 1.0, framing: Framing::SlcanCanopen, ..LinkFaults::NONE };
            tokio::spawn(relay(relay_client, relay_device, drops, 6, counts.clone()));
            for part in stream.chunks(cut) {
                device.write_all(part).await.unwrap();
                device.flush().await.unwrap();
                tokio::task::yield_now().await;
            }
            drop(device);
            let mut got = Vec::new();
            client.read_to_end(&mut got).await.unwrap();
            assert_eq!(got, b"z\rt705105\rz\r", "cut every {cut} bytes");
            let c = counts.json();
            assert_eq!((c["replies"].as_u64(), c["dropped"].as_u64()), (Some(4), Some(4)), "cut every {cut} bytes");
        }

        let (mut client, relay_client) = duplex(256);
        let (relay_device, mut device) = duplex(256);
        let counts = Arc::new(Counts::default());
        let garbles = LinkFaults { garble: 1.0, framing: Framing::SlcanCanopen, ..LinkFaults::NONE };
        tokio::spawn(relay(relay_client, relay_device, garbles, 7, counts.clone()));
        device.write_all(b"z\rt58580000000000000000\rz\r").await.unwrap();
        drop(device);
        let mut got = Vec::new();
        client.read_to_end(&mut got).await.unwrap();
        assert_eq!(got.len(), 26);
        assert_eq!((&got[..2], &got[24..]), (&b"z\r"[..], &b"z\r"[..]), "the acknowledgements pass");
        assert_ne!(&got[2..24], b"t58580000000000000000\r", "the SDO response is garbled");
        assert_eq!(counts.json()["garbled"], 1);
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
}
