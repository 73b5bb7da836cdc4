//! The pwgs encoder library: initialization, the rasterizer's backward pass, training and
//! metrics. Scene loading lives in the `pwgs-dataset` crate beside it, rendering and everything
//! normative in `pwgs-decoder`.

pub mod backward;
pub mod init;
pub mod metrics;
pub mod preview;
pub mod splat_op;
