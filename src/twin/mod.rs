//! The twin: what exists physically.

pub mod cell;
pub mod control;
pub mod diagnostics;
pub mod geometry;
pub mod physics;
pub mod robot;
pub mod sensing;
pub mod validate;
