//! The fleet (issue 26): every station that writes into this store, with a
//! heartbeat — what it is doing now, which run, how far, when it was last
//! heard — and the day's first-pass yield. Each `spinbench serve` beats
//! every few seconds; a station not heard for [`OFFLINE_AFTER_S`] is offline.

use crate::db::Value;
use crate::{Store, StoreError, now_s};

/// A station not heard from for this long is offline [s].
pub const OFFLINE_AFTER_S: i64 = 10;

/// What a station says of itself in a heartbeat.
#[derive(Debug, Clone, PartialEq)]
pub struct Heartbeat {
    /// The station's id (its config's `station`).
    pub station: String,
    /// `idle`, `running` or `faulted`.
    pub state: String,
    /// Its current (or last) run.
    pub run_id: Option<String>,
    /// Steps done and of, of the current run.
    pub progress: Option<(i64, i64)>,
    /// Where its web UI answers (for a link), if it serves one.
    pub address: Option<String>,
}

/// One station of the fleet as the store knows it.
#[derive(Debug, Clone, PartialEq)]
pub struct StationRow {
    /// Its heartbeat's fields (state `offline` when not heard recently).
    pub beat: Heartbeat,
    /// When it was first seen [Unix s].
    pub first_seen: i64,
    /// When it was last heard [Unix s].
    pub last_seen: i64,
    /// Instruments graded today (UTC) in first tests (not retests), each
    /// serial of a run once.
    pub tested_today: i64,
    /// Of them, passed in every mounting.
    pub passed_today: i64,
}

impl Store {
    /// Record a station's heartbeat (and the station, if new).
    pub fn heartbeat(&self, beat: &Heartbeat) -> Result<(), StoreError> {
        let now = now_s();
        let (done, of) = beat
            .progress
            .map_or((None, None), |(d, o)| (Some(d), Some(o)));
        self.db()
            .execute(
                "INSERT INTO stations (name, first_seen, last_seen, state, run_id, steps_done, steps_total, address)
                 VALUES ($1, $2, $3, $4, $5, $6, $7, $8)
                 ON CONFLICT (name) DO UPDATE SET last_seen = excluded.last_seen, state = excluded.state,
                   run_id = excluded.run_id, steps_done = excluded.steps_done,
                   steps_total = excluded.steps_total, address = excluded.address",
                &[
                    beat.station.as_str().into(),
                    now.into(),
                    now.into(),
                    beat.state.as_str().into(),
                    beat.run_id.clone().into(),
                    Value::Int(done),
                    Value::Int(of),
                    beat.address.clone().into(),
                ],
            )
            .map(|_| ())
            .map_err(self.err(&format!("record the heartbeat of station '{}'", beat.station)))
    }

    /// Every station, by name, with its state now (offline when its last
    /// heartbeat is older than [`OFFLINE_AFTER_S`], or it never beat) and
    /// today's first-pass yield.
    pub fn stations(&self) -> Result<Vec<StationRow>, StoreError> {
        let now = now_s();
        let midnight = now - now.rem_euclid(86_400);
        let rows = self.query(
            "list the stations",
            "SELECT name, first_seen, last_seen, state, run_id, steps_done, steps_total, address
             FROM stations ORDER BY name",
            &[],
        )?;
        let mut out = Vec::with_capacity(rows.len());
        for r in rows {
            let name = r.text(0);
            let last_seen = r.int(2);
            let beat_state = r.opt_text(3);
            let state = match beat_state {
                Some(s) if now - last_seen <= OFFLINE_AFTER_S => s,
                _ => "offline".to_string(),
            };
            let progress = match (r.0.get(5), r.0.get(6)) {
                (Some(Value::Int(Some(d))), Some(Value::Int(Some(o)))) => Some((*d, *o)),
                _ => None,
            };
            let yield_rows = self.query(
                "count today's first tests",
                "SELECT COUNT(*), COALESCE(SUM(CASE WHEN t.bad = 0 THEN 1 ELSE 0 END), 0)
                 FROM (SELECT res.run_id, res.serial,
                         SUM(CASE WHEN res.outcome = 'pass' THEN 0 ELSE 1 END) AS bad
                       FROM results res JOIN runs ru ON ru.id = res.run_id
                       WHERE ru.station = $1 AND ru.started_at >= $2 AND ru.retest_of IS NULL
                       GROUP BY res.run_id, res.serial) t",
                &[name.as_str().into(), midnight.into()],
            )?;
            let (tested_today, passed_today) =
                yield_rows.first().map_or((0, 0), |y| (y.int(0), y.int(1)));
            out.push(StationRow {
                beat: Heartbeat {
                    station: name,
                    state,
                    run_id: r.opt_text(4),
                    progress,
                    address: r.opt_text(7),
                },
                first_seen: r.int(1),
                last_seen,
                tested_today,
                passed_today,
            });
        }
        Ok(out)
    }

    /// Mark a station offline at once (its server is stopping).
    pub fn station_offline(&self, station: &str) -> Result<(), StoreError> {
        self.db()
            .execute(
                "UPDATE stations SET state = NULL WHERE name = $1",
                &[station.into()],
            )
            .map(|_| ())
            .map_err(self.err(&format!("mark station '{station}' offline")))
    }
}
