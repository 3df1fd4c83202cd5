//! The fleet: every station that writes into this store, with a
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
    /// The station's name (its config's `station`).
    pub station: String,
    /// Its identity: made at its first start and kept in its data
    /// directory, apart from the name (two installs left with one name are
    /// two identities). Empty for a station seen only through its runs.
    pub instance: String,
    /// `idle`, `running`, `waiting` (for the operator) or `faulted`.
    pub state: String,
    /// Its current (or last) run.
    pub run_id: Option<String>,
    /// Steps done and of, of the current run.
    pub progress: Option<(i64, i64)>,
    /// Where its web UI answers (for a link), if it serves one.
    pub address: Option<String>,
}

/// Who holds a station's name in the fleet.
#[derive(Debug, Clone, PartialEq)]
pub struct Holder {
    /// Its identity ('' for a station seen only through its runs).
    pub instance: String,
    /// Where its web UI answered.
    pub address: Option<String>,
    /// When it was last heard [Unix s].
    pub last_seen: i64,
}

/// The answer to a station's claim of its name at start.
#[derive(Debug, Clone, PartialEq)]
pub enum Claim {
    /// The name is this station's; `previous` is another identity that
    /// held it before (offline now), if one did.
    Taken {
        /// The identity that held the name before, if another.
        previous: Option<Holder>,
    },
    /// Another identity holds the name and is live: this station must not
    /// start under it.
    HeldBy(Holder),
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
    /// `server` (a `spinbench serve`, with a heartbeat) or `command line`
    /// (seen only through the runs of `spinbench run`).
    pub kind: String,
    /// Instruments graded today (UTC) in first tests (not retests), each
    /// serial of a run once.
    pub tested_today: i64,
    /// Of them, passed in every mounting.
    pub passed_today: i64,
    /// Its latest run's instruments by outcome (`pass`, `fail`, …, each
    /// with how many), in the outcomes' order.
    pub last_run_outcomes: Vec<(String, i64)>,
}

impl Store {
    /// Take `name` for the station `instance` at its start (and record
    /// its first heartbeat). Refused while another identity holds the name,
    /// live or not, until an admin retires it ([`Store::retire_station`],
    /// audited): a name is one station's, with its runs, its register and
    /// its yield. (A copied `DATA/station-id`, one identity in two places,
    /// is refused where it is read: `station_identity`.) A retired name
    /// taken by another identity says by whom it was held, so the start can
    /// warn.
    pub fn claim_station(&self, beat: &Heartbeat) -> Result<Claim, StoreError> {
        let before = self.station_holder(&beat.station)?;
        if self.write_beat(beat)? {
            let previous = before.filter(|h| !h.instance.is_empty() && h.instance != beat.instance);
            if let Some(p) = &previous {
                self.set_aside_register(&beat.station, &p.instance)?;
            }
            return Ok(Claim::Taken { previous });
        }
        // Refused by the store: someone live holds it.
        let holder = self.station_holder(&beat.station)?.unwrap_or(Holder {
            instance: String::new(),
            address: None,
            last_seen: now_s(),
        });
        Ok(Claim::HeldBy(holder))
    }

    /// Whether the station `instance` may use the name `station` for a run
    /// of its own (`spinbench run`, which has no heartbeat): the holder that
    /// keeps it from doing so (another identity, not retired), if any.
    pub fn name_held_by_another(
        &self,
        station: &str,
        instance: &str,
    ) -> Result<Option<Holder>, StoreError> {
        Ok(self
            .query(
                "read the fleet's station",
                "SELECT instance_id, address, last_seen FROM stations
                 WHERE name = $1 AND retired_at IS NULL AND instance_id IS NOT NULL
                   AND instance_id <> '' AND instance_id <> $2",
                &[station.into(), instance.into()],
            )?
            .first()
            .map(|r| Holder {
                instance: r.opt_text(0).unwrap_or_default(),
                address: r.opt_text(1),
                last_seen: r.int(2),
            }))
    }

    /// Let `instance` (a `spinbench run`, which claims no name with a
    /// heartbeat) take over the name `station` that a retired station of
    /// another identity held: that station's register is set aside
    /// ([`Store::set_aside_register`]) and the name recorded as this
    /// identity's. Whether a register was set aside.
    pub fn take_over_retired_name(
        &self,
        station: &str,
        instance: &str,
    ) -> Result<bool, StoreError> {
        let retired_other = self
            .query(
                "read the fleet's station",
                "SELECT instance_id FROM stations
                 WHERE name = $1 AND retired_at IS NOT NULL AND instance_id IS NOT NULL
                   AND instance_id <> '' AND instance_id <> $2",
                &[station.into(), instance.into()],
            )?
            .first()
            .and_then(|r| r.opt_text(0));
        let Some(previous) = retired_other else {
            return Ok(false);
        };
        self.set_aside_register(station, &previous)?;
        self.db()
            .execute(
                "UPDATE stations SET instance_id = $2 WHERE name = $1",
                &[station.into(), instance.into()],
            )
            .map_err(self.err(&format!("record station '{station}' as this one's")))?;
        Ok(true)
    }

    /// The register follows the identity, not the text of a name: when
    /// another identity takes over the name `station` (its holder
    /// `previous` retired by an admin), the entries of `previous` are kept
    /// under `NAME (retired, identity ID)`, listed with every station's,
    /// and the new holder starts with a register of its own. Audited.
    fn set_aside_register(&self, station: &str, previous: &str) -> Result<(), StoreError> {
        let short: String = previous.chars().take(12).collect();
        let aside = format!("{station} (retired, identity {short})");
        self.db()
            .transaction(|db| {
                let moved = db.execute(
                    "UPDATE equipment SET station = $2 WHERE station = $1
                       AND NOT EXISTS (SELECT 1 FROM equipment WHERE station = $2)",
                    &[station.into(), aside.as_str().into()],
                )?;
                if moved > 0 {
                    crate::users::insert_audit(
                        db,
                        "spinbench",
                        "set aside register",
                        &format!("'{station}' taken over by another identity: its {moved} entries kept as '{aside}'"),
                    )?;
                }
                Ok(())
            })
            .map_err(self.err(&format!("set aside the register of station '{station}'")))
    }

    /// Another station's name of the fleet that looks like `station` but is
    /// not it (`Line 1` beside `line 1`, a Cyrillic `А` for a Latin `A`):
    /// two such names would read as one station on every page.
    pub fn look_alike_station(&self, station: &str) -> Result<Option<String>, StoreError> {
        use spinbench_engine::bounds::look_alike;
        let folded = |s: &str| s.trim().to_lowercase();
        Ok(self
            .query("list the stations' names", "SELECT name FROM stations", &[])?
            .iter()
            .map(|r| r.text(0))
            .find(|other| {
                other != station
                    && (folded(other) == folded(station)
                        || look_alike(other, station)
                        || look_alike(&folded(other), &folded(station)))
            }))
    }

    /// Who holds the name `station` in the fleet, if anyone has.
    pub fn station_holder(&self, station: &str) -> Result<Option<Holder>, StoreError> {
        Ok(self
            .query(
                "read the fleet's station",
                "SELECT instance_id, address, last_seen FROM stations WHERE name = $1",
                &[station.into()],
            )?
            .first()
            .map(|r| Holder {
                instance: r.opt_text(0).unwrap_or_default(),
                address: r.opt_text(1),
                last_seen: r.int(2),
            }))
    }

    /// Record a station's heartbeat (and the station, if new). A beat of
    /// an identity that does not hold the name changes nothing and is an
    /// error: the fleet row of one station never flips to another's.
    pub fn heartbeat(&self, beat: &Heartbeat) -> Result<(), StoreError> {
        if self.write_beat(beat)? {
            return Ok(());
        }
        Err(StoreError::message(
            self.target(),
            &format!("record the heartbeat of station '{}'", beat.station),
            format!(
                "another live station holds the name '{}'; give this one its own name (`station` in its station.toml, or serve --name)",
                beat.station
            ),
        ))
    }

    /// Write a beat unless another identity live holds the name; whether
    /// it was written.
    fn write_beat(&self, beat: &Heartbeat) -> Result<bool, StoreError> {
        let now = now_s();
        let (done, of) = beat
            .progress
            .map_or((None, None), |(d, o)| (Some(d), Some(o)));
        self.db()
            .execute(
                "INSERT INTO stations (name, first_seen, last_seen, state, run_id, steps_done, steps_total, address,
                   instance_id, kind)
                 VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, 'server')
                 ON CONFLICT (name) DO UPDATE SET last_seen = excluded.last_seen, state = excluded.state,
                   run_id = excluded.run_id, steps_done = excluded.steps_done,
                   steps_total = excluded.steps_total, address = excluded.address,
                   instance_id = excluded.instance_id, kind = 'server', retired_at = NULL
                 WHERE stations.instance_id IS NULL OR stations.retired_at IS NOT NULL
                   OR stations.instance_id = excluded.instance_id",
                &[
                    beat.station.as_str().into(),
                    now.into(),
                    now.into(),
                    beat.state.as_str().into(),
                    beat.run_id.clone().into(),
                    Value::Int(done),
                    Value::Int(of),
                    beat.address.clone().into(),
                    beat.instance.as_str().into(),
                ],
            )
            .map(|n| n > 0)
            .map_err(self.err(&format!("record the heartbeat of station '{}'", beat.station)))
    }

    /// Take a station out of the Fleet list (an admin; audited by the
    /// caller): refused while it is live. It comes back when it runs again.
    pub fn retire_station(&self, station: &str, who: &str) -> Result<bool, StoreError> {
        let now = now_s();
        self.db()
            .transaction(|db| {
                let n = db.execute(
                    "UPDATE stations SET retired_at = $2, state = NULL, run_id = NULL, steps_done = NULL, steps_total = NULL
                     WHERE name = $1 AND retired_at IS NULL AND (state IS NULL OR last_seen < $3)",
                    &[station.into(), now.into(), (now - OFFLINE_AFTER_S).into()],
                )?;
                if n > 0 {
                    crate::users::insert_audit(db, who, "retire station", station)?;
                }
                Ok(n > 0)
            })
            .map_err(self.err(&format!("retire station '{station}'")))
    }

    /// Every station, by name, with its state now (offline when its last
    /// heartbeat is older than [`OFFLINE_AFTER_S`], or it never beat) and
    /// today's first-pass yield.
    pub fn stations(&self) -> Result<Vec<StationRow>, StoreError> {
        let now = now_s();
        let midnight = now - now.rem_euclid(86_400);
        let rows = self.query(
            "list the stations",
            "SELECT name, first_seen, last_seen, state, run_id, steps_done, steps_total, address,
               instance_id, kind
             FROM stations WHERE retired_at IS NULL ORDER BY name",
            &[],
        )?;
        let mut out = Vec::with_capacity(rows.len());
        for r in rows {
            let name = r.text(0);
            let last_seen = r.int(2);
            let beat_state = r.opt_text(3);
            let live = beat_state.is_some() && now - last_seen <= OFFLINE_AFTER_S;
            let state = match beat_state {
                Some(s) if live => s,
                _ => "offline".to_string(),
            };
            // An offline station's last run and progress are not what it
            // does now: not shown.
            let progress = match (r.0.get(5), r.0.get(6)) {
                (Some(Value::Int(Some(d))), Some(Value::Int(Some(o)))) if live => Some((*d, *o)),
                _ => None,
            };
            let yield_rows = self.query(
                "count today's first tests",
                "SELECT COUNT(*), COALESCE(SUM(CASE WHEN t.bad = 0 THEN 1 ELSE 0 END), 0)
                 FROM (SELECT res.run_id, res.serial,
                         SUM(CASE WHEN res.outcome IN ('pass', 'marginal') THEN 0 ELSE 1 END) AS bad
                       FROM results res JOIN runs ru ON ru.id = res.run_id
                       WHERE ru.station = $1 AND ru.started_at >= $2 AND ru.retest_of IS NULL
                       GROUP BY res.run_id, res.serial) t",
                &[name.as_str().into(), midnight.into()],
            )?;
            let (tested_today, passed_today) =
                yield_rows.first().map_or((0, 0), |y| (y.int(0), y.int(1)));
            let counted = self.query(
                "count the latest run's outcomes",
                "SELECT outcome, COUNT(*) FROM results WHERE run_id =
                   (SELECT id FROM runs WHERE station = $1 ORDER BY started_at DESC, id DESC LIMIT 1)
                 GROUP BY outcome",
                &[name.as_str().into()],
            )?;
            let mut last_run_outcomes: Vec<(String, i64)> =
                counted.iter().map(|r| (r.text(0), r.int(1))).collect();
            let order = ["pass", "marginal", "fail", "inconclusive", "incomplete"];
            last_run_outcomes
                .sort_by_key(|(o, _)| order.iter().position(|k| k == o).unwrap_or(order.len()));
            out.push(StationRow {
                beat: Heartbeat {
                    station: name,
                    instance: r.opt_text(8).unwrap_or_default(),
                    state,
                    run_id: r.opt_text(4).filter(|_| live),
                    progress,
                    address: r.opt_text(7),
                },
                first_seen: r.int(1),
                last_seen,
                kind: r.opt_text(9).unwrap_or_else(|| "server".into()),
                tested_today,
                passed_today,
                last_run_outcomes,
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
