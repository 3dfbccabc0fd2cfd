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
}

impl LinkFaults {
    /// No faults.
    pub const NONE: LinkFaults =
        LinkFaults { drop: 0.0, garble: 0.0, disconnect: 0.0, stall: 0.0, stall_for: Duration::ZERO };

    /// `rate` of all replies faulted, shared evenly among the four kinds.
    pub fn at_rate(rate: f64, stall_for: Duration) -> LinkFaults {
        let each = rate / 4.0;
        LinkFaults { drop: each, garble: each, disconnect: each, stall: each, stall_for }
    }

    fn any(&self) -> bool {
        self.drop + self.garble + self.disconnect + self.stall > 0.0
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

/// Relay bytes between `client` and `device` until either side closes or a
/// disconnect is injected. Requests go to the device unchanged; each chunk
/// the device sends (a reply) meets the faults.
pub async fn relay<C, D>(client: C, device: D, faults: LinkFaults, seed: u64, counts: Arc<Counts>)
where
    C: AsyncRead + AsyncWrite + Unpin + Send,
    D: AsyncRead + AsyncWrite + Unpin + Send,
{
    relay_with(client, device, faults, None, seed, counts).await;
}

/// [`relay`], with device faults armed at a rate per request.
pub async fn relay_with<C, D>(
    client: C,
    device: D,
    faults: LinkFaults,
    arm: Option<DeviceArm>,
    seed: u64,
    counts: Arc<Counts>,
) where
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
                Ok(0) | Err(_) => return,
                Ok(n) => {
                    if let Some(a) = &arm
                        && rng.random::<f64>() < a.rate
                    {
                        (a.arm)();
                        counts.device.fetch_add(1, Ordering::Relaxed);
                        tracing::info!("sim: the next request is refused with the instrument's fault code");
                    }
                    if device_tx.write_all(&buf[..n]).await.is_err() {
                        return;
                    }
                }
            }
        }
    };
    let replies = async {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut buf = vec![0u8; 4096];
        loop {
            let n = match device_rx.read(&mut buf).await {
                Ok(0) | Err(_) => return,
                Ok(n) => n,
            };
            counts.replies.fetch_add(1, Ordering::Relaxed);
            let chunk = &mut buf[..n];
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
                    let i = rng.random_range(0..chunk.len());
                    chunk[i] ^= 0x5a;
                    counts.garbled.fetch_add(1, Ordering::Relaxed);
                    tracing::info!("sim: garbled a reply");
                } else if x < edge + faults.disconnect {
                    let _ = client_tx.write_all(&chunk[..chunk.len() / 2]).await;
                    counts.disconnects.fetch_add(1, Ordering::Relaxed);
                    tracing::info!("sim: closed the link halfway through a reply");
                    return;
                } else if x < edge + faults.disconnect + faults.stall {
                    counts.stalls.fetch_add(1, Ordering::Relaxed);
                    tracing::info!(after = ?faults.stall_for, "sim: holding a reply past the client's timeout");
                    tokio::time::sleep(faults.stall_for).await;
                }
            }
            if client_tx.write_all(chunk).await.is_err() {
                return;
            }
        }
    };
    tokio::select! {
        () = requests => {}
        () = replies => {}
    }
    let _ = client_tx.shutdown().await;
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
}
