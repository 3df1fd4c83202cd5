//! Reading the store back: runs, results (typed records), points,
//! one-second values, radii.

use super::{Outcome, Store, StoreError, StoredState, UnitRecord, Value, now_s};
use crate::record::{parse_column, slot_index, stored_direction, stored_mount};
use spinbench_analysis::{Direction, Mount};

/// One run in a listing.
#[derive(Debug, Clone, PartialEq)]
pub struct RunRow {
    /// Run identifier.
    pub id: String,
    /// Station name.
    pub station: String,
    /// Final (or current) state.
    pub state: StoredState,
    /// Why it ended, if not completed.
    pub reason: Option<String>,
    /// Unix time it started.
    pub started_at: i64,
    /// Instruments with results.
    pub units: i64,
    /// Points stored.
    pub points: i64,
    /// The run this one retests, if it is a retest.
    pub retest_of: Option<String>,
    /// `reason` as a key and values, when the fault that ended it had one.
    pub reason_wording: Option<spinbench_engine::event::Wording>,
    /// Its number among its station's runs of its day (the label's `#7`).
    pub seq: Option<i64>,
    /// The station's offset from UTC when the run started [s]: its label's
    /// day is the station's (0 for a run stored before it was kept).
    pub utc_offset_s: i64,
}

/// One instrument's result in one run.
#[derive(Debug, Clone, PartialEq)]
pub struct ResultRow {
    /// Run identifier.
    pub run_id: String,
    /// Slot (0-based).
    pub slot: i64,
    /// Serial number.
    pub serial: String,
    /// Pass, marginal, fail or incomplete.
    pub outcome: Outcome,
    /// k2_max [µg/g²].
    pub k2_max_ug_per_g2: Option<f64>,
    /// The whole record, read back as the type the engine wrote (a
    /// stand-in with no figures when it cannot be read: `unreadable`).
    pub record: UnitRecord,
    /// Why the stored record cannot be read by this release, when it
    /// cannot: that instrument is shown as unreadable, the run's other
    /// instruments as they are.
    pub unreadable: Option<String>,
    /// How many times engineers changed it after the run (0 as the run
    /// wrote it): a change names the revision it was made from, so two
    /// changes made at once from one revision cannot both land.
    pub revision: i64,
}

/// One stored point (a row of the `points` table).
#[derive(Debug, Clone, PartialEq)]
pub struct PointRow {
    /// Step of the plan.
    pub step: i64,
    /// Slot (0-based).
    pub slot: i64,
    /// Serial number.
    pub serial: String,
    /// P or N.
    pub mount: Mount,
    /// Nominal level [g].
    pub g_nominal: f64,
    /// Up or down.
    pub direction: Direction,
    /// Applied acceleration, method.md (9) [g].
    pub g_applied: f64,
    /// Mean measured rate [deg/s].
    pub rate_deg_s: f64,
    /// Mean output dF [Hz].
    pub output_hz: f64,
    /// Standard deviation of the one-second values [Hz].
    pub std_hz: f64,
    /// Number of one-second values.
    pub n: i64,
    /// Times of the first and last one-second value averaged [s of the run].
    pub time_s: [f64; 2],
    /// The instrument's mean temperature over the point [°C].
    pub temperature_c: Option<f64>,
    /// Its change over the point, highest minus lowest [°C].
    pub temperature_change_c: Option<f64>,
}

/// One stored one-second value.
#[derive(Debug, Clone, PartialEq)]
pub struct ValueRow {
    /// Window time [s].
    pub t_s: f64,
    /// Slot (0-based).
    pub slot: i64,
    /// Output dF [Hz], none when the window was missing or incomplete.
    pub output_hz: Option<f64>,
    /// Measured rate [deg/s].
    pub rate_deg_s: f64,
    /// Whether the table was on speed.
    pub on_speed: bool,
    /// The instrument's temperature [°C], when its module reported one.
    pub temperature_c: Option<f64>,
}

/// One instrument's radius in one mounting (method.md (6)–(8)).
#[derive(Debug, Clone, PartialEq)]
pub struct UnitRow {
    /// Slot (0-based).
    pub slot: i64,
    /// P or N.
    pub mount: Mount,
    /// Serial number.
    pub serial: String,
    /// The fixture's drawing radius R0 [m].
    pub drawing_radius_m: f64,
    /// The radius found [m].
    pub radius_m: f64,
}

/// The most runs one page of the run list holds.
pub const MAX_RUNS_PAGE: usize = 1000;

impl Store {
    /// Every run, newest first.
    pub fn runs(&self) -> Result<Vec<RunRow>, StoreError> {
        self.runs_where("TRUE", &[])
    }

    /// One page of the runs, newest first (its size at most
    /// [`MAX_RUNS_PAGE`]): at most `limit` of them, only
    /// station `station`'s when given, those after `after` (the last run
    /// of the previous page: its start [Unix s] and id); the filter and the
    /// page are the database's (an index on the start), so a page costs
    /// the same however many runs the store holds. The second value says
    /// whether more runs follow.
    pub fn runs_page(
        &self,
        station: Option<&str>,
        after: Option<(i64, &str)>,
        limit: usize,
    ) -> Result<(Vec<RunRow>, bool), StoreError> {
        let mut clause = vec!["TRUE".to_string()];
        let mut params: Vec<Value> = Vec::new();
        if let Some(s) = station {
            params.push(s.into());
            clause.push(format!("r.station = ${}", params.len()));
        }
        if let Some((t, id)) = after {
            params.push(t.into());
            let at = params.len();
            params.push(id.into());
            let by = params.len();
            clause.push(format!(
                "(r.started_at < ${at} OR (r.started_at = ${at} AND r.id < ${by}))"
            ));
        }
        let limit = limit.clamp(1, MAX_RUNS_PAGE);
        let mut rows = self.runs_listed(
            &clause.join(" AND "),
            &format!(" LIMIT {}", limit + 1),
            &params,
        )?;
        let more = rows.len() > limit;
        rows.truncate(limit);
        Ok((rows, more))
    }

    pub(crate) fn runs_where(
        &self,
        clause: &str,
        params: &[Value],
    ) -> Result<Vec<RunRow>, StoreError> {
        self.runs_listed(clause, "", params)
    }

    /// The runs `clause` selects, newest first, then `tail` (a LIMIT).
    fn runs_listed(
        &self,
        clause: &str,
        tail: &str,
        params: &[Value],
    ) -> Result<Vec<RunRow>, StoreError> {
        let rows = self.query(
            "list runs",
            &format!(
                "SELECT r.id, r.station, r.state, r.reason, r.started_at,
                        (SELECT COUNT(*) FROM results s WHERE s.run_id = r.id),
                        (SELECT COUNT(*) FROM points p WHERE p.run_id = r.id),
                        r.retest_of, r.reason_wording, r.seq, r.utc_offset_s
                 FROM runs r WHERE {clause} ORDER BY r.started_at DESC, r.id DESC{tail}"
            ),
            params,
        )?;
        rows.iter()
            .map(|r| {
                Ok(RunRow {
                    id: r.text(0),
                    station: r.text(1),
                    state: parse_column(&r.text(2), "run state").map_err(self.err("list runs"))?,
                    reason: r.opt_text(3),
                    started_at: r.int(4),
                    units: r.int(5),
                    points: r.int(6),
                    retest_of: r.opt_text(7),
                    reason_wording: r
                        .opt_text(8)
                        .and_then(|json| serde_json::from_str(&json).ok()),
                    seq: r.opt_int(9),
                    utc_offset_s: r.int(10),
                })
            })
            .collect()
    }

    /// The runs that retest `id`, oldest first.
    pub fn retests_of(&self, id: &str) -> Result<Vec<String>, StoreError> {
        let rows = self.query(
            "list retests",
            "SELECT id FROM runs WHERE retest_of = $1 ORDER BY started_at, id",
            &[id.into()],
        )?;
        Ok(rows.iter().map(|r| r.text(0)).collect())
    }

    /// One run, if it exists.
    pub fn run(&self, id: &str) -> Result<Option<RunRow>, StoreError> {
        Ok(self
            .runs_where("r.id = $1", &[id.into()])?
            .into_iter()
            .next())
    }

    pub(crate) fn results_where(
        &self,
        clause: &str,
        arg: &str,
    ) -> Result<Vec<ResultRow>, StoreError> {
        let rows = self.query(
            "query results",
            &format!(
                "SELECT s.run_id, s.slot, s.serial, s.outcome, s.k2_max_ug_per_g2, s.record_json, s.revision
                 FROM results s JOIN runs r ON r.id = s.run_id WHERE {clause}
                 ORDER BY r.started_at, s.run_id, s.slot"
            ),
            &[arg.into()],
        )?;
        rows.iter()
            .map(|r| {
                let (run_id, serial) = (r.text(0), r.text(2));
                let unreadable = |problem: String| StoreError {
                    target: self.target.to_string(),
                    what: format!("read the result of '{serial}' in run {run_id}"),
                    reason: problem.into(),
                };
                let outcome_name = r.text(3);
                let outcome = Outcome::parse(&outcome_name)
                    .ok_or_else(|| unreadable(format!("'{outcome_name}' is not an outcome")))?;
                let slot = slot_index(r.int(1));
                let (record, why) = match serde_json::from_str::<UnitRecord>(&r.text(5)) {
                    Ok(record) => (record, None),
                    Err(e) => {
                        let why = format!("the stored record: {e}");
                        let stand_in = UnitRecord::unreadable(
                            usize::try_from(slot).unwrap_or(0),
                            &serial,
                            outcome,
                            r.opt_real(4),
                            &why,
                        );
                        (stand_in, Some(why))
                    }
                };
                Ok(ResultRow {
                    run_id,
                    slot,
                    serial,
                    outcome,
                    k2_max_ug_per_g2: r.opt_real(4),
                    record,
                    unreadable: why,
                    revision: r.int(6),
                })
            })
            .collect()
    }

    /// The per-instrument results of one run.
    pub fn results(&self, run_id: &str) -> Result<Vec<ResultRow>, StoreError> {
        self.results_where("s.run_id = $1", run_id)
    }

    /// The newest `runs` runs of `station` (at most [`MAX_RUNS_PAGE`]) and
    /// every result of them, both oldest first: two statements, whatever
    /// the window and however many runs the store holds (the control
    /// charts' read).
    pub fn newest_runs_with_results(
        &self,
        station: &str,
        runs: usize,
    ) -> Result<(Vec<RunRow>, Vec<ResultRow>), StoreError> {
        let runs = runs.clamp(1, MAX_RUNS_PAGE);
        let (mut listed, _) = self.runs_page(Some(station), None, runs)?;
        listed.reverse();
        let results = self.results_where(
            &format!(
                "s.run_id IN (SELECT n.id FROM runs n WHERE n.station = $1
                              ORDER BY n.started_at DESC, n.id DESC LIMIT {runs})"
            ),
            station,
        )?;
        Ok((listed, results))
    }

    /// A serial of an earlier run that looks like `serial` but is not it
    /// (a Cyrillic `А` for a Latin `A`, a case typed differently): a run
    /// under such a serial would split one instrument's history in two.
    pub fn look_alike_serial(&self, serial: &str) -> Result<Option<String>, StoreError> {
        use spinbench_engine::bounds::look_alike;
        let folded = |s: &str| s.trim().to_lowercase();
        Ok(self
            .query(
                "list the instruments' serials",
                "SELECT DISTINCT serial FROM units",
                &[],
            )?
            .iter()
            .map(|r| r.text(0))
            .find(|other| {
                other != serial && (look_alike(other, serial) || folded(other) == folded(serial))
            }))
    }

    /// Every result of one serial number, oldest run first.
    pub fn unit_history(&self, serial: &str) -> Result<Vec<ResultRow>, StoreError> {
        self.results_where("s.serial = $1", serial)
    }

    /// The points of a run, in the order taken.
    pub fn points(&self, run_id: &str) -> Result<Vec<PointRow>, StoreError> {
        let rows = self.query(
            "read points",
            "SELECT step, slot, serial, mount, g_nominal, direction, g_applied, rate_deg_s,
                    output_hz, std_hz, n, t0_s, t1_s, temperature_c, temperature_change_c
             FROM points WHERE run_id = $1 ORDER BY step, slot",
            &[run_id.into()],
        )?;
        let bad = self.err("read points");
        rows.iter()
            .map(|r| {
                Ok(PointRow {
                    step: r.int(0),
                    slot: slot_index(r.int(1)),
                    serial: r.text(2),
                    mount: stored_mount(&r.text(3)).map_err(&bad)?,
                    g_nominal: r.real(4),
                    direction: stored_direction(&r.text(5)).map_err(&bad)?,
                    g_applied: r.real(6),
                    rate_deg_s: r.real(7),
                    output_hz: r.real(8),
                    std_hz: r.real(9),
                    n: r.int(10),
                    time_s: [r.real(11), r.real(12)],
                    temperature_c: r.opt_real(13),
                    temperature_change_c: r.opt_real(14),
                })
            })
            .collect()
    }

    /// The one-second values of a run, by time and slot.
    pub fn values(&self, run_id: &str) -> Result<Vec<ValueRow>, StoreError> {
        let rows = self.query(
            "read one-second values",
            "SELECT t_s, slot, output_hz, rate_deg_s, temperature_c, on_speed FROM values_1s WHERE run_id = $1 ORDER BY t_s, slot",
            &[run_id.into()],
        )?;
        Ok(rows
            .iter()
            .map(|r| ValueRow {
                t_s: r.real(0),
                slot: slot_index(r.int(1)),
                output_hz: r.opt_real(2),
                rate_deg_s: r.real(3),
                on_speed: r.int(5) != 0,
                temperature_c: r.opt_real(4),
            })
            .collect())
    }

    /// Station time of the last one-second value stored for a run [s].
    pub fn last_value_time_s(&self, run_id: &str) -> Result<Option<f64>, StoreError> {
        Ok(self
            .query(
                "read the last one-second value's time",
                "SELECT t_s FROM values_1s WHERE run_id = $1 ORDER BY t_s DESC LIMIT 1",
                &[run_id.into()],
            )?
            .first()
            .map(|r| r.real(0)))
    }

    /// Number of one-second values stored for a run.
    pub fn value_count(&self, run_id: &str) -> Result<i64, StoreError> {
        Ok(self
            .query(
                "count one-second values",
                "SELECT COUNT(*) FROM values_1s WHERE run_id = $1",
                &[run_id.into()],
            )?
            .first()
            .map_or(0, |r| r.int(0)))
    }

    /// The (step, slot) keys of a run's stored points.
    pub fn point_keys(&self, run_id: &str) -> Result<Vec<(i64, i64)>, StoreError> {
        Ok(self
            .points(run_id)?
            .iter()
            .map(|p| (p.step, p.slot))
            .collect())
    }

    /// The radius found for each (slot, mount) of a run.
    pub fn unit_radii(&self, run_id: &str) -> Result<Vec<UnitRow>, StoreError> {
        let rows = self.query(
            "read units",
            "SELECT slot, mount, serial, drawing_radius_m, radius_m FROM units WHERE run_id = $1 ORDER BY slot, mount",
            &[run_id.into()],
        )?;
        let bad = self.err("read units");
        rows.iter()
            .map(|r| {
                Ok(UnitRow {
                    slot: slot_index(r.int(0)),
                    mount: stored_mount(&r.text(1)).map_err(&bad)?,
                    serial: r.text(2),
                    drawing_radius_m: r.real(3),
                    radius_m: r.real(4),
                })
            })
            .collect()
    }
}

impl Store {
    /// Mark run `id` interrupted (its process ended without finishing it: a
    /// crash, a power cut) when the store still has it `running`, with
    /// `reason`. True when it was marked.
    pub fn mark_interrupted(&self, id: &str, reason: &str) -> Result<bool, StoreError> {
        let changed = self
            .db()
            .execute(
                "UPDATE runs SET state = 'interrupted', reason = $2, finished_at = $3
                 WHERE id = $1 AND state = 'running'",
                &[id.into(), reason.into(), now_s().into()],
            )
            .map_err(self.err("mark a run interrupted"))?;
        Ok(changed > 0)
    }
}

impl Store {
    /// The runs of `station` the store has as `running` now (a process runs
    /// them, or one ended without finishing them).
    pub fn running_runs(&self, station: &str) -> Result<Vec<RunRow>, StoreError> {
        self.runs_where("r.state = 'running' AND r.station = $1", &[station.into()])
    }
}

impl Store {
    /// The devices `station` identified in its newest run that got as far
    /// (each with the identity its `*IDN?` or firmware answer gave): what
    /// the Equipment page offers an engineer to register. Empty before any.
    pub fn last_identified_devices(
        &self,
        station: &str,
    ) -> Result<Vec<crate::record::DeviceEntry>, StoreError> {
        let rows = self.query(
            "read the station's last device list",
            "SELECT devices_json FROM runs WHERE station = $1 AND devices_json IS NOT NULL
             ORDER BY started_at DESC, id DESC LIMIT 1",
            &[station.into()],
        )?;
        match rows.first().and_then(|r| r.opt_text(0)) {
            Some(json) => crate::record::stored_devices(&json)
                .map_err(self.err("read the station's last device list")),
            None => Ok(Vec::new()),
        }
    }
}

impl RunRow {
    /// Whether the run has ended ([`StoredState::is_ended`]).
    pub fn is_ended(&self) -> bool {
        self.state.is_ended()
    }
}
