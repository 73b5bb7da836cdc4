//! The splat operation on the GPU: CubeCL kernels on Burn's CubeCL backend, the same
//! computation as the CPU reference (projection, depth sort, tile binning, blending, and their
//! backward passes), its values checked against it by the tests.
//!
//! Nothing is copied to the host per render but one number (how many tile-list entries there
//! are, to size their buffers) and nothing from the host but the camera and settings (49
//! values): images, Gaussians and gradients stay on the device. A view whose tile lists would
//! outgrow its entry budget ([`SplatView::entry_budget`]) renders in windows that fit, one after the other, with one
//! such exchange each.

pub mod bins;
pub mod blend;
pub mod project;
pub mod project_backward;
pub mod sort;

use burn::backend::fusion::custom::TensorSpec;
use burn::tensor::{DType, Shape};
use burn_cubecl::CubeBackend;
use burn_cubecl::cubecl::prelude::*;
use burn_cubecl::ops::numeric::zeros_client;
use burn_cubecl::tensor::CubeTensor;
use pwgs_render::raster::Cutoff;

use bins::{Binned, Inputs, empty_f32, windows};
use blend::ENTRY_GRAD;
use burn::backend::ops::FloatTensorOps;
use sort::{blocks, cube_dim, empty_u32, grid};

use crate::train::splat_op::{
    GpuRender, GpuRenderMetadata, GpuSplatBackend, SplatTensors, SplatTensorsMetadata, SplatView,
};

/// The image's and the per-pixel arrays' shapes, for the lazy (fused) form of the operation.
pub fn render_meta(splats: &SplatTensorsMetadata, view: &SplatView) -> GpuRenderMetadata {
    let (h, w) = (view.window.height as usize, view.window.width as usize);
    GpuRenderMetadata {
        image: TensorSpec::new(Shape::new([h, w, 3]), splats.means.dtype),
        transmittance: TensorSpec::new(Shape::new([h, w]), splats.means.dtype),
        last: TensorSpec::new(Shape::new([h, w]), DType::U32),
    }
}

/// The gradients have the parameters' shapes.
pub fn backward_meta(
    splats: &SplatTensorsMetadata,
    _view: &SplatView,
    _transmittance: &TensorSpec,
    _last: &TensorSpec,
    _v_image: &TensorSpec,
) -> SplatTensorsMetadata {
    splats.clone()
}

fn launch_grid(binned: &Binned) -> CubeCount {
    CubeCount::new_2d(binned.tiles.0, binned.tiles.1)
}

fn tile_dim() -> CubeDim {
    let edge = pwgs_render::raster::TILE_SIZE;
    CubeDim::new_2d(edge, edge)
}

impl GpuSplatBackend for CubeBackend {
    fn gpu_render(splats: SplatTensors<Self>, view: SplatView) -> GpuRender<Self> {
        let inputs = Inputs::of(splats);
        let (h, w) = (view.window.height as usize, view.window.width as usize);
        let like = &inputs.means;
        let image = empty_f32(like, &[h, w, 3]);
        let transmittance = empty_f32(like, &[h, w]);
        let last = empty_u32(like, h * w);
        windows(&inputs, &view, view.window, &mut |binned| {
            blend::blend_forward::launch(
                &like.client,
                launch_grid(&binned),
                tile_dim(),
                binned.splats.into_tensor_arg(),
                binned.boxes.into_tensor_arg(),
                binned.entry_splat.into_tensor_arg(),
                binned.tile_start.into_tensor_arg(),
                binned.tile_end.into_tensor_arg(),
                binned.frame.into_tensor_arg(),
                binned.settings.into_tensor_arg(),
                image.clone().into_tensor_arg(),
                transmittance.clone().into_tensor_arg(),
                last.clone().into_tensor_arg(),
                view.options.cutoff == Cutoff::Smooth,
            );
        });
        GpuRender { image, transmittance, last: reshape(last, &[h, w]) }
    }

    fn gpu_render_backward(
        splats: SplatTensors<Self>,
        view: SplatView,
        transmittance: CubeTensor,
        last: CubeTensor,
        v_image: CubeTensor,
    ) -> SplatTensors<Self> {
        let shapes: Vec<Vec<usize>> = [
            &splats.means,
            &splats.log_scales,
            &splats.rotations,
            &splats.opacity_logits,
            &splats.sh,
            &splats.screen_probe,
        ]
        .iter()
        .map(|t| t.meta.shape().to_vec())
        .collect();
        let inputs = Inputs::of(splats);
        let like = &inputs.means;
        let client = &like.client;
        let transmittance = burn_cubecl::kernel::into_contiguous(transmittance);
        let last = burn_cubecl::kernel::into_contiguous(last);
        let v_image = burn_cubecl::kernel::into_contiguous(v_image);
        let n = inputs.count as usize;
        // Each window's gradients, and the screen-space gradients [N, 2] whose norm is the
        // probe's, summed over the windows.
        let mut sums: Option<Vec<CubeTensor>> = None;
        let mut windows_done = 0;
        windows(&inputs, &view, view.window, &mut |binned| {
            let total = binned.entry_slot.meta.num_elements();
            // Entries behind every pixel's last blended splat are not visited: their gradient is 0.
            let entry_grads =
                zeros_client(client.clone(), like.device.clone(), [total * ENTRY_GRAD as usize].into(), DType::F32);
            blend::blend_backward::launch(
                client,
                launch_grid(&binned),
                tile_dim(),
                binned.splats.clone().into_tensor_arg(),
                binned.boxes.clone().into_tensor_arg(),
                binned.entry_splat.clone().into_tensor_arg(),
                binned.entry_slot.clone().into_tensor_arg(),
                binned.tile_start.clone().into_tensor_arg(),
                binned.frame.clone().into_tensor_arg(),
                binned.settings.clone().into_tensor_arg(),
                transmittance.clone().into_tensor_arg(),
                last.clone().into_tensor_arg(),
                v_image.clone().into_tensor_arg(),
                entry_grads.clone().into_tensor_arg(),
                view.options.cutoff == Cutoff::Smooth,
            );
            let grads: Vec<CubeTensor> = shapes.iter().chain([&vec![n, 2]]).map(|s| empty_f32(like, s)).collect();
            project_backward::project_backward::launch(
                client,
                grid(blocks(inputs.count)),
                cube_dim(),
                inputs.means.clone().into_tensor_arg(),
                inputs.log_scales.clone().into_tensor_arg(),
                inputs.rotations.clone().into_tensor_arg(),
                inputs.logits.clone().into_tensor_arg(),
                inputs.sh.clone().into_tensor_arg(),
                binned.view.into_tensor_arg(),
                binned.frame.into_tensor_arg(),
                binned.order.into_tensor_arg(),
                binned.tile_counts.into_tensor_arg(),
                binned.offsets.into_tensor_arg(),
                entry_grads.into_tensor_arg(),
                grads[0].clone().into_tensor_arg(),
                grads[1].clone().into_tensor_arg(),
                grads[2].clone().into_tensor_arg(),
                grads[3].clone().into_tensor_arg(),
                grads[4].clone().into_tensor_arg(),
                grads[5].clone().into_tensor_arg(),
                grads[6].clone().into_tensor_arg(),
                inputs.count,
            );
            windows_done += 1;
            sums = Some(match sums.take() {
                None => grads,
                Some(sums) => sums.into_iter().zip(grads).map(|(a, b)| CubeBackend::float_add(a, b)).collect(),
            });
        });
        let [means, log_scales, rotations, opacity_logits, sh, screen_probe, screen_xy]: [CubeTensor; 7] =
            sums.expect("a view has at least one window").try_into().expect("seven gradients");
        // Over several windows the norms' sum is not the norm of the summed gradient.
        let screen_probe = if windows_done == 1 {
            screen_probe
        } else {
            let squares = CubeBackend::float_mul(screen_xy.clone(), screen_xy);
            let summed = CubeBackend::float_sum_dim(squares, 1);
            CubeBackend::float_sqrt(CubeBackend::float_reshape(summed, [n].into()))
        };
        SplatTensors { means, log_scales, rotations, opacity_logits, sh, screen_probe }
    }
}

fn reshape(tensor: CubeTensor, shape: &[usize]) -> CubeTensor {
    burn_cubecl::ops::reshape(tensor, shape.to_vec().into())
}
