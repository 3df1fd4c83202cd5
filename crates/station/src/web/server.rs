//! The HTTP connections of `spinbench serve`, held to a plant network's
//! limits: a cap on open connections and a cap per address, a deadline for
//! a request's headers (and for the TLS handshake under `--tls-cert`) and
//! for its body, an idle timeout, and a shutdown that ends within a bounded
//! time.
//!
//! **Slow clients** (issue 27): a client that opens many connections and
//! trickles a byte now and then would keep every slot taken, and an
//! operator reaching for Abort would be refused. So a new connection is
//! never refused for want of a slot: when its address holds
//! [`ConnectionLimits::max_per_address`] connections, or the server holds
//! `max_connections`, the oldest connection of that address (or of the
//! address holding the most) is closed to make room; and a request's body
//! must arrive within [`ConnectionLimits::body_timeout`] (408 otherwise,
//! `body_deadline`).
//!
//! Written over hyper's connection API rather than `axum::serve`, because
//! `axum::serve` sets none of these limits (no header timeout, no idle
//! timeout, no connection cap) and its graceful shutdown waits for ever on
//! a browser's open event stream.

use axum::Router;
use axum::extract::ConnectInfo;
use hyper::body::Incoming;
use hyper_util::rt::{TokioIo, TokioTimer};
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::task::{Context, Poll};
use std::time::{Duration, Instant};
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::watch;
use tower_service::Service;

/// The limits of the server's connections.
#[derive(Debug, Clone, Copy)]
pub struct ConnectionLimits {
    /// Most connections open at once; more are closed at once.
    pub max_connections: usize,
    /// A request's header must arrive within this.
    pub header_timeout: Duration,
    /// A connection with no byte either way for this long is closed.
    pub idle_timeout: Duration,
    /// After shutdown begins, connections get this long to finish.
    pub drain: Duration,
    /// Most connections from one address; a new one closes its oldest.
    pub max_per_address: usize,
    /// A request's body must arrive within this after its headers.
    pub body_timeout: Duration,
}

impl Default for ConnectionLimits {
    fn default() -> Self {
        ConnectionLimits {
            max_connections: 256,
            header_timeout: Duration::from_secs(10),
            idle_timeout: Duration::from_secs(60),
            drain: Duration::from_secs(5),
            max_per_address: 64,
            body_timeout: Duration::from_secs(10),
        }
    }
}

/// The open connections, by address, oldest first: (id, the sender that
/// closes it).
#[derive(Default)]
struct Connections {
    by_address: std::collections::HashMap<
        std::net::IpAddr,
        std::collections::VecDeque<(u64, watch::Sender<bool>)>,
    >,
    open: usize,
    next_id: u64,
}

impl Connections {
    /// Make room for a connection from `address` (closing the oldest of
    /// that address when it is at its cap, or of the address holding the
    /// most when the server is full) and register it: its id and the
    /// receiver that says it must close.
    fn admit(
        &mut self,
        address: std::net::IpAddr,
        limits: &ConnectionLimits,
    ) -> (u64, watch::Receiver<bool>) {
        let at_cap = self
            .by_address
            .get(&address)
            .is_some_and(|q| q.len() >= limits.max_per_address.max(1));
        let victim = if at_cap {
            Some(address)
        } else if self.open >= limits.max_connections.max(1) {
            self.by_address
                .iter()
                .max_by_key(|(_, q)| q.len())
                .map(|(a, _)| *a)
        } else {
            None
        };
        if let Some(v) = victim
            && let Some(q) = self.by_address.get_mut(&v)
            && let Some((_, close)) = q.pop_front()
        {
            let _ = close.send(true);
            self.open -= 1;
            if q.is_empty() {
                self.by_address.remove(&v);
            }
        }
        let (tx, rx) = watch::channel(false);
        let id = self.next_id;
        self.next_id += 1;
        self.by_address
            .entry(address)
            .or_default()
            .push_back((id, tx));
        self.open += 1;
        (id, rx)
    }

    /// Forget connection `id` of `address` (it ended).
    fn leave(&mut self, address: std::net::IpAddr, id: u64) {
        if let Some(q) = self.by_address.get_mut(&address) {
            let before = q.len();
            q.retain(|(i, _)| *i != id);
            self.open -= before - q.len();
            if q.is_empty() {
                self.by_address.remove(&address);
            }
        }
    }
}

/// A stream that notes when a byte last went either way.
struct Watched {
    stream: TcpStream,
    born: Instant,
    last_ms: Arc<AtomicU64>,
}

impl Watched {
    fn touch(&self) {
        self.last_ms
            .store(self.born.elapsed().as_millis() as u64, Ordering::Relaxed);
    }
}

impl AsyncRead for Watched {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        let before = buf.filled().len();
        let polled = Pin::new(&mut self.stream).poll_read(cx, buf);
        if buf.filled().len() > before {
            self.touch();
        }
        polled
    }
}

impl AsyncWrite for Watched {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<std::io::Result<usize>> {
        let polled = Pin::new(&mut self.stream).poll_write(cx, buf);
        if matches!(polled, Poll::Ready(Ok(n)) if n > 0) {
            self.touch();
        }
        polled
    }
    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.stream).poll_flush(cx)
    }
    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.stream).poll_shutdown(cx)
    }
}

/// Serve `app` on `listener` until `shutdown` completes; then stop
/// accepting, ask every connection to finish (`closing` is set first, so
/// event streams end) and wait at most `limits.drain` for them. With `tls`,
/// every connection is HTTPS (its handshake within `limits.header_timeout`).
pub async fn serve(
    listener: TcpListener,
    app: Router,
    limits: ConnectionLimits,
    tls: Option<Arc<rustls::ServerConfig>>,
    shutdown: impl Future<Output = ()>,
) {
    let acceptor = tls.map(tokio_rustls::TlsAcceptor::from);
    let body_timeout = limits.body_timeout;
    let app = app.layer(axum::middleware::from_fn(move |request, next| {
        body_deadline(body_timeout, MAX_BODY_BYTES, request, next)
    }));
    let connections = Arc::new(std::sync::Mutex::new(Connections::default()));
    let (stop_tx, stop_rx) = watch::channel(false);
    let mut tasks = tokio::task::JoinSet::new();
    tokio::pin!(shutdown);
    loop {
        let accepted = tokio::select! {
            () = &mut shutdown => break,
            accepted = listener.accept() => accepted,
        };
        let Ok((stream, peer)) = accepted else {
            // Out of descriptors and the like: wait a little, go on.
            tokio::time::sleep(Duration::from_millis(50)).await;
            continue;
        };
        let (id, mut evicted) = connections
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .admit(peer.ip(), &limits);
        let app = app.clone();
        let stop = stop_rx.clone();
        let acceptor = acceptor.clone();
        let registry = connections.clone();
        tasks.spawn(async move {
            // Gone from the registry however the connection ends.
            struct Leave(Arc<std::sync::Mutex<Connections>>, std::net::IpAddr, u64);
            impl Drop for Leave {
                fn drop(&mut self) {
                    self.0
                        .lock()
                        .unwrap_or_else(|e| e.into_inner())
                        .leave(self.1, self.2);
                }
            }
            let _leave = Leave(registry, peer.ip(), id);
            let watched = Watched {
                stream,
                born: Instant::now(),
                last_ms: Arc::new(AtomicU64::new(0)),
            };
            let activity = (watched.born, watched.last_ms.clone());
            let service = hyper::service::service_fn(move |mut req: hyper::Request<Incoming>| {
                req.extensions_mut().insert(ConnectInfo(peer));
                let mut app = app.clone();
                async move { app.call(req).await }
            });
            let serve = async move {
                match acceptor {
                    None => drive(TokioIo::new(watched), service, limits, activity, stop).await,
                    // TLS over the watched stream: its idle clock sees every byte.
                    Some(acceptor) => {
                        let handshake =
                            tokio::time::timeout(limits.header_timeout, acceptor.accept(watched))
                                .await;
                        // A failed or slow handshake just closes the connection.
                        if let Ok(Ok(tls)) = handshake {
                            drive(TokioIo::new(tls), service, limits, activity, stop).await;
                        }
                    }
                }
            };
            // Closed to make room for a newer connection (module docs).
            tokio::select! {
                () = serve => {}
                _ = evicted.wait_for(|closed| *closed) => {}
            }
        });
        // Reap finished connections so the set does not grow.
        while tasks.try_join_next().is_some() {}
    }
    drop(listener);
    let _ = stop_tx.send(true);
    let drained = tokio::time::timeout(limits.drain, async {
        while tasks.join_next().await.is_some() {}
    })
    .await;
    if drained.is_err() {
        tasks.abort_all();
    }
}

/// One connection served until it ends, the server stops (gracefully), or
/// it is idle longer than `limits.idle_timeout` (by `activity`: when the
/// stream was born, and the milliseconds after that of its last byte).
async fn drive<I, S>(
    io: I,
    service: S,
    limits: ConnectionLimits,
    activity: (Instant, Arc<AtomicU64>),
    mut stop: watch::Receiver<bool>,
) where
    I: hyper::rt::Read + hyper::rt::Write + Unpin + Send + 'static,
    S: hyper::service::HttpService<Incoming> + Send + 'static,
    S::Future: Send + 'static,
    S::ResBody: Send + 'static,
    <S::ResBody as hyper::body::Body>::Data: Send,
    <S::ResBody as hyper::body::Body>::Error: Into<Box<dyn std::error::Error + Send + Sync>>,
{
    let (born, last) = activity;
    let mut builder = hyper::server::conn::http1::Builder::new();
    builder
        .timer(TokioTimer::new())
        .header_read_timeout(limits.header_timeout);
    let conn = builder.serve_connection(io, service);
    tokio::pin!(conn);
    let mut tick = tokio::time::interval(Duration::from_millis(250));
    let mut stopping = false;
    loop {
        tokio::select! {
            _ = conn.as_mut() => break,
            changed = stop.changed(), if !stopping => {
                let _ = changed;
                stopping = true;
                conn.as_mut().graceful_shutdown();
            }
            _ = tick.tick() => {
                let idle_ms = (born.elapsed().as_millis() as u64)
                    .saturating_sub(last.load(Ordering::Relaxed));
                if idle_ms > limits.idle_timeout.as_millis() as u64 {
                    break;
                }
            }
        }
    }
}

/// The largest request body the server reads [bytes] (each route may take
/// less; axum's own default is this too).
pub const MAX_BODY_BYTES: usize = 2 * 1024 * 1024;

/// The body of every request read within `limit` (408 otherwise) and at
/// most `max_bytes` (413 otherwise), then handed on whole: a client
/// trickling its body holds its connection no longer than that.
pub async fn body_deadline(
    limit: Duration,
    max_bytes: usize,
    request: axum::extract::Request,
    next: axum::middleware::Next,
) -> axum::response::Response {
    use axum::response::IntoResponse;
    let (parts, body) = request.into_parts();
    match tokio::time::timeout(limit, axum::body::to_bytes(body, max_bytes)).await {
        Ok(Ok(bytes)) => {
            next.run(axum::extract::Request::from_parts(
                parts,
                axum::body::Body::from(bytes),
            ))
            .await
        }
        Ok(Err(_)) => (
            axum::http::StatusCode::PAYLOAD_TOO_LARGE,
            axum::Json(serde_json::json!({"error": format!("a body over {max_bytes} bytes")})),
        )
            .into_response(),
        Err(_) => (
            axum::http::StatusCode::REQUEST_TIMEOUT,
            [(axum::http::header::CONNECTION, "close")],
            axum::Json(serde_json::json!({"error": format!(
                "the request's body did not arrive within {} s",
                limit.as_secs()
            )})),
        )
            .into_response(),
    }
}
