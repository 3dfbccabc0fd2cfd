//! The one layer that injects link faults: a relay between a client's link
//! and a simulated instrument that, for the instrument's replies, drops the
//! reply (the client times out), garbles it, closes the link halfway through
//! it (a disconnect), holds it past the client's deadline and then delivers
//! it (a stall: the late reply must not be taken for the next request's), or
//! sends bytes after it (a stale answer). The faults come from the
//! [`Faults`] handle, armed one by one (a test) or drawn at [`FaultRates`]
//! (`survey sim`); a device fault drawn at its rate is armed in the
//! simulator behind the relay through the same handle (the simulator refuses
//! the next request with its own code). Our own design, not from an
//! instrument's documentation: a link fault looks the same on every wire.
//!
//! A fault lands on a *reply*, cut from the instrument's bytes by the
//! wire's [`Framing`]; what no request waits for (an SLCAN adapter's
//! transmit acknowledgements and a node's heartbeats, emScon's status changes
//! and streamed points) passes unfaulted and uncounted, since a fault there
//! would be injected and counted yet reach nothing. On a CAN bus
//! ([`relay_can`]) the replies are the SDO responses.

use rand::{Rng as _, SeedableRng as _};
use rand_chacha::ChaCha8Rng;
use std::net::SocketAddr;
use std::time::Duration;
use survey_positioner_drivers::canopen::frame::{CanBus, CanFrame};
use survey_sims::faults::{Fault, FaultRates, Faults, Garble};
use tokio::io::{AsyncRead, AsyncReadExt as _, AsyncWrite, AsyncWriteExt as _};
use tokio::net::TcpListener;

/// A relay's settings: the faults armed and counted, the rates, and how
/// replies are cut from the instrument's bytes.
#[derive(Debug, Clone)]
pub struct Relay {
    /// Armed faults and the counts (share it with the simulator behind the
    /// relay: device faults drawn at their rate are armed there).
    pub faults: Faults,
    /// Link faults per reply (timeout, garbled, disconnect, stall) and
    /// device faults per request (device); the other kinds are the
    /// simulators'.
    pub rates: FaultRates,
    /// How long a stalled reply is held at the rate, real time.
    pub stall_for: Duration,
    /// Where the replies are in the instrument's byte stream.
    pub framing: Framing,
    /// Seed of the draws.
    pub seed: u64,
}

impl Relay {
    /// Only armed faults (no rates), replies cut by `framing`.
    pub fn armed(faults: Faults, framing: Framing) -> Relay {
        Relay { faults, rates: FaultRates::default(), stall_for: Duration::ZERO, framing, seed: 0 }
    }

    /// The same relay with another seed.
    pub fn reseeded(&self, seed: u64) -> Relay {
        Relay { seed, ..self.clone() }
    }
}

/// Where the replies are in what an instrument writes: what a link fault
/// lands on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Framing {
    /// Each chunk read from the instrument is one reply.
    #[default]
    Chunks,
    /// Lines ending in LF (SCPI, the ELCOMAT's CR LF).
    Lines,
    /// emScon TPI packets (`lPacketSize` first); status changes and streamed
    /// points are no reply.
    Emscon,
    /// Modbus TCP frames (the MBAP header's length).
    ModbusTcp,
    /// Modbus RTU response frames (their length from the function code).
    ModbusRtu,
    /// An SLCAN adapter with CANopen nodes behind it: messages end at CR or
    /// BEL. The replies are the adapter's answers to the host's commands (CR,
    /// BEL, `V`/`N`/`F` lines) and the received frames that answer a request
    /// (SDO responses, COB-IDs 0x581..=0x5FF, CiA 301). The transmit
    /// acknowledgement (`z`, `Z`) and unsolicited frames (heartbeats,
    /// emergencies, PDOs, 29-bit and remote frames) are no reply.
    SlcanCanopen,
}

/// The longest message a framing waits for before it passes what it holds
/// on as one reply (a framing lost: an absurd length, no terminator).
const MAX_MESSAGE: usize = 1 << 16;

/// The longest SLCAN message (a line is at most 32 bytes and its CR).
const MAX_SLCAN_MESSAGE: usize = 64;

impl Framing {
    /// Cut `pending` into whole messages, each with whether it is a reply;
    /// an incomplete message stays in `pending`.
    fn take(self, pending: &mut Vec<u8>) -> Vec<(Vec<u8>, bool)> {
        let mut out = Vec::new();
        if self == Framing::Chunks {
            out.push((std::mem::take(pending), true));
            return out;
        }
        while let Some(len) = self.message_len(pending) {
            let message: Vec<u8> = pending.drain(..len.min(pending.len())).collect();
            let reply = self.is_reply(&message);
            out.push((message, reply));
        }
        let limit = if self == Framing::SlcanCanopen { MAX_SLCAN_MESSAGE } else { MAX_MESSAGE };
        if pending.len() > limit {
            out.push((std::mem::take(pending), true));
        }
        out
    }

    /// The length of the whole message at the start of `b`, once it is there.
    fn message_len(self, b: &[u8]) -> Option<usize> {
        let whole = |n: usize| (n > 0 && b.len() >= n).then_some(n);
        match self {
            Framing::Chunks => whole(b.len()),
            Framing::Lines => b.iter().position(|&c| c == b'\n').map(|i| i + 1),
            Framing::SlcanCanopen => b.iter().position(|&c| c == b'\r' || c == 0x07).map(|i| i + 1),
            Framing::Emscon => {
                let size = i32::from_le_bytes(b.get(..4)?.try_into().ok()?);
                // A size the framing cannot follow: everything held is one message.
                let n = usize::try_from(size).ok().filter(|n| (8..=MAX_MESSAGE).contains(n)).unwrap_or(b.len());
                whole(n)
            }
            Framing::ModbusTcp => whole(6 + usize::from(u16::from_be_bytes([*b.get(4)?, *b.get(5)?]))),
            Framing::ModbusRtu => whole(survey_positioner_drivers::modbus::rtu_response_len(b)?),
        }
    }

    fn is_reply(self, message: &[u8]) -> bool {
        match self {
            Framing::SlcanCanopen => slcan_reply(message),
            Framing::Emscon => {
                use survey_drivers::emscon::codes::data_type;
                let kind = message.get(4..8).and_then(|t| t.try_into().ok()).map(i32::from_le_bytes);
                !matches!(
                    kind,
                    Some(
                        data_type::SYSTEM_STATUS_CHANGE | data_type::MULTI_MEAS_RESULT | data_type::MULTI_MEAS_RESULT2
                    )
                )
            }
            _ => true,
        }
    }
}

/// Whether an SLCAN message (its terminator included) answers a request of
/// the host: see [`Framing::SlcanCanopen`].
fn slcan_reply(message: &[u8]) -> bool {
    use survey_positioner_drivers::canopen::slcan::Message;
    let line = message.strip_suffix(b"\r").unwrap_or(message);
    match Message::parse(line) {
        Ok(Message::TransmitAck | Message::OtherFrame) => false,
        Ok(Message::Frame(f)) => (0x581..=0x5FF).contains(&f.id()),
        // CR, BEL, the answers to V, N, F; and what does not parse (a host
        // waiting for an answer meets it).
        _ => true,
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

/// What becomes of one reply.
enum Verdict {
    /// Send these bytes (the reply, garbled or not, and what follows it).
    Send(Vec<u8>),
    /// Send nothing.
    Dropped,
    /// Send these bytes (half the reply), then close the client's link.
    Cut(Vec<u8>),
    /// Hold the reply this long, then send it.
    Late(Duration, Vec<u8>),
}

/// The draws of one relay: the faults at their rates, seeded.
struct Draws<'a> {
    relay: &'a Relay,
    replies: ChaCha8Rng,
    requests: ChaCha8Rng,
}

impl<'a> Draws<'a> {
    fn new(relay: &'a Relay) -> Self {
        let replies = ChaCha8Rng::seed_from_u64(relay.seed);
        let requests = ChaCha8Rng::seed_from_u64(relay.seed ^ 0xdead_beef);
        Draws { relay, replies, requests }
    }

    /// A request on its way to the instrument: at the device rate, the
    /// simulator is asked to refuse it with its own code.
    fn request(&mut self) {
        let rate = self.relay.rates.device;
        if rate > 0.0 && self.requests.random::<f64>() < rate {
            self.relay.faults.arm(Fault::Refuse(None));
            tracing::info!("sim: the next request is refused with the instrument's fault code");
        }
    }

    /// The fate of one reply: the next armed fault that fits it, or one
    /// drawn at the rates.
    fn reply(&mut self, message: Vec<u8>) -> Verdict {
        let relay = self.relay;
        let faults = &relay.faults;
        faults.injected().count_reply();
        let armed = faults.next_link(|f| match f {
            Fault::Garble(Garble::Edit(_, edit)) => edit(&message).map(Verdict::Send),
            other => Some(self.apply(other, &message)),
        });
        if let Some(v) = armed {
            return v;
        }
        let r = &relay.rates;
        if r.timeout + r.garbled + r.disconnect + r.stall <= 0.0 {
            return Verdict::Send(message);
        }
        let x: f64 = self.replies.random();
        let fault = if x < r.timeout {
            Fault::Drop
        } else if x < r.timeout + r.garbled {
            Fault::Garble(Garble::Byte)
        } else if x < r.timeout + r.garbled + r.disconnect {
            Fault::Disconnect
        } else if x < r.timeout + r.garbled + r.disconnect + r.stall {
            Fault::Stall(relay.stall_for)
        } else {
            return Verdict::Send(message);
        };
        if let Some(kind) = fault.kind() {
            faults.injected().add(kind);
        }
        self.apply(&fault, &message)
    }

    /// A link fault applied to a reply (an edit that fits applied above).
    fn apply(&mut self, fault: &Fault, message: &[u8]) -> Verdict {
        match fault {
            Fault::Drop => {
                tracing::info!("sim: dropped a reply");
                Verdict::Dropped
            }
            Fault::Garble(g) => {
                let mut garbled = message.to_vec();
                match g {
                    Garble::Byte if !garbled.is_empty() => {
                        let i = self.replies.random_range(0..garbled.len());
                        garbled[i] ^= 0x5a;
                    }
                    Garble::Byte => {}
                    Garble::Edit(_, edit) => garbled = edit(message).unwrap_or(garbled),
                }
                tracing::info!(how = ?g, "sim: garbled a reply");
                Verdict::Send(garbled)
            }
            Fault::Disconnect => {
                tracing::info!("sim: closed the link halfway through a reply");
                Verdict::Cut(message[..message.len() / 2].to_vec())
            }
            Fault::Stall(d) => {
                tracing::info!(after = ?d, "sim: holding a reply past the client's timeout");
                Verdict::Late(*d, message.to_vec())
            }
            Fault::Trailing(extra) => {
                tracing::info!("sim: a stale answer follows the reply");
                Verdict::Send([message, extra.as_slice()].concat())
            }
            _ => Verdict::Send(message.to_vec()),
        }
    }
}

/// Relay bytes between `client` and `device` until either side closes or a
/// disconnect is injected. Requests go to the device unchanged; each reply
/// the device sends meets the faults.
pub async fn relay<C, D>(client: C, device: D, relay: &Relay) -> Ended
where
    C: AsyncRead + AsyncWrite + Unpin + Send,
    D: AsyncRead + AsyncWrite + Unpin + Send,
{
    let (mut client_rx, mut client_tx) = tokio::io::split(client);
    let (mut device_rx, mut device_tx) = tokio::io::split(device);
    let draws = std::sync::Mutex::new(Draws::new(relay));
    let draws = &draws;
    let lock = || draws.lock().unwrap_or_else(|p| p.into_inner());
    let requests = async {
        let mut buf = vec![0u8; 4096];
        loop {
            match client_rx.read(&mut buf).await {
                Ok(0) | Err(_) => return Ended::Closed,
                Ok(n) => {
                    lock().request();
                    if device_tx.write_all(&buf[..n]).await.is_err() {
                        return Ended::Closed;
                    }
                }
            }
        }
    };
    let replies = async {
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
            for (message, reply) in relay.framing.take(&mut pending) {
                if !reply {
                    out.extend_from_slice(&message);
                    continue;
                }
                let verdict = lock().reply(message);
                match verdict {
                    Verdict::Send(bytes) => out.extend_from_slice(&bytes),
                    Verdict::Dropped => {}
                    Verdict::Cut(half) => {
                        out.extend_from_slice(&half);
                        let _ = client_tx.write_all(&out).await;
                        return Ended::Disconnect;
                    }
                    Verdict::Late(d, bytes) => {
                        if !out.is_empty() && client_tx.write_all(&std::mem::take(&mut out)).await.is_err() {
                            return Ended::Closed;
                        }
                        tokio::time::sleep(d).await;
                        out.extend_from_slice(&bytes);
                    }
                }
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

/// Accept clients on `listener` and relay each to the simulator at `inner`,
/// one at a time, like the instruments; each connection's draws seeded
/// afresh from the relay's seed.
pub async fn relay_tcp(listener: TcpListener, inner: SocketAddr, relay_cfg: Relay) {
    let mut k = 0u64;
    crate::serve::one_client_at_a_time(listener, |client| {
        k += 1;
        let cfg = relay_cfg.reseeded(survey_sims::derive_seed(relay_cfg.seed, k));
        async move {
            let Ok(device) = tokio::net::TcpStream::connect(inner).await else { return };
            device.set_nodelay(true).ok();
            relay(client, device, &cfg).await;
        }
    })
    .await;
}

/// A relay on a serial line, for tests: two pty pairs joined by `relay`;
/// returns the slave the client opens, the master the simulator serves on,
/// and the relay's task.
#[cfg(test)]
pub(crate) fn pty_relay(
    relay_cfg: Relay,
) -> (tokio_serial::SerialStream, tokio_serial::SerialStream, tokio::task::JoinHandle<Ended>) {
    let (client_master, client_slave) = crate::elcomat_server::pty_pair().expect("pty pair");
    let (device_master, device_slave) = crate::elcomat_server::pty_pair().expect("pty pair");
    let task = tokio::spawn(async move { relay(client_master, device_slave, &relay_cfg).await });
    (client_slave, device_master, task)
}

/// A relay in front of a TCP simulator, for tests: the simulator serves on
/// the returned listener, clients connect to the returned address.
#[cfg(test)]
pub(crate) async fn tcp_relay(relay_cfg: Relay) -> (TcpListener, SocketAddr, tokio::task::JoinHandle<()>) {
    let inner = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let public = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let addr = public.local_addr().expect("an address");
    let inner_addr = inner.local_addr().expect("an address");
    (inner, addr, tokio::spawn(relay_tcp(public, inner_addr, relay_cfg)))
}

/// [`relay`] between two CAN buses: the host's frames go to the device's bus
/// unchanged, each SDO response (COB-ID 0x581..=0x5FF) from the device's bus
/// meets the faults on its data bytes, every other frame passes. A
/// disconnect (a CAN node has no link to close) ends the relay: the host's
/// bus goes quiet.
pub async fn relay_can<H: CanBus, D: CanBus>(mut host: H, mut device: D, relay: &Relay) -> Ended {
    let mut draws = Draws::new(relay);
    loop {
        tokio::select! {
            frame = host.recv() => {
                let Ok(frame) = frame else { return Ended::Closed };
                if (0x601..=0x67F).contains(&frame.id()) {
                    draws.request();
                }
                if device.send(frame).await.is_err() {
                    return Ended::Closed;
                }
            }
            frame = device.recv() => {
                let Ok(frame) = frame else { return Ended::Closed };
                if !(0x581..=0x5FF).contains(&frame.id()) {
                    if host.send(frame).await.is_err() {
                        return Ended::Closed;
                    }
                    continue;
                }
                let data = match draws.reply(frame.data().to_vec()) {
                    Verdict::Send(data) => data,
                    Verdict::Dropped => continue,
                    Verdict::Cut(_) => return Ended::Disconnect,
                    Verdict::Late(d, data) => {
                        tokio::time::sleep(d).await;
                        data
                    }
                };
                // Bytes past the 8 a frame holds (a stale answer after it) are a frame of their own.
                for chunk in data.chunks(8).chain(data.is_empty().then_some(&[][..])) {
                    let Ok(f) = CanFrame::new(frame.id(), chunk) else { continue };
                    if host.send(f).await.is_err() {
                        return Ended::Closed;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests;
