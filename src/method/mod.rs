//! The paper's method.

pub mod manifold;
pub mod primitives;
pub mod register;
pub mod trial;
