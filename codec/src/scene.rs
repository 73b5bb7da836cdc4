//! A decoded scene, whatever its base: what tools render, hash and export go through here, so
//! that a second kind of base adds a variant of [`Base`] rather than a `match` in every tool
//! (rendering one: `pwgs_render::show`).
//!
//! The plain base is one set of Gaussians for every view; the anchor base derives its
//! Gaussians from anchors for each camera; [`Scene::gaussians_for`] and
//! [`Scene::attribute_hash`] are the two questions every tool asks of either.

use std::borrow::Cow;

use crate::anchor::AnchorModel;
use crate::stream::attribute_hash;
use crate::wrapper::WrapperView;
use crate::wrapper::synthesis::SynthesisWeights;
use pwgs_core::camera::Camera;
use pwgs_core::frame::SceneFrame;
use pwgs_core::gaussians::Gaussians;

/// The representation a stream's base reconstructs.
#[derive(Debug, Clone, PartialEq)]
pub enum Base {
    /// Plain 3DGS: the same Gaussians for every camera.
    Plain(Gaussians),
    /// Anchors whose MLPs derive each view's Gaussians.
    Anchors(Box<AnchorModel>),
}

/// A base, the perceptual wrapper when the stream has one, and what rendering needs of the
/// stream's header.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    pub base: Base,
    /// The synthesis network's dequantized weights.
    pub wrapper: Option<SynthesisWeights>,
    /// The frame the wrapper's Plücker embeddings are expressed in.
    pub frame: SceneFrame,
    pub background: [f32; 3],
}

impl Scene {
    /// The Gaussians that render `camera`'s view.
    pub fn gaussians_for(&self, camera: &Camera) -> Cow<'_, Gaussians> {
        match &self.base {
            Base::Plain(g) => Cow::Borrowed(g),
            Base::Anchors(model) => Cow::Owned(model.gaussians_for(camera)),
        }
    }

    /// The base's Gaussians when they do not depend on the view (the plain base): what a PLY
    /// export or a re-encoding takes.
    pub fn plain_gaussians(&self) -> Option<&Gaussians> {
        match &self.base {
            Base::Plain(g) => Some(g),
            Base::Anchors(_) => None,
        }
    }

    /// How many Gaussians the base holds (for an anchor base: per view, at most).
    pub fn gaussian_count(&self) -> usize {
        match &self.base {
            Base::Plain(g) => g.len(),
            Base::Anchors(model) => model.len() * model.offsets_per_anchor,
        }
    }

    /// SHA-256 of the normative reconstruction (the plain base's Gaussians, or the anchors and
    /// their MLPs): two decoders agree when their hashes do (SPEC.md section 7).
    pub fn attribute_hash(&self) -> String {
        match &self.base {
            Base::Plain(g) => attribute_hash(g),
            Base::Anchors(model) => model.hash(),
        }
    }

    /// The wrapper with the scene's frame, if the stream has one.
    pub fn wrapper_view(&self) -> Option<WrapperView<'_>> {
        self.wrapper.as_ref().map(|weights| WrapperView { weights, frame: self.frame })
    }
}
