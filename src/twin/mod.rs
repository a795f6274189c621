//! The twin: what exists physically — the parts, the robot, the physics world, the controller,
//! the sensors and the cell that steps them together. Nothing here knows the paper's method; the
//! checks of its physics are in `crate::selfcheck`.

pub mod assembly;
pub mod control;
pub mod energy;
pub mod geometry;
pub mod physics;
pub mod real_cell;
pub mod robot;
pub mod sensing;
pub mod workcell;
