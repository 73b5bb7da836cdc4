//! The anchor base's encoder side (docs/architecture.md section 1.1): the initial model from a
//! point cloud ([`init`]), training for pixels ([`train`]) with anchors grown and pruned
//! ([`growth`]) and the stream content of a trained
//! model ([`quantize`]), with its networks' steps chosen after training ([`network_steps`]) and, for a byte budget, its
//! least important anchors dropped ([`trim`]). The model itself, and how it turns into each view's Gaussians, is the
//! decoder's [`pwgs_codec::anchor`].

pub mod context;
pub mod growth;
mod host;
pub mod init;
pub mod network_steps;
pub mod quantize;
pub mod rate;
pub mod train;
pub mod trim;
