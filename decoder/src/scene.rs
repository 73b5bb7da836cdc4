//! A decoded scene, whatever its base: what tools render, hash and export go through here, so
//! that a second kind of base adds a variant of [`Base`] rather than a `match` in every tool.
//!
//! The plain base is one set of Gaussians for every view; the anchor base derives its
//! Gaussians from anchors for each camera; [`Scene::gaussians_for`] and
//! [`Scene::attribute_hash`] are the two questions every tool asks of either.

use std::borrow::Cow;

use crate::anchor::AnchorModel;
use crate::raster::{RenderOptions, render};
use crate::stream::attribute_hash;
use crate::wrapper::synthesis::SynthesisWeights;
use crate::wrapper::{WrapperView, apply};
use pwgs_core::camera::Camera;
use pwgs_core::frame::SceneFrame;
use pwgs_core::gaussians::Gaussians;
use pwgs_core::rgb_image::RgbImage;

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

/// A view as a decoder shows it.
#[derive(Debug, Clone, PartialEq)]
pub struct Shown {
    pub image: RgbImage,
    /// The wrapper's residual R (image = base render + R, clamped), [H, W, 3], when the
    /// wrapper was applied.
    pub residual: Option<Vec<f32>>,
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

    /// Render options with the scene's background.
    pub fn render_options(&self) -> RenderOptions {
        RenderOptions { background: self.background, ..Default::default() }
    }

    /// The base render of `camera`, without the wrapper.
    pub fn render_base(&self, camera: &Camera, options: &RenderOptions) -> RgbImage {
        render(&self.gaussians_for(camera), camera, options)
    }

    /// What a decoder shows for `camera`: the base render, through the wrapper when the stream
    /// has one and `wrapped` asks for it.
    pub fn render(&self, camera: &Camera, options: &RenderOptions, wrapped: bool) -> Shown {
        let base = self.render_base(camera, options);
        match self.wrapper_view().filter(|_| wrapped) {
            Some(w) => {
                let out = apply(w.weights, &base, camera, w.frame);
                Shown { image: out.image, residual: Some(out.residual) }
            }
            None => Shown { image: base, residual: None },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wrapper::synthesis::WrapperConfig;
    use pwgs_core::random::{SplitMix64, axis_camera, random_gaussians};

    #[test]
    fn a_scene_shows_its_base_through_its_wrapper() {
        let mut rng = SplitMix64(5);
        let g = random_gaussians(&mut rng, 40, 1, [-3.0, -1.5]);
        let config = WrapperConfig { width: 4, noise: true, plucker: true, seed: 11 };
        let values: Vec<f32> = (0..config.parameter_count()).map(|_| rng.uniform(-0.3, 0.3)).collect();
        let frame = SceneFrame { center: glam::Vec3::ZERO, scale: 1.0 };
        let plain = Scene { base: Base::Plain(g.clone()), wrapper: None, frame, background: [0.2, 0.3, 0.4] };
        let wrapped = Scene { wrapper: Some(SynthesisWeights::from_values(config, &values)), ..plain.clone() };
        let camera = axis_camera(24, 16, 20.0, 20.0, 12.0, 8.0);
        let options = plain.render_options();
        assert_eq!(options.background, [0.2, 0.3, 0.4]);
        let base = render(&g, &camera, &options);

        // Without a wrapper, or when not asked for, the base render is what is shown.
        assert_eq!(plain.render(&camera, &options, true), Shown { image: base.clone(), residual: None });
        assert_eq!(wrapped.render(&camera, &options, false), Shown { image: base.clone(), residual: None });
        // Through the wrapper: the base plus the residual, clamped.
        let shown = wrapped.render(&camera, &options, true);
        let residual = shown.residual.expect("the wrapper's residual");
        assert!(residual.iter().any(|&r| r != 0.0), "a random f changes the image");
        let expected: Vec<f32> = base.data.iter().zip(&residual).map(|(b, r)| (b + r).clamp(0.0, 1.0)).collect();
        assert_eq!(shown.image.data, expected);

        assert_eq!(plain.attribute_hash(), attribute_hash(&g));
        assert_eq!((plain.gaussian_count(), plain.plain_gaussians()), (40, Some(&g)));
    }
}
