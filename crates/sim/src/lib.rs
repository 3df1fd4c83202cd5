//! The virtual bench: a simulated centrifuge, VBA instruments, counter
//! modules (FMUs) and power supplies that speak exactly the bytes the real
//! hardware speaks, with known truth and fault injection.
//!
//! * [`config`] — the bench's TOML configuration (every key defaulted);
//! * [`realism`] — the presets `ideal`, `typical` and `harsh` the config
//!   starts from (the error sources of precision centrifuge testing);
//! * [`vba`], [`table`], [`counter`], [`supply`] — the physics and the
//!   devices, each a small deterministic model;
//! * [`world`] — the whole bench as one state machine advanced in 2.5 ms
//!   ticks: the same seed and the same commands give the same bytes;
//! * [`serve`] — the bench behind real pseudo-terminals and TCP sockets,
//!   paced in real time, N× faster, or as fast as the station reads.

pub mod chamber;
pub mod config;
pub mod counter;
pub mod realism;
pub mod serve;
pub mod station;
pub mod supply;
pub mod table;
pub mod vba;
pub mod world;

pub use config::SimConfig;
pub use realism::Realism;
pub use vba::Mounting;
pub use world::{SupplyId, Truth, World};
