use crate::points::Mount;

/// Why a reduction could not be made. Each variant says what the user can do.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AnalysisError {
    /// Fewer distinct acceleration levels than the model has coefficients.
    #[error(
        "{what} has {levels} distinct level(s); an order-{order} fit needs at least {needed} \
         (add levels or choose a lower order with --order)"
    )]
    TooFewLevels {
        /// What was being fitted, e.g. "mounting P".
        what: String,
        /// Distinct levels present.
        levels: usize,
        /// Distinct levels needed.
        needed: usize,
        /// Polynomial order requested.
        order: u8,
    },
    /// A value that must be finite was NaN or infinite.
    #[error("{what} is not a finite number ({value})")]
    NonFinite {
        /// Which quantity.
        what: String,
        /// The offending value.
        value: f64,
    },
    /// The output does not change with acceleration, so no scale factor exists.
    #[error(
        "{what}: the fitted scale factor is zero, the output does not follow the acceleration \
         (check that the output column holds the instrument output)"
    )]
    ZeroScaleFactor {
        /// What was being fitted.
        what: String,
    },
    /// The least-squares problem is singular even after scaling.
    #[error(
        "{what}: the design is singular (condition {condition:.3e}); the levels do not determine the model"
    )]
    Singular {
        /// What was being fitted.
        what: String,
        /// Ratio of largest to smallest singular value.
        condition: f64,
    },
    /// A parameter of the computation is out of its domain.
    #[error("{0}")]
    InvalidInput(String),
    /// A mounting the caller asked for has no points.
    #[error("no points in mounting {0}")]
    NoPoints(Mount),
}
