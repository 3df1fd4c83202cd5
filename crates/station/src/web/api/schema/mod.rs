//! The API's bodies as types: every request a handler
//! parses and every JSON answer it sends is one of these, and the OpenAPI
//! document's schemas are derived from the same types (utoipa), so the
//! document cannot say one thing while the server does another. The
//! engine's own records inside an answer (a board slot, a wording, the
//! plan's prediction) are documented by types of [`live`] that the web
//! tests hold to what is sent.
//!
//! One room per surface: [`station`] (the session, status, plans and the
//! shared names), [`live`], [`runs`], [`charts`] and [`admin`].

mod admin;
mod charts;
mod live;
mod runs;
mod station;

pub use admin::*;
pub use charts::*;
pub use live::*;
pub use runs::*;
pub use station::*;
