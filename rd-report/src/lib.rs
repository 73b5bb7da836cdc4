//! pwbench's library: reading `pwenc --report` files into rate-distortion curves, Bjøntegaard
//! deltas between curves, and reports with charts.

pub mod bjontegaard;
pub mod plot;
pub mod report;
pub mod runs;
pub mod sweep;
