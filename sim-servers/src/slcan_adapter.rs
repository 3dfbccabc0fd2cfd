//! A simulated SLCAN (Lawicel) USB-CAN adapter: a host on a byte stream (a
//! pty's master end, the host opening the slave as its serial port) and a CAN
//! bus behind it (an endpoint of a [`MemoryBus`](survey_positioner_drivers::canopen::MemoryBus)
//! carrying the simulated drive).
//!
//! Written from the protocol as python-can's `slcan` interface speaks it and
//! the Lawicel command list (see [`survey_positioner_drivers::canopen::slcan`]), not from
//! our bus: it answers `Sn` (bitrate, only while the channel is closed), `O`
//! and `L` (open; BEL when already open or no bitrate was set), `C` (close;
//! BEL when closed), `V` (`V1013`), `N` (`NSIM1`), `F` (`F00`) with CR, and
//! `tiiildd..` with `z` CR while open (BEL when closed). Frames from the bus
//! go to the host as `tiiildd..` CR while the channel is open (listen-only
//! refuses transmits with BEL). Anything else is answered with BEL.

use crate::serve::{self, Answer, Codec, Service};
use async_trait::async_trait;
use survey_positioner_drivers::canopen::frame::CanBus;
use survey_positioner_drivers::canopen::slcan::{LineDecoder, Message, SlcanError};
use tokio::io::{AsyncRead, AsyncWrite};

/// The adapter's version answer (`V1013`: hardware 10, software 13).
pub const VERSION: (u8, u8) = (10, 13);

/// What the adapter did, for tests.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub struct AdapterReport {
    /// Commands the host sent (frames included), as lines.
    pub commands: Vec<String>,
    /// Frames passed from the host to the bus.
    pub to_bus: usize,
    /// Frames passed from the bus to the host.
    pub to_host: usize,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Channel {
    Closed,
    Open,
    ListenOnly,
}

/// The adapter: the host's lines in, the answers out; the frames of the bus
/// behind it passed to the host of its own accord.
struct Adapter<B> {
    bus: B,
    channel: Channel,
    bitrate: Option<u8>,
    report: AdapterReport,
}

impl Codec for LineDecoder {
    type Item = Result<Vec<u8>, SlcanError>;
    fn push(&mut self, bytes: &[u8]) {
        LineDecoder::push(self, bytes);
    }
    fn next_item(&mut self) -> Option<Self::Item> {
        self.next_line()
    }
}

/// Serve the adapter until the host side closes or the bus fails.
pub async fn serve_adapter<S, B>(host: S, bus: B) -> AdapterReport
where
    S: AsyncRead + AsyncWrite + Unpin,
    B: CanBus,
{
    let mut adapter = Adapter { bus, channel: Channel::Closed, bitrate: None, report: AdapterReport::default() };
    serve::serve_stream(host, LineDecoder::new(), &mut adapter).await;
    adapter.report
}

#[async_trait]
impl<B: CanBus> Service for Adapter<B> {
    type Request = Result<Vec<u8>, SlcanError>;
    type Reply = Vec<u8>;

    async fn call(&mut self, line: Self::Request) -> Answer<Vec<u8>> {
        let Ok(line) = line else { return Answer::Send(Message::Error.encode()) };
        let text = String::from_utf8_lossy(&line).into_owned();
        if !text.is_empty() {
            self.report.commands.push(text);
        }
        let reply = match (Message::parse(&line), self.channel) {
            (Ok(Message::Ok), _) => return Answer::Nothing, // a stray CR
            (Ok(Message::Bitrate(n)), Channel::Closed) if n <= 9 => {
                self.bitrate = Some(n);
                Message::Ok
            }
            (Ok(Message::Open), Channel::Closed) if self.bitrate.is_some() => {
                self.channel = Channel::Open;
                Message::Ok
            }
            (Ok(Message::ListenOnly), Channel::Closed) if self.bitrate.is_some() => {
                self.channel = Channel::ListenOnly;
                Message::Ok
            }
            (Ok(Message::Close), Channel::Open | Channel::ListenOnly) => {
                self.channel = Channel::Closed;
                Message::Ok
            }
            (Ok(Message::Version(None)), _) => Message::Version(Some(VERSION)),
            (Ok(Message::Serial(None)), _) => Message::Serial(Some(*b"SIM1")),
            (Ok(Message::Status(None)), _) => Message::Status(Some(0)),
            (Ok(Message::Frame(f)), Channel::Open) => {
                if self.bus.send(f).await.is_err() {
                    return Answer::Close;
                }
                self.report.to_bus += 1;
                Message::TransmitAck
            }
            _ => Message::Error,
        };
        Answer::Send(reply.encode())
    }

    /// A frame from the bus, to the host while the channel is open.
    async fn unsolicited(&mut self) -> Answer<Vec<u8>> {
        let Ok(frame) = self.bus.recv().await else { return Answer::Close };
        if self.channel == Channel::Closed {
            return Answer::Nothing;
        }
        self.report.to_host += 1;
        Answer::Send(Message::Frame(frame).encode())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::canopen_node::{NodeConfig, serve};
    use crate::elcomat_server::pty_pair;
    use std::sync::Arc;
    use std::time::Duration;
    use survey_drivers::VirtualClock;
    use survey_drivers::traits::Positioner;
    use survey_positioner_drivers::canopen::slcan::SlcanBus;
    use survey_positioner_drivers::canopen::{CanopenConfig, Cia402Positioner, MemoryBus};
    use survey_sims::faults::Faults;
    use survey_sims::positioner::{PositionerConfig, SimPositioner};
    use survey_sims::presets::Preset;
    use tokio::io::{AsyncReadExt, AsyncWriteExt};

    /// The raw protocol on a pty, as a host writes it.
    #[tokio::test]
    async fn the_adapter_answers_the_lawicel_commands() {
        let bus = MemoryBus::new();
        let mut other = bus.endpoint();
        let (master, mut slave) = pty_pair().unwrap();
        let adapter = tokio::spawn(serve_adapter(master, bus.endpoint()));
        async fn ask(s: &mut tokio_serial::SerialStream, line: &[u8], want: usize) -> Vec<u8> {
            s.write_all(line).await.unwrap();
            let mut got = Vec::new();
            let mut buf = [0u8; 64];
            while got.len() < want {
                let n = s.read(&mut buf).await.unwrap();
                got.extend_from_slice(&buf[..n]);
            }
            got
        }
        assert_eq!(ask(&mut slave, b"O\r", 1).await, b"\x07", "no bitrate yet");
        assert_eq!(ask(&mut slave, b"S6\r", 1).await, b"\r");
        assert_eq!(ask(&mut slave, b"t1230\r", 1).await, b"\x07", "closed: no transmit");
        assert_eq!(ask(&mut slave, b"O\r", 1).await, b"\r");
        assert_eq!(ask(&mut slave, b"S4\r", 1).await, b"\x07", "no bitrate change while open");
        assert_eq!(ask(&mut slave, b"V\r", 6).await, b"V1013\r");
        assert_eq!(ask(&mut slave, b"t7051AB\r", 2).await, b"z\r");
        let f = other.recv().await.unwrap();
        assert_eq!(f.to_string(), "705#AB");
        other.send(survey_positioner_drivers::canopen::frame::CanFrame::new(0x185, &[1, 2]).unwrap()).await.unwrap();
        let mut buf = [0u8; 32];
        let n = slave.read(&mut buf).await.unwrap();
        assert_eq!(&buf[..n], b"t18520102\r");
        assert_eq!(ask(&mut slave, b"C\r", 1).await, b"\r");
        assert_eq!(ask(&mut slave, b"Q\r", 1).await, b"\x07");
        drop(slave);
        let report = adapter.await.unwrap();
        assert_eq!((report.to_bus, report.to_host), (1, 1));
        assert_eq!(report.commands[..4], ["O", "S6", "t1230", "O"]);
    }

    /// Our CiA 402 driver through our SLCAN bus on a pty, the simulated
    /// adapter and drive behind it: enable, move, read back.
    #[tokio::test]
    async fn the_driver_moves_a_drive_behind_a_simulated_usb_can_adapter() {
        let clock = VirtualClock::new();
        let model = Preset::by_name("fig8").unwrap().model;
        let sim = SimPositioner::new(PositionerConfig::new(model), Arc::new(clock.clone()));
        let bus = MemoryBus::new();
        tokio::spawn(serve(bus.endpoint(), sim, NodeConfig::new(4), Faults::new()));
        let (master, slave) = pty_pair().unwrap();
        let path = tokio_serial::SerialPort::name(&slave).unwrap();
        tokio::spawn(serve_adapter(master, bus.endpoint()));
        let can = SlcanBus::open_port(&path, 500_000, Duration::from_secs(1)).await.unwrap();
        drop(slave);
        let cfg = CanopenConfig { node_id: 4, ..CanopenConfig::default() };
        let mut d = Cia402Positioner::connect(can, cfg).await.unwrap();
        d.move_to(30.0).await.unwrap();
        for _ in 0..200 {
            if d.status().await.unwrap().in_position {
                break;
            }
            clock.advance(Duration::from_millis(100));
        }
        assert!(d.status().await.unwrap().in_position);
        assert_eq!(d.readout().await.unwrap(), 30.0);
    }
}
