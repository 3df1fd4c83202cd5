//! `spinbench equipment` and the register at `spinbench run` (
//! part 4): an overdue device stops a run before anything moves, unless
//! overridden with a reason, which the audit log keeps.

mod common;

use spinbench_store::{Store, StoreTarget};

use common::spinbench;

#[test]
fn an_overdue_device_stops_a_run_unless_overridden_with_a_reason() {
    let dir = tempfile::tempdir().expect("tempdir");
    let data = dir.path().join("data");
    let db = data.join("spinbench.db");
    std::fs::create_dir_all(&data).expect("data");
    let (data_s, db_s) = (data.to_str().expect("utf-8"), db.to_str().expect("utf-8"));
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, common::short_plan("E")).expect("plan");
    let plan_s = plan.to_str().expect("utf-8");
    let set = |due: &str| {
        spinbench(&[
            "equipment",
            "set",
            "fmu 1",
            "--identity",
            "FMU-8 SN 31",
            "--certificate",
            "C-77",
            "--calibrated",
            "2025-01-01",
            "--due",
            due,
            "--station",
            "spinbench virtual bench",
            "--db",
            db_s,
        ])
    };
    // A date that is not one is refused, naming the option.
    let (ok, _, err) = set("2026-02-30");
    assert!(!ok && err.contains("--due '2026-02-30'"), "{err}");
    let (ok, said, err) = set("2026-01-01");
    assert!(ok && said.contains("overdue"), "{said}{err}");
    let (ok, listed, _) = spinbench(&["equipment", "list", "--db", db_s]);
    assert!(
        ok && listed.contains("fmu 1") && listed.contains("C-77"),
        "{listed}"
    );

    let run = |extra: &[&str]| {
        let mut args = vec!["run", "--simulate", "--quiet", "--data", data_s];
        args.extend_from_slice(extra);
        args.push(plan_s);
        spinbench(&args)
    };
    let (ok, _, err) = run(&[]);
    assert!(
        !ok && err.contains("fmu 1 (due 2026-01-01, overdue)"),
        "{err}"
    );
    let store = Store::connect(&StoreTarget::File(db.clone())).expect("store");
    assert!(store.runs().expect("runs").is_empty(), "nothing ran");
    let (_, said, err) = run(&["--override-overdue", "certificate renewal in the post"]);
    assert!(said.contains("started anyway"), "{said}{err}");
    assert_eq!(store.runs().expect("runs").len(), 1);
    let log: Vec<String> = store
        .audit_log(20)
        .expect("audit")
        .into_iter()
        .map(|a| format!("{} {}", a.action, a.detail))
        .collect();
    assert!(
        log.iter()
            .any(|l| l.starts_with("override overdue calibration") && l.contains("renewal")),
        "{log:?}"
    );
}

/// The register is per station: an entry of one station
/// is not another's; with two stations known, `--station` is asked for.
#[test]
fn the_register_is_kept_per_station() {
    let dir = tempfile::tempdir().expect("tempdir");
    let db = dir.path().join("spinbench.db");
    let db_s = db.to_str().expect("utf-8");
    let set = |station: Option<&str>| {
        let mut args = vec![
            "equipment",
            "set",
            "centrifuge",
            "--identity",
            "CT 1",
            "--certificate",
            "K-1",
            "--calibrated",
            "2025-01-01",
            "--due",
            "2099-01-01",
            "--db",
            db_s,
        ];
        if let Some(s) = station {
            args.extend(["--station", s]);
        }
        spinbench(&args)
    };
    // No station known yet: the command asks which.
    let (ok, _, err) = set(None);
    assert!(!ok && err.contains("--station NAME is needed"), "{err}");
    let (ok, said, err) = set(Some("A"));
    assert!(ok && said.contains("of station 'A'"), "{said}{err}");
    let store = Store::connect(&StoreTarget::File(db.clone())).expect("store");
    assert_eq!(store.equipment(Some("A")).expect("A").len(), 1);
    assert!(
        store.equipment(Some("B")).expect("B").is_empty(),
        "station A's centrifuge is station B's"
    );
    let (ok, listed, _) = spinbench(&["equipment", "list", "--station", "B", "--db", db_s]);
    assert!(ok && !listed.contains("K-1"), "{listed}");
    let (ok, listed, _) = spinbench(&["equipment", "list", "--db", db_s]);
    assert!(
        ok && listed.contains("A ") && listed.contains("K-1"),
        "{listed}"
    );
}
