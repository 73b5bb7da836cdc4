//! Rendering the Gaussians a stream reconstructs: the reference CPU rasterizer (forward; the
//! encoder differentiates it), a decoded scene shown through its wrapper, the export of an
//! anchor base as standard Gaussians, and the wgpu renderer (feature `gpu`).

pub mod anchor_export;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod raster;
pub mod show;
