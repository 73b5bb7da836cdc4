//! The pwgs encoder library, in folders that mirror the method: [`plain`] (plain 3DGS: its
//! training and densification, and turning trained or imported Gaussians into a stream),
//! [`anchor`] (the anchor base), [`wrapper`] (the perceptual wrapper's synthesis network and
//! its training stage), [`train`] (what both bases' training shares: the rasterizer's backward
//! pass as a Burn operation, the parameters and Adam), [`metrics`] (image quality and
//! evaluation), and [`session`] (whole encoder runs). Scene loading lives in `pwgs-dataset`,
//! rendering in `pwgs-render`, everything normative in `pwgs-codec`.

pub mod anchor;
pub mod metrics;
pub mod plain;
pub mod session;
pub mod size_fit;
pub mod train;
pub mod wrapper;
