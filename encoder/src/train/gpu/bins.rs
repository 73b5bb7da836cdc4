//! What both passes of the GPU splat operation share: every Gaussian projected, sorted front
//! to back, and binned into the window's tiles, each tile's list in depth order. The steps are
//! deterministic (stable sorts, scans in a fixed order), so the backward pass rebuilds exactly
//! the lists the forward pass blended instead of keeping them.

use burn::backend::ops::{FloatTensorOps, IntTensorOps};
use burn::tensor::{DType, TensorData};
use burn_cubecl::CubeBackend;
use burn_cubecl::cubecl;
use burn_cubecl::cubecl::prelude::*;
use burn_cubecl::kernel::{cast, into_contiguous, slice};
use burn_cubecl::ops::into_data_sync;
use burn_cubecl::ops::numeric::{empty_device_dtype, zeros_client};
use burn_cubecl::tensor::CubeTensor;
use pwgs_render::raster::TILE_SIZE;

use super::project::{BOX_WORDS, SPLAT_FLOATS, blend_values, frame_at, frame_values, project_kernel, view_values};
use super::sort::{
    blocks, cube_dim, element_index, empty_u32, exclusive_scan, gather, grid, iota, key_bits, radix_sort,
};
use crate::train::splat_op::{SplatTensors, SplatView};
use pwgs_render::raster::Window;

/// The Gaussians' parameters, contiguous.
pub struct Inputs {
    pub means: CubeTensor,
    pub log_scales: CubeTensor,
    pub rotations: CubeTensor,
    pub logits: CubeTensor,
    pub sh: CubeTensor,
    pub count: u32,
    /// SH coefficients per channel.
    pub sh_coeffs: u32,
}

impl Inputs {
    pub fn of(splats: SplatTensors<CubeBackend>) -> Self {
        let shape = splats.sh.meta.shape().to_vec();
        assert!(shape.len() == 3 && shape[2] == 3, "sh must be [N, K, 3], got {shape:?}");
        Self {
            count: u32::try_from(shape[0]).expect("fewer than 2^32 Gaussians"),
            sh_coeffs: shape[1] as u32,
            means: into_contiguous(splats.means),
            log_scales: into_contiguous(splats.log_scales),
            rotations: into_contiguous(splats.rotations),
            logits: into_contiguous(splats.opacity_logits),
            sh: into_contiguous(splats.sh),
        }
    }
}

/// A render's splats and tile lists, on the device.
pub struct Binned {
    /// The camera, settings and blend settings as the kernels read them.
    pub view: CubeTensor,
    pub frame: CubeTensor,
    pub settings: CubeTensor,
    pub tiles: (u32, u32),
    /// Per Gaussian: its splat, pixel box, and number of tiles (0 when culled).
    pub splats: CubeTensor,
    pub boxes: CubeTensor,
    pub tile_counts: CubeTensor,
    /// Gaussian indices front to back (culled ones last), and where each one's list entries
    /// start in the unsorted entry order (n + 1 values, the last the entry count).
    pub order: CubeTensor,
    pub offsets: CubeTensor,
    /// Per list entry, by tile then depth: its Gaussian, and its position before the tile
    /// sort (where its Gaussian's entries are contiguous).
    pub entry_splat: CubeTensor,
    pub entry_slot: CubeTensor,
    /// Per tile: its entries' range.
    pub tile_start: CubeTensor,
    pub tile_end: CubeTensor,
}

pub fn upload_f32(like: &CubeTensor, values: Vec<f32>) -> CubeTensor {
    let len = values.len();
    CubeBackend::float_from_data(TensorData::new(values, [len]), &like.device)
}

fn upload_u32(like: &CubeTensor, values: Vec<u32>) -> CubeTensor {
    let len = values.len();
    CubeBackend::int_from_data(TensorData::new(values, [len]), &like.device)
}

pub fn empty_f32(like: &CubeTensor, shape: &[usize]) -> CubeTensor {
    empty_device_dtype(like.client.clone(), like.device.clone(), shape.to_vec().into(), DType::F32)
}

/// One unit per depth rank: the Gaussian's list entries (tile, unsorted position), at its
/// offset, tiles row by row.
#[cube(launch)]
#[allow(clippy::too_many_arguments)]
fn emit_entries(
    order: &Tensor<u32>,
    boxes: &Tensor<u32>,
    tile_counts: &Tensor<u32>,
    offsets: &Tensor<u32>,
    frame: &Tensor<u32>,
    tile_keys: &mut Tensor<u32>,
    slots: &mut Tensor<u32>,
    emitted_splat: &mut Tensor<u32>,
    count: u32,
) {
    let rank = element_index();
    if rank >= count {
        terminate!();
    }
    let g = order[rank as usize];
    if tile_counts[g as usize] == 0 {
        terminate!();
    }
    let w = frame_at::WINDOW as usize;
    let (wx0, wy0) = (frame[w], frame[w + 1]);
    let tiles_x = frame[frame_at::TILES_X as usize];
    let b = (g * BOX_WORDS) as usize;
    let tx0 = (boxes[b] - wx0) / TILE_SIZE;
    let tx1 = (boxes[b + 1] - 1 - wx0) / TILE_SIZE + 1;
    let ty0 = (boxes[b + 2] - wy0) / TILE_SIZE;
    let ty1 = (boxes[b + 3] - 1 - wy0) / TILE_SIZE + 1;
    let mut e = offsets[rank as usize];
    for ty in ty0..ty1 {
        for tx in tx0..tx1 {
            tile_keys[e as usize] = ty * tiles_x + tx;
            slots[e as usize] = e;
            emitted_splat[e as usize] = g;
            e += 1;
        }
    }
}

/// One unit per sorted entry: the first and one-past-last entry of each tile.
#[cube(launch)]
fn tile_ranges(tile_keys: &Tensor<u32>, tile_start: &mut Tensor<u32>, tile_end: &mut Tensor<u32>, count: u32) {
    let k = element_index();
    if k >= count {
        terminate!();
    }
    let tile = tile_keys[k as usize];
    if k == 0 || tile_keys[(k - 1) as usize] != tile {
        tile_start[tile as usize] = k;
    }
    if k + 1 == count || tile_keys[(k + 1) as usize] != tile {
        tile_end[tile as usize] = k + 1;
    }
}

/// The windows of `view.window` whose lists fit `view.entry_budget`, binned, in order: the whole
/// window when it fits, else its two halves (split on a tile edge across its longer side in
/// tiles), each in turn; a single tile is never split, so its list may hold up to every
/// Gaussian. Every window's pixels are the same as in a render of the whole view
/// (its tiles are the same tiles, their lists the same lists); `output` is the window of the
/// image-sized arrays they are blended into.
pub fn windows(inputs: &Inputs, view: &SplatView, output: Window, each: &mut impl FnMut(Binned)) {
    if let Some(binned) = bin(inputs, view, output) {
        return each(binned);
    }
    let w = view.window;
    let (tiles_x, tiles_y) = w.tile_counts();
    let halves = if tiles_y >= tiles_x {
        let top = tiles_y / 2 * TILE_SIZE;
        [Window { height: top, ..w }, Window { y0: w.y0 + top, height: w.height - top, ..w }]
    } else {
        let left = tiles_x / 2 * TILE_SIZE;
        [Window { width: left, ..w }, Window { x0: w.x0 + left, width: w.width - left, ..w }]
    };
    for window in halves {
        windows(inputs, &SplatView { window, ..*view }, output, each);
    }
}

/// How many list entries the Gaussians' `tile_counts` make, or `None` when over `budget`.
/// Where the u32 sum could wrap (Gaussians x tiles of 2^32 or more), the
/// counts are first summed in f32, which is exact enough to compare with the budget.
fn entry_count(tile_counts: &CubeTensor, offsets: &CubeTensor, n: u32, tiles: u32, budget: u64) -> Option<u32> {
    if u64::from(n) * u64::from(tiles) >= 1 << 32 {
        let sum = CubeBackend::float_sum(cast(tile_counts.clone(), DType::F32));
        let sum = into_data_sync(sum).convert::<f32>().try_into_vec::<f32>().expect("an f32 sum")[0];
        if f64::from(sum) > budget as f64 {
            return None;
        }
    }
    let total = list_length(offsets, n);
    (u64::from(total) <= budget).then_some(total)
}

/// The last of the n + 1 `offsets`: the lists' length.
fn list_length(offsets: &CubeTensor, n: u32) -> u32 {
    let last = n as usize..n as usize + 1;
    let total = into_data_sync(slice(offsets.clone(), std::slice::from_ref(&last)));
    total.convert::<u32>().try_into_vec::<u32>().expect("u32 entry count")[0]
}

/// Projects, sorts and bins the Gaussians for `view`, to be blended into the `output` window
/// of the image-sized arrays; `None` when the lists would hold more than `view.entry_budget`
/// entries and the window has more than one tile. Reads one number back from the device: how
/// many list entries there are, to size their buffers.
fn bin(inputs: &Inputs, view: &SplatView, output: Window) -> Option<Binned> {
    let like = &inputs.means;
    let client = like.client.clone();
    let n = inputs.count;
    let window = view.window;
    let tiles = window.tile_counts();
    let view_t = upload_f32(like, view_values(view));
    let frame = upload_u32(like, frame_values(window, inputs.sh_coeffs, output));
    let settings = upload_f32(like, blend_values(&view.options));

    let splats = empty_f32(like, &[(n * SPLAT_FLOATS).max(1) as usize]);
    let boxes = empty_u32(like, (n * BOX_WORDS) as usize);
    let tile_counts = empty_u32(like, n as usize);
    let depth_keys = empty_u32(like, n as usize);
    project_kernel::launch(
        &client,
        grid(blocks(n)),
        cube_dim(),
        inputs.means.clone().into_tensor_arg(),
        inputs.log_scales.clone().into_tensor_arg(),
        inputs.rotations.clone().into_tensor_arg(),
        inputs.logits.clone().into_tensor_arg(),
        inputs.sh.clone().into_tensor_arg(),
        view_t.clone().into_tensor_arg(),
        frame.clone().into_tensor_arg(),
        splats.clone().into_tensor_arg(),
        boxes.clone().into_tensor_arg(),
        tile_counts.clone().into_tensor_arg(),
        depth_keys.clone().into_tensor_arg(),
        n,
    );
    let (_, order) = radix_sort(depth_keys, iota(like, n), n, u32::BITS);
    let offsets = exclusive_scan(&gather(&tile_counts, &order, n), n + 1);
    let total = match entry_count(&tile_counts, &offsets, n, tiles.0 * tiles.1, view.entry_budget) {
        Some(total) => total,
        None if tiles.0 * tiles.1 > 1 => return None,
        // One tile holds at most one entry a Gaussian: its u32 count is exact.
        None => list_length(&offsets, n),
    };

    let tile_keys = empty_u32(like, total as usize);
    let slots = empty_u32(like, total as usize);
    let emitted_splat = empty_u32(like, total as usize);
    emit_entries::launch(
        &client,
        grid(blocks(n)),
        cube_dim(),
        order.clone().into_tensor_arg(),
        boxes.clone().into_tensor_arg(),
        tile_counts.clone().into_tensor_arg(),
        offsets.clone().into_tensor_arg(),
        frame.clone().into_tensor_arg(),
        tile_keys.clone().into_tensor_arg(),
        slots.clone().into_tensor_arg(),
        emitted_splat.clone().into_tensor_arg(),
        n,
    );
    let tile_count = tiles.0 * tiles.1;
    let (tile_keys, entry_slot) = radix_sort(tile_keys, slots, total, key_bits(tile_count.saturating_sub(1)));
    let entry_splat = gather(&emitted_splat, &entry_slot, total);
    let tile_start = zeros_client(client.clone(), like.device.clone(), [tile_count as usize].into(), DType::U32);
    let tile_end = zeros_client(client.clone(), like.device.clone(), [tile_count as usize].into(), DType::U32);
    tile_ranges::launch(
        &client,
        grid(blocks(total)),
        cube_dim(),
        tile_keys.into_tensor_arg(),
        tile_start.clone().into_tensor_arg(),
        tile_end.clone().into_tensor_arg(),
        total,
    );
    Some(Binned {
        view: view_t,
        frame,
        settings,
        tiles,
        splats,
        boxes,
        tile_counts,
        order,
        offsets,
        entry_splat,
        entry_slot,
        tile_start,
        tile_end,
    })
}
