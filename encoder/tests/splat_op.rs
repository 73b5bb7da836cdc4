//! The rasterizer as a Burn operation: forward equals the decoder's, and autodiff delivers
//! exactly the analytic gradients of the backward pass.

use burn::tensor::{Device, Tensor, TensorData};
use pwgs_core::gaussians::Gaussians;
use pwgs_core::random::{SplitMix64, axis_camera, random_gaussians};
use pwgs_encoder::train::backward::backward;
use pwgs_encoder::train::splat_op::{SplatView, render};
use pwgs_render::raster::{RenderOptions, Window, rasterize};

struct Params {
    means: Tensor<2>,
    log_scales: Tensor<2>,
    rotations: Tensor<2>,
    opacity: Tensor<1>,
    sh: Tensor<3>,
    probe: Tensor<1>,
}

fn params(g: &Gaussians, device: &Device, track: bool) -> Params {
    let n = g.len();
    let t2 = |v: Vec<f32>, w: usize| {
        let t = Tensor::<2>::from_data(TensorData::new(v, [n, w]), device);
        if track { t.require_grad() } else { t }
    };
    let t1 = |v: Vec<f32>| {
        let t = Tensor::<1>::from_data(TensorData::new(v, [n]), device);
        if track { t.require_grad() } else { t }
    };
    let sh = Tensor::<3>::from_data(TensorData::new(g.sh.clone(), [n, g.coeffs_per_channel(), 3]), device);
    Params {
        means: t2(g.means.iter().flatten().copied().collect(), 3),
        log_scales: t2(g.log_scales.iter().flatten().copied().collect(), 3),
        rotations: t2(g.rotations.iter().flatten().copied().collect(), 4),
        opacity: t1(g.opacity_logits.clone()),
        sh: if track { sh.require_grad() } else { sh },
        probe: t1(vec![0.0; n]),
    }
}

fn draw(p: &Params, view: SplatView) -> Tensor<3> {
    render(
        p.means.clone(),
        p.log_scales.clone(),
        p.rotations.clone(),
        p.opacity.clone(),
        p.sh.clone(),
        p.probe.clone(),
        view,
    )
}

fn values<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data().convert::<f32>().try_into_vec::<f32>().unwrap()
}

fn scene() -> (Gaussians, SplatView) {
    let g = random_gaussians(&mut SplitMix64(5), 300, 2, [-3.5, -1.5]);
    let view = SplatView::full(
        axis_camera(48, 40, 40.0, 42.0, 23.0, 21.0),
        RenderOptions { background: [0.2, 0.3, 0.4], ..Default::default() },
    );
    (g, view)
}

#[test]
fn forward_equals_the_decoder_rasterizer() {
    let (g, view) = scene();
    let image = draw(&params(&g, &Device::flex(), false), view);
    assert_eq!(image.dims(), [40, 48, 3]);
    let expected = rasterize(&g, &view.camera, &view.options).color.data;
    assert_eq!(values(image), expected);
}

#[test]
fn autodiff_gradients_are_the_analytic_ones() {
    let (g, view) = scene();
    let device = Device::flex().autodiff();
    let p = params(&g, &device, true);
    let image = draw(&p, view);
    let weights: Vec<f32> = {
        let mut rng = SplitMix64(8);
        (0..40 * 48 * 3).map(|_| rng.uniform(-1.0, 1.0)).collect()
    };
    let w = Tensor::<3>::from_data(TensorData::new(weights.clone(), [40, 48, 3]), &device);
    let grads = (image * w).sum().backward();

    let rendered = rasterize(&g, &view.camera, &view.options);
    let expected = backward(&g, &view.camera, &view.options, &rendered, &weights);
    let grad = |t: &Tensor<2>| values(t.grad(&grads).expect("tracked"));
    assert_eq!(grad(&p.means), expected.means.iter().flatten().copied().collect::<Vec<_>>());
    assert_eq!(grad(&p.log_scales), expected.log_scales.iter().flatten().copied().collect::<Vec<_>>());
    assert_eq!(grad(&p.rotations), expected.rotations.iter().flatten().copied().collect::<Vec<_>>());
    assert_eq!(values(p.opacity.grad(&grads).unwrap()), expected.opacity_logits);
    assert_eq!(values(p.sh.grad(&grads).unwrap()), expected.sh);
    let probe = values(p.probe.grad(&grads).expect("the probe is tracked"));
    assert_eq!(probe, expected.screen_mean);
    assert!(probe.iter().filter(|&&v| v > 0.0).count() > 100, "visible Gaussians have a densification signal");
}

#[test]
fn a_window_passes_the_gradients_of_its_pixels_only() {
    let (g, full) = scene();
    let window = Window { x0: 9, y0: 13, width: 21, height: 17 };
    let view = SplatView { window, ..full };
    let device = Device::flex().autodiff();
    let mut rng = SplitMix64(21);
    let weights: Vec<f32> = (0..21 * 17 * 3).map(|_| rng.uniform(-1.0, 1.0)).collect();
    // The same weights on the whole image, zero outside the window.
    let mut padded = vec![0.0f32; 40 * 48 * 3];
    for y in 0..17 {
        for x in 0..21 {
            let (p, q) = ((y * 21 + x) * 3, ((13 + y) * 48 + 9 + x) * 3);
            padded[q..q + 3].copy_from_slice(&weights[p..p + 3]);
        }
    }
    let gradients = |view: SplatView, w: Vec<f32>| {
        let p = params(&g, &device, true);
        let image = draw(&p, view);
        let [h, wd, _] = image.dims();
        let grads = (image * Tensor::<3>::from_data(TensorData::new(w, [h, wd, 3]), &device)).sum().backward();
        let mut all = values(p.means.grad(&grads).unwrap());
        all.extend(values(p.log_scales.grad(&grads).unwrap()));
        all.extend(values(p.rotations.grad(&grads).unwrap()));
        all.extend(values(p.opacity.grad(&grads).unwrap()));
        all.extend(values(p.sh.grad(&grads).unwrap()));
        all
    };
    let (part, whole) = (gradients(view, weights), gradients(full, padded));
    let scale = whole.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    assert!(part.iter().filter(|v| **v != 0.0).count() > 100, "the window's Gaussians get gradients");
    for (a, b) in part.iter().zip(&whole) {
        assert!((a - b).abs() <= 1e-5 * scale, "{a} vs {b}");
    }
}
