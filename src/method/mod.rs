//! The paper's method (Section IV, Fig. 3), one file per stage: sample the reference manifold
//! ([`primitives`], [`manifold`]), observe ([`observe`], after [`search`] when starting above),
//! register ([`register`], Algorithm 1), insert ([`insert`]); [`trial`] runs them in order.
//! [`adaptive`] says when an observation that stops itself has seen enough.
//! Every stage drives the cell through a [`session::Session`], which lends it the real robot's
//! ports and nothing of the simulation's truth. [`env`] lends the cell to a learned
//! policy, step by step (the Python package's Gymnasium environment). [`request`] takes a trial's arguments as people
//! type them (the command line, the Python package).

pub mod adaptive;
pub mod config;
pub mod env;
pub mod insert;
pub mod manifold;
pub mod observe;
pub mod primitives;
pub mod register;
pub mod request;
pub mod search;
pub mod seeds;
pub mod session;
pub mod trace_mcap;
pub mod trial;
