//! The same store tests against an SQLite file and a real PostgreSQL server
//! (`SPINBENCH_TEST_POSTGRES`, started by `scripts/test`; a fresh database per
//! test). Nothing is mocked.

use spinbench_analysis::{Direction, Mount};
use spinbench_engine::TestPlan;
use spinbench_engine::event::{DeviceIdentity, Event, EventSink, RunState};
use spinbench_engine::plan::CompiledPlan;
use spinbench_engine::record::{Outcome, PointRecord, UnitRecord};
use spinbench_store::testing::{fresh_postgres_database, postgres_url};
use spinbench_store::{MIGRATIONS, Store, StoreTarget};

/// Run `check` against an SQLite file and against a fresh PostgreSQL database.
fn on_both(check: impl Fn(&StoreTarget)) {
    let dir = tempfile::tempdir().expect("tempdir");
    check(&StoreTarget::File(dir.path().join("store.db")));
    let admin = postgres_url().unwrap_or_else(|e| panic!("{e}"));
    let url = fresh_postgres_database(&admin).expect("a fresh PostgreSQL database");
    check(&StoreTarget::Postgres(url));
}

fn plan(serials: &[&str]) -> CompiledPlan {
    CompiledPlan {
        plan: TestPlan::default(),
        serials: serials.iter().map(|s| Some(s.to_string())).collect(),
        passes: Vec::new(),
        steps: Vec::new(),
        order: Default::default(),
        table_prior: None,
    }
}

fn point(slot: usize, g: f64, output_hz: f64) -> PointRecord {
    PointRecord {
        slot,
        mount: Mount::P,
        g_nominal: g,
        direction: Direction::Up,
        g_applied: g * 1.0001,
        rate_deg_s: 100.0 * g,
        output_hz,
        std_hz: 0.001,
        n: 10,
        time_s: [1.0, 10.0],
        setpoint_c: None,
        temperature_c: Some(25.0 + 0.01 * g),
        temperature_change_c: Some(0.02),
        resonator_sum_hz: Some(60_000.0),
        resonator_sum_change_ppm: Some(0.5),
        temperature_unsettled: false,
    }
}

fn record(slot: usize, serial: &str, k2: f64) -> UnitRecord {
    UnitRecord {
        slot,
        serial: serial.into(),
        tumble: None,
        cross_axis_ug_per_g: Some(21.5),
        at_temperatures: Vec::new(),
        temperature_coefficients: None,
        drawing_radius_m: 0.8,
        radius_m: Default::default(),
        radius_reading_u_ppm: [(Mount::P, 3.5)].into_iter().collect(),
        points: Vec::new(),
        analysis: None,
        k2_max_ug_per_g2: Some(k2),
        outcome: Outcome::Pass,
        reasons: Vec::new(),
        decision_rule: Some(spinbench_engine::plan::DecisionRule::Guarded),
        decision: Some(spinbench_engine::plan::Decision {
            measurand: spinbench_engine::plan::Measurand::K2,
            limit_ug_per_g2: 20.0,
            rule: spinbench_engine::plan::DecisionRule::Guarded,
        }),
        table_signature: None,
        exclusions: Vec::new(),
    }
}

/// A short run's events: two instruments, three levels, one step redone.
fn write_run(store: &Store, run_id: &str, serials: &[&str]) {
    write_run_graded(store, run_id, serials, [Outcome::Pass, Outcome::Pass]);
}

/// [`write_run`] with the two instruments graded `outcomes`.
fn write_run_graded(store: &Store, run_id: &str, serials: &[&str], outcomes: [Outcome; 2]) {
    let graded = |slot: usize, k2: f64| {
        let mut r = record(slot, serials[slot], k2);
        r.outcome = outcomes[slot];
        Box::new(r)
    };
    let mut sink = store.sink().expect("sink");
    let events = vec![
        Event::RunStarted {
            run_id: run_id.into(),
            station: "bench 1".into(),
            plan: Box::new(plan(serials)),
            resumed: false,
            station_config: "station = \"bench 1\"\n".into(),
        },
        Event::Identified {
            devices: vec![DeviceIdentity {
                role: spinbench_engine::DeviceRole::Centrifuge,
                identity: "ACUTRONIC,X".into(),
            }],
        },
        Event::Prompt {
            text: "Mount IA up".into(),
            fixtures: Vec::new(),
        },
        Event::PromptAnswered {
            proceed: true,
            by: "operator 李四".into(),
        },
        Event::RadiusDone {
            slot: 0,
            mount: Mount::P,
            drawing_radius_m: 0.8,
            radius_m: 0.8003,
            reading_u_ppm: 12.0,
        },
        Event::Values {
            time_s: 1.0,
            rate_deg_s: 10.0,
            demand_deg_s: 10.0,
            on_speed: true,
            outputs_hz: vec![Some(1.5), None],
            temperatures_c: vec![Some(24.75), None],
        },
        Event::PointDone {
            step: 3,
            points: vec![point(0, 0.0, 1.0), point(1, 0.0, 2.0)],
        },
        Event::PointDone {
            step: 4,
            points: vec![point(0, 5.0, 11.0), point(1, 5.0, 12.0)],
        },
        // Step 4 redone (after a resume): replaces, never doubles.
        Event::PointDone {
            step: 4,
            points: vec![point(0, 5.0, 11.5), point(1, 5.0, 12.5)],
        },
        Event::UnitResult {
            record: graded(0, 3.25),
        },
        Event::UnitResult {
            record: graded(1, -7.5),
        },
        Event::RunFinished {
            state: RunState::Completed,
            reason: None,
            wording: None,
        },
    ];
    for e in &events {
        sink.emit(e).expect("the store takes the event");
    }
}

#[test]
fn the_schema_is_migrated_once_and_reopening_changes_nothing() {
    on_both(|target| {
        let store = Store::connect(target).expect("open");
        assert_eq!(
            store.schema_version().expect("version"),
            MIGRATIONS.len() as i64
        );
        write_run(&store, "r1", &["A1", "A2"]);
        drop(store);
        let again = Store::connect(target).expect("reopen");
        assert_eq!(
            again.schema_version().expect("version"),
            MIGRATIONS.len() as i64
        );
        assert_eq!(again.runs().expect("runs").len(), 1, "{target}");
        assert_eq!(again.integrity_check().expect("check"), "ok");
    });
}

#[test]
fn a_run_is_stored_whole_and_a_redone_step_replaces_its_points() {
    on_both(|target| {
        let store = Store::connect(target).expect("open");
        write_run(&store, "r1", &["A1", "中文-7"]);
        let run = store.run("r1").expect("query").expect("the run");
        assert_eq!(run.state, spinbench_store::StoredState::Completed);
        assert_eq!((run.units, run.points), (2, 4), "{target}");
        let points = store.points("r1").expect("points");
        let redone: Vec<f64> = points
            .iter()
            .filter(|p| p.step == 4)
            .map(|p| p.output_hz)
            .collect();
        assert_eq!(
            redone,
            vec![11.5, 12.5],
            "{target}: the redo replaced the first take"
        );
        assert_eq!(points[1].serial, "中文-7");
        assert_eq!(
            points[0].temperature_c,
            Some(25.0 + 0.01 * points[0].g_nominal)
        );
        assert_eq!(points[0].temperature_change_c, Some(0.02));
        let results = store.results("r1").expect("results");
        assert_eq!(results[1].k2_max_ug_per_g2, Some(-7.5));
        assert_eq!(store.unit_history("中文-7").expect("history").len(), 1);
        assert_eq!(store.value_count("r1").expect("values"), 2);
        let values = store.values("r1").expect("values");
        assert_eq!(values[0].output_hz, Some(1.5));
        assert_eq!(values[0].temperature_c, Some(24.75), "{target}");
        assert_eq!(
            values[1].temperature_c, None,
            "no temperature stored as none"
        );
        assert_eq!(
            values[1].output_hz, None,
            "a missing output is stored as missing"
        );
        // The whole run in one call, typed: the same as the parts.
        let record = store.run_record("r1").expect("record").expect("the run");
        assert_eq!(
            record.start.station_config.as_deref(),
            Some("station = \"bench 1\"\n")
        );
        assert_eq!(record.start.record_version, spinbench_store::RECORD_VERSION);
        assert!(
            record.start.plan.plan.is_some(),
            "{:?}",
            record.start.plan.unread
        );
        assert_eq!(record.devices.len(), 1);
        assert_eq!(
            record.devices[0].role,
            spinbench_engine::DeviceRole::Centrifuge
        );
        assert_eq!(record.devices[0].identity, "ACUTRONIC,X");
        assert_eq!(
            record.devices[0].calibration,
            Some(spinbench_store::equipment::CalibrationStatus::Unregistered)
        );
        assert_eq!(record.operator_actions.len(), 1);
        assert_eq!(record.operator_actions[0].who, "operator 李四");
        assert!(record.operator_actions[0].action.contains("Mount IA up"));
        assert_eq!(record.points, points);
        assert_eq!(record.results, results);
        assert_eq!(record.end.state, spinbench_store::StoredState::Completed);
        assert_eq!(record.row(), run);
        assert!(store.run_record("no such run").expect("read").is_none());
        let radii = store.unit_radii("r1").expect("units");
        assert_eq!(radii.len(), 1);
        assert_eq!(
            (
                radii[0].slot,
                radii[0].mount.to_string().as_str(),
                radii[0].serial.as_str()
            ),
            (0, "P", "A1")
        );
        assert_eq!(
            (radii[0].drawing_radius_m, radii[0].radius_m),
            (0.8, 0.8003)
        );
        let csv = store.points_csv("r1").expect("csv");
        assert_eq!(csv.lines().count(), 5, "header + 4 points:\n{csv}");
        assert!(
            csv.lines()
                .nth(3)
                .unwrap_or_default()
                .starts_with("A1,P,5.0,5.0005,11.5,up,r1")
        );
    });
}

#[test]
fn a_write_the_database_refuses_is_an_error_that_names_the_store() {
    on_both(|target| {
        let store = Store::connect(target).expect("open");
        let mut sink = store.sink().expect("sink");
        // A point of a run that was never started: the reference to runs refuses it.
        sink.emit(&Event::RunStarted {
            run_id: "r1".into(),
            station: "s".into(),
            plan: Box::new(plan(&["A1"])),
            resumed: false,
            station_config: String::new(),
        })
        .expect("start");
        let mut other = store.sink().expect("sink");
        let err = other
            .emit(&Event::PointDone {
                step: 1,
                points: vec![point(0, 1.0, 1.0)],
            })
            .expect_err("a point without its run is refused");
        assert!(err.problem.contains("point_done"), "{err}");
        assert!(err.problem.contains("store "), "{err}");
        assert!(store.points("r1").expect("points").is_empty());
    });
}

#[test]
fn many_writers_at_once_keep_their_runs_apart() {
    on_both(|target| {
        Store::connect(target).expect("create the schema");
        let handles: Vec<_> = (0..4)
            .map(|k| {
                let target = target.clone();
                std::thread::spawn(move || {
                    let store = Store::connect(&target).expect("open");
                    for r in 0..3 {
                        let id = format!("s{k}-r{r}");
                        let a = format!("S{k}-{r}-A");
                        let b = format!("S{k}-{r}-B");
                        write_run(&store, &id, &[&a, &b]);
                    }
                })
            })
            .collect();
        for h in handles {
            h.join().expect("writer");
        }
        let store = Store::connect(target).expect("open");
        let runs = store.runs().expect("runs");
        assert_eq!(runs.len(), 12, "{target}");
        for run in runs {
            assert_eq!((run.units, run.points), (2, 4), "{}", run.id);
            let prefix = format!("S{}-{}-", &run.id[1..2], &run.id[4..5]);
            for p in store.points(&run.id).expect("points") {
                assert!(
                    p.serial.starts_with(&prefix),
                    "{}: {} mixed in",
                    run.id,
                    p.serial
                );
            }
        }
    });
}

#[test]
fn a_runs_events_are_read_through_an_index_enumerations_are_checked_and_migrations_recorded() {
    // SQLite: the planner's own account of a run's events.
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("store.db");
    drop(Store::open(&path).expect("store"));
    let conn = rusqlite::Connection::open(&path).expect("sqlite");
    let plan: Vec<String> = conn
        .prepare("EXPLAIN QUERY PLAN SELECT json FROM events WHERE run_id = 'r' ORDER BY seq")
        .expect("explain")
        .query_map([], |r| r.get::<_, String>(3))
        .expect("rows")
        .map(|r| r.expect("row"))
        .collect();
    assert!(plan.iter().any(|l| l.contains("events_run")), "{plan:?}");
    let history: Vec<(i64, Option<i64>, Option<String>)> = conn
        .prepare("SELECT version, applied_at, release FROM spinbench_migrations ORDER BY version")
        .expect("history")
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))
        .expect("rows")
        .map(|r| r.expect("row"))
        .collect();
    assert_eq!(history.len(), MIGRATIONS.len());
    let last = history.last().expect("a row");
    assert!(last.1.is_some_and(|t| t > 1_700_000_000), "{last:?}");
    assert_eq!(last.2.as_deref(), Some(env!("CARGO_PKG_VERSION")));
    assert!(
        history
            .iter()
            .all(|h| h.1.is_some() && h.2.as_deref() == Some(env!("CARGO_PKG_VERSION"))),
        "a new store: every migration applied now, by this release: {history:?}"
    );

    // PostgreSQL: an index scan, checks on the enumerations, the history.
    let admin = postgres_url().unwrap_or_else(|e| panic!("{e}"));
    let url = fresh_postgres_database(&admin).expect("a fresh PostgreSQL database");
    drop(Store::connect(&StoreTarget::Postgres(url.clone())).expect("store"));
    let mut pg = postgres::Client::connect(&url, postgres::NoTls).expect("postgres");
    pg.batch_execute("SET enable_seqscan = off").expect("set");
    let plan: Vec<String> = pg
        .query(
            "EXPLAIN SELECT json FROM events WHERE run_id = 'r' ORDER BY seq",
            &[],
        )
        .expect("explain")
        .iter()
        .map(|r| r.get(0))
        .collect();
    assert!(plan.iter().any(|l| l.contains("events_run")), "{plan:?}");
    for (sql, constraint) in [
        (
            "INSERT INTO runs (id, station, plan_json, software_version, state, started_at) \
             VALUES ('r', 's', '{}', 'v', 'finished-ish', to_timestamp(0))",
            "runs_state_known",
        ),
        (
            "INSERT INTO users (name, role, password_hash, created_at) VALUES ('u', 'root', 'x', to_timestamp(0))",
            "users_role_known",
        ),
    ] {
        let e = pg.batch_execute(sql).expect_err("refused");
        assert_eq!(
            e.as_db_error().and_then(|d| d.constraint()),
            Some(constraint),
            "{e:?}"
        );
    }
    // PostgreSQL's own types (migration 15).
    for (table, column, wanted) in [
        ("runs", "started_at", "timestamp with time zone"),
        ("runs", "finished_at", "timestamp with time zone"),
        ("runs", "plan_json", "jsonb"),
        ("runs", "devices_json", "jsonb"),
        ("results", "record_json", "jsonb"),
        ("events", "at", "timestamp with time zone"),
        ("events", "json", "jsonb"),
        ("values_1s", "on_speed", "boolean"),
        ("equipment", "due_on", "date"),
        ("equipment", "calibrated_on", "date"),
        ("users", "created_at", "timestamp with time zone"),
        ("sessions", "last_seen", "timestamp with time zone"),
        ("audit", "at", "timestamp with time zone"),
        ("stations", "last_seen", "timestamp with time zone"),
        ("operator_actions", "at", "timestamp with time zone"),
    ] {
        let row = pg
            .query_one(
                "SELECT data_type FROM information_schema.columns WHERE table_name = $1 AND column_name = $2",
                &[&table, &column],
            )
            .expect("the column");
        assert_eq!(row.get::<_, String>(0), wanted, "{table}.{column}");
    }
    let rows = pg
        .query(
            "SELECT version, applied_at IS NOT NULL, release FROM spinbench_migrations ORDER BY version",
            &[],
        )
        .expect("history");
    assert_eq!(rows.len(), MIGRATIONS.len());
    let last = rows.last().expect("a row");
    assert!(last.get::<_, bool>(1));
    assert_eq!(
        last.get::<_, Option<String>>(2).as_deref(),
        Some(env!("CARGO_PKG_VERSION"))
    );
}

#[test]
fn a_postgresql_store_is_changed_only_by_migrate_and_refused_until_then() {
    let admin = postgres_url().unwrap_or_else(|e| panic!("{e}"));
    let url = spinbench_store::testing::empty_postgres_database(&admin).expect("an empty database");
    let target = StoreTarget::Postgres(url.clone());
    let refused = Store::connect(&target)
        .err()
        .expect("an empty database is refused for work");
    let said = refused.to_string();
    assert!(
        said.contains("schema is version 0")
            && said.contains(&format!("spinbench migrate --db {}", target.for_owner()))
            && said.contains("OWNER@")
            && target
                .role()
                .is_none_or(|r| said.contains(&format!("not `{r}`"))),
        "{said}"
    );
    let (store, before, after) = Store::migrate_target(&target).expect("migrate");
    assert_eq!((before, after), (0, MIGRATIONS.len() as i64));
    drop(store);
    let (_, again, now) = Store::migrate_target(&target).expect("migrate again");
    assert_eq!(
        (again, now),
        (after, after),
        "a second migrate changes nothing"
    );
    Store::connect(&target).expect("a migrated store opens for work");
    // A newer release's store is refused, not written.
    let mut pg = postgres::Client::connect(&url, postgres::NoTls).expect("postgres");
    pg.batch_execute("UPDATE spinbench_schema SET version = version + 1")
        .expect("bump");
    let newer = Store::connect(&target)
        .err()
        .expect("a newer schema is refused");
    assert!(newer.to_string().contains("newer release"), "{newer}");
}

#[test]
fn a_results_figures_are_columns_and_a_runs_rows_belong_to_it() {
    on_both(|target| {
        let store = Store::connect(target).expect("open");
        write_run(&store, "r1", &["A1", "B2"]);
        let sql = "SELECT serial, k2_max_ug_per_g2, measurand, limit_ug_per_g2 FROM results ORDER BY slot";
        type Figures = (String, Option<f64>, Option<String>, Option<f64>);
        let rows: Vec<Figures> = match target {
            StoreTarget::File(path) => {
                let c = rusqlite::Connection::open(path).expect("sqlite");
                let mut s = c.prepare(sql).expect("prepare");
                s.query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?)))
                    .expect("rows")
                    .map(|r| r.expect("row"))
                    .collect()
            }
            StoreTarget::Postgres(url) => {
                let mut pg = postgres::Client::connect(url, postgres::NoTls).expect("postgres");
                // A run's rows belong to a run: an event of no run is refused.
                let e = pg
                    .batch_execute(
                        "INSERT INTO events (run_id, at, kind, json) VALUES ('no such run', to_timestamp(0), 'x', '{}')",
                    )
                    .expect_err("refused");
                assert_eq!(
                    e.as_db_error().and_then(|d| d.constraint()),
                    Some("events_run"),
                    "{e:?}"
                );
                pg.query(sql, &[])
                    .expect("rows")
                    .iter()
                    .map(|r| (r.get(0), r.get(1), r.get(2), r.get(3)))
                    .collect()
            }
        };
        let stored = store.results("r1").expect("results");
        assert_eq!(rows.len(), stored.len(), "{target}");
        for ((serial, k2_max, measurand, limit), r) in rows.iter().zip(&stored) {
            assert_eq!(serial, &r.serial);
            assert_eq!(*k2_max, r.record.k2_max_ug_per_g2, "{target}");
            assert_eq!(measurand.as_deref(), Some("K2"), "{target}");
            assert_eq!(*limit, Some(20.0), "{target}");
        }
    });
}

#[test]
fn a_text_with_a_nul_is_stored_on_both_back_ends() {
    // jsonb cannot hold a NUL escape: it is kept as U+FFFD, never a write
    // refused (which would hold the run).
    on_both(|target| {
        let store = Store::connect(target).expect("open");
        let mut sink = store.sink().expect("sink");
        sink.emit(&Event::RunStarted {
            run_id: "nul".into(),
            station: "bench 1".into(),
            plan: Box::new(plan(&["A1"])),
            resumed: false,
            station_config: String::new(),
        })
        .expect("start");
        sink.emit(&Event::Prompt {
            text: "a device said \u{0}\\u0000 here".into(),
            fixtures: Vec::new(),
        })
        .unwrap_or_else(|e| panic!("{target}: {e}"));
        sink.emit(&Event::PromptAnswered {
            proceed: true,
            by: "op".into(),
        })
        .expect("answer");
        let record = store.run_record("nul").expect("read").expect("the run");
        assert_eq!(record.operator_actions.len(), 1, "{target}");
        assert!(record.operator_actions[0].action.contains("a device said"));
        assert!(
            !record.operator_actions[0].action.contains('\0')
                || matches!(target, StoreTarget::File(_))
        );
    });
}

/// Two engineers change one instrument's result at once,
/// each from the revision they read (on two connections, as two servers):
/// one change lands, the other is told the result changed meanwhile and
/// writes nothing — never both answered done with one of them lost.
#[test]
fn two_changes_of_one_result_from_one_revision_do_not_both_land() {
    on_both(|target| {
        let store = Store::connect(target).expect("store");
        write_run(&store, "R-CAS", &["CAS-1", "CAS-2"]);
        for round in 0..10 {
            let read = store.results("R-CAS").expect("results");
            let from = read[0].revision;
            assert_eq!(from, round, "one revision per landed change");
            let barrier = std::sync::Barrier::new(2);
            let outcomes: Vec<spinbench_store::Replaced> = std::thread::scope(|s| {
                let handles: Vec<_> = [10.0, 20.0]
                    .into_iter()
                    .map(|k2| {
                        let (barrier, target) = (&barrier, target.clone());
                        let mut changed = read[0].record.clone();
                        changed.k2_max_ug_per_g2 = Some(k2 + round as f64);
                        s.spawn(move || {
                            let other = Store::connect(&target).expect("second connection");
                            barrier.wait();
                            other
                                .replace_result(
                                    "R-CAS",
                                    &changed,
                                    from,
                                    "eng",
                                    "exclude level",
                                    "x",
                                )
                                .expect("no store error")
                        })
                    })
                    .collect();
                handles
                    .into_iter()
                    .map(|h| h.join().expect("thread"))
                    .collect()
            });
            let done = outcomes
                .iter()
                .filter(|o| **o == spinbench_store::Replaced::Done)
                .count();
            assert_eq!(done, 1, "{target}: round {round}: {outcomes:?}");
            let audited = store
                .audit_log(100)
                .expect("audit")
                .iter()
                .filter(|a| a.action == "exclude level")
                .count();
            assert_eq!(
                audited as i64,
                round + 1,
                "one audit entry per landed change"
            );
        }
    });
}

/// A process killed outright loses what its outbox held in memory; its
/// journal has it. The journal's measurements the store lacks are written
/// again before a resume (and when a crashed run is marked interrupted),
/// each once: a second catch-up writes nothing new and doubles nothing.
#[test]
fn what_a_killed_process_journaled_reaches_the_store_once() {
    on_both(|target| {
        let store = Store::connect(target).expect("store");
        let started = Event::RunStarted {
            run_id: "r-killed".into(),
            station: "bench 1".into(),
            plan: Box::new(plan(&["A", "B"])),
            resumed: false,
            station_config: "station = \"bench 1\"\n".into(),
        };
        let values = |t: f64| Event::Values {
            time_s: t,
            rate_deg_s: 10.0,
            demand_deg_s: 10.0,
            on_speed: true,
            outputs_hz: vec![Some(1.5), Some(2.5)],
            temperatures_c: vec![None, None],
        };
        let journal = vec![
            started.clone(),
            values(1.0),
            Event::PointDone {
                step: 3,
                points: vec![point(0, 0.0, 1.0), point(1, 0.0, 2.0)],
            },
            Event::StepDone { index: 3 },
            values(2.0),
            Event::PointDone {
                step: 4,
                points: vec![point(0, 5.0, 11.0), point(1, 5.0, 12.0)],
            },
            Event::StepDone { index: 4 },
        ];
        // The store took the first three events before the kill.
        let mut sink = store.sink().expect("sink");
        for e in &journal[..3] {
            sink.emit(e).expect("taken");
        }
        assert_eq!(store.point_keys("r-killed").expect("keys").len(), 2);
        let written =
            spinbench_store::outbox::catch_up_from_journal(&store, &journal).expect("caught up");
        assert_eq!(written, 2, "{target}: step 4's points and the second value");
        let mut keys = store.point_keys("r-killed").expect("keys");
        keys.sort_unstable();
        assert_eq!(keys, vec![(3, 0), (3, 1), (4, 0), (4, 1)], "{target}");
        assert_eq!(store.last_value_time_s("r-killed").expect("t"), Some(2.0));
        // Once only.
        let again = spinbench_store::outbox::catch_up_from_journal(&store, &journal)
            .expect("caught up again");
        assert_eq!(again, 0, "{target}");
        assert_eq!(store.point_keys("r-killed").expect("keys").len(), 4);
        // A run the store never heard of is started in it first.
        let mut unseen = journal.clone();
        if let Event::RunStarted { run_id, .. } = &mut unseen[0] {
            *run_id = "r-unseen".into();
        }
        let written =
            spinbench_store::outbox::catch_up_from_journal(&store, &unseen).expect("caught up");
        assert_eq!(written, 1 + 4, "{target}: the start, two values, two steps");
        assert_eq!(store.point_keys("r-unseen").expect("keys").len(), 4);
    });
}

/// Two `migrate`s of one new store at once: one brings it up, the other
/// waits for the lock and finds nothing to do (it never claims the first's
/// migrations as its own).
fn two_migrates_at_once_apply_each_migration_once_on(target: &StoreTarget) {
    let (a, b) = std::thread::scope(|scope| {
        let first = scope.spawn(|| Store::migrate_target(target).map(|(_, from, to)| (from, to)));
        let second = scope.spawn(|| Store::migrate_target(target).map(|(_, from, to)| (from, to)));
        (
            first.join().expect("a thread").expect("migrate"),
            second.join().expect("a thread").expect("migrate"),
        )
    });
    let all = MIGRATIONS.len() as i64;
    let mut from = [a.0, b.0];
    from.sort_unstable();
    assert_eq!(from, [0, all], "{a:?} {b:?}");
    assert_eq!((a.1, b.1), (all, all));
}

#[test]
fn two_migrates_at_once_apply_each_migration_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    two_migrates_at_once_apply_each_migration_once_on(&StoreTarget::File(dir.path().join("s.db")));
}

#[test]
fn postgres_two_migrates_at_once_apply_each_migration_once() {
    let admin = postgres_url().unwrap_or_else(|e| panic!("{e}"));
    let url = spinbench_store::testing::empty_postgres_database(&admin).expect("an empty database");
    two_migrates_at_once_apply_each_migration_once_on(&StoreTarget::Postgres(url));
}

#[test]
fn the_control_charts_window_is_read_in_two_statements_whatever_the_history() {
    on_both(|target| {
        let store = Store::connect(target).expect("store");
        let window_cost = |store: &Store| {
            let before = spinbench_store::testing::statements_on_this_thread();
            let (runs, results) = store
                .newest_runs_with_results("bench 1", 4)
                .expect("the window");
            (
                spinbench_store::testing::statements_on_this_thread() - before,
                runs,
                results,
            )
        };
        for i in 0..6 {
            write_run(&store, &format!("c-{i:02}"), &["A", "B"]);
        }
        let (small, runs, results) = window_cost(&store);
        let ids: Vec<&str> = runs.iter().map(|r| r.id.as_str()).collect();
        assert_eq!(
            ids,
            ["c-02", "c-03", "c-04", "c-05"],
            "{target}: the newest, oldest first"
        );
        assert_eq!(results.len(), 8, "{target}: two instruments a run");
        assert!(results.iter().all(|r| ids.contains(&r.run_id.as_str())));
        for i in 6..20 {
            write_run(&store, &format!("c-{i:02}"), &["A", "B"]);
        }
        let (large, runs, results) = window_cost(&store);
        assert_eq!(runs.len(), 4);
        assert_eq!(runs[3].id, "c-19", "{target}");
        assert_eq!(results.len(), 8);
        assert_eq!(
            (small, large),
            (2, 2),
            "{target}: the window cost {small} statements at 6 runs, {large} at 20"
        );
    });
}

#[test]
fn the_run_list_is_paged_by_the_database_at_a_cost_that_does_not_grow_with_history() {
    on_both(|target| {
        let store = Store::connect(target).expect("store");
        let page_cost = |store: &Store| {
            let before = spinbench_store::testing::statements_on_this_thread();
            let (page, more) = store.runs_page(Some("bench 1"), None, 3).expect("page");
            (
                spinbench_store::testing::statements_on_this_thread() - before,
                page.len(),
                more,
            )
        };
        for i in 0..5 {
            write_run(&store, &format!("r-{i:02}"), &["A", "B"]);
        }
        let (small, n, more) = page_cost(&store);
        assert_eq!((n, more), (3, true), "{target}");
        for i in 5..12 {
            write_run(&store, &format!("r-{i:02}"), &["A", "B"]);
        }
        let (large, n, _) = page_cost(&store);
        assert_eq!(n, 3, "{target}");
        assert_eq!(
            small, large,
            "{target}: a page cost {small} statements at 5 runs, {large} at 12"
        );
        assert!(small <= 2, "{target}: {small} statements for one page");
        // Walked page by page with the cursor: every run once, newest first.
        let mut seen = Vec::new();
        let mut after: Option<(i64, String)> = None;
        loop {
            let (page, more) = store
                .runs_page(None, after.as_ref().map(|(t, id)| (*t, id.as_str())), 5)
                .expect("page");
            seen.extend(page.iter().map(|r| r.id.clone()));
            after = page.last().map(|r| (r.started_at, r.id.clone()));
            if !more {
                break;
            }
        }
        let all: Vec<String> = store
            .runs()
            .expect("runs")
            .into_iter()
            .map(|r| r.id)
            .collect();
        assert_eq!(seen, all, "{target}");
        assert_eq!(seen.len(), 12, "{target}");
        // Another station's filter is the database's too.
        let (none, more) = store.runs_page(Some("bench 2"), None, 3).expect("page");
        assert!(none.is_empty() && !more, "{target}");
    });
}

#[test]
fn the_fleets_first_pass_yield_counts_a_marginal_pass_as_passed_as_the_charts_do() {
    on_both(|target| {
        let store = Store::connect(target).expect("store");
        write_run_graded(
            &store,
            "y-1",
            &["A", "B"],
            [Outcome::Pass, Outcome::Marginal],
        );
        write_run_graded(
            &store,
            "y-2",
            &["C", "D"],
            [Outcome::Fail, Outcome::Inconclusive],
        );
        store
            .heartbeat(&spinbench_store::fleet::Heartbeat {
                station: "bench 1".into(),
                instance: "i-1".into(),
                state: "idle".into(),
                run_id: None,
                progress: None,
                address: None,
            })
            .expect("heartbeat");
        let stations = store.stations().expect("stations");
        let bench = stations
            .iter()
            .find(|s| s.beat.station == "bench 1")
            .unwrap_or_else(|| panic!("{target}: bench 1 not listed"));
        assert_eq!(
            (bench.tested_today, bench.passed_today),
            (4, 2),
            "{target}: pass and marginal passed, fail and inconclusive not"
        );
    });
}

/// A run of station "bench 1" whose config says `time_zone = zone`, started now.
fn write_run_in_zone(store: &Store, run_id: &str, zone: &str) {
    let mut sink = store.sink().expect("sink");
    for e in [
        Event::RunStarted {
            run_id: run_id.into(),
            station: "bench 1".into(),
            plan: Box::new(plan(&["A"])),
            resumed: false,
            station_config: format!("station = \"bench 1\"\ntime_zone = \"{zone}\"\n"),
        },
        Event::RunFinished {
            state: RunState::Completed,
            reason: None,
            wording: None,
        },
    ] {
        sink.emit(&e).expect("the store takes the event");
    }
}

#[test]
fn a_runs_label_and_its_number_are_of_the_stations_day_not_utcs() {
    on_both(|target| {
        let store = Store::connect(target).expect("store");
        // At one instant, 26 hours apart on the station's clock: two days.
        write_run_in_zone(&store, "z-east-1", "UTC+14:00");
        write_run_in_zone(&store, "z-west-1", "UTC-12:00");
        write_run_in_zone(&store, "z-east-2", "UTC+14:00");
        let row = |id: &str| store.run(id).expect("read").expect("stored");
        let (east_1, west_1, east_2) = (row("z-east-1"), row("z-west-1"), row("z-east-2"));
        let day = |r: &spinbench_store::RunRow, offset_s: i64| {
            spinbench_store::equipment::civil_date(r.started_at + offset_s)
        };
        assert_eq!(
            (east_1.utc_offset_s, west_1.utc_offset_s),
            (50_400, -43_200)
        );
        assert_eq!(
            east_1.label(),
            format!("{} · bench 1 · #1", day(&east_1, 50_400))
        );
        assert_eq!(
            west_1.label(),
            format!("{} · bench 1 · #1", day(&west_1, -43_200))
        );
        // Numbered among the station's runs of its own day.
        assert_eq!(
            east_2.label(),
            format!("{} · bench 1 · #2", day(&east_2, 50_400))
        );
        assert_ne!(day(&east_1, 50_400), day(&west_1, -43_200), "{target}");
        // The label, typed, names its run.
        for r in [&east_1, &west_1, &east_2] {
            assert_eq!(
                store.resolve_run(&r.label()).expect("resolved"),
                r.id,
                "{target}"
            );
        }
        // The whole record says the same day.
        let record = store.run_record("z-west-1").expect("read").expect("stored");
        assert_eq!(record.label(), west_1.label());
    });
}
