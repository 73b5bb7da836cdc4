//! The anchor base's encoder side (DESIGN.md section 8, issue 15): the initial model from a
//! point cloud ([`init`]) and training for pixels ([`train`]). The model itself, and how it
//! turns into each view's Gaussians, is the decoder's [`pwgs_decoder::anchor`].

pub mod init;
pub mod train;
