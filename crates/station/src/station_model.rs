//! The station's model of itself ([`spinbench_analysis::design`]), learned
//! from its own completed runs in the store: the instruments' noise, the
//! table's settle time and the between-level scatter of K2. The store keeps
//! the runs, so the model is always the one their records give; a station
//! with no history (or a store it cannot read) uses the defaults and says so.

use spinbench_analysis::design::StationModel;
use spinbench_store::{Store, StoreTarget, StoredState};

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
        .filter(|r| r.station == station && r.state == StoredState::Completed)
        .take(runs.min(MAX_MODEL_RUNS))
    {
        let plan = store
            .run_start(&run.id)
            .ok()
            .flatten()
            .and_then(|start| start.plan.plan);
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

/// What the station's past runs on this centrifuge measured of its
/// signature (docs/method.md §6): the newest `runs` completed runs of
/// station `config.station` on the same table ([`same_table`]: another arm
/// or centrifuge, or a raised `arm.signature_epoch`, forgets them), each
/// run's own signature pooled. `None` with none, or a
/// store that cannot be read (the run then learns alone).
pub fn table_prior(
    target: &StoreTarget,
    config: &spinbench_engine::StationConfig,
    runs: usize,
) -> Option<spinbench_analysis::table_signature::Prior> {
    if let StoreTarget::File(path) = target
        && !path.exists()
    {
        return None;
    }
    let store = Store::open_read_only(target).ok()?;
    let past: Vec<_> = signatures_on_table(&store, config)
        .take(runs.min(MAX_MODEL_RUNS))
        .map(|(_, signature)| signature)
        .collect();
    spinbench_analysis::table_signature::Prior::of(&past)
}

/// The signatures the station's completed runs on the table `config`
/// describes learned, newest first, with each run's id.
fn signatures_on_table<'a>(
    store: &'a Store,
    config: &'a spinbench_engine::StationConfig,
) -> impl Iterator<Item = (String, spinbench_analysis::table_signature::TableSignature)> + 'a {
    store
        .runs()
        .unwrap_or_default()
        .into_iter()
        .filter(move |r| r.station == config.station && r.state == StoredState::Completed)
        .filter(move |r| {
            store
                .run_start(&r.id)
                .ok()
                .flatten()
                .and_then(|start| start.station_config)
                .and_then(|text| spinbench_engine::StationConfig::from_toml(&text).ok())
                .is_some_and(|then| same_table(&then, config))
        })
        .filter_map(move |r| {
            let signature = store
                .results(&r.id)
                .ok()?
                .into_iter()
                .find_map(|res| res.record.table_signature)?;
            Some((r.id, signature))
        })
}

/// The newest signature of the table `config` describes in `store` (its
/// newest completed run on that table that learned one, which pooled the
/// runs before it), with the run's id.
pub fn latest_signature(
    store: &Store,
    config: &spinbench_engine::StationConfig,
) -> Option<(String, spinbench_analysis::table_signature::TableSignature)> {
    signatures_on_table(store, config).next()
}

/// Whether two station configs describe the same table: the same `[arm]`
/// (its radii, rating, stretch and `signature_epoch`) and the same
/// centrifuge (its name and rate limit); how it is reached (its port, its
/// command language, its deadlines) is not the table.
pub fn same_table(
    a: &spinbench_engine::StationConfig,
    b: &spinbench_engine::StationConfig,
) -> bool {
    a.arm == b.arm
        && a.centrifuge.name == b.centrifuge.name
        && a.centrifuge.max_rate_deg_s().ok() == b.centrifuge.max_rate_deg_s().ok()
}

#[cfg(test)]
mod table_tests {
    use super::same_table;
    use spinbench_engine::StationConfig;

    const SHIPPED: &str = include_str!("../../../packaging/station.toml");

    #[test]
    fn the_table_is_its_arm_and_centrifuge_not_the_port_that_reaches_it() {
        let base = StationConfig::from_toml(SHIPPED).expect("the shipped config");
        let moved = SHIPPED.replace("usb-centrifuge-controller", "usb-another-port");
        assert_ne!(moved, SHIPPED);
        let moved = StationConfig::from_toml(&moved).expect("config");
        assert!(same_table(&base, &moved), "another port is the same table");
        let repaired = SHIPPED.replacen("[arm]\n", "[arm]\nsignature_epoch = 1\n", 1);
        assert_ne!(repaired, SHIPPED);
        let repaired = StationConfig::from_toml(&repaired).expect("config");
        assert!(
            !same_table(&base, &repaired),
            "a raised epoch forgets the table"
        );
    }
}
