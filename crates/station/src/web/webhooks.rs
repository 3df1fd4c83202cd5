//! Webhooks: the station pushes its runs' start, end and faults to a URL of
//! the plant's (an MES that would otherwise poll `/api/status`). Each POST
//! is JSON signed with HMAC-SHA256 under a secret shared with the receiver
//! (`X-Spinbench-Signature`), tried again with back-off until the receiver
//! answers 2xx or [`MAX_ATTEMPTS`] are spent, one delivery at a time in the
//! order of the events. The last deliveries are listed for an admin
//! (`GET /api/webhooks`) and counted in `/metrics`.
//!
//! The events are read from the hub, as the browsers read them: a webhook
//! never reaches into the run. A delivery waiting when the server stops is
//! given [`DRAIN_LIMIT`] and then dropped, said on standard error: the
//! run's record is in the store whatever its webhook did.

use super::hub::HubEvent;
use super::metrics::Metrics;
use anyhow::{Context, Result, bail};
use hmac::{KeyInit, Mac};
use serde_json::{Value, json};
use std::collections::{BTreeMap, VecDeque};
use std::path::Path;
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// The most tries of one delivery (about two minutes of back-off).
pub const MAX_ATTEMPTS: u32 = 8;
/// The first wait before a delivery is tried again; doubled each time.
const FIRST_BACKOFF: Duration = Duration::from_secs(1);
/// The longest wait between two tries.
const MAX_BACKOFF: Duration = Duration::from_secs(60);
/// How long one try may take (connect, send, answer).
const ATTEMPT_TIMEOUT: Duration = Duration::from_secs(10);
/// How many deliveries are kept for the list (the newest).
const KEPT: usize = 200;
/// How many deliveries may wait; beyond, the oldest waiting is dropped
/// (a receiver down for days must not fill the server's memory).
const MAX_WAITING: usize = 1_000;
/// The longest URL accepted.
const MAX_URL_LEN: usize = 2_048;
/// The shortest and longest secret accepted [bytes].
const SECRET_LEN: std::ops::RangeInclusive<usize> = 16..=1_024;
/// How long a stopping server waits for the deliveries still waiting.
pub const DRAIN_LIMIT: Duration = Duration::from_secs(5);

/// Where the webhooks go and the secret they are signed with.
#[derive(Clone)]
pub struct WebhookTarget {
    url: String,
    secret: Vec<u8>,
}

impl std::fmt::Debug for WebhookTarget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Never the secret.
        f.debug_struct("WebhookTarget")
            .field("url", &shown_url(&self.url))
            .finish_non_exhaustive()
    }
}

impl WebhookTarget {
    /// `--webhook-url URL --webhook-secret-file FILE`, checked: an http or
    /// https URL; a secret file of 16 to 1024 bytes (its surrounding
    /// whitespace is not part of it).
    pub fn from_args(url: &str, secret_file: &Path) -> Result<WebhookTarget> {
        let shown = spinbench_engine::bounds::shown(url);
        if url.len() > MAX_URL_LEN {
            bail!("--webhook-url: longer than {MAX_URL_LEN} characters");
        }
        let rest = url
            .strip_prefix("https://")
            .or_else(|| url.strip_prefix("http://"));
        match rest {
            Some(rest)
                if !rest.is_empty()
                    && !rest.starts_with('/')
                    && !url.chars().any(|c| c.is_whitespace() || c.is_control()) => {}
            _ => bail!(
                "--webhook-url {shown}: expected http://HOST[:PORT]/PATH or https://… (the receiver of the plant's MES)"
            ),
        }
        let size = std::fs::metadata(secret_file)
            .with_context(|| {
                format!(
                    "--webhook-secret-file {}: cannot read it",
                    secret_file.display()
                )
            })?
            .len();
        if size > 4 * *SECRET_LEN.end() as u64 {
            bail!(
                "--webhook-secret-file {}: {size} bytes; a secret is at most {} bytes",
                secret_file.display(),
                SECRET_LEN.end()
            );
        }
        let text = std::fs::read(secret_file).with_context(|| {
            format!(
                "--webhook-secret-file {}: cannot read it",
                secret_file.display()
            )
        })?;
        let secret = text.trim_ascii().to_vec();
        if !SECRET_LEN.contains(&secret.len()) {
            bail!(
                "--webhook-secret-file {}: the secret is {} bytes; use {} to {} (e.g. `openssl rand -hex 32 > FILE`)",
                secret_file.display(),
                secret.len(),
                SECRET_LEN.start(),
                SECRET_LEN.end()
            );
        }
        Ok(WebhookTarget {
            url: url.to_string(),
            secret,
        })
    }

    /// The URL as it may be shown (without any user or password in it).
    pub fn shown_url(&self) -> String {
        shown_url(&self.url)
    }
}

/// `url` without its user information.
fn shown_url(url: &str) -> String {
    let Some((scheme, rest)) = url.split_once("://") else {
        return url.to_string();
    };
    let authority_end = rest.find('/').unwrap_or(rest.len());
    match rest[..authority_end].rfind('@') {
        Some(at) => format!("{scheme}://…@{}", &rest[at + 1..]),
        None => url.to_string(),
    }
}

/// The HMAC-SHA256 signature of a delivery as the header carries it:
/// `sha256=` and the hex digest of `TIMESTAMP.BODY` under `secret` (the
/// timestamp is `X-Spinbench-Timestamp`, so a receiver can refuse a replay).
pub fn signature(secret: &[u8], timestamp: i64, body: &str) -> String {
    let mut mac = hmac::Hmac::<sha2::Sha256>::new_from_slice(secret)
        .unwrap_or_else(|_| unreachable!("HMAC takes a key of any length"));
    mac.update(timestamp.to_string().as_bytes());
    mac.update(b".");
    mac.update(body.as_bytes());
    let digest = mac.finalize().into_bytes();
    let hex: String = digest.iter().map(|b| format!("{b:02x}")).collect();
    format!("sha256={hex}")
}

/// One delivery, as the list shows it.
#[derive(Debug, Clone, serde::Serialize, utoipa::ToSchema)]
pub struct WebhookDelivery {
    /// Its id (`X-Spinbench-Delivery`; the same on every try).
    pub id: String,
    /// `run.started`, `run.ended` or `run.faulted`.
    pub event: String,
    /// The run it is about.
    pub run_id: String,
    /// When it was queued [Unix s].
    pub queued_at: i64,
    /// Tries so far.
    pub attempts: u32,
    /// `waiting`, `delivered` or `failed` (every try spent, or dropped).
    pub state: String,
    /// The receiver's last HTTP status, if it answered.
    pub last_status: Option<u16>,
    /// Why the last try failed, if it did.
    pub last_error: Option<String>,
    /// When the receiver took it [Unix s].
    pub delivered_at: Option<i64>,
}

/// A delivery still to be made.
struct Waiting {
    index_id: String,
    event: String,
    body: String,
}

#[derive(Default)]
struct Queue {
    waiting: VecDeque<Waiting>,
    in_flight: bool,
    closed: bool,
}

/// The webhooks of this server: the target (if any), the deliveries.
pub struct Webhooks {
    target: Option<WebhookTarget>,
    queue: Mutex<Queue>,
    changed: Condvar,
    deliveries: Mutex<VecDeque<WebhookDelivery>>,
}

impl Webhooks {
    /// Webhooks to `target` (none: nothing is sent, the list is empty).
    pub fn new(target: Option<WebhookTarget>) -> Webhooks {
        Webhooks {
            target,
            queue: Mutex::new(Queue::default()),
            changed: Condvar::new(),
            deliveries: Mutex::new(VecDeque::new()),
        }
    }

    /// The receiver's URL as it may be shown, if webhooks are on.
    pub fn url(&self) -> Option<String> {
        self.target.as_ref().map(WebhookTarget::shown_url)
    }

    /// The kept deliveries, newest first.
    pub fn deliveries(&self) -> Vec<WebhookDelivery> {
        lock(&self.deliveries).iter().rev().cloned().collect()
    }

    /// Start reading the hub and delivering (nothing when no target).
    pub fn spawn(self: &Arc<Self>, state: Arc<super::AppState>) -> Result<()> {
        let Some(target) = self.target.clone() else {
            return Ok(());
        };
        let reader = self.clone();
        let reading = state.clone();
        let mut events = state.hub.subscribe();
        std::thread::Builder::new()
            .name("webhook-events".into())
            .spawn(move || {
                let mut runs = RunsSeen::default();
                loop {
                    match events.blocking_recv() {
                        Ok(event) => {
                            for (name, run_id, body) in runs.read(&event) {
                                reader.enqueue(name, run_id, event.seq, body, &reading.metrics);
                            }
                        }
                        Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => continue,
                        Err(tokio::sync::broadcast::error::RecvError::Closed) => break,
                    }
                }
                reader.close();
            })
            .context("cannot start the webhooks' thread")?;
        let sender = self.clone();
        std::thread::Builder::new()
            .name("webhook-sender".into())
            .spawn(move || sender.deliver_all(&target, &state.metrics))
            .context("cannot start the webhooks' sender")?;
        Ok(())
    }

    /// Wait (at most `limit`) for the deliveries still waiting; true when
    /// none is left.
    pub fn drain(&self, limit: Duration) -> bool {
        let until = Instant::now() + limit;
        let mut q = lock(&self.queue);
        while !q.waiting.is_empty() || q.in_flight {
            let now = Instant::now();
            if now >= until || self.target.is_none() {
                return false;
            }
            q = self
                .changed
                .wait_timeout(q, until - now)
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
        true
    }

    fn enqueue(
        &self,
        event: &'static str,
        run_id: String,
        seq: u64,
        mut body: Value,
        metrics: &Metrics,
    ) {
        // Unique per server: a resumed run starts again.
        let id = format!("{run_id}.{event}.{seq}");
        body["delivery"] = Value::from(id.clone());
        let delivery = WebhookDelivery {
            id: id.clone(),
            event: event.to_string(),
            run_id,
            queued_at: spinbench_store::now_s(),
            attempts: 0,
            state: "waiting".into(),
            last_status: None,
            last_error: None,
            delivered_at: None,
        };
        {
            let mut list = lock(&self.deliveries);
            list.push_back(delivery);
            while list.len() > KEPT {
                list.pop_front();
            }
        }
        let mut q = lock(&self.queue);
        q.waiting.push_back(Waiting {
            index_id: id,
            event: event.to_string(),
            body: body.to_string(),
        });
        while q.waiting.len() > MAX_WAITING {
            if let Some(dropped) = q.waiting.pop_front() {
                self.update(&dropped.index_id, |d| {
                    d.state = "failed".into();
                    d.last_error = Some("dropped: too many deliveries waiting".into());
                });
                metrics
                    .webhook_deliveries
                    .with_label_values(&["failed"])
                    .inc();
            }
        }
        metrics.webhook_waiting.set(q.waiting.len() as i64);
        drop(q);
        self.changed.notify_all();
    }

    fn close(&self) {
        lock(&self.queue).closed = true;
        self.changed.notify_all();
    }

    /// The sender's loop: one delivery at a time, in order.
    fn deliver_all(&self, target: &WebhookTarget, metrics: &Metrics) {
        let agent: ureq::Agent = ureq::Agent::config_builder()
            .http_status_as_error(false)
            .timeout_global(Some(ATTEMPT_TIMEOUT))
            .user_agent(format!("spinbench/{}", env!("CARGO_PKG_VERSION")))
            .build()
            .into();
        loop {
            let next = {
                let mut q = lock(&self.queue);
                loop {
                    if let Some(w) = q.waiting.pop_front() {
                        q.in_flight = true;
                        break Some(w);
                    }
                    if q.closed {
                        break None;
                    }
                    q = self.changed.wait(q).unwrap_or_else(|e| e.into_inner());
                }
            };
            let Some(waiting) = next else { return };
            let delivered = self.deliver(&agent, target, &waiting, metrics);
            metrics
                .webhook_deliveries
                .with_label_values(&[if delivered { "delivered" } else { "failed" }])
                .inc();
            let mut q = lock(&self.queue);
            q.in_flight = false;
            metrics.webhook_waiting.set(q.waiting.len() as i64);
            drop(q);
            self.changed.notify_all();
        }
    }

    /// Every try of one delivery; true when the receiver took it.
    fn deliver(
        &self,
        agent: &ureq::Agent,
        target: &WebhookTarget,
        waiting: &Waiting,
        metrics: &Metrics,
    ) -> bool {
        let mut backoff = FIRST_BACKOFF;
        for attempt in 1..=MAX_ATTEMPTS {
            let timestamp = spinbench_store::now_s();
            let answer = agent
                .post(&target.url)
                .header("Content-Type", "application/json")
                .header("X-Spinbench-Event", &waiting.event)
                .header("X-Spinbench-Delivery", &waiting.index_id)
                .header("X-Spinbench-Timestamp", timestamp.to_string())
                .header(
                    "X-Spinbench-Signature",
                    signature(&target.secret, timestamp, &waiting.body),
                )
                .send(waiting.body.as_bytes());
            let (status, error) = match answer {
                Ok(r) if r.status().is_success() => (Some(r.status().as_u16()), None),
                Ok(r) => (
                    Some(r.status().as_u16()),
                    Some(format!("the receiver answered {}", r.status())),
                ),
                Err(e) => (None, Some(e.to_string())),
            };
            let done = error.is_none();
            self.update(&waiting.index_id, |d| {
                d.attempts = attempt;
                d.last_status = status;
                d.last_error = error.clone();
                if done {
                    d.state = "delivered".into();
                    d.delivered_at = Some(spinbench_store::now_s());
                } else if attempt == MAX_ATTEMPTS {
                    d.state = "failed".into();
                }
            });
            if done {
                return true;
            }
            metrics.webhook_failed_attempts.inc();
            if attempt == MAX_ATTEMPTS {
                eprintln!(
                    "webhook {} to {}: not delivered after {MAX_ATTEMPTS} tries ({})",
                    waiting.index_id,
                    target.shown_url(),
                    error.unwrap_or_default()
                );
                return false;
            }
            // A stopping server does not wait out a long back-off.
            let q = lock(&self.queue);
            if q.closed {
                drop(q);
                std::thread::sleep(backoff.min(Duration::from_millis(500)));
            } else {
                let _ = self.changed.wait_timeout_while(q, backoff, |q| !q.closed);
            }
            backoff = (backoff * 2).min(MAX_BACKOFF);
        }
        false
    }

    fn update(&self, id: &str, change: impl FnOnce(&mut WebhookDelivery)) {
        if let Some(d) = lock(&self.deliveries).iter_mut().rev().find(|d| d.id == id) {
            change(d);
        }
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// The runs the hub has told of: turns its events into webhook bodies.
#[derive(Default)]
struct RunsSeen {
    station: String,
    run_id: String,
    /// Each instrument's outcome so far, by serial (a later mounting's
    /// record is the instrument's final one).
    outcomes: BTreeMap<String, String>,
}

impl RunsSeen {
    /// The webhooks `event` makes: (event name, run id, body).
    fn read(&mut self, event: &HubEvent) -> Vec<(&'static str, String, Value)> {
        if !matches!(
            event.kind.as_str(),
            "run_started" | "fault" | "unit_result" | "run_finished"
        ) {
            return Vec::new();
        }
        let Ok(v) = serde_json::from_str::<Value>(&event.json) else {
            return Vec::new();
        };
        let at = spinbench_store::now_s();
        match event.kind.as_str() {
            "run_started" => {
                self.station = v["station"].as_str().unwrap_or_default().to_string();
                self.run_id = v["run_id"].as_str().unwrap_or_default().to_string();
                self.outcomes.clear();
                let plan = &v["plan"]["plan"];
                vec![(
                    "run.started",
                    self.run_id.clone(),
                    json!({
                        "event": "run.started",
                        "station": self.station,
                        "run_id": self.run_id,
                        "resumed": v["resumed"],
                        "plan": plan["name"],
                        "operator": plan["operator"],
                        "serials": v["plan"]["serials"],
                        "at_unix_s": at,
                        "run": format!("/api/runs/{}", self.run_id),
                    }),
                )]
            }
            "fault" => vec![(
                "run.faulted",
                self.run_id.clone(),
                json!({
                    "event": "run.faulted",
                    "station": self.station,
                    "run_id": self.run_id,
                    "reason": v["reason"],
                    "at_unix_s": at,
                    "run": format!("/api/runs/{}", self.run_id),
                }),
            )],
            "unit_result" => {
                let record = &v["record"];
                if let (Some(serial), Some(outcome)) =
                    (record["serial"].as_str(), record["outcome"].as_str())
                {
                    self.outcomes
                        .insert(serial.to_string(), outcome.to_string());
                }
                Vec::new()
            }
            _ => vec![(
                "run.ended",
                self.run_id.clone(),
                json!({
                    "event": "run.ended",
                    "station": self.station,
                    "run_id": self.run_id,
                    "state": v["state"],
                    "reason": v["reason"],
                    "outcomes": self.outcomes,
                    "at_unix_s": at,
                    "run": format!("/api/runs/{}", self.run_id),
                }),
            )],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_signature_is_hmac_sha256_of_timestamp_dot_body() {
        // The HMAC the signature is made with gives RFC 4231's test case 2;
        // the receiver's side (Python's hmac) is checked in web_webhooks.rs.
        let mut mac = hmac::Hmac::<sha2::Sha256>::new_from_slice(b"Jefe").expect("key");
        mac.update(b"what do ya want for nothing?");
        let hex: String = mac
            .finalize()
            .into_bytes()
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        assert_eq!(
            hex,
            "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843"
        );
        let a = signature(b"0123456789abcdef", 1_700_000_000, "{}");
        assert!(a.starts_with("sha256=") && a.len() == 7 + 64, "{a}");
        assert_ne!(a, signature(b"0123456789abcdef", 1_700_000_001, "{}"));
        assert_ne!(a, signature(b"0123456789abcdeF", 1_700_000_000, "{}"));
        assert_ne!(a, signature(b"0123456789abcdef", 1_700_000_000, "{ }"));
    }

    #[test]
    fn a_shown_url_has_no_credentials() {
        assert_eq!(
            shown_url("https://mes:pw@host:8443/hook?x=1"),
            "https://…@host:8443/hook?x=1"
        );
        assert_eq!(shown_url("http://host/a@b"), "http://host/a@b");
    }

    #[test]
    fn hub_events_become_start_fault_and_end_bodies() {
        let event = |seq, kind: &str, json: Value| HubEvent {
            seq,
            kind: kind.into(),
            json: json.to_string(),
        };
        let mut runs = RunsSeen::default();
        let started = runs.read(&event(
            1,
            "run_started",
            json!({"run_id": "r1", "station": "s1", "resumed": false,
                   "plan": {"plan": {"name": "p", "operator": "op"}, "serials": ["A", ""]}}),
        ));
        assert_eq!(started.len(), 1);
        assert_eq!(started[0].0, "run.started");
        assert_eq!(started[0].2["serials"], json!(["A", ""]));
        assert!(runs.read(&event(2, "values", json!({}))).is_empty());
        assert!(
            runs.read(&event(
                3,
                "unit_result",
                json!({"record": {"serial": "A", "outcome": "pass"}})
            ))
            .is_empty()
        );
        let fault = runs.read(&event(4, "fault", json!({"reason": "door open"})));
        assert_eq!(fault[0].0, "run.faulted");
        assert_eq!(fault[0].2["reason"], "door open");
        let end = runs.read(&event(
            5,
            "run_finished",
            json!({"state": "faulted", "reason": "door open"}),
        ));
        assert_eq!(end[0].0, "run.ended");
        assert_eq!(end[0].1, "r1");
        assert_eq!(end[0].2["station"], "s1");
        assert_eq!(end[0].2["outcomes"], json!({"A": "pass"}));
    }
}
