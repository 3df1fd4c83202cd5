//! A compiled plan's steps, and the fixtures an operator is asked to mount.

use serde::{Deserialize, Serialize};
use spinbench_analysis::{Direction, Mount};

/// The instrument mounting an operator is asked for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Fixture {
    /// On the bench, input axis up.
    Up,
    /// On the bench, input axis down.
    Down,
    /// On the arm, mounting P or N.
    Arm(Mount),
    /// On the bench, input axis horizontal, with gravity along the cross
    /// axis that is vertical on the arm: as on the arm, or inverted.
    Crosswise {
        /// As on the arm (else upside down).
        as_on_arm: bool,
    },
}

impl Fixture {
    /// Its code, as the catalogue's `arg.fixture.<code>` words it
    /// (`tumble_up`, `arm_p`, `crosswise_as_on_arm`, …).
    pub fn code(self) -> &'static str {
        match self {
            Fixture::Up => "tumble_up",
            Fixture::Down => "tumble_down",
            Fixture::Arm(Mount::P) => "arm_p",
            Fixture::Arm(Mount::N) => "arm_n",
            Fixture::Crosswise { as_on_arm: true } => "crosswise_as_on_arm",
            Fixture::Crosswise { as_on_arm: false } => "crosswise_inverted",
        }
    }
}

/// One step of a compiled plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Step {
    /// Switch the supplies and relays on, start streaming.
    PowerOn,
    /// Check each instrument draws current and its resonators are in range.
    CheckAlive,
    /// Wait for the instruments to warm up.
    WarmUp {
        /// Seconds of station time.
        seconds: f64,
    },
    /// Ask the operator to mount the instruments (per slot; `None` = leave).
    Mount {
        /// Requested fixture per slot.
        fixtures: Vec<Option<Fixture>>,
    },
    /// Record the 1 g outputs with the input axis up or down (method.md (5)).
    Tumble {
        /// Up (+1 g) or down (−1 g).
        up: bool,
    },
    /// Bring the chamber to a temperature and wait until it and the
    /// instruments have soaked (`[soak]`).
    Soak {
        /// Chamber setpoint [°C].
        setpoint_c: f64,
    },
    /// Record the output with the input axis horizontal and gravity along
    /// the cross axis that is vertical on the arm (four-position tumble).
    CrossTumble {
        /// As on the arm (else inverted).
        as_on_arm: bool,
    },
    /// Spin to 1 g at R0 and find each instrument's radius (method.md (6)–(8)).
    Radius {
        /// Pass number.
        pass: usize,
    },
    /// Take one averaged point at a level.
    Level {
        /// Pass number.
        pass: usize,
        /// Nominal level [g] at the drawing radius.
        g_nominal: f64,
        /// Ascending or descending.
        direction: Direction,
    },
    /// One round of measuring until the verdict is certain (the plan's
    /// `[sequential]`): a level chosen by the data for the pass's
    /// undecided instruments, or nothing when none is left.
    Decide {
        /// Pass number.
        pass: usize,
        /// The round, from 0 (at most `max_levels_per_pass` per pass).
        round: usize,
    },
    /// Controlled stop of the centrifuge.
    Stop,
}

impl Step {
    /// The pass whose instruments this step measures (a radius, a level,
    /// a round of deciding); `None` for the steps of every instrument or none.
    pub fn measured_pass(&self) -> Option<usize> {
        match self {
            Step::Radius { pass } | Step::Level { pass, .. } | Step::Decide { pass, .. } => {
                Some(*pass)
            }
            _ => None,
        }
    }
}
