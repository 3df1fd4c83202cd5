//! The batch report: every instrument test of many runs together — the
//! distributions of k2 and the scale-factor figures (histogram, mean, σ),
//! outliers, and the repeatability of serial numbers tested more than once.

mod render;
mod stats;
mod tables;
#[cfg(test)]
mod tests;

pub(crate) use render::batch_xlsx;
pub use render::{batch_csv, batch_html, batch_html_in};
use stats::distribution;
pub(crate) use tables::{
    OUTLIER_HEADERS, REPEAT_HEADERS, STATISTICS_HEADERS, TEST_HEADERS, draw_histogram,
    outlier_rows, repeat_rows, statistics_rows, test_rows,
};
use tables::{histogram_svg, test_numbers};

use crate::{ReportError, esc, fmt, unix_date};
use plotters::coord::Shift;
use plotters::prelude::*;
use spinbench_analysis::UnitAnalysis;
use spinbench_analysis::unit::repeatability_of;
use spinbench_engine::Outcome;
use spinbench_store::{ResultRow, RunRow, Store};
use std::collections::BTreeMap;

/// One instrument test (one unit of one run).
#[derive(Debug, Clone, PartialEq)]
pub struct BatchTest {
    /// Run identifier.
    pub run_id: String,
    /// When the run started [Unix s].
    pub started_at: i64,
    /// Serial number.
    pub serial: String,
    /// Slot (0-based): the fixture position.
    pub slot: usize,
    /// The radius found per mounting [m].
    pub radius_m: BTreeMap<spinbench_analysis::Mount, f64>,
    /// Pass, marginal, fail or incomplete.
    pub outcome: Outcome,
    /// k2_max [µg/g²].
    pub k2_max_ug_per_g2: Option<f64>,
    /// k2 of the full-range IEEE 1293 fit (signed input) [µg/g²].
    pub k2_ug_per_g2: Option<f64>,
    /// K1 of the full-range fit [Hz/g].
    pub k1_hz_per_g: Option<f64>,
    /// Scale-factor nonlinearity: largest residual of (11) [ppm].
    pub sf_nonlinearity_ppm: Option<f64>,
    /// Asymmetry [ppm].
    pub asymmetry_ppm: Option<f64>,
    /// The whole reduction of the test, when it was made.
    pub analysis: Option<UnitAnalysis>,
    /// Its temperature coefficients, when the plan had temperatures.
    pub temperature_coefficients: Option<spinbench_analysis::temperature::TemperatureCoefficients>,
}

/// The figures whose distributions the batch report shows: (name, unit, value).
type Figure = (&'static str, &'static str, fn(&BatchTest) -> Option<f64>);
const FIGURES: [Figure; 8] = [
    ("k2", "µg/g²", |t| t.k2_ug_per_g2),
    ("k2_max", "µg/g²", |t| t.k2_max_ug_per_g2),
    ("K1", "Hz/g", |t| t.k1_hz_per_g),
    ("SF nonlinearity", "ppm", |t| t.sf_nonlinearity_ppm),
    ("asymmetry", "ppm", |t| t.asymmetry_ppm),
    // Only batches tested at several temperatures have these.
    ("k0 temperature coefficient", "µg/°C", |t| {
        t.temperature_coefficients.map(|c| c.k0_ug_per_c)
    }),
    ("k1 temperature coefficient", "ppm/°C", |t| {
        t.temperature_coefficients.map(|c| c.k1_ppm_per_c)
    }),
    ("K2 temperature coefficient", "µg/g²/°C", |t| {
        t.temperature_coefficients
            .and_then(|c| c.k2_ug_per_g2_per_c)
    }),
];

/// An outlying test of one figure.
#[derive(Debug, Clone, PartialEq)]
pub struct Outlier {
    /// Serial number.
    pub serial: String,
    /// Run identifier.
    pub run_id: String,
    /// The value.
    pub value: f64,
    /// Robust z-score 0.6745·(x − median)/MAD (Iglewicz–Hoaglin; |z| > 3.5 is an outlier).
    pub robust_z: f64,
}

/// The distribution of one figure over the batch.
#[derive(Debug, Clone, PartialEq)]
pub struct Distribution {
    /// Figure name.
    pub name: &'static str,
    /// Unit.
    pub unit: &'static str,
    /// Number of tests with a value.
    pub n: usize,
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation (n − 1).
    pub std: f64,
    /// Smallest value.
    pub min: f64,
    /// Median.
    pub median: f64,
    /// Largest value.
    pub max: f64,
    /// Histogram: (bin low edge, bin high edge, count).
    pub bins: Vec<(f64, f64, usize)>,
    /// Tests with |robust z| > 3.5.
    pub outliers: Vec<Outlier>,
    /// The values, in test order (for the plot).
    pub values: Vec<f64>,
}

/// A serial number tested in more than one run.
#[derive(Debug, Clone, PartialEq)]
pub struct Repeat {
    /// Serial number.
    pub serial: String,
    /// Number of tests.
    pub tests: usize,
    /// k2_max of each test, oldest first [µg/g²].
    pub k2_max_ug_per_g2: Vec<f64>,
    /// Largest − smallest k2_max [µg/g²].
    pub k2_max_spread: Option<f64>,
    /// Scale-factor repeatability of K1 (method.md §3.4) [ppm].
    pub k1_repeatability_ppm: Option<f64>,
}

/// Everything the batch report shows.
#[derive(Debug, Clone, PartialEq)]
pub struct BatchReport {
    /// The runs, oldest first.
    pub runs: Vec<RunRow>,
    /// Every instrument test, in run order then slot order.
    pub tests: Vec<BatchTest>,
    /// One distribution per figure.
    pub distributions: Vec<Distribution>,
    /// Serial numbers tested more than once.
    pub repeats: Vec<Repeat>,
    /// Control charts and first-pass yields ([`BatchReport::rebaseline`]
    /// chooses their baseline; the first [`crate::control::DEFAULT_BASELINE_RUNS`] runs by default).
    pub control: crate::control::ControlReport,
}

impl BatchReport {
    /// Limits of the control charts from the first `runs` runs instead.
    pub fn rebaseline(&mut self, runs: usize) {
        self.control = crate::control::control_report(self, runs);
    }

    /// How many tests had each outcome: (pass, marginal, fail).
    pub fn outcomes(&self) -> (usize, usize, usize) {
        let count = |o: Outcome| self.tests.iter().filter(|t| t.outcome == o).count();
        (
            count(Outcome::Pass),
            count(Outcome::Marginal),
            count(Outcome::Fail),
        )
    }

    /// Tests whose run ended before they were measured whole (never graded).
    pub fn incomplete(&self) -> usize {
        self.tests
            .iter()
            .filter(|t| t.outcome == Outcome::Incomplete)
            .count()
    }

    /// ", N incomplete" when there are any, for the totals line.
    pub fn incomplete_note(&self) -> String {
        self.incomplete_note_in(crate::Lang::En)
    }

    /// [`BatchReport::incomplete_note`] in `lang`.
    pub fn incomplete_note_in(&self, lang: crate::Lang) -> String {
        let inconclusive = self
            .tests
            .iter()
            .filter(|t| t.outcome == Outcome::Inconclusive)
            .count();
        let mut note = match inconclusive {
            0 => String::new(),
            n => rust_i18n::t!("batch.inconclusive", n = n, locale = lang.code()).into_owned(),
        };
        if let n @ 1.. = self.incomplete() {
            note.push_str(&rust_i18n::t!(
                "batch.incomplete",
                n = n,
                locale = lang.code()
            ));
        }
        note
    }
}

/// Read the batch from the store: the runs named, or every run when none is.
pub fn gather_batch(store: &Store, run_ids: &[String]) -> Result<BatchReport, ReportError> {
    let mut runs = Vec::new();
    if run_ids.is_empty() {
        runs = store.runs()?;
    } else {
        for id in run_ids {
            runs.push(
                store
                    .run(id)?
                    .ok_or_else(|| ReportError::NoRun(id.clone()))?,
            );
        }
    }
    let mut results = Vec::new();
    for run in &runs {
        results.extend(store.results(&run.id)?);
    }
    Ok(batch_of(runs, results))
}

/// The batch of `station`'s newest `runs` runs (the control charts'
/// window), read in two statements whatever the store's history.
pub fn newest_batch(store: &Store, station: &str, runs: usize) -> Result<BatchReport, ReportError> {
    let (runs, results) = store.newest_runs_with_results(station, runs)?;
    Ok(batch_of(runs, results))
}

/// The batch of `runs` and their `results` (no store read).
pub fn batch_of(mut runs: Vec<RunRow>, results: Vec<ResultRow>) -> BatchReport {
    runs.sort_by(|a, b| a.started_at.cmp(&b.started_at).then(a.id.cmp(&b.id)));
    let started: BTreeMap<&str, i64> = runs.iter().map(|r| (r.id.as_str(), r.started_at)).collect();
    let mut results: Vec<(i64, ResultRow)> = results
        .into_iter()
        .filter_map(|r| started.get(r.run_id.as_str()).map(|t| (*t, r)))
        .collect();
    results.sort_by(|(ta, a), (tb, b)| {
        ta.cmp(tb)
            .then(a.run_id.cmp(&b.run_id))
            .then(a.slot.cmp(&b.slot))
    });
    let mut tests = Vec::new();
    {
        for (started_at, r) in results {
            let temperature_coefficients = r.record.temperature_coefficients;
            let a = r.record.analysis;
            tests.push(BatchTest {
                run_id: r.run_id,
                started_at,
                serial: r.serial,
                slot: r.record.slot,
                radius_m: r.record.radius_m.clone(),
                outcome: r.outcome,
                k2_max_ug_per_g2: r.k2_max_ug_per_g2,
                k2_ug_per_g2: a
                    .as_ref()
                    .and_then(|a| a.full_range.as_ref())
                    .and_then(|f| f.fit.k2_ug_per_g2),
                k1_hz_per_g: a
                    .as_ref()
                    .and_then(|a| a.full_range.as_ref())
                    .map(|f| f.fit.k1),
                sf_nonlinearity_ppm: a
                    .as_ref()
                    .and_then(|a| a.scale_factor.as_ref())
                    .map(|s| s.residual_max_ppm),
                asymmetry_ppm: a.as_ref().and_then(|a| a.figures.asymmetry_ppm),
                analysis: a,
                temperature_coefficients,
            });
        }
    }
    // An incomplete test (its run aborted or faulted before it was measured
    // whole) is listed, but its partial figures enter no statistics.
    let measured: Vec<BatchTest> = tests
        .iter()
        .filter(|t| t.outcome != Outcome::Incomplete)
        .cloned()
        .collect();
    let distributions = FIGURES
        .iter()
        .filter_map(|(name, unit, value)| distribution(name, unit, &measured, *value))
        .collect();
    let mut by_serial: BTreeMap<&str, Vec<&BatchTest>> = BTreeMap::new();
    for t in &measured {
        by_serial.entry(&t.serial).or_default().push(t);
    }
    let repeats = by_serial
        .into_iter()
        .filter(|(_, ts)| ts.len() > 1)
        .map(|(serial, ts)| {
            let k2: Vec<f64> = ts.iter().filter_map(|t| t.k2_max_ug_per_g2).collect();
            Repeat {
                serial: serial.to_string(),
                tests: ts.len(),
                k2_max_spread: (k2.len() > 1).then(|| {
                    k2.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                        - k2.iter().copied().fold(f64::INFINITY, f64::min)
                }),
                k2_max_ug_per_g2: k2,
                // The one definition, as `analyze` and `spinbench unit` give it.
                k1_repeatability_ppm: repeatability_of(
                    &ts.iter()
                        .filter_map(|t| t.analysis.as_ref())
                        .collect::<Vec<_>>(),
                )
                .map(|r| r.scale_factor_ppm),
            }
        })
        .collect();
    let mut report = BatchReport {
        runs,
        tests,
        distributions,
        repeats,
        control: crate::control::ControlReport::default(),
    };
    report.rebaseline(crate::control::DEFAULT_BASELINE_RUNS);
    report
}
