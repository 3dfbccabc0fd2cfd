//! The server's doors: connections accepted, bounded, timed out and closed
//! (hyper's HTTP/1 connection under the axum router).
//!
//! - a connection whose request head is not whole within
//!   [`Limits::header_timeout`] is closed (hyper's header read timeout: it
//!   runs from when the server waits for a head, so an idle kept-alive
//!   connection is closed after the same time);
//! - at most [`Limits::max_connections`] connections are open (never more
//!   than the open-file limit leaves, less a reserve for the store's files):
//!   a connection beyond the bound closes the oldest one that has no request
//!   under way (one sending half a head, or idle), or, when every one is
//!   answering, is closed at once; so connections left half-open cannot
//!   make the server unreachable, and `/api/live` answers;
//! - on shutdown the listener closes, every connection is told to close
//!   once its response is sent (an idle one closes at once), and those still
//!   open after [`Limits::stop_within`] are dropped;
//! - with [`Tls`], each connection's TLS handshake must end within the
//!   header timeout too (a connection in its handshake counts as one with no
//!   request under way), and the same HTTP/1 is served inside it.

use axum::Router;
use hyper::body::Incoming;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncWrite};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::watch;
use tokio::task::AbortHandle;

/// The bounds on the server's work ([`crate::ServeOptions::limits`]).
#[derive(Debug, Clone)]
pub struct Limits {
    /// A request's head must be whole within this time from when the server
    /// waits for it (a new connection, or a kept-alive one after a response).
    pub header_timeout: Duration,
    /// Connections open at once (at most the open-file limit less [`FILE_RESERVE`]).
    pub max_connections: usize,
    /// Pages and documents computed at once (the others wait their turn).
    pub heavy_at_once: usize,
    /// Pages and documents waiting their turn beyond those; more are answered
    /// 503 with `Retry-After`.
    pub heavy_queue: usize,
    /// On SIGINT or SIGTERM, connections still open after this are dropped.
    pub stop_within: Duration,
    /// For tests only: every page or document holds its turn this much longer.
    pub hold: Duration,
}

impl Default for Limits {
    fn default() -> Limits {
        let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
        Limits {
            header_timeout: Duration::from_secs(10),
            max_connections: 512,
            heavy_at_once: cores,
            heavy_queue: 8 * cores,
            stop_within: Duration::from_secs(10),
            hold: Duration::ZERO,
        }
    }
}

/// Open files kept free of connections: the store's files (a SQLite file
/// and its `-wal` and `-shm` per request computed at once), the blocking
/// threads' and the runtime's own descriptors, the log.
pub const FILE_RESERVE: u64 = 64;

/// The bound on connections: `wanted`, but no more than the process's
/// open-file limit leaves (less [`FILE_RESERVE`], at least 8).
pub fn connection_bound(wanted: usize) -> usize {
    use nix::sys::resource::{Resource, getrlimit};
    match getrlimit(Resource::RLIMIT_NOFILE) {
        Ok((soft, _)) => {
            let free = soft.saturating_sub(FILE_RESERVE).max(8);
            wanted.min(usize::try_from(free).unwrap_or(usize::MAX))
        }
        Err(_) => wanted,
    }
}

/// TLS on the server itself: the certificate chain and key of `--tls-cert`
/// and `--tls-key` (rustls, TLS 1.2 and 1.3, HTTP/1.1).
#[derive(Clone)]
pub struct Tls(tokio_rustls::TlsAcceptor);

impl std::fmt::Debug for Tls {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Tls")
    }
}

/// A TLS file that cannot be used: its path and why.
#[derive(Debug)]
pub struct TlsFileError(pub String);

impl std::fmt::Display for TlsFileError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for TlsFileError {}

impl Tls {
    /// The acceptor of the PEM certificate chain `cert` (the server's
    /// certificate first) and the PEM private key `key` (PKCS#8, PKCS#1 or SEC1).
    pub fn from_pem_files(cert: &Path, key: &Path) -> Result<Tls, TlsFileError> {
        use rustls_pki_types::pem::{Error as PemError, PemObject as _};
        use rustls_pki_types::{CertificateDer, PrivateKeyDer};
        let said = |path: &Path, what: &str, e: PemError| {
            let why = match e {
                PemError::Io(io) if io.kind() == std::io::ErrorKind::NotFound => "no such file".to_string(),
                PemError::Io(io) if io.kind() == std::io::ErrorKind::PermissionDenied => "permission denied".into(),
                PemError::Io(io) => io.to_string().split(" (os error").next().unwrap_or_default().to_string(),
                PemError::NoItemsFound => format!("holds no PEM {what}"),
                _ => format!("is not a PEM {what}"),
            };
            TlsFileError(format!("{}: {why}", path.display()))
        };
        let chain: Vec<CertificateDer<'static>> = CertificateDer::pem_file_iter(cert)
            .map_err(|e| said(cert, "certificate", e))?
            .collect::<Result<_, _>>()
            .map_err(|e| said(cert, "certificate", e))?;
        if chain.is_empty() {
            return Err(said(cert, "certificate (-----BEGIN CERTIFICATE-----)", PemError::NoItemsFound));
        }
        let private = PrivateKeyDer::from_pem_file(key).map_err(|e| said(key, "private key", e))?;
        let provider = Arc::new(tokio_rustls::rustls::crypto::ring::default_provider());
        let config = tokio_rustls::rustls::ServerConfig::builder_with_provider(provider)
            .with_safe_default_protocol_versions()
            .map_err(|e| TlsFileError(format!("TLS: {e}")))?
            .with_no_client_auth()
            .with_single_cert(chain, private)
            .map_err(|e| {
                TlsFileError(format!(
                    "{} and {}: the certificate and the key cannot be used together ({e})",
                    cert.display(),
                    key.display()
                ))
            })?;
        let mut config = config;
        config.alpn_protocols = vec![b"http/1.1".to_vec()];
        Ok(Tls(tokio_rustls::TlsAcceptor::from(Arc::new(config))))
    }
}

/// One open connection: how many of its requests are under way, and how to drop it.
#[derive(Debug)]
struct Open {
    busy: Arc<AtomicUsize>,
    abort: AbortHandle,
}

/// The open connections, by the order they were accepted in.
#[derive(Debug, Default)]
struct Connections {
    open: Mutex<BTreeMap<u64, Open>>,
    next: AtomicUsize,
    /// Told when the last connection closes.
    none_left: tokio::sync::Notify,
}

impl Connections {
    fn lock(&self) -> std::sync::MutexGuard<'_, BTreeMap<u64, Open>> {
        self.open.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    fn len(&self) -> usize {
        self.lock().len()
    }

    /// Close the oldest connection with no request under way: `false` when
    /// every open connection is answering one.
    fn evict_idle(&self) -> bool {
        let mut open = self.lock();
        let idle = open.iter().find(|(_, c)| c.busy.load(Ordering::Acquire) == 0).map(|(&id, _)| id);
        match idle.and_then(|id| open.remove(&id)) {
            Some(c) => {
                c.abort.abort();
                true
            }
            None => false,
        }
    }

    fn closed(&self, id: u64) {
        let mut open = self.lock();
        open.remove(&id);
        if open.is_empty() {
            self.none_left.notify_waiters();
        }
    }

    /// Drop every connection still open.
    fn abort_all(&self) {
        for (_, c) in std::mem::take(&mut *self.lock()) {
            c.abort.abort();
        }
    }
}

/// Serve `router` on `listener` within `limits` until `shutdown` resolves;
/// then close as the module says and return.
pub async fn serve(
    listener: TcpListener,
    router: Router,
    limits: &Limits,
    tls: Option<Tls>,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let bound = connection_bound(limits.max_connections);
    let connections = Arc::new(Connections::default());
    let (stop, stopping) = watch::channel(false);
    let mut http = hyper::server::conn::http1::Builder::new();
    http.timer(TokioTimer::new()).header_read_timeout(limits.header_timeout);
    let mut shutdown = std::pin::pin!(shutdown);
    loop {
        let (stream, peer) = tokio::select! {
            () = &mut shutdown => break,
            accepted = listener.accept() => match accepted {
                Ok(accepted) => accepted,
                Err(e) => {
                    on_accept_error(&e, &connections).await;
                    continue;
                }
            },
        };
        if connections.len() >= bound && !connections.evict_idle() {
            tracing::warn!(bound, "a connection closed at once: {bound} connections are answering requests");
            drop(stream);
            continue;
        }
        let how = How { http: http.clone(), tls: tls.clone(), handshake_within: limits.header_timeout };
        open(stream, peer, &connections, how, router.clone(), stopping.clone());
    }
    drop(listener);
    let _ = stop.send(true);
    let closed = async {
        loop {
            let notified = connections.none_left.notified();
            if connections.len() == 0 {
                return;
            }
            notified.await;
        }
    };
    if tokio::time::timeout(limits.stop_within, closed).await.is_err() {
        tracing::warn!(
            left = connections.len(),
            "connections still open {} s after the signal: dropped",
            limits.stop_within.as_secs_f64()
        );
        connections.abort_all();
    }
    Ok(())
}

/// An error accepting: out of file descriptors, one idle connection is
/// closed and the listener rests a moment; any other (a connection reset
/// before it was accepted) is the client's.
async fn on_accept_error(e: &std::io::Error, connections: &Connections) {
    const EMFILE: i32 = 24;
    const ENFILE: i32 = 23;
    if matches!(e.raw_os_error(), Some(EMFILE | ENFILE)) {
        tracing::warn!("cannot accept a connection: {e}; the oldest idle one is closed");
        connections.evict_idle();
        tokio::time::sleep(Duration::from_millis(10)).await;
    } else {
        tracing::debug!("a connection failed before it was accepted: {e}");
    }
}

/// How a connection is served: HTTP/1 (with its timeouts), inside TLS or not.
struct How {
    http: hyper::server::conn::http1::Builder,
    tls: Option<Tls>,
    handshake_within: Duration,
}

/// Serve one connection on its own task, registered in `connections` until it closes.
fn open(
    stream: TcpStream,
    peer: SocketAddr,
    connections: &Arc<Connections>,
    how: How,
    router: Router,
    stopping: watch::Receiver<bool>,
) {
    let id = connections.next.fetch_add(1, Ordering::Relaxed) as u64;
    let busy = Arc::new(AtomicUsize::new(0));
    let tower = TowerToHyperService::new(router);
    let counted = Arc::clone(&busy);
    let service = hyper::service::service_fn(move |mut req: hyper::Request<Incoming>| {
        req.extensions_mut().insert(crate::gate::Peer(peer));
        let turn = Busy::new(&counted);
        let call = hyper::service::Service::call(&tower, req);
        async move {
            let response = call.await;
            drop(turn);
            response
        }
    });
    let left = Arc::clone(connections);
    // The registry holds the connection before its task can end and remove it.
    let mut open = connections.lock();
    let task = tokio::spawn(async move {
        match how.tls {
            None => drive(&how.http, stream, service, stopping).await,
            Some(Tls(acceptor)) => match tokio::time::timeout(how.handshake_within, acceptor.accept(stream)).await {
                Ok(Ok(tls)) => drive(&how.http, tls, service, stopping).await,
                Ok(Err(e)) => tracing::debug!("a TLS handshake failed: {e}"),
                Err(_) => tracing::debug!("a TLS handshake did not end within the header timeout"),
            },
        }
        left.closed(id);
    });
    open.insert(id, Open { busy, abort: task.abort_handle() });
}

/// Serve HTTP/1 on `io` until the client closes it, or until the server
/// stops (then gracefully: the request under way is answered).
async fn drive<IO, S>(
    http: &hyper::server::conn::http1::Builder,
    io: IO,
    service: S,
    mut stopping: watch::Receiver<bool>,
) where
    IO: AsyncRead + AsyncWrite + Unpin + Send + 'static,
    S: hyper::service::HttpService<Incoming> + Send,
    S::Future: Send + 'static,
    S::ResBody: Send + 'static,
    <S::ResBody as hyper::body::Body>::Data: Send,
    <S::ResBody as hyper::body::Body>::Error: Into<Box<dyn std::error::Error + Send + Sync>>,
{
    let conn = http.serve_connection(TokioIo::new(io), service);
    let mut conn = std::pin::pin!(conn);
    let served = tokio::select! {
        r = conn.as_mut() => r,
        () = async { let _ = stopping.wait_for(|&s| s).await; } => {
            conn.as_mut().graceful_shutdown();
            conn.await
        }
    };
    if let Err(e) = served {
        tracing::debug!("a connection ended: {e}");
    }
}

/// A request under way on its connection (counted while it lives).
struct Busy(Arc<AtomicUsize>);

impl Busy {
    fn new(count: &Arc<AtomicUsize>) -> Busy {
        count.fetch_add(1, Ordering::AcqRel);
        Busy(Arc::clone(count))
    }
}

impl Drop for Busy {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::AcqRel);
    }
}
