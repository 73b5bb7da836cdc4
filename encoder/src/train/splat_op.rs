//! The rasterizer as a Burn operation with its own backward pass, so training code can write
//! `render(&splats, camera)` on tensors and get gradients for every Gaussian parameter.
//!
//! On Burn's `flex` CPU backend, forward and backward are the CPU reference implementations
//! (the decoder's forward, this crate's [`crate::train::backward`]), the tensors read on the
//! host. With the `gpu` feature, on Burn's CubeCL backend (wgpu), they are the CubeCL kernels
//! of [`crate::train::gpu`], checked against the reference by the tests; the tensors stay on
//! the device.

use std::sync::Arc;

use burn::backend::autodiff::Autodiff;
use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy;
use burn::backend::autodiff::grads::Gradients as AutodiffGradients;
use burn::backend::autodiff::ops::{Backward, NodeGuard, Ops, OpsKind};
use burn::backend::tensor::FloatTensor;
#[cfg(feature = "gpu")]
use burn::backend::tensor::IntTensor;
use burn::backend::{Backend, Dispatch, ExtensionType, Flex, TensorMetadata, backend_extension};
use burn::tensor::{Tensor, TensorData};
use pwgs_core::camera::Camera;
use pwgs_core::gaussians::Gaussians;
use pwgs_render::raster::{RenderOptions, Rendered, Window, rasterize_window};

use crate::train::backward::{Gradients, backward};

/// The trainable parameters of a set of Gaussians, as backend tensors.
#[derive(ExtensionType, Debug, Clone)]
#[extension_type(fusion: cfg(feature = "gpu"))]
pub struct SplatTensors<B: Backend> {
    /// [N, 3]
    pub means: FloatTensor<B>,
    /// [N, 3]
    pub log_scales: FloatTensor<B>,
    /// [N, 4], (w, x, y, z), not necessarily normalized.
    pub rotations: FloatTensor<B>,
    /// [N]
    pub opacity_logits: FloatTensor<B>,
    /// [N, (degree + 1)^2, 3]
    pub sh: FloatTensor<B>,
    /// [N] zeros. Its gradient is |dL/d(projected center)| per Gaussian, the densification
    /// signal of 3DGS, which is not the gradient of any parameter.
    pub screen_probe: FloatTensor<B>,
}

/// Most tile-list entries the GPU kernels bin at once by default: 2^25, about 1.9 GB across
/// the binning's and the backward pass's buffers (56 bytes an entry).
pub const ENTRY_BUDGET: u64 = 1 << 25;

/// What to render: camera, rasterizer settings and the part of the image wanted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplatView {
    pub camera: Camera,
    pub options: RenderOptions,
    /// The pixels rendered (the image is [window height, window width, 3]); they are exactly
    /// those pixels of the whole render, and only they pass gradients back.
    pub window: Window,
    /// Most tile-list entries one binning on the GPU holds: a view whose lists would hold more
    /// renders in windows that fit, to the same pixels and gradients. (The CPU reference bins
    /// within its own budget, `pwgs_render`'s `BinBudget`.)
    pub entry_budget: u64,
}

impl SplatView {
    /// The whole image of `camera`.
    pub fn full(camera: Camera, options: RenderOptions) -> Self {
        Self { camera, options, window: Window::full(&camera), entry_budget: ENTRY_BUDGET }
    }

    fn rasterize(&self, gaussians: &Gaussians) -> Rendered {
        rasterize_window(gaussians, &self.camera, self.window, &self.options)
    }
}

#[backend_extension(Flex, Cube: cfg(feature = "gpu"), Autodiff)]
pub trait SplatBackend: Backend {
    /// Renders [H, W, 3] colors.
    fn render_splats(#[extension_type] splats: SplatTensors<Self>, view: SplatView) -> FloatTensor<Self>;
}

/// A render on the GPU with what its backward pass needs besides the inputs.
#[cfg(feature = "gpu")]
#[derive(ExtensionType, Debug, Clone)]
#[extension_type(fusion: cfg(feature = "gpu"))]
pub struct GpuRender<B: Backend> {
    /// [H, W, 3]
    pub image: FloatTensor<B>,
    /// [H, W] final transmittance.
    pub transmittance: FloatTensor<B>,
    /// [H, W] u32: one past the last list position blended into each pixel.
    pub last: IntTensor<B>,
}

/// The splat operation's two passes on Burn's CubeCL backend ([`crate::train::gpu`]), lazily
/// through its operation fusion.
#[cfg(feature = "gpu")]
#[backend_extension(Cube: cfg(feature = "gpu"), Fusion: cfg(feature = "gpu"))]
pub trait GpuSplatBackend: Backend {
    #[fusion(meta = crate::train::gpu::render_meta)]
    fn gpu_render(#[extension_type] splats: SplatTensors<Self>, view: SplatView) -> GpuRender<Self>;

    /// The gradients of every input (the screen probe's: |dL/d(projected center)|).
    #[fusion(meta = crate::train::gpu::backward_meta)]
    fn gpu_render_backward(
        #[extension_type] splats: SplatTensors<Self>,
        view: SplatView,
        transmittance: FloatTensor<Self>,
        last: IntTensor<Self>,
        v_image: FloatTensor<Self>,
    ) -> SplatTensors<Self>;
}

/// Resolves a future that the CPU backend has already completed.
fn ready<T>(future: impl Future<Output = T>) -> T {
    let mut future = std::pin::pin!(future);
    let mut context = std::task::Context::from_waker(std::task::Waker::noop());
    match future.as_mut().poll(&mut context) {
        std::task::Poll::Ready(value) => value,
        std::task::Poll::Pending => panic!("the splat op runs on synchronous CPU backends only"),
    }
}

fn host_values<B: Backend>(tensor: FloatTensor<B>) -> Vec<f32> {
    let data = ready(B::float_into_data(tensor)).expect("reading a CPU tensor cannot fail");
    data.convert::<f32>().try_into_vec::<f32>().expect("converted to f32")
}

fn arrays<const N: usize>(values: &[f32]) -> Vec<[f32; N]> {
    values.chunks_exact(N).map(|c| c.try_into().expect("chunk of N")).collect()
}

/// Copies the tensors into a Gaussian set, checking their shapes against each other.
fn gaussians_from<B: Backend>(splats: &SplatTensors<B>) -> Gaussians {
    let n = splats.means.shape().as_slice()[0];
    let sh_shape = splats.sh.shape().to_vec();
    assert!(sh_shape.len() == 3 && sh_shape[0] == n && sh_shape[2] == 3, "sh must be [N, K, 3], got {sh_shape:?}");
    let degree = (0..=pwgs_core::gaussians::MAX_SH_DEGREE)
        .find(|&d| pwgs_core::gaussians::sh_coeff_count(d) == sh_shape[1])
        .unwrap_or_else(|| panic!("{} SH coefficients is not a whole degree", sh_shape[1]));
    let g = Gaussians {
        means: arrays(&host_values::<B>(splats.means.clone())),
        log_scales: arrays(&host_values::<B>(splats.log_scales.clone())),
        rotations: arrays(&host_values::<B>(splats.rotations.clone())),
        opacity_logits: host_values::<B>(splats.opacity_logits.clone()),
        sh_degree: degree,
        sh: host_values::<B>(splats.sh.clone()),
    };
    assert!(g.is_consistent() && g.len() == n, "splat tensors disagree on the Gaussian count");
    g
}

fn image_tensor<B: Backend>(rendered: &Rendered, device: &B::Device) -> FloatTensor<B> {
    let (w, h) = (rendered.color.width as usize, rendered.color.height as usize);
    B::float_from_data(TensorData::new(rendered.color.data.clone(), [h, w, 3]), device)
}

impl SplatBackend for Flex {
    fn render_splats(splats: SplatTensors<Self>, view: SplatView) -> FloatTensor<Self> {
        let device = splats.means.device();
        let g = gaussians_from(&splats);
        image_tensor::<Self>(&view.rasterize(&g), &device)
    }
}

/// What the forward pass keeps for the backward pass.
#[derive(Debug)]
struct Saved {
    gaussians: Gaussians,
    view: SplatView,
    rendered: Rendered,
}

#[derive(Debug)]
struct RenderBackward;

impl<B: Backend> Backward<B, 6> for RenderBackward {
    type State = Arc<Saved>;

    fn backward(self, ops: Ops<Self::State, 6>, grads: &mut AutodiffGradients, _checkpointer: &mut Checkpointer) {
        let saved = ops.state;
        let v_image = grads.consume::<B>(&ops.node);
        let device = v_image.device();
        let v_color = host_values::<B>(v_image);
        let Gradients { means, log_scales, rotations, opacity_logits, sh, screen_mean } =
            backward(&saved.gaussians, &saved.view.camera, &saved.view.options, &saved.rendered, &v_color);
        let n = saved.gaussians.len();
        let k = saved.gaussians.coeffs_per_channel();
        let flat = |v: Vec<[f32; 3]>| v.into_iter().flatten().collect::<Vec<f32>>();
        let values: [(Vec<f32>, Vec<usize>); 6] = [
            (flat(means), vec![n, 3]),
            (flat(log_scales), vec![n, 3]),
            (rotations.into_iter().flatten().collect(), vec![n, 4]),
            (opacity_logits, vec![n]),
            (sh, vec![n, k, 3]),
            (screen_mean, vec![n]),
        ];
        for (parent, (data, shape)) in ops.parents.into_iter().zip(values) {
            if let Some(node) = parent {
                grads.register::<B>(node.id, B::float_from_data(TensorData::new(data, shape), &device));
            }
        }
    }
}

/// The autodiff nodes of the six inputs, in [`SplatTensors`]' field order, and their inner
/// backend's tensors.
fn tracked<B: Backend, C: CheckpointStrategy>(
    splats: &SplatTensors<Autodiff<B, C>>,
) -> ([NodeGuard; 6], SplatTensors<B>) {
    let s = splats;
    let nodes = [
        s.means.node(),
        s.log_scales.node(),
        s.rotations.node(),
        s.opacity_logits.node(),
        s.sh.node(),
        s.screen_probe.node(),
    ];
    let inner = SplatTensors {
        means: s.means.primitive().clone(),
        log_scales: s.log_scales.primitive().clone(),
        rotations: s.rotations.primitive().clone(),
        opacity_logits: s.opacity_logits.primitive().clone(),
        sh: s.sh.primitive().clone(),
        screen_probe: s.screen_probe.primitive().clone(),
    };
    (nodes, inner)
}

impl<C: CheckpointStrategy> SplatBackend for Autodiff<Flex, C> {
    fn render_splats(splats: SplatTensors<Self>, view: SplatView) -> FloatTensor<Self> {
        let (nodes, inner) = tracked(&splats);
        let device = inner.means.device();
        let gaussians = gaussians_from(&inner);
        let rendered = view.rasterize(&gaussians);
        let image = image_tensor::<Flex>(&rendered, &device);
        match RenderBackward.prepare::<C>(nodes).compute_bound().stateful() {
            OpsKind::Tracked(prep) => prep.finish(Arc::new(Saved { gaussians, view, rendered }), image),
            OpsKind::UnTracked(prep) => prep.finish(image),
        }
    }
}

#[cfg(feature = "gpu")]
mod on_gpu {
    use super::*;
    use burn_cubecl::Cube;

    impl SplatBackend for Cube {
        fn render_splats(splats: SplatTensors<Self>, view: SplatView) -> FloatTensor<Self> {
            Self::gpu_render(splats, view).image
        }
    }

    /// What the GPU forward pass keeps for the backward pass: the inputs (their tensors, not
    /// copies) and the per-pixel arrays.
    #[derive(Debug, Clone)]
    struct Saved {
        splats: SplatTensors<Cube>,
        view: SplatView,
        transmittance: FloatTensor<Cube>,
        last: IntTensor<Cube>,
    }

    #[derive(Debug)]
    struct GpuRenderBackward;

    impl Backward<Cube, 6> for GpuRenderBackward {
        type State = Saved;

        fn backward(self, ops: Ops<Self::State, 6>, grads: &mut AutodiffGradients, _checkpointer: &mut Checkpointer) {
            let Saved { splats, view, transmittance, last } = ops.state;
            let v_image = grads.consume::<Cube>(&ops.node);
            let g = Cube::gpu_render_backward(splats, view, transmittance, last, v_image);
            let values = [g.means, g.log_scales, g.rotations, g.opacity_logits, g.sh, g.screen_probe];
            for (parent, value) in ops.parents.into_iter().zip(values) {
                if let Some(node) = parent {
                    grads.register::<Cube>(node.id, value);
                }
            }
        }
    }

    impl<C: CheckpointStrategy> SplatBackend for Autodiff<Cube, C> {
        fn render_splats(splats: SplatTensors<Self>, view: SplatView) -> FloatTensor<Self> {
            let (nodes, inner) = tracked(&splats);
            let out = Cube::gpu_render(inner.clone(), view);
            match GpuRenderBackward.prepare::<C>(nodes).compute_bound().stateful() {
                OpsKind::Tracked(prep) => prep
                    .finish(Saved { splats: inner, view, transmittance: out.transmittance, last: out.last }, out.image),
                OpsKind::UnTracked(prep) => prep.finish(out.image),
            }
        }
    }
}

/// Renders Gaussians held as tensors ([N,3], [N,3], [N,4], [N], [N,K,3], [N]) to an
/// [H, W, 3] image tensor, differentiably when the tensors track gradients.
pub fn render(
    means: Tensor<2>,
    log_scales: Tensor<2>,
    rotations: Tensor<2>,
    opacity_logits: Tensor<1>,
    sh: Tensor<3>,
    screen_probe: Tensor<1>,
    view: SplatView,
) -> Tensor<3> {
    let splats = SplatTensors {
        means: means.into_dispatch(),
        log_scales: log_scales.into_dispatch(),
        rotations: rotations.into_dispatch(),
        opacity_logits: opacity_logits.into_dispatch(),
        sh: sh.into_dispatch(),
        screen_probe: screen_probe.into_dispatch(),
    };
    Tensor::from_dispatch(<Dispatch as SplatBackend>::render_splats(splats, view))
}
