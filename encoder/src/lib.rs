//! The pwgs encoder library: initialization, training and metrics. Scene loading lives in the
//! `pwgs-dataset` crate beside it, rendering and everything normative in `pwgs-decoder`.

pub mod init;
pub mod metrics;
pub mod preview;
