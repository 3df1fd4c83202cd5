//! The HTTP connections of `spinbench serve`, held to a plant network's
//! limits: a cap on open connections and a cap per address, a deadline for
//! a request's headers (and for the TLS handshake under `--tls-cert`) and
//! for its body, an idle timeout, and a shutdown that ends within a bounded
//! time.
//!
//! **Slow clients**: a client that opens many connections and
//! trickles a byte now and then would keep every slot taken, and an
//! operator reaching for Abort would be refused. So a new connection is
//! never refused for want of a slot: when its address holds
//! [`ConnectionLimits::max_per_address`] connections, or the server holds
//! `max_connections`, one connection (of that address, or of any) is closed
//! to make room, the least useful first (300 connections
//! from 300 addresses closed an operator's event stream 120 times in 45 s):
//! one that never sent a request; then one without a session; then a
//! logged-in one; an event stream of a logged-in user last
//! ([`Usefulness`]); among equals the oldest (the one trickling its header
//! longest). A request's body must arrive within
//! [`ConnectionLimits::body_timeout`] (408 otherwise, `body_deadline`), and
//! is never buffered beyond its route's limit, nor at all for a change
//! without a session cookie (item 8).
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

/// What a connection has shown itself to be, noted as its requests are
/// answered (by the API's middleware, through the request's extensions).
#[derive(Debug, Default)]
pub struct ConnectionState {
    /// Requests it sent (0: not even one header).
    requests: AtomicU64,
    /// It carried a session the server accepted.
    logged_in: std::sync::atomic::AtomicBool,
    /// It holds an event stream.
    streaming: std::sync::atomic::AtomicBool,
}

impl ConnectionState {
    /// A request of this connection was answered; `logged_in`: with a
    /// session the server accepted; `stream`: an event stream.
    pub fn answered(&self, logged_in: bool, stream: bool) {
        if logged_in {
            self.logged_in.store(true, Ordering::Relaxed);
        }
        if stream {
            self.streaming.store(true, Ordering::Relaxed);
        }
    }

    /// How useful the connection is to keep: the lowest is closed first.
    fn usefulness(&self) -> Usefulness {
        let logged_in = self.logged_in.load(Ordering::Relaxed);
        if self.requests.load(Ordering::Relaxed) == 0 {
            Usefulness::NoRequest
        } else if self.streaming.load(Ordering::Relaxed) && logged_in {
            Usefulness::OperatorsStream
        } else if logged_in {
            Usefulness::LoggedIn
        } else {
            Usefulness::Anonymous
        }
    }
}

/// A connection's worth when one must close, lowest first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Usefulness {
    /// No request yet (a header not sent, or trickling).
    NoRequest,
    /// Requests without a session (a scraper, a login page, an attacker).
    Anonymous,
    /// A logged-in user's requests.
    LoggedIn,
    /// A logged-in user's event stream (the Run page).
    OperatorsStream,
}

/// One open connection: its id (increasing with age), its state and the
/// sender that closes it.
struct Open {
    id: u64,
    state: Arc<ConnectionState>,
    close: watch::Sender<bool>,
}

/// The open connections, by address, oldest first.
#[derive(Default)]
struct Connections {
    by_address: std::collections::HashMap<std::net::IpAddr, std::collections::VecDeque<Open>>,
    open: usize,
    next_id: u64,
}

impl Connections {
    /// Make room for a connection from `address` (closing the least
    /// useful of that address when it is at its cap, or of all when the
    /// server is full: module docs) and register it: its id, its state and
    /// the receiver that says it must close.
    fn admit(
        &mut self,
        address: std::net::IpAddr,
        limits: &ConnectionLimits,
    ) -> (u64, Arc<ConnectionState>, watch::Receiver<bool>) {
        let at_cap = self
            .by_address
            .get(&address)
            .is_some_and(|q| q.len() >= limits.max_per_address.max(1));
        let full = self.open >= limits.max_connections.max(1);
        if at_cap || full {
            // Lowest usefulness; among equals, the oldest (a connection
            // trickling its header is the oldest that never sent one).
            let victim = self
                .by_address
                .iter()
                .filter(|(a, _)| !at_cap || **a == address)
                .flat_map(|(a, q)| q.iter().map(move |o| (*a, o)))
                .min_by_key(|(_, o)| (o.state.usefulness(), o.id))
                .map(|(a, o)| (a, o.id));
            if let Some((a, id)) = victim {
                if let Some(q) = self.by_address.get(&a)
                    && let Some(o) = q.iter().find(|o| o.id == id)
                {
                    let _ = o.close.send(true);
                }
                self.leave(a, id);
            }
        }
        let (tx, rx) = watch::channel(false);
        let id = self.next_id;
        self.next_id += 1;
        let state = Arc::new(ConnectionState::default());
        self.by_address.entry(address).or_default().push_back(Open {
            id,
            state: state.clone(),
            close: tx,
        });
        self.open += 1;
        (id, state, rx)
    }

    /// Forget connection `id` of `address` (it ended).
    fn leave(&mut self, address: std::net::IpAddr, id: u64) {
        if let Some(q) = self.by_address.get_mut(&address) {
            let before = q.len();
            q.retain(|o| o.id != id);
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
    gate: impl FnOnce(Router) -> Router,
    shutdown: impl Future<Output = ()>,
) {
    let acceptor = tls.map(tokio_rustls::TlsAcceptor::from);
    let body_timeout = limits.body_timeout;
    // `gate` outside the body's deadline: a request it refuses (no valid
    // session) is answered before its body is read.
    let app = gate(app.layer(axum::middleware::from_fn(move |request, next| {
        body_deadline(body_timeout, request, next)
    })));
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
        let (id, state, mut evicted) = connections
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
                state.requests.fetch_add(1, Ordering::Relaxed);
                req.extensions_mut().insert(ConnectInfo(peer));
                req.extensions_mut().insert(state.clone());
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

/// The most a request's body may hold on its route [bytes]: a login's is
/// small, a read's smaller still, a change's [`MAX_BODY_BYTES`].
pub fn route_body_limit(method: &axum::http::Method, path: &str) -> usize {
    use axum::http::Method;
    if path == "/api/login" {
        super::api::LOGIN_BODY_LIMIT
    } else if matches!(*method, Method::GET | Method::HEAD | Method::DELETE) {
        4 * 1024
    } else {
        MAX_BODY_BYTES
    }
}

/// The body of every request read within `limit` (408 otherwise) and at
/// most its route's limit ([`route_body_limit`]; 413 otherwise, at once
/// when its Content-Length says so), then handed on whole: a client
/// trickling its body holds its connection no longer than that. A change
/// (POST, PUT, DELETE) other than a login without a session cookie or an
/// API token is answered 401 before its body is read: nothing is buffered for a request
/// that cannot be done.
pub async fn body_deadline(
    limit: Duration,
    request: axum::extract::Request,
    next: axum::middleware::Next,
) -> axum::response::Response {
    use axum::http::{Method, StatusCode, header};
    use axum::response::IntoResponse;
    let max_bytes = route_body_limit(request.method(), request.uri().path());
    let close = [(header::CONNECTION, "close")];
    let declared = request
        .headers()
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok());
    if declared.is_some_and(|n| n > max_bytes as u64) {
        return (
            StatusCode::PAYLOAD_TOO_LARGE,
            close,
            axum::Json(serde_json::json!({"error": format!("a body over {max_bytes} bytes")})),
        )
            .into_response();
    }
    let change = matches!(
        *request.method(),
        Method::POST | Method::PUT | Method::DELETE
    );
    let path = request.uri().path();
    let has_session = request
        .headers()
        .get(header::COOKIE)
        .and_then(|v| v.to_str().ok())
        .and_then(super::auth::session_token)
        .is_some()
        || super::api::bearer(request.headers())
            .is_some_and(|secret| crate::tokens::is_token_shaped(&secret));
    if change && path.starts_with("/api/") && path != "/api/login" && !has_session {
        return (
            StatusCode::UNAUTHORIZED,
            close,
            axum::Json(serde_json::json!({"error": "not logged in: POST /api/login first"})),
        )
            .into_response();
    }
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
