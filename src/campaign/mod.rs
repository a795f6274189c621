//! Campaigns: many trials of the method from a scenario file, their statistics, the paper's
//! figures, gain tuning and the regression gate.

pub mod bench;
pub mod calibrate;
pub mod check;
pub mod export;
pub mod journal;
pub mod records;
pub mod replays;
pub mod report;
pub mod run;
pub mod scenario;
pub mod sharing;
pub mod summary;
pub mod tune;
pub mod tuning;
pub mod usage;
