//! The splat operation on the GPU: CubeCL kernels on Burn's CubeCL backend, the same
//! computation as the CPU reference (projection, depth sort, tile binning, blending, and their
//! backward passes), its values checked against it by the tests.
//!
//! Nothing is copied to the host per render but one number (how many tile-list entries there
//! are, to size their buffers) and nothing from the host but the camera and settings (46
//! values): images, Gaussians and gradients stay on the device.

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

use bins::{Binned, Inputs, bin, empty_f32};
use blend::ENTRY_GRAD;
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
        let binned = bin(&inputs, &view);
        let (h, w) = (view.window.height as usize, view.window.width as usize);
        let like = &inputs.means;
        let image = empty_f32(like, &[h, w, 3]);
        let transmittance = empty_f32(like, &[h, w]);
        let last = empty_u32(like, h * w);
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
        let binned = bin(&inputs, &view);
        let like = &inputs.means;
        let client = &like.client;
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
            burn_cubecl::kernel::into_contiguous(transmittance).into_tensor_arg(),
            burn_cubecl::kernel::into_contiguous(last).into_tensor_arg(),
            burn_cubecl::kernel::into_contiguous(v_image).into_tensor_arg(),
            entry_grads.clone().into_tensor_arg(),
            view.options.cutoff == Cutoff::Smooth,
        );
        let grads: Vec<CubeTensor> = shapes.iter().map(|s| empty_f32(like, s)).collect();
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
            inputs.count,
        );
        let [means, log_scales, rotations, opacity_logits, sh, screen_probe]: [CubeTensor; 6] =
            grads.try_into().expect("six gradients");
        SplatTensors { means, log_scales, rotations, opacity_logits, sh, screen_probe }
    }
}

fn reshape(tensor: CubeTensor, shape: &[usize]) -> CubeTensor {
    burn_cubecl::ops::reshape(tensor, shape.to_vec().into())
}
