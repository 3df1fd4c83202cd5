//! The analyst's view (`analyst_results`): what each verdict judged, the
//! rule, the reasons' codes, the plan and the operator as columns, the same
//! on SQLite and PostgreSQL as the station's own record says; on
//! PostgreSQL a role granted the view reads it and nothing else.

mod common;

use common::spinbench;
use spinbench_store::{Store, StoreTarget};
use std::collections::BTreeMap;

/// (measurand, judged value, its U95, limit, rule, outcome) per serial, as
/// the stored records say.
type Judged = BTreeMap<String, (String, Option<f64>, Option<f64>, f64, String, String)>;

/// The test's plan: seed 4's bench fails two of its three instruments
/// against 25 µg/g².
fn plan_text() -> String {
    format!(
        "operator = \"analyst test\"\n{}[limits]\nk2_max_ug_per_g2 = 25\n",
        // Warmed up: without it the warm-up drift widens every U95 over
        // the limit and nothing is decided.
        common::short_plan("AV").replace("warmup_s = 0", "warmup_s = 600")
    )
}

/// Its name, as the station reads it.
fn plan_name() -> String {
    spinbench_engine::TestPlan::from_toml(&plan_text())
        .expect("plan")
        .name
}

/// A short run on the virtual bench into `db` (`--db`, or the data folder's
/// file), with a limit some instruments miss; what its records judged.
fn run_into(dir: &std::path::Path, db: Option<&str>) -> (StoreTarget, Judged) {
    let plan = dir.join("plan.toml");
    let text = plan_text();
    std::fs::write(&plan, text).expect("plan");
    let data = dir.join("data");
    let mut args = vec!["run", "--simulate", "--quiet", "--seed", "4", "--data"];
    let data_s = data.to_str().expect("utf-8");
    args.push(data_s);
    if let Some(url) = db {
        args.extend(["--db", url]);
    }
    args.push(plan.to_str().expect("utf-8"));
    let (_, said, err) = spinbench(&args);
    let target = match db {
        Some(url) => StoreTarget::Postgres(url.to_string()),
        None => StoreTarget::File(data.join("spinbench.db")),
    };
    let store = Store::connect(&target).expect("store");
    let runs = store.runs().expect("runs");
    assert_eq!(runs.len(), 1, "{said}{err}");
    let judged = store
        .results(&runs[0].id)
        .expect("results")
        .into_iter()
        .map(|r| {
            let j = r.record.judged().expect("a decision recorded");
            (
                r.serial.clone(),
                (
                    j.measurand.name().to_string(),
                    j.value_ug_per_g2,
                    j.u95_ug_per_g2,
                    j.limit_ug_per_g2,
                    j.rule.name().to_string(),
                    r.outcome.to_string(),
                ),
            )
        })
        .collect();
    (target, judged)
}

const VIEW: &str = "SELECT serial, measurand, judged_ug_per_g2, judged_u95, limit_ug_per_g2, decision_rule, outcome, plan_name, operator FROM analyst_results ORDER BY serial";

#[test]
fn the_analyst_reads_what_each_verdict_judged_from_one_view_on_sqlite() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (target, judged) = run_into(dir.path(), None);
    let StoreTarget::File(path) = target else {
        panic!("a file")
    };
    let db = rusqlite::Connection::open(path).expect("sqlite");
    let mut q = db.prepare(VIEW).expect("the view");
    let rows: Judged = q
        .query_map([], |r| {
            assert_eq!(r.get::<_, String>(7)?, plan_name());
            assert_eq!(r.get::<_, String>(8)?, "analyst test");
            Ok((
                r.get::<_, String>(0)?,
                (
                    r.get(1)?,
                    r.get(2)?,
                    r.get(3)?,
                    r.get(4)?,
                    r.get(5)?,
                    r.get(6)?,
                ),
            ))
        })
        .expect("rows")
        .collect::<Result<_, _>>()
        .expect("rows");
    assert_eq!(rows, judged);
    assert!(rows.values().any(|r| r.5 == "fail"), "{rows:?}");
    // A fail's reasons as their codes, for a filter.
    let codes: String = db
        .query_row(
            "SELECT reason_codes FROM analyst_results WHERE outcome = 'fail' LIMIT 1",
            [],
            |r| r.get(0),
        )
        .expect("a fail's codes");
    assert!(codes.split(',').any(|c| c == "k2_over_limit"), "{codes}");
}

#[test]
fn postgres_the_analyst_role_reads_the_view_and_nothing_else() {
    let admin = spinbench_store::testing::postgres_url().unwrap_or_else(|e| panic!("{e}"));
    let url = spinbench_store::testing::fresh_postgres_database(&admin).expect("a fresh database");
    let dir = tempfile::tempdir().expect("tempdir");
    let (_, judged) = run_into(dir.path(), Some(&url));
    let role = common::role_for(&url, "analyst");
    let mut owner = postgres::Client::connect(&url, postgres::NoTls).expect("owner");
    owner
        .batch_execute(&format!("CREATE ROLE {role} LOGIN;"))
        .expect("role");
    let (ok, said, err) = spinbench(&["migrate", "--db", &url, "--grant-analyst", &role]);
    assert!(
        ok && said.contains(&format!("role {role} may read analyst_results")),
        "{said}{err}"
    );
    let (ok, _, err) = spinbench(&[
        "migrate",
        "--db",
        &url,
        "--grant-analyst",
        "x; DROP TABLE runs",
    ]);
    assert!(!ok && err.contains("not a PostgreSQL role name"), "{err}");
    // The view and the tables say what they hold.
    let comment: Option<String> = owner
        .query_one(
            "SELECT obj_description('analyst_results'::regclass, 'pg_class')",
            &[],
        )
        .expect("comment")
        .get(0);
    assert!(comment.is_some_and(|c| c.contains("judged_ug_per_g2")));
    let comment: Option<String> = owner
        .query_one(
            "SELECT obj_description('results'::regclass, 'pg_class')",
            &[],
        )
        .expect("comment")
        .get(0);
    assert!(comment.is_some());
    let as_analyst = url.replacen("://spinbench@", &format!("://{role}@"), 1);
    let mut analyst = postgres::Client::connect(&as_analyst, postgres::NoTls).expect("analyst");
    let rows: Judged = analyst
        .query(VIEW, &[])
        .expect("the analyst reads the view")
        .iter()
        .map(|r| {
            assert_eq!(r.get::<_, String>(7), plan_name());
            assert_eq!(r.get::<_, String>(8), "analyst test");
            (
                r.get::<_, String>(0),
                (r.get(1), r.get(2), r.get(3), r.get(4), r.get(5), r.get(6)),
            )
        })
        .collect();
    assert_eq!(rows, judged);
    for private in [
        "SELECT password_hash FROM users",
        "SELECT csrf FROM sessions",
        "SELECT record_json FROM results",
    ] {
        let refused = analyst.query(private, &[]).expect_err(private);
        assert!(
            refused.to_string().contains("permission denied")
                || format!("{refused:?}").contains("permission denied"),
            "{private}: {refused:?}"
        );
    }
}
