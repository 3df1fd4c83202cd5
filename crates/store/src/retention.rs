//! Retention: the bulk of an old run's rows — its one-second values (about
//! 86,000 rows per two-hour run) and its event log — read out for an
//! archive and then deleted, in one transaction per run. The run's record
//! (its plan, devices, radii, points, results, operator actions and end)
//! stays in the store. `spinbench prune` writes the archive (Parquet) and
//! deletes only what it wrote and read back.

use super::{Db, DbError, RunRow, Store, StoreError, StoredState};

/// One stored event.
#[derive(Debug, Clone, PartialEq)]
pub struct EventRow {
    /// Its order in the store.
    pub seq: i64,
    /// When it was written [Unix s].
    pub at: i64,
    /// Its kind (`run_started`, `point_done`, …).
    pub kind: String,
    /// The event (JSON).
    pub json: String,
}

/// A run whose values and events may be pruned, with how many there are.
#[derive(Debug, Clone, PartialEq)]
pub struct PrunableRun {
    /// The run.
    pub run: RunRow,
    /// Its one-second value rows.
    pub values: i64,
    /// Its event rows.
    pub events: i64,
}

impl Store {
    /// The runs that ended and started before `before` [Unix s] and still
    /// have one-second values or events, oldest first. A run still
    /// `running` is never among them.
    pub fn prunable_runs(&self, before: i64) -> Result<Vec<PrunableRun>, StoreError> {
        let runs = self.runs_where("r.started_at < $1", &[before.into()])?;
        let mut out = Vec::new();
        for run in runs.into_iter().rev().filter(RunRow::is_ended) {
            let values = self.value_count(&run.id)?;
            let events = self.event_count(&run.id)?;
            if values > 0 || events > 0 {
                out.push(PrunableRun {
                    run,
                    values,
                    events,
                });
            }
        }
        Ok(out)
    }

    /// Number of events stored for a run.
    pub fn event_count(&self, run_id: &str) -> Result<i64, StoreError> {
        Ok(self
            .query(
                "count events",
                "SELECT COUNT(*) FROM events WHERE run_id = $1",
                &[run_id.into()],
            )?
            .first()
            .map_or(0, |r| r.int(0)))
    }

    /// A run's events, in the order written.
    pub fn events(&self, run_id: &str) -> Result<Vec<EventRow>, StoreError> {
        Ok(self
            .query(
                "read events",
                "SELECT seq, at, kind, json FROM events WHERE run_id = $1 ORDER BY seq",
                &[run_id.into()],
            )?
            .iter()
            .map(|r| EventRow {
                seq: r.int(0),
                at: r.int(1),
                kind: r.text(2),
                json: r.text(3),
            })
            .collect())
    }

    /// Delete run `run_id`'s one-second values and events, in one
    /// transaction, when they are still exactly `values` and `events` rows
    /// (what was archived); otherwise nothing is deleted and the error says
    /// so. The run itself must have ended. Returns the rows deleted.
    pub fn delete_values_and_events(
        &self,
        run_id: &str,
        values: i64,
        events: i64,
    ) -> Result<(u64, u64), StoreError> {
        let what = format!("prune run {run_id}");
        let mut db = self.db();
        db.transaction(|db| {
            let state = db
                .query_one("SELECT state FROM runs WHERE id = $1", &[run_id.into()])?
                .map(|r| r.text(0))
                .ok_or_else(|| -> DbError { "no such run".into() })?;
            if !crate::record::parse_column::<StoredState>(&state, "run state")?.is_ended() {
                return Err(format!("it is {state}: only an ended run is pruned").into());
            }
            let count = |db: &mut Db, table: &str| -> Result<i64, DbError> {
                Ok(db
                    .query_one(
                        &format!("SELECT COUNT(*) FROM {table} WHERE run_id = $1"),
                        &[run_id.into()],
                    )?
                    .map_or(0, |r| r.int(0)))
            };
            let (now_values, now_events) = (count(db, "values_1s")?, count(db, "events")?);
            if (now_values, now_events) != (values, events) {
                return Err(format!(
                    "it has {now_values} values and {now_events} events now, not the {values} and {events} archived: nothing deleted; prune again"
                )
                .into());
            }
            let deleted_values =
                db.execute("DELETE FROM values_1s WHERE run_id = $1", &[run_id.into()])?;
            let deleted_events =
                db.execute("DELETE FROM events WHERE run_id = $1", &[run_id.into()])?;
            Ok((deleted_values, deleted_events))
        })
        .map_err(|reason| StoreError {
            target: self.target.to_string(),
            what,
            reason,
        })
    }
}
