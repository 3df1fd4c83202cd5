//! The API's bodies as types: every request a handler
//! parses and every JSON answer it sends is one of these, and the OpenAPI
//! document's schemas are derived from the same types (utoipa), so the
//! document cannot say one thing while the server does another. Deep
//! records of the engine (a plan, an exclusion, a board slot) travel as
//! JSON objects, described as such.

//!
//! One room per surface: [`station`] (the session, status, plans and the
//! shared names), [`runs`], [`charts`] and [`admin`].

mod admin;
mod charts;
mod runs;
mod station;

pub use admin::*;
pub use charts::*;
pub use runs::*;
pub use station::*;
