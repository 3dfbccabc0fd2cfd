//! A simulated positioner controller on Modbus TCP and Modbus RTU.
//!
//! A [`ModbusDevice`] serves a [`SimPositioner`] through a
//! [`RegisterMap`] (the same type, and so the same map, the driver in
//! [`survey_drivers::modbus`] is configured with; see its module
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
//!   ([`PositionerFaults`](crate::positioner::PositionerFaults)) become the
//!   same fault on the wire: `Timeout` = no reply, `Disconnected` = the
//!   link is closed, `Garbled` = a reply of another function.
//! - The unit id: requests to another unit get no reply (a shared RTU bus;
//!   over TCP, 0xFF, "the device itself", is also accepted).
//! - The positioner's fault code goes to the fault code register (0xFFFF if
//!   it does not fit 16 bits); the sim's following error is 0x8611.
//!
//! # Fault injection ([`ModbusFaults`])
//!
//! A handle shared with the test: what is armed applies to the next requests
//! to this unit as they come, one request per armed fault, checked in this
//! order:
//!
//! - [`close_during_next_reply`](ModbusFaults::close_during_next_reply): the
//!   request is executed; over TCP the first half of the reply frame is sent
//!   and the connection is closed (the listener keeps accepting); over RTU
//!   nothing is sent and the server stops, closing the pty master;
//! - [`reject_next_request`](ModbusFaults::reject_next_request): not executed,
//!   answered with the given exception;
//! - [`drop_next_replies`](ModbusFaults::drop_next_replies): executed, no reply
//!   (the client times out);
//! - [`garble_next_replies`](ModbusFaults::garble_next_replies): executed,
//!   answered with a reply of another function (the client sees a mismatch);
//! - [`discard_nth_next_write`](ModbusFaults::discard_nth_next_write): the
//!   n-th write from now is acknowledged but not applied (data lost inside
//!   the device: the table checksum catches it).

mod device;

use crate::faults::{Countdown, FaultPlan};
use crate::positioner::SimPositioner;
use device::{DeviceState, Outcome};
use std::collections::VecDeque;
use std::future::Future;
use std::io;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};
use std::task::{Context, Poll};
use survey_drivers::modbus::{ExceptionCode, MapError, RegisterMap, Request, Response};
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::Notify;
use tokio::task::JoinHandle;
use tokio_modbus::SlaveRequest;
use tokio_modbus::server::Service;
use tokio_modbus::server::tcp::accept_tcp_connection;

/// Most rows a staged table column may hold.
pub const MAX_TABLE_ROWS: u16 = 16_384;

/// Faults to inject, shared between the test and the server (clone it before
/// passing it in). Nothing is armed by default.
#[derive(Debug, Clone, Default)]
pub struct ModbusFaults {
    inner: FaultPlan<Armed>,
}

#[derive(Debug, Default)]
struct Armed {
    close: bool,
    reject: VecDeque<ExceptionCode>,
    drop: Countdown,
    garble: Countdown,
    discard_write: Option<usize>,
    requests: usize,
}

/// What to do with one request.
#[derive(Debug, Clone, Copy, Default)]
struct Plan {
    close: bool,
    reject: Option<ExceptionCode>,
    drop: bool,
    garble: bool,
}

impl ModbusFaults {
    /// Nothing armed.
    pub fn new() -> Self {
        Self::default()
    }

    /// Execute the next `n` requests but send no reply.
    pub fn drop_next_replies(&self, n: usize) {
        self.inner.lock().drop.add(n);
    }

    /// Execute the next `n` requests and answer each with a reply of another
    /// function.
    pub fn garble_next_replies(&self, n: usize) {
        self.inner.lock().garble.add(n);
    }

    /// Answer the next request (not executed) with `code`. Several calls queue.
    pub fn reject_next_request(&self, code: ExceptionCode) {
        self.inner.lock().reject.push_back(code);
    }

    /// Execute the next request, then close the link in the middle of its
    /// reply (TCP: half the frame; RTU: before the reply).
    pub fn close_during_next_reply(&self) {
        self.inner.lock().close = true;
    }

    /// Acknowledge the `n`-th write request from now (1 = the next one)
    /// without applying it.
    pub fn discard_nth_next_write(&self, n: usize) {
        self.inner.lock().discard_write = Some(n.max(1));
    }

    /// Requests to this unit received so far.
    pub fn requests(&self) -> usize {
        self.inner.lock().requests
    }

    /// Count a write request that is about to be executed; true when it is
    /// the one to discard.
    fn discard_this_write(&self) -> bool {
        let mut a = self.inner.lock();
        match a.discard_write {
            Some(1) => {
                a.discard_write = None;
                true
            }
            Some(n) => {
                a.discard_write = Some(n - 1);
                false
            }
            None => false,
        }
    }

    fn next_plan(&self) -> Plan {
        let mut a = self.inner.lock();
        a.requests += 1;
        let mut plan = Plan::default();
        if std::mem::take(&mut a.close) {
            plan.close = true;
        } else if let Some(code) = a.reject.pop_front() {
            plan.reject = Some(code);
        } else if a.drop.take() {
            plan.drop = true;
        } else if a.garble.take() {
            plan.garble = true;
        }
        plan
    }
}

/// The simulated controller: a [`SimPositioner`] behind a [`RegisterMap`].
/// Cloning gives another handle on the same controller.
#[derive(Clone)]
pub struct ModbusDevice {
    state: Arc<tokio::sync::Mutex<DeviceState>>,
    map: Arc<RegisterMap>,
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
    /// An injected fault (or the positioner's injected disconnect) closed the port.
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
        Ok(Self { state: Arc::new(tokio::sync::Mutex::new(state)), map: Arc::new(map) })
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

    fn session(&self, faults: &ModbusFaults, link: Link) -> Session {
        Session { device: self.clone(), faults: faults.clone(), link }
    }

    /// Serve Modbus TCP on `listener` until the future is dropped (or the
    /// listener fails). Every connection gets its own session on the same
    /// controller.
    pub async fn serve_tcp(&self, listener: TcpListener, faults: ModbusFaults) -> io::Result<()> {
        let server = tokio_modbus::server::tcp::Server::new(listener);
        let device = self.clone();
        let on_connected = move |stream: TcpStream, peer: SocketAddr| {
            let cut = Arc::new(AtomicU8::new(CUT_NONE));
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
    pub async fn spawn_tcp(&self, faults: ModbusFaults) -> io::Result<TcpServer> {
        let listener = TcpListener::bind("127.0.0.1:0").await?;
        let addr = listener.local_addr()?;
        let device = self.clone();
        let task = tokio::spawn(async move { device.serve_tcp(listener, faults).await });
        Ok(TcpServer { addr, task })
    }

    /// Serve Modbus RTU on `port` (the master side of a pty pair, or a real
    /// serial port) until the stream ends, fails, or a fault closes it. The
    /// port is closed on return.
    pub async fn serve_rtu(&self, port: tokio_serial::SerialStream, faults: ModbusFaults) -> RtuEnd {
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
    /// The cut mode of the connection's [`FaultyStream`].
    Tcp(Arc<AtomicU8>),
    /// Wakes `serve_until`'s abort signal.
    Rtu(Arc<Notify>),
}

const CUT_NONE: u8 = 0;
const CUT_HALF: u8 = 1;
const CUT_NOW: u8 = 2;

/// One client's view of the controller: the `Service` tokio-modbus calls.
#[derive(Debug)]
struct Session {
    device: ModbusDevice,
    faults: ModbusFaults,
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
        let plan = self.faults.next_plan();
        let faults = self.faults.clone();
        let device = self.device.clone();
        let link = self.link.clone();
        Box::pin(async move {
            if let Some(code) = plan.reject {
                tracing::debug!(?code, "sim Modbus controller rejects a request (injected)");
                return Err(code);
            }
            let is_write = matches!(request, Request::WriteSingleRegister(..) | Request::WriteMultipleRegisters(..));
            let discard = is_write && faults.discard_this_write();
            let outcome = device.state.lock().await.handle(&request, discard).await;
            let reply: Reply = match outcome {
                Outcome::Reply(r) => Ok(Some(r)),
                Outcome::Exception(code) => Err(code),
                Outcome::Silent => return Ok(None),
                Outcome::Garble => return Ok(Some(mismatched(&request))),
                Outcome::Close => return close(&link, CUT_NOW, Ok(Some(mismatched(&request)))).await,
            };
            if plan.close {
                tracing::debug!("sim Modbus controller closes the link mid-reply (injected)");
                return close(&link, CUT_HALF, reply).await;
            }
            if plan.drop {
                tracing::debug!("sim Modbus controller drops its reply (injected)");
                return Ok(None);
            }
            if plan.garble {
                tracing::debug!("sim Modbus controller garbles its reply (injected)");
                return Ok(Some(mismatched(&request)));
            }
            reply
        })
    }
}

/// Close the link: over TCP arm the stream's cut (the reply goes out as far
/// as `mode` allows, then the connection fails and closes); over RTU stop the
/// server and never answer.
async fn close(link: &Link, mode: u8, reply: Reply) -> Reply {
    match link {
        Link::Tcp(cut) => {
            cut.store(mode, Ordering::SeqCst);
            reply
        }
        Link::Rtu(notify) => {
            notify.notify_one();
            std::future::pending().await
        }
    }
}

/// A TCP stream whose writes can be cut: after [`CUT_HALF`] the next write
/// sends half its bytes and every later write fails; after [`CUT_NOW`] every
/// write fails. The failed write ends the tokio-modbus session task, which
/// drops (closes) the socket.
#[derive(Debug)]
struct FaultyStream {
    inner: TcpStream,
    cut: Arc<AtomicU8>,
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
        match self.cut.load(Ordering::SeqCst) {
            CUT_NONE => Pin::new(&mut self.inner).poll_write(cx, buf),
            CUT_HALF => {
                let half = (buf.len() / 2).max(1).min(buf.len());
                let r = Pin::new(&mut self.inner).poll_write(cx, &buf[..half]);
                if let Poll::Ready(Ok(_)) = r {
                    self.cut.store(CUT_NOW, Ordering::SeqCst);
                }
                r
            }
            _ => Poll::Ready(Err(cut_error())),
        }
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
