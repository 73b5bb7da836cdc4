//! Plain 3DGS: initialization from points, training with adaptive density control, and turning
//! trained or imported Gaussians into a stream (quantization steps, importance classes, the step
//! search, colour and shape refits, the rotation frame, and the fidelity of the result).

pub mod colour_refit;
pub mod compress;
pub mod densify;
pub mod fidelity;
pub mod importance;
pub mod init;
pub mod rotation_frame;
pub mod shape_refit;
pub mod step_search;
pub mod train;
