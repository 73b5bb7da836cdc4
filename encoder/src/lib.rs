//! The pwgs encoder library: initialization, the rasterizer's backward pass and its Burn
//! operation, training, evaluation, metrics, and whole encoder runs (`session`). Scene loading lives in the `pwgs-dataset`
//! crate beside it, rendering and everything normative in `pwgs-decoder`.

pub mod anchor;
pub mod backward;
pub mod colour_refit;
pub mod compress;
pub mod evaluate;
pub mod exit;
pub mod fidelity;
pub mod heap;
pub mod importance;
pub mod init;
pub mod metrics;
pub mod rotation_frame;
pub mod session;
pub mod shape_refit;
pub mod size_fit;
pub mod splat_op;
pub mod step_search;
pub mod synthesis;
pub mod train;
