//! Each slot's instrument as the run knows it: its tumble readings and
//! calibration, its radii, its points and why it failed, if it did.

use crate::record::{PointRecord, Reason};
use spinbench_analysis::Mount;
use spinbench_analysis::tumble::{CrossAxisSensitivity, MeanReading, TumbleCalibration};
use std::collections::BTreeMap;

/// One slot's instrument during the run.
#[derive(Debug, Clone, Default)]
pub(super) struct UnitState {
    /// The tumble's reading with the input axis up.
    pub(super) up: Option<MeanReading>,
    /// The tumble's reading with the input axis down.
    pub(super) down: Option<MeanReading>,
    /// Bias and scale factor from the tumble.
    pub(super) cal: Option<TumbleCalibration>,
    /// The four-position tumble's extra readings: [as on the arm, inverted].
    pub(super) crosswise: [Option<MeanReading>; 2],
    /// The cross-axis sensitivity, once both cross positions are read.
    pub(super) cross_axis: Option<CrossAxisSensitivity>,
    /// The effective radius found per mounting [m].
    pub(super) radius: BTreeMap<Mount, f64>,
    /// Each radius's relative standard uncertainty from its readings [ppm].
    pub(super) radius_reading_u_ppm: BTreeMap<Mount, f64>,
    /// The levels measured so far.
    pub(super) points: Vec<PointRecord>,
    /// Why the instrument dropped out of the run, if it did.
    pub(super) failed: Option<Reason>,
}

impl UnitState {
    /// The cross-axis sensitivity once the tumble and both cross positions
    /// are read (nothing until then).
    pub(super) fn find_cross_axis(&mut self) -> Result<(), spinbench_analysis::AnalysisError> {
        if let (Some(cal), [Some(on_arm), Some(inverted)]) = (self.cal, self.crosswise) {
            self.cross_axis = Some(CrossAxisSensitivity::from_readings(&cal, on_arm, inverted)?);
        }
        Ok(())
    }
}
