//! The store as a subscriber of the engine's events: every event written
//! as it happens; a failed write is an error the engine answers by holding
//! the run (nothing is dropped).

use super::{DbError, Event, EventSink, Store, StoreError, now_s};
use crate::record::{DeviceEntry, NoticeKind, StoredState, result_row_values, stored_slot};
use spinbench_engine::event::Wording;

/// Writes a run's events as they happen. A failed write is an error the
/// engine answers by holding the run and offering the same event again
/// every second (nothing is dropped); only after its hold limit does the
/// run fault into the safe state.
pub struct StoreSink {
    pub(crate) store: Store,
    serials: Vec<Option<String>>,
    run_id: String,
    /// The run's station (its devices' register entries are its own).
    station: String,
    /// The last prompt, recorded with the operator's answer.
    prompt: String,
    /// Its fixtures' codes per slot, comma-separated (an empty code: the
    /// slot is left alone), for the answer's wording.
    prompt_fixtures: String,
}

impl StoreSink {
    /// Take the run's identity from its start (`RunStarted`) without
    /// writing it: for events of a run already started, written later.
    pub(crate) fn prime(&mut self, started: &Event) {
        if let Event::RunStarted {
            run_id,
            plan,
            station,
            ..
        } = started
        {
            self.run_id = run_id.clone();
            self.station = station.clone();
            self.serials = plan.serials.clone();
        }
    }

    pub(crate) fn write(&mut self, event: &Event) -> Result<(), DbError> {
        let mut db = self.store.db();
        let run_id = self.run_id.clone();
        match event {
            Event::Progress { .. } => return Ok(()),
            Event::Values {
                time_s,
                rate_deg_s,
                on_speed,
                outputs_hz,
                temperatures_c,
                ..
            } => {
                let serials = &self.serials;
                return db.transaction(|db| {
                    for (slot, v) in outputs_hz.iter().enumerate() {
                        if serials.get(slot).is_some_and(Option::is_some) {
                            db.execute(
                                "INSERT INTO values_1s (run_id, t_s, slot, output_hz, rate_deg_s, on_speed, temperature_c)
                                 VALUES ($1, $2, $3, $4, $5, $6, $7)
                                 ON CONFLICT (run_id, t_s, slot) DO UPDATE SET output_hz = excluded.output_hz,
                                   rate_deg_s = excluded.rate_deg_s, on_speed = excluded.on_speed,
                                   temperature_c = excluded.temperature_c",
                                &[
                                    run_id.as_str().into(),
                                    (*time_s).into(),
                                    stored_slot(slot).into(),
                                    (*v).into(),
                                    (*rate_deg_s).into(),
                                    i64::from(*on_speed).into(),
                                    temperatures_c.get(slot).copied().flatten().into(),
                                ],
                            )?;
                        }
                    }
                    Ok(())
                });
            }
            Event::RunStarted {
                run_id,
                station,
                plan,
                resumed,
                station_config,
            } => {
                self.run_id = run_id.clone();
                self.station = station.clone();
                self.serials = plan.serials.clone();
                let plan_json = serde_json::to_string(&plan.plan).unwrap_or_default();
                let now = now_s();
                // The station's zone, for its label's day: the station read
                // its own config before it started, so a zone it names is
                // one this release reads (UTC for a config without one).
                let offset_s = spinbench_engine::time_zone::of_station_config(station_config)
                    .unwrap_or_default()
                    .seconds();
                db.transaction(|db| {
                    db.execute(
                        // A station first seen through a run (not a server's
                        // heartbeat) is a command-line station; a retired one
                        // that runs again is back in the fleet.
                        "INSERT INTO stations (name, first_seen, last_seen, kind) VALUES ($1, $2, $3, 'command line')
                         ON CONFLICT (name) DO UPDATE SET last_seen = excluded.last_seen,
                           kind = COALESCE(stations.kind, excluded.kind), retired_at = NULL",
                        &[station.into(), now.into(), now.into()],
                    )?;
                    let existing = db.query_one("SELECT id FROM runs WHERE id = $1", &[run_id.into()])?;
                    if existing.is_some() {
                        db.execute(
                            "UPDATE runs SET starts = starts + 1, state = 'running' WHERE id = $1",
                            &[run_id.into()],
                        )?;
                    } else {
                        // The label's number: one more than the station's runs
                        // of today, each run's day by its station's clock then.
                        // (The column is a timestamp on PostgreSQL: the
                        // window is computed here, wide enough for every zone.)
                        let today = crate::label::run_day(now, offset_s);
                        let (from, to) = crate::label::day_window(today);
                        let seq = 1 + db
                            .query(
                                "SELECT started_at, utc_offset_s FROM runs WHERE station = $1 AND started_at >= $2 AND started_at < $3",
                                &[station.into(), from.into(), to.into()],
                            )?
                            .iter()
                            .filter(|r| crate::label::run_day(r.int(0), r.int(1)) == today)
                            .count() as i64;
                        db.execute(
                            "INSERT INTO runs (id, station, plan_json, software_version, state, started_at, starts,
                               station_config, retest_of, seq, record_version, utc_offset_s)
                             VALUES ($1, $2, $3, $4, 'running', $5, $6, $7, $8, $9, $10, $11)",
                            &[
                                run_id.into(),
                                station.into(),
                                plan_json.into(),
                                env!("CARGO_PKG_VERSION").into(),
                                now.into(),
                                (1 + i64::from(*resumed)).into(),
                                (!station_config.is_empty()).then(|| station_config.clone()).into(),
                                plan.plan.retest_of.clone().into(),
                                seq.into(),
                                crate::record::RECORD_VERSION.into(),
                                offset_s.into(),
                            ],
                        )?;
                    }
                    Ok(())
                })?;
            }
            Event::Identified { devices } => {
                // Each device with its calibration as the register has it now
                // (the reports keep the status the run was made under).
                let today = crate::equipment::today();
                let mut listed = Vec::new();
                for d in devices {
                    let row = db.query_one(
                        "SELECT certificate, calibrated_on, due_on FROM equipment WHERE station = $1 AND role = $2",
                        &[self.station.as_str().into(), d.role.name().into()],
                    )?;
                    let mut entry = DeviceEntry {
                        role: d.role,
                        identity: d.identity.clone(),
                        calibration: Some(crate::equipment::CalibrationStatus::Unregistered),
                        certificate: None,
                        calibrated_on: None,
                        due_on: None,
                    };
                    if let Some(r) = row {
                        let due = r.text(2);
                        entry.calibration = Some(crate::equipment::status_of_due(&due, today));
                        entry.certificate = Some(r.text(0));
                        entry.calibrated_on = Some(r.text(1));
                        entry.due_on = Some(due);
                    }
                    listed.push(entry);
                }
                let listed = serde_json::to_string(&listed)
                    .map_err(|e| -> DbError { format!("the device list: {e}").into() })?;
                db.execute(
                    "UPDATE runs SET devices_json = $2 WHERE id = $1",
                    &[run_id.as_str().into(), listed.into()],
                )?;
            }
            Event::RadiusDone {
                slot,
                mount,
                drawing_radius_m,
                radius_m,
                ..
            } => {
                let serial = self
                    .serials
                    .get(*slot)
                    .cloned()
                    .flatten()
                    .unwrap_or_default();
                db.execute(
                    "INSERT INTO units (run_id, slot, mount, serial, drawing_radius_m, radius_m)
                     VALUES ($1, $2, $3, $4, $5, $6)
                     ON CONFLICT (run_id, slot, mount) DO UPDATE SET radius_m = excluded.radius_m",
                    &[
                        run_id.as_str().into(),
                        stored_slot(*slot).into(),
                        mount.to_string().into(),
                        serial.into(),
                        (*drawing_radius_m).into(),
                        (*radius_m).into(),
                    ],
                )?;
            }
            Event::Prompt { text, fixtures } => {
                self.prompt = text.clone();
                self.prompt_fixtures = fixtures
                    .iter()
                    .map(|f| f.map_or("", |f| f.code()))
                    .collect::<Vec<_>>()
                    .join(",");
            }
            Event::PromptAnswered { proceed, by } => {
                let action = format!(
                    "{} at the prompt: {}",
                    if *proceed { "went on" } else { "aborted" },
                    self.prompt
                );
                let wording = Wording::new("action.prompt")
                    .with("answer", if *proceed { "went_on" } else { "aborted" })
                    .with("fixtures", &self.prompt_fixtures);
                db.execute(
                    "INSERT INTO operator_actions (run_id, at, who, action, wording_json) VALUES ($1, $2, $3, $4, $5)",
                    &[
                        run_id.as_str().into(),
                        now_s().into(),
                        by.into(),
                        action.into(),
                        serde_json::to_string(&wording).ok().into(),
                    ],
                )?;
            }
            Event::Notice { message, wording }
            | Event::Fault {
                reason: message,
                wording,
            } if !run_id.is_empty() => {
                let kind = if matches!(event, Event::Fault { .. }) {
                    NoticeKind::Fault
                } else {
                    NoticeKind::Notice
                };
                db.execute(
                    "INSERT INTO run_notices (run_id, at, kind, message, wording_json) VALUES ($1, $2, $3, $4, $5)",
                    &[
                        run_id.as_str().into(),
                        now_s().into(),
                        kind.as_str().into(),
                        message.into(),
                        wording.as_ref().and_then(|w| serde_json::to_string(w).ok()).into(),
                    ],
                )?;
            }
            Event::PointDone { step, points } => {
                let serials = &self.serials;
                db.transaction(|db| {
                    for p in points {
                        let serial = serials.get(p.slot).cloned().flatten().unwrap_or_default();
                        // A step redone after a resume replaces its row: nothing doubled.
                        db.execute(
                            "INSERT INTO points (run_id, step, slot, serial, mount, g_nominal, direction,
                               g_applied, rate_deg_s, output_hz, std_hz, n, t0_s, t1_s,
                               temperature_c, temperature_change_c)
                             VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14, $15, $16)
                             ON CONFLICT (run_id, step, slot) DO UPDATE SET serial = excluded.serial,
                               mount = excluded.mount, g_nominal = excluded.g_nominal,
                               direction = excluded.direction, g_applied = excluded.g_applied,
                               rate_deg_s = excluded.rate_deg_s, output_hz = excluded.output_hz,
                               std_hz = excluded.std_hz, n = excluded.n, t0_s = excluded.t0_s,
                               t1_s = excluded.t1_s, temperature_c = excluded.temperature_c,
                               temperature_change_c = excluded.temperature_change_c",
                            &[
                                run_id.as_str().into(),
                                (*step as i64).into(),
                                stored_slot(p.slot).into(),
                                serial.into(),
                                p.mount.to_string().into(),
                                p.g_nominal.into(),
                                p.direction.as_str().into(),
                                p.g_applied.into(),
                                p.rate_deg_s.into(),
                                p.output_hz.into(),
                                p.std_hz.into(),
                                i64::from(p.n).into(),
                                p.time_s[0].into(),
                                p.time_s[1].into(),
                                p.temperature_c.into(),
                                p.temperature_change_c.into(),
                            ],
                        )?;
                    }
                    Ok(())
                })?;
            }
            Event::UnitResult { record } => {
                let json = serde_json::to_string(record)
                    .map_err(|e| -> DbError { format!("the unit's record: {e}").into() })?;
                db.execute(
                    "INSERT INTO results (run_id, slot, serial, outcome, k2_max_ug_per_g2, record_json,
                       k2_p_ug_per_g2, k2_p_u95, k2_n_ug_per_g2, k2_n_u95,
                       instrument_k2_ug_per_g2, instrument_k2_u95, measurand, limit_ug_per_g2)
                     VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14)
                     ON CONFLICT (run_id, slot) DO UPDATE SET serial = excluded.serial,
                       outcome = excluded.outcome, k2_max_ug_per_g2 = excluded.k2_max_ug_per_g2,
                       record_json = excluded.record_json, k2_p_ug_per_g2 = excluded.k2_p_ug_per_g2,
                       k2_p_u95 = excluded.k2_p_u95, k2_n_ug_per_g2 = excluded.k2_n_ug_per_g2,
                       k2_n_u95 = excluded.k2_n_u95,
                       instrument_k2_ug_per_g2 = excluded.instrument_k2_ug_per_g2,
                       instrument_k2_u95 = excluded.instrument_k2_u95,
                       measurand = excluded.measurand, limit_ug_per_g2 = excluded.limit_ug_per_g2",
                    &result_row_values(&run_id, record, &json),
                )?;
            }
            Event::RunFinished {
                state,
                reason,
                wording,
            } => {
                let wording = wording.as_ref().and_then(|w| serde_json::to_string(w).ok());
                db.execute(
                    "UPDATE runs SET state = $2, reason = $3, finished_at = $4, reason_wording = $5
                     WHERE id = $1",
                    &[
                        run_id.as_str().into(),
                        StoredState::of_engine(*state).as_str().into(),
                        reason.clone().into(),
                        now_s().into(),
                        wording.into(),
                    ],
                )?;
            }
            _ => {}
        }
        let kind = serde_json::to_value(event)
            .ok()
            .and_then(|v| v["event"].as_str().map(str::to_string))
            .unwrap_or_default();
        let json = serde_json::to_string(event).unwrap_or_default();
        db.execute(
            "INSERT INTO events (run_id, at, kind, json) VALUES ($1, $2, $3, $4)",
            &[
                self.run_id.as_str().into(),
                now_s().into(),
                kind.into(),
                json.into(),
            ],
        )?;
        Ok(())
    }
}

impl EventSink for StoreSink {
    fn emit(&mut self, event: &Event) -> Result<(), spinbench_engine::event::SinkError> {
        self.write(event).map_err(|e| {
            format!(
                "store {}: cannot record the {} event: {}",
                self.store.target,
                serde_json::to_value(event)
                    .ok()
                    .and_then(|v| v["event"].as_str().map(str::to_string))
                    .unwrap_or_default(),
                crate::whole_reason(&e)
            )
            .into()
        })
    }
}

impl Store {
    /// A sink that writes the events of a run to this store (its own connection).
    pub fn sink(&self) -> Result<StoreSink, StoreError> {
        Ok(StoreSink {
            store: Store::connect(&self.target)?,
            serials: Vec::new(),
            run_id: String::new(),
            station: String::new(),
            prompt: String::new(),
            prompt_fixtures: String::new(),
        })
    }
}
