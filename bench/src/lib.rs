//! pwbench's library: reading `pwenc --report` files into rate-distortion curves, Bjøntegaard
//! deltas between curves, and reports with charts (issue 17).

pub mod bjontegaard;
pub mod plot;
pub mod report;
pub mod runs;
pub mod sweep;
