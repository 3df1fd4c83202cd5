//! `GET /metrics`: the station for the plant's monitoring, in the
//! Prometheus text format through the `prometheus` crate (TiKV's, the
//! classic text format `promtool check metrics` reads). The gauges are read
//! from the hub when scraped; the counters and the store's write latency
//! are kept as they happen.

use prometheus::{
    Encoder, Gauge, GaugeVec, Histogram, HistogramOpts, IntCounter, IntCounterVec, IntGauge, Opts,
    Registry, TextEncoder,
};

/// The station's metrics.
pub struct Metrics {
    registry: Registry,
    state: GaugeVec,
    rate_deg_s: Gauge,
    demand_deg_s: Gauge,
    progress: Gauge,
    instruments_live: IntGauge,
    slot_temperature_c: GaugeVec,
    /// The store's write latency [s] (each heartbeat's write).
    pub store_write_s: Histogram,
    /// HTTP requests by route and status.
    pub http_requests: IntCounterVec,
    /// Logins refused (wrong name or password, or locked out).
    pub login_failures: IntCounter,
    /// 1 while the store takes writes (the heartbeat's, and the run's).
    pub store_up: IntGauge,
    /// The heartbeat's writes that failed.
    pub store_errors: IntCounter,
    /// Since when the heartbeat's write now in flight has waited (a stalled
    /// store does not fail the write; it does not answer).
    pub store_write_since: std::sync::Mutex<Option<std::time::Instant>>,
    store_queue_depth: IntGauge,
    store_queue_age_s: Gauge,
    store_run_errors: IntGauge,
    /// Webhook deliveries ended, by result (`delivered`, `failed`).
    pub webhook_deliveries: IntCounterVec,
    /// Webhook tries the receiver did not take (each is tried again).
    pub webhook_failed_attempts: IntCounter,
    /// Webhook deliveries waiting.
    pub webhook_waiting: IntGauge,
    chamber_busy_replies: IntGauge,
    /// The process's failed run writes already counted into `store_errors`.
    run_failures_counted: std::sync::atomic::AtomicU64,
}

/// The run states the state gauge has a series for (1 for the one now).
const STATES: [&str; 4] = ["idle", "running", "waiting", "faulted"];

impl Metrics {
    /// Every metric, registered; names as the README lists them.
    pub fn new() -> Result<Metrics, prometheus::Error> {
        let registry = Registry::new();
        let state = GaugeVec::new(
            Opts::new(
                "spinbench_station_state",
                "1 for the station's state now (idle, running, waiting, faulted)",
            ),
            &["state"],
        )?;
        let rate_deg_s = Gauge::new(
            "spinbench_table_rate_degrees_per_second",
            "the table's measured rate [deg/s]",
        )?;
        let demand_deg_s = Gauge::new(
            "spinbench_table_demand_degrees_per_second",
            "the table's demanded rate [deg/s]",
        )?;
        let progress = Gauge::new(
            "spinbench_run_progress_ratio",
            "steps done over the run's steps (0 without a run)",
        )?;
        let instruments_live = IntGauge::new(
            "spinbench_instruments_live",
            "instruments of the run not failed (with an output or still to be measured)",
        )?;
        let slot_temperature_c = GaugeVec::new(
            Opts::new(
                "spinbench_slot_temperature_celsius",
                "each slot's instrument temperature [°C] (slots numbered from 1, as on the fixtures)",
            ),
            &["slot"],
        )?;
        let store_write_s = Histogram::with_opts(
            HistogramOpts::new(
                "spinbench_store_write_seconds",
                "the store's write latency (heartbeat writes) [s]",
            )
            .buckets(prometheus::exponential_buckets(0.0005, 2.0, 14)?),
        )?;
        let http_requests = IntCounterVec::new(
            Opts::new(
                "spinbench_http_requests_total",
                "HTTP requests by route and status",
            ),
            &["route", "status"],
        )?;
        let login_failures = IntCounter::new("spinbench_login_failures_total", "logins refused")?;
        let store_up = IntGauge::new(
            "spinbench_store_up",
            "1 while the store takes the station's writes (heartbeat and run), 0 while they fail",
        )?;
        let store_errors = IntCounter::new(
            "spinbench_store_errors_total",
            "the station's writes to the store that failed: the heartbeat's and every run's",
        )?;
        let store_queue_depth = IntGauge::new(
            "spinbench_store_queue_events",
            "the run's events waiting for the store (its outbox)",
        )?;
        let store_queue_age_s = Gauge::new(
            "spinbench_store_queue_age_seconds",
            "how long the oldest event waiting for the store has waited [s]",
        )?;
        let store_run_errors = IntGauge::new(
            "spinbench_store_run_write_errors",
            "the running (or last) run's writes to the store that failed and were tried again",
        )?;
        let chamber_busy_replies = IntGauge::new(
            "spinbench_chamber_busy_replies",
            "the chamber controller's busy replies ridden in the running (or last) run",
        )?;
        registry.register(Box::new(chamber_busy_replies.clone()))?;
        let webhook_deliveries = IntCounterVec::new(
            Opts::new(
                "spinbench_webhook_deliveries_total",
                "webhook deliveries ended, by result (delivered, failed: every try spent)",
            ),
            &["result"],
        )?;
        let webhook_failed_attempts = IntCounter::new(
            "spinbench_webhook_failed_attempts_total",
            "webhook tries the receiver did not take (tried again with back-off)",
        )?;
        let webhook_waiting = IntGauge::new(
            "spinbench_webhook_waiting",
            "webhook deliveries waiting to be made",
        )?;
        // Both results shown from the start (0), so an alert on `failed`
        // has its series before the first failure.
        for result in ["delivered", "failed"] {
            webhook_deliveries.with_label_values(&[result]);
        }
        registry.register(Box::new(webhook_deliveries.clone()))?;
        registry.register(Box::new(webhook_failed_attempts.clone()))?;
        registry.register(Box::new(webhook_waiting.clone()))?;
        registry.register(Box::new(state.clone()))?;
        registry.register(Box::new(rate_deg_s.clone()))?;
        registry.register(Box::new(demand_deg_s.clone()))?;
        registry.register(Box::new(progress.clone()))?;
        registry.register(Box::new(instruments_live.clone()))?;
        registry.register(Box::new(slot_temperature_c.clone()))?;
        registry.register(Box::new(store_write_s.clone()))?;
        registry.register(Box::new(http_requests.clone()))?;
        registry.register(Box::new(login_failures.clone()))?;
        // Up until a write says otherwise (the server opened its store).
        store_up.set(1);
        registry.register(Box::new(store_up.clone()))?;
        registry.register(Box::new(store_errors.clone()))?;
        registry.register(Box::new(store_queue_depth.clone()))?;
        registry.register(Box::new(store_queue_age_s.clone()))?;
        registry.register(Box::new(store_run_errors.clone()))?;
        Ok(Metrics {
            registry,
            state,
            rate_deg_s,
            demand_deg_s,
            progress,
            instruments_live,
            slot_temperature_c,
            store_write_s,
            http_requests,
            login_failures,
            store_up,
            store_errors,
            store_write_since: std::sync::Mutex::new(None),
            store_queue_depth,
            store_queue_age_s,
            store_run_errors,
            webhook_deliveries,
            webhook_failed_attempts,
            webhook_waiting,
            chamber_busy_replies,
            run_failures_counted: std::sync::atomic::AtomicU64::new(0),
        })
    }

    /// Whether the store takes the heartbeat's writes: the last was taken
    /// and none has waited [`spinbench_store::outbox::STALLED_AFTER`].
    pub fn store_answering(&self) -> bool {
        let since = *self
            .store_write_since
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        self.store_up.get() == 1
            && since.is_none_or(|t| t.elapsed() < spinbench_store::outbox::STALLED_AFTER)
    }

    /// The text a scrape gets, with the gauges set from `status` (the
    /// hub's snapshot) and `state` (the heartbeat's word for it).
    pub fn render(
        &self,
        status: &super::hub::StatusSnapshot,
        state: &str,
        store: Option<&spinbench_store::outbox::HealthReading>,
    ) -> String {
        if !self.store_answering() {
            self.store_up.set(0);
        }
        // Every run's failed writes, counted once each.
        let run_failures = spinbench_store::outbox::run_write_failures();
        let seen = self
            .run_failures_counted
            .swap(run_failures, std::sync::atomic::Ordering::Relaxed);
        self.store_errors.inc_by(run_failures.saturating_sub(seen));
        if let Some(h) = store {
            if !h.up {
                self.store_up.set(0);
            }
            self.store_queue_depth.set(h.depth as i64);
            self.store_queue_age_s.set(h.age_s);
            self.store_run_errors.set(h.errors as i64);
        }
        for s in STATES {
            self.state
                .with_label_values(&[s])
                .set(if s == state { 1.0 } else { 0.0 });
        }
        // A rate not known (no run has read the table) is NaN, not 0: a
        // table at rest and a table not read are two things.
        self.rate_deg_s.set(status.rate_deg_s.unwrap_or(f64::NAN));
        self.demand_deg_s
            .set(status.demand_deg_s.unwrap_or(f64::NAN));
        // The instruments and their temperatures are a run's: after it
        // ends none are live and no slot's temperature is current.
        let active = matches!(state, "running" | "waiting");
        let progress = match (&status.step, active) {
            (Some(step), true) if step.of > 0 => {
                (step.index as f64 + 1.0).min(step.of as f64) / step.of as f64
            }
            _ => 0.0,
        };
        self.progress.set(progress);
        self.chamber_busy_replies
            .set(status.chamber_busy_replies.unwrap_or(0) as i64);
        let live = status
            .board
            .iter()
            .filter(|s| {
                !s.serial.is_empty() && s.phase != spinbench_engine::board::SlotPhase::Failed
            })
            .count();
        self.instruments_live
            .set(if active { live as i64 } else { 0 });
        self.slot_temperature_c.reset();
        for s in status.board.iter().filter(|_| active) {
            if let Some(t) = s.temperature_c.filter(|t| t.is_finite()) {
                self.slot_temperature_c
                    .with_label_values(&[&s.slot.to_string()])
                    .set(t);
            }
        }
        let mut out = Vec::new();
        // Encoding into memory fails only on a metric the registry refused.
        let _ = TextEncoder::new().encode(&self.registry.gather(), &mut out);
        String::from_utf8(out).unwrap_or_default()
    }
}
