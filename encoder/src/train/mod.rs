//! What both bases' training shares: the rasterizer as a Burn operation with its analytic
//! backward pass ([`splat_op`], [`backward`]), the trainable Gaussians as tensors ([`params`]),
//! Adam with per-parameter rates ([`adam`]), the training views' images on the device within a
//! budget ([`views`]), and the allocator setting training runs under ([`heap`]).

pub mod adam;
pub mod backward;
pub mod device;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod heap;
pub mod params;
pub mod splat_op;
pub mod views;
