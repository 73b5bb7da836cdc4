//! The pwgs stream (SPEC.md): what each section holds and how a decoder turns it back into
//! Gaussians. The container syntax itself lives in `pwgs-bitstream`.

pub mod entropy;
pub mod octree;
