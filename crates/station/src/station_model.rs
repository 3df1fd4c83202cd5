//! The station's model of itself ([`spinbench_analysis::design`]), learned
//! from its own completed runs in the store: the instruments' noise, the
//! table's settle time and the between-level scatter of K2. The store keeps
//! the runs, so the model is always the one their records give; a station
//! with no history (or a store it cannot read) uses the defaults and says so.

use spinbench_analysis::design::StationModel;
use spinbench_store::{Store, StoreTarget};

/// Runs the model learns from unless told otherwise (the newest completed ones).
pub const DEFAULT_MODEL_RUNS: usize = 10;
/// Most runs the model learns from (`--runs`).
pub const MAX_MODEL_RUNS: usize = 200;

/// The model, and where it came from (one line for the operator).
pub struct Learned {
    /// The model.
    pub model: StationModel,
    /// Where it came from.
    pub source: String,
}

/// Learn the model of station `station` from its newest `runs` completed
/// runs in `target`; the defaults when there are none or the store cannot
/// be read (the reason in `source`).
pub fn learn(target: &StoreTarget, station: &str, runs: usize) -> Learned {
    let defaults = |why: String| Learned {
        model: StationModel::default(),
        source: format!("{why}: the defaults of a station with no history"),
    };
    if let StoreTarget::File(path) = target
        && !path.exists()
    {
        return defaults(format!("no store yet at {}", path.display()));
    }
    match Store::open_read_only(target) {
        Ok(store) => learn_from(&store, station, runs),
        Err(e) => defaults(format!("the store cannot be read ({e})")),
    }
}

/// [`learn`] from an open store.
pub fn learn_from(store: &Store, station: &str, runs: usize) -> Learned {
    let defaults = |why: String| Learned {
        model: StationModel::default(),
        source: format!("{why}: the defaults of a station with no history"),
    };
    let listed = match store.runs() {
        Ok(r) => r,
        Err(e) => return defaults(format!("the runs cannot be listed ({e})")),
    };
    let mut records = Vec::new();
    let mut at_rest = Vec::new();
    for run in listed
        .iter()
        .filter(|r| r.station == station && r.state == "completed")
        .take(runs.min(MAX_MODEL_RUNS))
    {
        let plan =
            store.run_context(&run.id).ok().flatten().and_then(|c| {
                serde_json::from_str::<spinbench_engine::TestPlan>(&c.plan_json).ok()
            });
        if let (Some(plan), Ok(results)) = (plan, store.results(&run.id)) {
            let records_of_run: Vec<_> = results.into_iter().map(|r| r.record).collect();
            // The one-second values at rest, per instrument (its noise's Allan deviation).
            if let Ok(values) = store.values(&run.id) {
                // The run's values by slot, once (they come by time, then slot).
                let mut by_slot: std::collections::BTreeMap<i64, Vec<(f64, f64, Option<f64>)>> =
                    Default::default();
                for v in values {
                    by_slot
                        .entry(v.slot)
                        .or_default()
                        .push((v.t_s, v.rate_deg_s, v.output_hz));
                }
                for record in &records_of_run {
                    let own = by_slot
                        .get(&(record.slot as i64))
                        .map_or(&[][..], Vec::as_slice);
                    let series = spinbench_engine::planning::at_rest_ug(record, own);
                    if !series.is_empty() {
                        at_rest.push(series);
                    }
                }
            }
            records.push((plan, records_of_run));
        }
    }
    match spinbench_engine::planning::learn(&records, &at_rest) {
        Some(model) if model.runs > 0 => Learned {
            source: format!(
                "learned from {} completed run(s) of station '{station}' ({} instrument-runs; achieved over predicted {:.2})",
                model.runs, model.instruments, model.calibration
            ),
            model,
        },
        _ => defaults(format!(
            "no completed run of station '{station}' in the store"
        )),
    }
}
