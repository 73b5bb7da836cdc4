//! What a decoder shows of a scene: its base rendered for a camera, through the perceptual
//! wrapper when the stream has one.

use pwgs_codec::scene::Scene;
use pwgs_codec::wrapper::apply;
use pwgs_core::camera::Camera;
use pwgs_core::rgb_image::RgbImage;

use crate::raster::tile_lists::TooMuchBlending;
use crate::raster::{RenderOptions, render_limited};

/// A view as a decoder shows it.
#[derive(Debug, Clone, PartialEq)]
pub struct Shown {
    pub image: RgbImage,
    /// The wrapper's residual R (image = base render + R, clamped), [H, W, 3], when the
    /// wrapper was applied.
    pub residual: Option<Vec<f32>>,
}

/// Rendering a decoded [`Scene`].
pub trait SceneRender {
    /// Render options with the scene's background.
    fn render_options(&self) -> RenderOptions;

    /// The base render of `camera`, without the wrapper; refused when the view needs more blend
    /// work than [`render_limited`] allows.
    fn render_base(&self, camera: &Camera, options: &RenderOptions) -> Result<RgbImage, TooMuchBlending>;

    /// What a decoder shows for `camera`: the base render, through the wrapper when the stream
    /// has one and `wrapped` asks for it.
    fn render(&self, camera: &Camera, options: &RenderOptions, wrapped: bool) -> Result<Shown, TooMuchBlending>;
}

impl SceneRender for Scene {
    fn render_options(&self) -> RenderOptions {
        RenderOptions { background: self.background, ..Default::default() }
    }

    fn render_base(&self, camera: &Camera, options: &RenderOptions) -> Result<RgbImage, TooMuchBlending> {
        render_limited(&self.gaussians_for(camera), camera, options)
    }

    fn render(&self, camera: &Camera, options: &RenderOptions, wrapped: bool) -> Result<Shown, TooMuchBlending> {
        let base = self.render_base(camera, options)?;
        Ok(match self.wrapper_view().filter(|_| wrapped) {
            Some(w) => {
                let out = apply(w.weights, &base, camera, w.frame);
                Shown { image: out.image, residual: Some(out.residual) }
            }
            None => Shown { image: base, residual: None },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::render;
    use pwgs_codec::random_scene::random_anchor_model;
    use pwgs_codec::scene::Base;
    use pwgs_codec::stream::attribute_hash;
    use pwgs_codec::wrapper::synthesis::{SynthesisWeights, WrapperConfig};
    use pwgs_core::frame::SceneFrame;
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
        assert_eq!(plain.render(&camera, &options, true), Ok(Shown { image: base.clone(), residual: None }));
        assert_eq!(wrapped.render(&camera, &options, false), Ok(Shown { image: base.clone(), residual: None }));
        // Through the wrapper: the base plus the residual, clamped.
        let shown = wrapped.render(&camera, &options, true).expect("within the work limit");
        let residual = shown.residual.expect("the wrapper's residual");
        assert!(residual.iter().any(|&r| r != 0.0), "a random f changes the image");
        let expected: Vec<f32> = base.data.iter().zip(&residual).map(|(b, r)| (b + r).clamp(0.0, 1.0)).collect();
        assert_eq!(shown.image.data, expected);

        assert_eq!(plain.attribute_hash(), attribute_hash(&g));
        assert_eq!((plain.gaussian_count(), plain.plain_gaussians()), (40, Some(&g)));
    }

    #[test]
    fn a_scene_of_anchors_renders_its_views_gaussians() {
        let mut rng = SplitMix64(4);
        let m = random_anchor_model(&mut rng, 20, 4, 3);
        let frame = SceneFrame { center: glam::Vec3::ZERO, scale: 1.0 };
        let scene = Scene { base: Base::Anchors(Box::new(m.clone())), wrapper: None, frame, background: [0.0; 3] };
        let camera = axis_camera(24, 16, 20.0, 20.0, 12.0, 8.0);
        let options = scene.render_options();
        assert_eq!(
            scene.render(&camera, &options, true).expect("within the limit").image,
            render(&m.gaussians_for(&camera), &camera, &options)
        );
        assert_eq!((scene.plain_gaussians(), scene.gaussian_count()), (None, 60));
        assert_eq!(scene.attribute_hash(), m.hash());
    }
}
