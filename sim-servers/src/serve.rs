//! One way to serve a simulated instrument: the instrument is a [`Service`]
//! (a request in, on its codec; a reply out), and one generic loop per
//! transport serves it: [`serve_stream`] on a byte stream (a pty's master
//! end, one TCP connection), [`serve_tcp`] on a listener (one client at a
//! time, as the instruments serve), [`serve_can`] on a CAN bus. The Modbus
//! controller is a tokio-modbus `Service` served by tokio-modbus's own
//! server ([`crate::modbus_server`]). Link faults are never a service's: the
//! [`relay`](crate::relay) in front of it injects them.

use async_trait::async_trait;
use survey_positioner_drivers::canopen::frame::{CanBus, CanFrame};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::task::JoinSet;

/// What a service does after a request (or on its own).
#[derive(Debug, Clone, PartialEq)]
pub enum Answer<R> {
    /// Send this.
    Send(R),
    /// Send nothing (a command without reply; a request the instrument lost).
    Nothing,
    /// Close the link (the instrument dropped it, or the framing is lost).
    Close,
}

/// A simulated instrument: requests in, answers out.
#[async_trait]
pub trait Service: Send {
    /// One request as the instrument's codec frames it (its framing errors
    /// included: the instrument answers those too).
    type Request: Send;
    /// What goes back on the wire (bytes; frames on a CAN bus).
    type Reply: Send;

    /// Serve one request.
    async fn call(&mut self, request: Self::Request) -> Answer<Self::Reply>;

    /// What the instrument sends of its own accord (emScon's streamed
    /// points, an adapter's received CAN frames, a node's boot-up), awaited
    /// between requests; cancel-safe. Never, by default.
    async fn unsolicited(&mut self) -> Answer<Self::Reply> {
        std::future::pending().await
    }

    /// Whether a second TCP client, while one is served, is refused (its
    /// first request answered with [`Service::busy`], then disconnected)
    /// rather than left waiting until the first has gone (the default).
    const REFUSES_SECOND_CLIENT: bool = false;

    /// The answer to a refused second client's first request.
    fn busy(_request: Self::Request) -> Option<Vec<u8>> {
        None
    }
}

/// An instrument's request codec on a byte stream: bytes in, requests out.
pub trait Codec: Send {
    /// One request (or a framing error).
    type Item: Send;
    /// Bytes as they arrive.
    fn push(&mut self, bytes: &[u8]);
    /// The next whole request, if one is there.
    fn next_item(&mut self) -> Option<Self::Item>;
}

/// Why a serve loop returned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ServeEnd {
    /// End of file from the peer.
    PeerClosed,
    /// A read or write failed (a pty master reads EIO once the other side is
    /// closed).
    LinkError(std::io::ErrorKind),
    /// The service closed the link.
    Closed,
}

/// Serve `service` on one byte stream until the peer closes, the link fails
/// or the service closes it.
pub async fn serve_stream<S, C, V>(mut stream: S, mut codec: C, service: &mut V) -> ServeEnd
where
    S: AsyncRead + AsyncWrite + Unpin,
    C: Codec,
    V: Service<Request = C::Item, Reply = Vec<u8>>,
{
    let mut buf = vec![0u8; 4096];
    loop {
        let read = tokio::select! {
            read = stream.read(&mut buf) => read,
            own = service.unsolicited() => match own {
                Answer::Send(bytes) => {
                    if let Err(e) = send(&mut stream, &bytes).await {
                        return ServeEnd::LinkError(e.kind());
                    }
                    continue;
                }
                Answer::Nothing => continue,
                Answer::Close => return ServeEnd::Closed,
            },
        };
        let n = match read {
            Ok(0) => return ServeEnd::PeerClosed,
            Ok(n) => n,
            Err(e) => return ServeEnd::LinkError(e.kind()),
        };
        codec.push(&buf[..n]);
        while let Some(request) = codec.next_item() {
            match service.call(request).await {
                Answer::Send(bytes) => {
                    if let Err(e) = send(&mut stream, &bytes).await {
                        return ServeEnd::LinkError(e.kind());
                    }
                }
                Answer::Nothing => {}
                Answer::Close => return ServeEnd::Closed,
            }
        }
    }
}

async fn send<S: AsyncWrite + Unpin>(stream: &mut S, bytes: &[u8]) -> std::io::Result<()> {
    if bytes.is_empty() {
        return Ok(());
    }
    stream.write_all(bytes).await?;
    stream.flush().await
}

/// The next client on `listener` (a failed accept is logged and the next
/// one awaited).
async fn accept(listener: &TcpListener) -> TcpStream {
    loop {
        match listener.accept().await {
            Ok((stream, peer)) => {
                tracing::debug!(%peer, "simulator: client connected");
                stream.set_nodelay(true).ok();
                return stream;
            }
            Err(e) => {
                tracing::warn!(error = %e, "simulator: accept failed");
                tokio::task::yield_now().await;
            }
        }
    }
}

/// Accept clients on `listener` one at a time and give each to `handle`
/// until it is done with it (the next client waits in the backlog), until
/// the task running this future is dropped or aborted.
pub async fn one_client_at_a_time<F, Fut>(listener: TcpListener, mut handle: F)
where
    F: FnMut(TcpStream) -> Fut,
    Fut: std::future::Future<Output = ()>,
{
    loop {
        handle(accept(&listener).await).await;
        tracing::debug!("simulator: client gone");
    }
}

/// Serve `service` on `listener`, one client at a time (its state survives
/// the clients), each connection framed by a new `codec()`, until the task
/// running this future is dropped or aborted. A second client while one is
/// served waits, or is refused when the service says so
/// ([`Service::REFUSES_SECOND_CLIENT`], [`Service::busy`]).
pub async fn serve_tcp<C, V>(listener: TcpListener, codec: impl Fn() -> C, mut service: V)
where
    C: Codec + 'static,
    V: Service<Request = C::Item, Reply = Vec<u8>> + 'static,
{
    let mut refused = JoinSet::new();
    loop {
        let stream = accept(&listener).await;
        if !V::REFUSES_SECOND_CLIENT {
            serve_stream(stream, codec(), &mut service).await;
            tracing::debug!("simulator: client gone");
            continue;
        }
        let mut serving = std::pin::pin!(serve_stream(stream, codec(), &mut service));
        loop {
            tokio::select! {
                biased;
                _ = &mut serving => break,
                accepted = listener.accept() => match accepted {
                    Ok((other, who)) => {
                        tracing::info!(%who, "simulator: refusing a second client");
                        refused.spawn(refuse(other, codec(), V::busy));
                    }
                    Err(e) => tracing::warn!(error = %e, "simulator: accept failed"),
                },
                Some(_) = refused.join_next(), if !refused.is_empty() => {}
            }
        }
        tracing::debug!("simulator: client gone");
    }
}

/// Answer a second client's first request with `busy`'s answer, then hang up.
async fn refuse<C: Codec>(mut stream: TcpStream, mut codec: C, busy: fn(C::Item) -> Option<Vec<u8>>) {
    let mut buf = [0u8; 512];
    loop {
        match stream.read(&mut buf).await {
            Ok(0) | Err(_) => return,
            Ok(n) => codec.push(&buf[..n]),
        }
        if let Some(request) = codec.next_item() {
            if let Some(answer) = busy(request) {
                let _ = stream.write_all(&answer).await;
            }
            return;
        }
    }
}

/// Serve `service` on a CAN bus: its frames of its own first (a node's
/// boot-up), then each frame on the bus answered, until the bus fails.
pub async fn serve_can<B, V>(mut bus: B, service: &mut V)
where
    B: CanBus,
    V: Service<Request = CanFrame, Reply = Vec<CanFrame>>,
{
    loop {
        let answer = tokio::select! {
            frame = bus.recv() => match frame {
                Ok(frame) => service.call(frame).await,
                Err(e) => {
                    tracing::debug!(error = %e, "simulator: CAN bus gone");
                    return;
                }
            },
            own = service.unsolicited() => own,
        };
        match answer {
            Answer::Send(frames) => {
                for frame in frames {
                    if let Err(e) = bus.send(frame).await {
                        tracing::debug!(error = %e, "simulator: CAN bus gone while answering");
                        return;
                    }
                }
            }
            Answer::Nothing => {}
            Answer::Close => return,
        }
    }
}
