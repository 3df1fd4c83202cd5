//! The mathematics of a centrifuge nonlinearity test, with no I/O.
//!
//! Every function here takes plain data and returns plain data, so the same
//! code reduces points from the live station, from the store and from a
//! spreadsheet of hand-recorded tests. Formula numbers such as `method.md (6)`
//! refer to `shared/docs/method.md`, the project's domain brief.
//!
//! The data flow of a reduction is:
//!
//! * [`temperature`] — temperature coefficients of k0, k1 and K2 (weighted lines);
//! * [`tumble`] — bias and scale factor from 1 g readings, method.md (5), and
//!   a multi-position tumble with input-axis misalignment;
//! * [`centrifuge`] and [`radius`] — applied acceleration from rate and
//!   radius (3)–(4), each instrument's own radius (6)–(9);
//! * [`model`] — the IEEE Std 1293 fit (2) per mounting and over the full
//!   signed range, with standard errors and Student-t intervals;
//! * [`joint`] — the two mountings together: K2 (even) and the odd part
//!   (Koq plus arm stretch), method.md (15);
//! * [`diagnostics`] — does the model fit: lack of fit against pure error,
//!   outlier levels, each level's influence on k2;
//! * [`inadequacy`] — the level random effect: the pure error, the
//!   between-level variance a misfit adds, the outlier-level test, and the
//!   same for the two mountings paired (K2);
//! * [`scale_factor`] — the scale-factor nonlinearity model (10)–(11);
//! * [`figures`] — asymmetry, nonlinearity, hysteresis, repeatability;
//! * [`compare`] — polynomial and non-polynomial model families side by side;
//! * [`exclusion`] — an engineer's exclusion of a level, with its reason,
//!   applied before the fits and reported beside them;
//! * [`design`] — the station's model learned from its runs, a plan's
//!   predicted K2 U95 and centrifuge time, and the plan that reaches a
//!   target in the least time;
//! * [`unit`] — all of the above for one instrument, and [`unit::analyze_dataset`]
//!   for a batch.
//!
//! Units live in names: `_g` is acceleration in units of local gravity,
//! `_ug_per_g2` is µg/g², `_m` metres, `_rad_s` radians per second. Outputs
//! (`output`) are in the instrument's own unit (Hz for a VBA); `k1` is in
//! output units per g.

pub mod centrifuge;
pub mod compare;
pub mod control;
pub mod design;
pub mod diagnostics;
mod error;
pub mod exclusion;
pub mod figures;
pub mod inadequacy;
pub mod joint;
pub mod lsq;
pub mod model;
pub mod points;
pub mod radius;
pub mod scale_factor;
pub mod statistics;
pub mod table_signature;
pub mod temperature;
pub mod tumble;
pub mod uncertainty;
pub mod unit;

pub use error::AnalysisError;
pub use model::{Coefficients, Ieee1293Fit, ModelOrder, MountingFit};
pub use points::{Direction, Mount, Point};
pub use unit::{
    AnalysisOptions, AnomalyRule, DatasetAnalysis, UnitAnalysis, UnitPoints, analyze_dataset,
};

/// Standard gravity, 9.80665 m/s² (the default `g_local`).
pub const STANDARD_GRAVITY_M_S2: f64 = 9.806_65;

/// One part per million, for converting ratios to ppm (`ratio * PPM`).
pub const PPM: f64 = 1e6;

/// Micro-g per g: a dimensionless coefficient times this is µg/gⁿ.
pub const UG_PER_G: f64 = 1e6;
