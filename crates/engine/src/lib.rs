//! The middle layer: everything between the drivers and the operator.
//!
//! * [`bench`] — the hardware of a station as the engine sees it (device traits);
//! * [`abort`] — the abort request a run watches, with who or what asked;
//! * [`bounds`] — the named bounds every number from outside is checked against;
//! * [`config`] — the station config (TOML), validated with errors that name the key;
//! * [`plan`] — test plans (TOML) compiled into a list of steps (a plan is
//!   data), refused before anything moves if any level exceeds a limit;
//! * [`executor`] — the one executor: stability, safety, per-instrument
//!   records, an explicit table of run states;
//! * [`event`] — the typed event stream the CLI, journal, store and UI subscribe to;
//! * [`judgement`] — an instrument's points reduced and graded against the
//!   plan's limits, at the end of a run and after an exclusion;
//! * [`journal`] — the append-only, flushed journal, and reading it back for resume;
//! * [`planning`] — a plan's prediction against what its run achieved, and
//!   the readings of past runs the station's model learns from;
//! * [`record`] — per-instrument records with an outcome;

pub mod abort;
pub mod bench;
pub mod board;
pub mod bounds;
pub mod config;
pub mod event;
pub mod executor;
pub mod journal;
pub mod judgement;
pub mod plan;
pub mod planning;
pub mod record;
pub mod retest;
pub mod soak;
pub mod time_zone;

pub use abort::AbortFlag;
pub use config::StationConfig;
pub use event::{DeviceRole, Event, EventSink, RunState};
pub use executor::{Answer, Bench, EngineError, Executor, Operator, RunOptions, RunSummary};
pub use plan::{CompiledPlan, Fixture, TestPlan};
pub use record::{Judged, Outcome, PointRecord, Reason, ReasonCode, UnitRecord};
