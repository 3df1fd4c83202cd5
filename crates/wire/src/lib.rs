//! The byte protocols of the station, with no I/O: pure functions and state
//! machines that turn bytes into typed messages and back.
//!
//! * [`fmu`] — the frequency-measurement unit (FMU) protocol of method.md
//!   §3.1: the frame codec ([`fmu::FrameDecoder`], [`fmu::FrameEncoder`]),
//!   typed payloads ([`fmu::Message`]), the one-second windows that turn
//!   400 ticks into one value per instrument ([`fmu::WindowAccumulator`]),
//!   and the check that a line can carry the configured stream
//!   ([`fmu::check_line_rate`]);
//! * [`scpi`] — SCPI-style command lines: parsing with abbreviations (the
//!   instrument side) and reply parsing (the driver side);
//! * [`centrifuge`] — controller dialects: ACUTROL, and a line dialect
//!   configured entirely in TOML;
//! * [`psu`] — SCPI commands of a programmable DC supply.
//!
//! Nothing here reads a clock, a port or a file; the `devices` crate moves
//! the bytes. Every decoder accepts arbitrary input without panicking.

pub mod centrifuge;
pub mod chamber;
pub mod fmu;
pub mod psu;
pub mod scpi;
