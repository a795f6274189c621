//! pegtwin: a digital twin for robotic peg-in-hole assembly of complex parts by contact-manifold
//! pose estimation (Negi et al.). See README.md for the pipeline and the commands.

pub mod campaign;
pub mod cell;
pub mod check;
pub mod cli;
pub mod control;
pub mod diagnostics;
pub mod error;
pub mod geometry;
pub mod manifold;
pub mod pose;
pub mod primitives;
pub mod registration;
pub mod report;
pub mod robot;
pub mod scenario;
pub mod sensing;
pub mod sim;
pub mod trial;
pub mod tune;
pub mod validate;
