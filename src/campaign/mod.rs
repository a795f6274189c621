//! Campaigns.

pub mod check;
pub mod report;
pub mod run;
pub mod scenario;
pub mod summary;
pub mod tune;
