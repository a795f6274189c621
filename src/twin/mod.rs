//! The twin: what exists physically — the parts, the robot, the physics world, the controller,
//! the sensors and the cell that steps them together — and the checks of its physics. Nothing
//! here knows the paper's method.

pub mod assembly;
pub mod cell;
pub mod control;
pub mod diagnostics;
pub mod energy;
pub mod geometry;
pub mod physics;
pub mod robot;
pub mod sensing;
pub mod validate;
