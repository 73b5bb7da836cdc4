//! The normative part of pwgs: what a stream means, bit for bit. The container's sections, the
//! entropy coding, both bases' syntax and reconstruction (plain Gaussians; anchors, their
//! networks and context model), the perceptual wrapper's noise pyramid, Plücker embeddings and
//! network, and the portable math they use. The encoder calls these instead of re-implementing
//! them; renderers take what they reconstruct.
//!
//! The whole crate keeps to the determinism rule: no platform math (clippy.toml) outside its
//! tests, so that every machine decodes the same bits.
#![cfg_attr(not(test), deny(clippy::disallowed_methods))]

pub mod anchor;
pub mod context_grid;
pub mod hashing;
pub mod portable_math;
pub mod random_scene;
pub mod scene;
pub mod stream;
pub mod wrapper;
