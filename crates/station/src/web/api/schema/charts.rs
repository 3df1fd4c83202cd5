//! The bodies of the control charts, the yield and the centrifuge's
//! learned signature.

use serde::Serialize;
use utoipa::ToSchema;

/// One point of a control chart.
#[derive(Debug, Serialize, ToSchema)]
pub struct ChartPoint {
    /// Its run.
    pub run_id: String,
    /// Its serial (empty for a per-run figure).
    pub serial: String,
    /// Its value, in the chart's unit.
    pub value: f64,
}

/// A Western Electric rule broken.
#[derive(Debug, Serialize, ToSchema)]
pub struct ChartViolation {
    /// The point (1-based) that completes it.
    pub point: usize,
    /// Its run.
    pub run_id: String,
    /// Its run's label (`2026-11-24 · station 1 · #7`), as people name runs.
    pub run_label: String,
    /// The instrument of the point (empty on a radius chart).
    pub serial: String,
    /// The rule (`beyond3_sigma`, …).
    pub rule: String,
    /// The rule in words, in the user's language.
    pub says: String,
}

/// One control chart.
#[derive(Debug, Serialize, ToSchema)]
pub struct ChartReply {
    /// What it charts (`k2_max`, `radius slot 2 P`, …).
    pub quantity: String,
    /// Its unit.
    pub unit: String,
    /// The fixture position (slot), for a radius chart.
    pub slot: Option<usize>,
    /// Points that set its limits.
    pub baseline: usize,
    /// Centre line.
    pub centre: Option<f64>,
    /// σ̂ (from the mean moving range).
    pub sigma: Option<f64>,
    /// A rule is broken.
    pub flagged: bool,
    /// Its points, in time order.
    pub points: Vec<ChartPoint>,
    /// The rules broken.
    pub violations: Vec<ChartViolation>,
    /// The chart as SVG.
    pub svg: Option<String>,
}

/// First-pass yield of a run or a day.
#[derive(Debug, Serialize, ToSchema)]
pub struct YieldRow {
    /// The run or the day.
    pub label: String,
    /// Serials tested for the first time.
    pub first_tests: usize,
    /// Of those, passed.
    pub first_passes: usize,
    /// The fraction (none without first tests).
    #[serde(rename = "yield")]
    pub fraction: Option<f64>,
}

/// `GET /api/control-charts`.
#[derive(Debug, Serialize, ToSchema)]
pub struct ChartsReply {
    /// Limits from the first this many runs.
    pub baseline_runs: usize,
    /// Runs in the store.
    pub runs: usize,
    /// Every chart.
    pub charts: Vec<ChartReply>,
    /// First-pass yield per run.
    pub yield_by_run: Vec<YieldRow>,
    /// First-pass yield per day.
    pub yield_by_day: Vec<YieldRow>,
}

/// The centrifuge's signature the station has learned (docs/method.md §6).
#[derive(Debug, Serialize, ToSchema)]
pub struct SignatureReply {
    /// The run whose signature this is (none: nothing learned yet).
    pub run_id: Option<String>,
    /// The runs it rests on (0: nothing learned yet).
    pub runs: usize,
    /// The instruments of that run it rests on.
    pub instruments: usize,
    /// The sharp resonances, each at one level, corrected whole.
    pub spikes: Vec<SignatureSpike>,
    /// The levels at which that run found the table changed since the
    /// runs before it [g] (empty: no change; the earlier runs are set
    /// aside when not).
    pub changed_at_g: Vec<f64>,
    /// What it rests on and what it corrected, in the user's language.
    pub text: String,
    /// Its plot (SVG), when learned.
    pub svg: Option<String>,
}

/// A sharp resonance of the table.
#[derive(Debug, Serialize, ToSchema)]
pub struct SignatureSpike {
    /// The level [g].
    pub g: f64,
    /// Its error of the applied acceleration [µg].
    pub height_ug: f64,
}
