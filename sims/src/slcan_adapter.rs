//! A simulated SLCAN (Lawicel) USB-CAN adapter: a host on a byte stream (a
//! pty's master end, the host opening the slave as its serial port) and a CAN
//! bus behind it (an endpoint of a [`MemoryBus`](survey_drivers::canopen::MemoryBus)
//! carrying the simulated drive).
//!
//! Written from the protocol as python-can's `slcan` interface speaks it and
//! the Lawicel command list (see [`survey_drivers::canopen::slcan`]), not from
//! our bus: it answers `Sn` (bitrate, only while the channel is closed), `O`
//! and `L` (open; BEL when already open or no bitrate was set), `C` (close;
//! BEL when closed), `V` (`V1013`), `N` (`NSIM1`), `F` (`F00`) with CR, and
//! `tiiildd..` with `z` CR while open (BEL when closed). Frames from the bus
//! go to the host as `tiiildd..` CR while the channel is open (listen-only
//! refuses transmits with BEL). Anything else is answered with BEL.

use survey_drivers::canopen::frame::CanBus;
use survey_drivers::canopen::slcan::{LineDecoder, Message};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};

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

/// Serve the adapter until the host side closes or the bus fails.
pub async fn serve_adapter<S, B>(mut host: S, mut bus: B) -> AdapterReport
where
    S: AsyncRead + AsyncWrite + Unpin,
    B: CanBus,
{
    let mut report = AdapterReport::default();
    let mut decoder = LineDecoder::new();
    let mut channel = Channel::Closed;
    let mut bitrate: Option<u8> = None;
    let mut buf = [0u8; 512];
    loop {
        tokio::select! {
            read = host.read(&mut buf) => {
                let n = match read {
                    Ok(0) | Err(_) => return report,
                    Ok(n) => n,
                };
                decoder.push(&buf[..n]);
                let mut out = Vec::new();
                while let Some(line) = decoder.next_line() {
                    let reply = match line.map(|l| (String::from_utf8_lossy(&l).into_owned(), Message::parse(&l))) {
                        Err(_) => Message::Error,
                        Ok((text, parsed)) => {
                            if !text.is_empty() {
                                report.commands.push(text);
                            }
                            match (parsed, channel) {
                                (Ok(Message::Ok), _) => continue, // a stray CR
                                (Ok(Message::Bitrate(n)), Channel::Closed) if n <= 9 => {
                                    bitrate = Some(n);
                                    Message::Ok
                                }
                                (Ok(Message::Open), Channel::Closed) if bitrate.is_some() => {
                                    channel = Channel::Open;
                                    Message::Ok
                                }
                                (Ok(Message::ListenOnly), Channel::Closed) if bitrate.is_some() => {
                                    channel = Channel::ListenOnly;
                                    Message::Ok
                                }
                                (Ok(Message::Close), Channel::Open | Channel::ListenOnly) => {
                                    channel = Channel::Closed;
                                    Message::Ok
                                }
                                (Ok(Message::Version(None)), _) => {
                                    out.extend(Message::Version(Some(VERSION)).encode());
                                    continue;
                                }
                                (Ok(Message::Serial(None)), _) => {
                                    out.extend(Message::Serial(Some(*b"SIM1")).encode());
                                    continue;
                                }
                                (Ok(Message::Status(None)), _) => {
                                    out.extend(Message::Status(Some(0)).encode());
                                    continue;
                                }
                                (Ok(Message::Frame(f)), Channel::Open) => {
                                    if bus.send(f).await.is_err() {
                                        return report;
                                    }
                                    report.to_bus += 1;
                                    Message::TransmitAck
                                }
                                _ => Message::Error,
                            }
                        }
                    };
                    out.extend(reply.encode());
                }
                if !out.is_empty() && (host.write_all(&out).await.is_err() || host.flush().await.is_err()) {
                    return report;
                }
            }
            frame = bus.recv() => {
                let Ok(frame) = frame else { return report };
                if channel != Channel::Closed {
                    report.to_host += 1;
                    if host.write_all(&Message::Frame(frame).encode()).await.is_err() {
                        return report;
                    }
                    let _ = host.flush().await;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::canopen_node::{NodeConfig, NodeFaults, serve};
    use crate::elcomat_server::pty_pair;
    use crate::positioner::{PositionerConfig, SimPositioner};
    use crate::presets::Preset;
    use std::sync::Arc;
    use std::time::Duration;
    use survey_drivers::VirtualClock;
    use survey_drivers::canopen::slcan::SlcanBus;
    use survey_drivers::canopen::{CanopenConfig, Cia402Positioner, MemoryBus};
    use survey_drivers::traits::Positioner;

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
        other.send(survey_drivers::canopen::frame::CanFrame::new(0x185, &[1, 2]).unwrap()).await.unwrap();
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
        tokio::spawn(serve(bus.endpoint(), sim, NodeConfig::new(4), NodeFaults::new()));
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
