//! Per-instrument records (OpenHTF's "every unit under test gets its own
//! record with an outcome").

use serde::{Deserialize, Serialize};
use spinbench_analysis::unit::UnitAnalysis;
use spinbench_analysis::{Direction, Mount};
use std::collections::BTreeMap;

/// One averaged point of one instrument.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointRecord {
    /// Slot (0-based).
    pub slot: usize,
    /// Mounting.
    pub mount: Mount,
    /// Nominal level [g].
    pub g_nominal: f64,
    /// Ascending or descending.
    pub direction: Direction,
    /// Acceleration applied at this instrument's own radius, method.md (9) [g].
    pub g_applied: f64,
    /// Mean measured rate during the dwell [deg/s].
    pub rate_deg_s: f64,
    /// Mean dF [Hz].
    pub output_hz: f64,
    /// Standard deviation of the one-second values [Hz].
    pub std_hz: f64,
    /// Number of one-second values.
    pub n: u32,
    /// Station time of the first and last value [s].
    pub time_s: [f64; 2],
}

/// Pass, fail, marginal, or incomplete (never graded).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Within the limits.
    Pass,
    /// Within the limits but close to them.
    Marginal,
    /// Outside the limits, dead, noisy, or not measurable.
    Fail,
    /// The run ended (aborted, faulted) before this instrument's part of
    /// the plan was done: not graded, the reasons say why.
    Incomplete,
}

/// Everything the station found for one instrument.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UnitRecord {
    /// Slot (0-based).
    pub slot: usize,
    /// Serial number.
    pub serial: String,
    /// Tumble bias k0' [Hz] and scale factor k1' [Hz/g] (method.md (5)).
    pub tumble: Option<[f64; 2]>,
    /// Drawing radius R0 [m].
    pub drawing_radius_m: f64,
    /// Radius found per mounting [m].
    pub radius_m: BTreeMap<Mount, f64>,
    /// The averaged points.
    pub points: Vec<PointRecord>,
    /// The reduction (fits, figures), when it could be made.
    #[serde(skip_deserializing)]
    pub analysis: Option<UnitAnalysis>,
    /// The larger |k2| of the mountings [µg/g²].
    pub k2_max_ug_per_g2: Option<f64>,
    /// Pass, fail, marginal or incomplete.
    pub outcome: Outcome,
    /// Why, when not a plain pass.
    pub reasons: Vec<String>,
}
