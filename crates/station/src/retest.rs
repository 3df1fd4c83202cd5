//! The retest of a finished run, read from the store:
//! shared by `spinbench retest RUN` and `POST /api/runs/{id}/retest`. The
//! selection itself is the engine's ([`spinbench_engine::retest`]).

use spinbench_engine::TestPlan;
use spinbench_engine::retest::{RetestError, is_run_id, retest_plan};
use spinbench_store::{Store, StoreError};

/// Why a run cannot be retested.
#[derive(Debug, thiserror::Error)]
pub enum RetestFromStoreError {
    /// No such run.
    #[error("no run {0} in the store (`spinbench runs list` lists them)")]
    NotFound(String),
    /// It has not ended.
    #[error("run {0} is still {1}: retest it once it has ended")]
    NotEnded(String, String),
    /// Its stored plan cannot be read back.
    #[error("run {0}'s stored plan could not be read: {1}")]
    Plan(String, String),
    /// Nothing to retest, not graded, or not a run id.
    #[error(transparent)]
    Retest(#[from] RetestError),
    /// A serial of the plan looks like an earlier run's but is not it.
    #[error(
        "serial '{given}' looks like the instrument '{stored}' of an earlier run but is not it: \
         the two would be two histories of one instrument. Type the serial as it is on the instrument \
         (if it is '{stored}', use that)"
    )]
    LookAlikeSerial {
        /// The plan's serial.
        given: String,
        /// The stored serial it looks like.
        stored: String,
    },
    /// A plan's `retest_of` names a run that did not test this instrument,
    /// or where it needs no retest.
    #[error(
        "retest_of = '{run}': {serial} is not an instrument of run {run} that needs a retest ({needing}); \
         retest a run with `spinbench retest RUN`, or take retest_of out of the plan"
    )]
    NotToRetest {
        /// The run named.
        run: String,
        /// The plan's serial.
        serial: String,
        /// The run's instruments that need one, or "none".
        needing: String,
    },
    /// The store failed.
    #[error(transparent)]
    Store(#[from] StoreError),
}

/// Check a plan against the store before it runs: no serial looks like an
/// earlier run's without being it; and, for a retest (`retest_of`), the run
/// exists and has ended, and every serial of the plan is one of its
/// instruments that may be retested ([`spinbench_engine::retest::may_retest`]:
/// one that needs it, or a fail on purpose), so no record claims to retest
/// what was never tested or passed.
pub fn check_retest_of(store: &Store, plan: &TestPlan) -> Result<(), RetestFromStoreError> {
    for given in plan.serials.values() {
        if let Some(stored) = store.look_alike_serial(given)? {
            return Err(RetestFromStoreError::LookAlikeSerial {
                given: spinbench_engine::bounds::shown(given),
                stored: spinbench_engine::bounds::shown(&stored),
            });
        }
    }
    let Some(run_id) = plan.retest_of.as_deref() else {
        return Ok(());
    };
    let run = store
        .run(run_id)?
        .ok_or_else(|| RetestFromStoreError::NotFound(run_id.to_string()))?;
    if !run.is_ended() {
        return Err(RetestFromStoreError::NotEnded(
            run_id.to_string(),
            run.state.to_string(),
        ));
    }
    let needing: Vec<String> = store
        .results(run_id)?
        .into_iter()
        .filter(|r| spinbench_engine::retest::may_retest(&r.record))
        .map(|r| r.record.serial)
        .collect();
    if let Some(serial) = plan.serials.values().find(|s| !needing.contains(s)) {
        return Err(RetestFromStoreError::NotToRetest {
            run: run_id.to_string(),
            serial: serial.clone(),
            needing: if needing.is_empty() {
                "none".into()
            } else {
                needing.join(", ")
            },
        });
    }
    Ok(())
}

/// The most runs of a chain of retests read back for an instrument's tries.
pub const MAX_RETEST_CHAIN: usize = 20;

/// A finished run's retest, ready to start.
#[derive(Debug, Clone)]
pub struct Retest {
    /// The retest plan (only the instruments that need one; `retest_of` set).
    pub plan: TestPlan,
    /// The serials it tests again.
    pub serials: Vec<String>,
    /// The station config the run used.
    pub station_config: Option<String>,
    /// For each inconclusive instrument: what would decide it and whether
    /// the retest is predicted to.
    pub advice: Vec<spinbench_engine::retest::RetestAdvice>,
}

/// The retest of `run_id`: its plan, the serials it tests again, the
/// station config the run used, and the advice for its inconclusive
/// instruments against the retest plan's prediction from the station's
/// model of its own runs.
pub fn retest_plan_from_store(
    store: &Store,
    run_id: &str,
    choice: spinbench_engine::retest::RetestChoice,
) -> Result<Retest, RetestFromStoreError> {
    if !is_run_id(run_id) {
        return Err(RetestError::BadRunId(run_id.chars().take(80).collect()).into());
    }
    let record = store
        .run_record(run_id)?
        .ok_or_else(|| RetestFromStoreError::NotFound(run_id.to_string()))?;
    if !record.end.state.is_ended() {
        return Err(RetestFromStoreError::NotEnded(
            run_id.to_string(),
            record.end.state.to_string(),
        ));
    }
    let original = record.start.plan.plan.ok_or_else(|| {
        RetestFromStoreError::Plan(
            run_id.to_string(),
            record.start.plan.unread.unwrap_or_default(),
        )
    })?;
    let records: Vec<_> = record.results.into_iter().map(|r| r.record).collect();
    let (mut plan, serials) = retest_plan(run_id, &original, &records, choice)?;
    let learned = crate::station_model::learn_from(
        store,
        &record.start.station,
        crate::station_model::DEFAULT_MODEL_RUNS,
    );
    // A target the station cannot reach keeps the original plan's: the
    // advice then says which instruments it cannot decide.
    let designed = match plan.designed(&learned.model) {
        Ok(d) => Some(d),
        Err(_) if plan.target_k2_u95_ug_per_g2 != original.target_k2_u95_ug_per_g2 => {
            plan.target_k2_u95_ug_per_g2 = original.target_k2_u95_ug_per_g2;
            plan.designed(&learned.model).ok()
        }
        Err(_) => None,
    };
    let predicted = designed
        .and_then(|d| d.prediction)
        .map(|p| p.k2_u95_ug_per_g2);
    let mut advice = spinbench_engine::retest::retest_advice(&records, predicted, plan.is_auto());
    // Each instrument's tries: the runs this one retests, one after the other.
    let mut earlier = record.start.retest_of.clone();
    for _ in 0..MAX_RETEST_CHAIN {
        let Some(id) = earlier.take() else { break };
        let results = store.results(&id)?;
        for a in &mut advice {
            let inconclusive = results.iter().any(|r| {
                r.serial == a.serial && r.outcome == spinbench_engine::Outcome::Inconclusive
            });
            a.inconclusive_runs += usize::from(inconclusive);
        }
        earlier = store.run_start(&id)?.and_then(|s| s.retest_of);
    }
    Ok(Retest {
        plan,
        serials,
        station_config: record.start.station_config,
        advice,
    })
}
