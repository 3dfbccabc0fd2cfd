//! A simulated positioner controller on Modbus TCP and Modbus RTU.
//!
//! A [`ModbusDevice`] serves a [`SimPositioner`] through a
//! [`RegisterMap`] (the same type, and so the same map, the driver in
//! [`survey_positioner_drivers::modbus`] is configured with; see its module
//! documentation for the default map, the command codes and the status
//! bits). It is a `tokio_modbus::server::Service`: over TCP with
//! `server::tcp::Server::serve` ([`ModbusDevice::serve_tcp`],
//! [`ModbusDevice::spawn_tcp`] on 127.0.0.1:0), over RTU with
//! `server::rtu::Server::serve_until` on the master side of a pty pair
//! ([`ModbusDevice::serve_rtu`]; create the pair with
//! [`pty_pair`](crate::elcomat_server::pty_pair)).
//!
//! # How the async positioner is called from the service
//!
//! tokio-modbus 0.17's `Service::call(&self, request)` returns a `Future`
//! associated type that must be `Send`, with no lifetime tied to `&self`
//! (looked up in its `src/server/service.rs`; the crate's own examples use
//! `std::future::Ready`). Here it is a boxed `'static` future that owns a
//! clone of the device handle: the device state sits behind an
//! `Arc<tokio::sync::Mutex<_>>`, and the future locks it and awaits the
//! [`SimPositioner`]'s async methods (which sleep on the sim's clock: use a
//! [`VirtualClock`](survey_drivers::VirtualClock) and every call costs no
//! real time). Requests from several TCP connections are served one at a
//! time, in arrival order.
//!
//! # What was looked up
//!
//! In the tokio-modbus 0.17.0 source (`src/server/{service,tcp,rtu}.rs`,
//! `src/frame/mod.rs`) and its `examples/tcp-server.rs`: the TCP server's
//! `serve(&on_connected, on_process_error)` builds a service and a transport
//! per connection (`accept_tcp_connection` gives the service; the transport
//! may be any `AsyncRead + AsyncWrite`, which is how the TCP faults wrap the
//! socket in a stream whose writes can be cut); its per-connection tasks are
//! cancelled when `serve` is dropped. The RTU server takes a
//! `tokio_serial::SerialStream` only, so an RTU "close" stops the server
//! through `serve_until`'s abort signal. A `Response` type of
//! `Option<Response>` lets the service send no reply at all.
//!
//! # Behaviour
//!
//! - Reads (functions 3 and 4) of 1 to 125 registers. Every register read
//!   must belong to an item of the map in that table, or the request fails
//!   with `IllegalDataAddress` (0x02). Live items call the positioner: the
//!   actual position calls `readout()`, the status and fault code registers
//!   call `status()` (once per request). Holding items read back the value
//!   last written (the command register: the last command executed). The
//!   checksum is CRC-16/MODBUS over the staged table (an unwritten row counts
//!   as `0xFFFF 0xFFFF`; with no table staged, the CRC of nothing, 0xFFFF).
//! - Writes (functions 6 and 16) of 1 to 123 registers, to writable items
//!   only (`IllegalDataAddress` otherwise). A 32-bit value and the table
//!   header must be written whole, in one request; a chunk must start at the
//!   window and carry whole values (`IllegalDataAddress` otherwise). A write
//!   may span several items (position, velocity and command in one request):
//!   they are applied in address order, and a refusal stops there.
//!   - commanded position: stored (a non-finite float32 is `IllegalDataValue`);
//!   - velocity: `set_velocity` at once;
//!   - command: move (to the stored commanded position), stop, clear fault,
//!     apply or stop applying the table, load the staged table; an unknown
//!     code is `IllegalDataValue`;
//!   - table header: rows in `2..=`[`MAX_TABLE_ROWS`], 1 or 2 columns
//!     (`IllegalDataValue` otherwise); starts a new, empty staged table;
//!   - table window: `[column, first row, values...]`; before a header, a
//!     column or row beyond the header, or a non-finite value is
//!     `IllegalDataValue`. Load with rows missing is `IllegalDataValue`.
//! - Other functions: `IllegalFunction` (0x01).
//! - A refusal of the simulated positioner becomes an exception: `Usage`
//!   (target outside the travel, velocity not positive, table or correction
//!   switched while moving, no table) is `IllegalDataValue` (0x03), `Device`
//!   (a move while a fault is latched) is `ServerDeviceFailure` (0x04). The
//!   positioner's own injected link faults
//!   ([`PositionerFaults`](survey_sims::positioner::PositionerFaults)) become the
//!   same fault on the wire: `Timeout` = no reply, `Disconnected` = the
//!   link is closed, `Garbled` = a reply of another function.
//! - The unit id: requests to another unit get no reply (a shared RTU bus;
//!   over TCP, 0xFF, "the device itself", is also accepted).
//! - The positioner's fault code goes to the fault code register (0xFFFF if
//!   it does not fit 16 bits); the sim's following error is 0x8611.
//!
//! # Faults ([`Faults`])
//!
//! Link faults are the [`relay`](crate::relay)'s in front of the controller
//! ([`garbled`]: a reply of another function, the Modbus way to garble).
//! Device faults armed in its [`Faults`] apply to the next requests to this
//! unit as they come:
//!
//! - [`Fault::Refuse`]: not executed, answered with the exception whose code
//!   is given (`None`: `ServerDeviceFailure`, 4);
//! - [`Fault::LoseWrite`]: the n-th write from now is acknowledged but not applied
//!   (data lost inside the device: the table checksum catches it).

mod device;

use device::{DeviceState, Outcome};
use std::future::Future;
use std::io;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::task::{Context, Poll};
use survey_positioner_drivers::modbus::{ExceptionCode, MapError, RegisterMap, Request, Response};
use survey_sims::faults::{Fault, Faults, Garble};
use survey_sims::positioner::SimPositioner;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::Notify;
use tokio::task::JoinHandle;
use tokio_modbus::SlaveRequest;
use tokio_modbus::server::Service;
use tokio_modbus::server::tcp::accept_tcp_connection;

/// Most rows a staged table column may hold.
pub const MAX_TABLE_ROWS: u16 = 16_384;

/// The Modbus way to garble a reply, for the relay in front of the
/// controller: a well-formed reply of another function (the client sees a
/// mismatch), over TCP (`rtu` false: the MBAP header kept) or RTU (the CRC
/// recomputed).
pub fn garbled(rtu: bool) -> Fault {
    Fault::Garble(Garble::edit("Modbus reply of another function", move |frame: &[u8]| {
        let header = if rtu { 1 } else { 7 };
        let function = *frame.get(header)?;
        let pdu: &[u8] = if matches!(function, 3 | 4) { &[6, 0, 0, 0, 0] } else { &[3, 2, 0, 0] };
        let mut out = frame[..header].to_vec();
        if rtu {
            out.extend_from_slice(pdu);
            let crc = survey_positioner_drivers::modbus::crc16_modbus_bytes(&out);
            out.extend_from_slice(&crc.to_le_bytes());
        } else {
            out[4..6].copy_from_slice(&(1 + pdu.len() as u16).to_be_bytes());
            out.extend_from_slice(pdu);
        }
        Some(out)
    }))
}

/// The simulated controller: a [`SimPositioner`] behind a [`RegisterMap`].
/// Cloning gives another handle on the same controller.
#[derive(Clone)]
pub struct ModbusDevice {
    state: Arc<tokio::sync::Mutex<DeviceState>>,
    map: Arc<RegisterMap>,
    requests: Arc<AtomicUsize>,
}

impl std::fmt::Debug for ModbusDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ModbusDevice").field("map", &self.map).finish_non_exhaustive()
    }
}

/// Why [`ModbusDevice::serve_rtu`] returned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RtuEnd {
    /// The stream ended.
    PeerClosed,
    /// A read or write failed (a pty master reads EIO once the other side is
    /// closed).
    LinkError(io::ErrorKind),
    /// The simulated positioner's own injected disconnect closed the port.
    ClosedByFault,
}

/// A TCP server task on an ephemeral loopback port; aborted on drop.
#[derive(Debug)]
pub struct TcpServer {
    /// Where it listens.
    pub addr: SocketAddr,
    task: JoinHandle<io::Result<()>>,
}

impl Drop for TcpServer {
    fn drop(&mut self) {
        self.task.abort();
    }
}

impl ModbusDevice {
    /// A controller serving `positioner` through `map` (refused when the map
    /// does not validate).
    pub fn new(positioner: SimPositioner, map: RegisterMap) -> Result<Self, MapError> {
        map.validate()?;
        let state = DeviceState::new(positioner, map.clone());
        let state = Arc::new(tokio::sync::Mutex::new(state));
        Ok(Self { state, map: Arc::new(map), requests: Arc::default() })
    }

    /// The register map.
    pub fn map(&self) -> &RegisterMap {
        &self.map
    }

    /// Run `f` on the simulated positioner (between requests).
    pub async fn with_positioner<R>(&self, f: impl FnOnce(&mut SimPositioner) -> R) -> R {
        f(&mut self.state.lock().await.sim)
    }

    /// The stored value of a holding register (what the master last wrote
    /// there; 0 when never written).
    pub async fn holding_register(&self, address: u16) -> u16 {
        self.state.lock().await.holding(address)
    }

    /// Requests to this unit received so far.
    pub fn requests(&self) -> usize {
        self.requests.load(Ordering::Relaxed)
    }

    fn session(&self, faults: &Faults, link: Link) -> Session {
        Session { device: self.clone(), faults: faults.clone(), link }
    }

    /// Serve Modbus TCP on `listener` until the future is dropped (or the
    /// listener fails). Every connection gets its own session on the same
    /// controller.
    pub async fn serve_tcp(&self, listener: TcpListener, faults: Faults) -> io::Result<()> {
        let server = tokio_modbus::server::tcp::Server::new(listener);
        let device = self.clone();
        let on_connected = move |stream: TcpStream, peer: SocketAddr| {
            let cut = Arc::new(AtomicBool::new(false));
            let accepted =
                accept_tcp_connection(stream, peer, |_| Ok(Some(device.session(&faults, Link::Tcp(cut.clone())))))
                    .map(|o| o.map(|(session, stream)| (session, FaultyStream { inner: stream, cut: cut.clone() })));
            tracing::debug!(%peer, "sim Modbus controller: TCP connection");
            std::future::ready(accepted)
        };
        server
            .serve(
                &on_connected,
                |e| tracing::debug!(error = %e, "sim Modbus controller: a TCP session ended with an error"),
            )
            .await
    }

    /// Bind 127.0.0.1:0 and serve Modbus TCP in a task.
    pub async fn spawn_tcp(&self, faults: Faults) -> io::Result<TcpServer> {
        let listener = TcpListener::bind("127.0.0.1:0").await?;
        let addr = listener.local_addr()?;
        let device = self.clone();
        let task = tokio::spawn(async move { device.serve_tcp(listener, faults).await });
        Ok(TcpServer { addr, task })
    }

    /// Serve Modbus RTU on `port` (the master side of a pty pair, or a real
    /// serial port) until the stream ends, fails, or a fault closes it. The
    /// port is closed on return.
    pub async fn serve_rtu(&self, port: tokio_serial::SerialStream, faults: Faults) -> RtuEnd {
        let notify = Arc::new(Notify::new());
        let session = self.session(&faults, Link::Rtu(notify.clone()));
        let abort = async move { notify.notified().await };
        match tokio_modbus::server::rtu::Server::new(port).serve_until(session, abort).await {
            Ok(tokio_modbus::server::Terminated::Aborted) => RtuEnd::ClosedByFault,
            Ok(tokio_modbus::server::Terminated::Finished) => RtuEnd::PeerClosed,
            Err(e) => {
                tracing::debug!(error = %e, "sim Modbus controller: RTU link closed");
                RtuEnd::LinkError(e.kind())
            }
        }
    }
}

/// How a session closes its link.
#[derive(Debug, Clone)]
enum Link {
    /// Cuts the connection's [`FaultyStream`].
    Tcp(Arc<AtomicBool>),
    /// Wakes `serve_until`'s abort signal.
    Rtu(Arc<Notify>),
}

/// One client's view of the controller: the `Service` tokio-modbus calls.
#[derive(Debug)]
struct Session {
    device: ModbusDevice,
    faults: Faults,
    link: Link,
}

type Reply = Result<Option<Response>, ExceptionCode>;

/// A reply of another function than the request's.
fn mismatched(request: &Request<'_>) -> Response {
    match request {
        Request::ReadHoldingRegisters(..) | Request::ReadInputRegisters(..) => Response::WriteSingleRegister(0, 0),
        _ => Response::ReadHoldingRegisters(vec![0]),
    }
}

impl Service for Session {
    type Request = SlaveRequest<'static>;
    type Response = Option<Response>;
    type Exception = ExceptionCode;
    type Future = Pin<Box<dyn Future<Output = Reply> + Send>>;

    fn call(&self, req: Self::Request) -> Self::Future {
        let SlaveRequest { slave, request } = req;
        let tcp = matches!(self.link, Link::Tcp(_));
        if slave != self.device.map.unit_id && !(tcp && slave == 0xFF) {
            tracing::debug!(slave, "sim Modbus controller: request to another unit, no reply");
            return Box::pin(std::future::ready(Ok(None)));
        }
        self.device.requests.fetch_add(1, Ordering::Relaxed);
        let faults = self.faults.clone();
        let device = self.device.clone();
        let link = self.link.clone();
        Box::pin(async move {
            if let Some(fault) = faults.take_device(|f| matches!(f, Fault::Refuse(_) | Fault::RefuseWithError(_))) {
                let code = match &fault {
                    Fault::Refuse(Some(d)) | Fault::RefuseWithError(d) => {
                        ExceptionCode::new(u8::try_from(d.code).unwrap_or(4))
                    }
                    _ => ExceptionCode::ServerDeviceFailure,
                };
                tracing::debug!(?code, "sim Modbus controller rejects a request (injected)");
                return Err(code);
            }
            let is_write = matches!(request, Request::WriteSingleRegister(..) | Request::WriteMultipleRegisters(..));
            let due = |f: &mut Fault| match f {
                Fault::LoseWrite(n) if *n <= 1 => true,
                Fault::LoseWrite(n) => {
                    *n -= 1;
                    false
                }
                _ => false,
            };
            let discard = is_write && faults.take_device(due).is_some();
            let outcome = device.state.lock().await.handle(&request, discard).await;
            match outcome {
                Outcome::Reply(r) => Ok(Some(r)),
                Outcome::Exception(code) => Err(code),
                Outcome::Silent => Ok(None),
                Outcome::Garble => Ok(Some(mismatched(&request))),
                Outcome::Close => close(&link, Ok(Some(mismatched(&request)))).await,
            }
        })
    }
}

/// Close the link: over TCP cut the stream (the reply's write fails and the
/// connection closes); over RTU stop the server and never answer.
async fn close(link: &Link, reply: Reply) -> Reply {
    match link {
        Link::Tcp(cut) => {
            cut.store(true, Ordering::SeqCst);
            reply
        }
        Link::Rtu(notify) => {
            notify.notify_one();
            std::future::pending().await
        }
    }
}

/// A TCP stream whose writes can be cut: once cut, every write fails. The
/// failed write ends the tokio-modbus session task, which drops (closes) the
/// socket.
#[derive(Debug)]
struct FaultyStream {
    inner: TcpStream,
    cut: Arc<AtomicBool>,
}

fn cut_error() -> io::Error {
    io::Error::new(io::ErrorKind::ConnectionAborted, "connection closed by an injected fault")
}

impl AsyncRead for FaultyStream {
    fn poll_read(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_read(cx, buf)
    }
}

impl AsyncWrite for FaultyStream {
    fn poll_write(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        if self.cut.load(Ordering::SeqCst) {
            return Poll::Ready(Err(cut_error()));
        }
        Pin::new(&mut self.inner).poll_write(cx, buf)
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }
}

#[cfg(test)]
mod interop;
#[cfg(test)]
mod tests;
