//! Prefix sums and a stable radix sort of u32 keys with u32 values, as CubeCL kernels: the
//! depth sort and the tile binning of the GPU splat operation.
//!
//! Both work on blocks of [`BLOCK`] elements, one per unit. The radix sort is least significant
//! digit first, four bits a pass: count each block's digits, scan the counts digit-major (every
//! block's zeros, then every block's ones, ...), scatter each element to its digit's offset plus
//! its rank among the block's elements of that digit. Ranks follow the input order, so the sort
//! is stable and its result does not depend on scheduling.

use burn::tensor::DType;
use burn_cubecl::cubecl;
use burn_cubecl::cubecl::prelude::*;
use burn_cubecl::ops::numeric::empty_device_dtype;
use burn_cubecl::tensor::CubeTensor;

/// Units per cube and elements per block.
pub const BLOCK: u32 = 256;
/// [`BLOCK`] as a shared-memory length.
pub const BLOCK_SLOTS: usize = BLOCK as usize;

/// Digits per radix pass.
const RADIX_BITS: u32 = 4;
const RADIX: u32 = 1 << RADIX_BITS;

/// Cubes per grid row: wgpu allows at most 65,535 in each dimension.
const GRID_ROW: u32 = 65_535;

/// A grid of at least `cubes` cubes; kernels number them [`block_index`] and skip those past
/// the count.
pub fn grid(cubes: u32) -> CubeCount {
    let x = cubes.clamp(1, GRID_ROW);
    CubeCount::new_2d(x, cubes.div_ceil(x).max(1))
}

/// This cube's number in a [`grid`].
#[cube]
pub fn block_index() -> u32 {
    CUBE_POS_Y * CUBE_COUNT_X + CUBE_POS_X
}

/// The element this unit handles in a [`grid`] of one element per unit.
#[cube]
pub fn element_index() -> u32 {
    block_index() * BLOCK + UNIT_POS
}

pub fn blocks(elements: u32) -> u32 {
    elements.div_ceil(BLOCK).max(1)
}

pub fn cube_dim() -> CubeDim {
    CubeDim::new_1d(BLOCK)
}

/// A new u32 tensor of `len` elements (contents undefined).
pub fn empty_u32(like: &CubeTensor, len: usize) -> CubeTensor {
    empty_device_dtype(like.client.clone(), like.device.clone(), [len.max(1)].into(), DType::U32)
}

#[cube(launch)]
fn scan_blocks(input: &Tensor<u32>, output: &mut Tensor<u32>, sums: &mut Tensor<u32>, len: u32) {
    // Cubes past the last block (the grid's last row) have nothing to do; block 0 always writes
    // its sum, even of nothing.
    if block_index() * BLOCK >= len && block_index() > 0 {
        terminate!();
    }
    let i = element_index();
    let mut buffer = Shared::<[u32]>::new_slice(BLOCK_SLOTS);
    let unit = UNIT_POS as usize;
    let mut value = 0u32.runtime();
    if i < len {
        value = input[i as usize];
    }
    buffer[unit] = value;
    sync_cube();
    // Inclusive scan by doubling (Hillis-Steele): log2(BLOCK) rounds.
    let mut offset = 1u32;
    while offset < BLOCK {
        let mut add = 0u32.runtime();
        if UNIT_POS >= offset {
            add = buffer[unit - offset as usize];
        }
        sync_cube();
        buffer[unit] += add;
        sync_cube();
        offset *= 2;
    }
    if i < len {
        output[i as usize] = buffer[unit] - value;
    }
    if UNIT_POS == BLOCK - 1 {
        sums[block_index() as usize] = buffer[unit];
    }
}

#[cube(launch)]
fn add_block_offsets(output: &mut Tensor<u32>, offsets: &Tensor<u32>, len: u32) {
    let i = element_index();
    if i < len {
        output[i as usize] += offsets[block_index() as usize];
    }
}

/// The exclusive prefix sum of the first `len` elements of `input`.
pub fn exclusive_scan(input: &CubeTensor, len: u32) -> CubeTensor {
    let output = empty_u32(input, len as usize);
    let count = blocks(len);
    let sums = empty_u32(input, count as usize);
    let client = &input.client;
    scan_blocks::launch(
        client,
        grid(count),
        cube_dim(),
        input.clone().into_tensor_arg(),
        output.clone().into_tensor_arg(),
        sums.clone().into_tensor_arg(),
        len,
    );
    if count > 1 {
        let offsets = exclusive_scan(&sums, count);
        add_block_offsets::launch(
            client,
            grid(count),
            cube_dim(),
            output.clone().into_tensor_arg(),
            offsets.into_tensor_arg(),
            len,
        );
    }
    output
}

/// Each unit's digit (RADIX for units past the end), shared across the cube.
#[cube]
fn share_digits(keys: &Tensor<u32>, shift: u32, len: u32, digits: &mut Shared<[u32]>) -> u32 {
    let i = element_index();
    let mut digit = RADIX.runtime();
    if i < len {
        digit = (keys[i as usize] >> shift) & (RADIX - 1);
    }
    digits[UNIT_POS as usize] = digit;
    sync_cube();
    digit
}

#[cube(launch)]
fn radix_count(keys: &Tensor<u32>, counts: &mut Tensor<u32>, shift: u32, len: u32, block_count: u32) {
    let block = block_index();
    if block >= block_count {
        terminate!();
    }
    let mut digits = Shared::<[u32]>::new_slice(BLOCK_SLOTS);
    share_digits(keys, shift, len, &mut digits);
    if UNIT_POS < RADIX {
        let mut count = 0u32.runtime();
        for j in 0..BLOCK {
            if digits[j as usize] == UNIT_POS {
                count += 1;
            }
        }
        counts[(UNIT_POS * block_count + block) as usize] = count;
    }
}

#[cube(launch)]
#[allow(clippy::too_many_arguments)]
fn radix_scatter(
    keys: &Tensor<u32>,
    values: &Tensor<u32>,
    keys_out: &mut Tensor<u32>,
    values_out: &mut Tensor<u32>,
    offsets: &Tensor<u32>,
    shift: u32,
    len: u32,
    block_count: u32,
) {
    let block = block_index();
    if block >= block_count {
        terminate!();
    }
    let mut digits = Shared::<[u32]>::new_slice(BLOCK_SLOTS);
    let digit = share_digits(keys, shift, len, &mut digits);
    let i = element_index();
    if i < len {
        let mut rank = 0u32.runtime();
        for j in 0..UNIT_POS {
            if digits[j as usize] == digit {
                rank += 1;
            }
        }
        let target = (offsets[(digit * block_count + block) as usize] + rank) as usize;
        keys_out[target] = keys[i as usize];
        values_out[target] = values[i as usize];
    }
}

/// Sorts the first `len` (key, value) pairs by the low `bits` bits of the keys (higher bits
/// must be zero), stably; returns the sorted keys and values.
pub fn radix_sort(keys: CubeTensor, values: CubeTensor, len: u32, bits: u32) -> (CubeTensor, CubeTensor) {
    let count = blocks(len);
    let client = keys.client.clone();
    let counts = empty_u32(&keys, (count * RADIX) as usize);
    let (mut keys, mut values) = (keys, values);
    let mut shift = 0;
    while shift < bits {
        radix_count::launch(
            &client,
            grid(count),
            cube_dim(),
            keys.clone().into_tensor_arg(),
            counts.clone().into_tensor_arg(),
            shift,
            len,
            count,
        );
        let offsets = exclusive_scan(&counts, count * RADIX);
        let keys_out = empty_u32(&keys, len as usize);
        let values_out = empty_u32(&keys, len as usize);
        radix_scatter::launch(
            &client,
            grid(count),
            cube_dim(),
            keys.into_tensor_arg(),
            values.into_tensor_arg(),
            keys_out.clone().into_tensor_arg(),
            values_out.clone().into_tensor_arg(),
            offsets.into_tensor_arg(),
            shift,
            len,
            count,
        );
        (keys, values) = (keys_out, values_out);
        shift += RADIX_BITS;
    }
    (keys, values)
}

/// Bits needed for keys up to `max_key`, rounded up to whole radix passes.
pub fn key_bits(max_key: u32) -> u32 {
    let bits = u32::BITS - max_key.leading_zeros();
    bits.div_ceil(RADIX_BITS) * RADIX_BITS
}

#[cube(launch)]
fn fill_iota(output: &mut Tensor<u32>, len: u32) {
    let i = element_index();
    if i < len {
        output[i as usize] = i;
    }
}

/// 0, 1, ..., len - 1.
pub fn iota(like: &CubeTensor, len: u32) -> CubeTensor {
    let output = empty_u32(like, len as usize);
    fill_iota::launch(&like.client, grid(blocks(len)), cube_dim(), output.clone().into_tensor_arg(), len);
    output
}

#[cube(launch)]
fn gather_kernel(source: &Tensor<u32>, indices: &Tensor<u32>, output: &mut Tensor<u32>, len: u32) {
    let i = element_index();
    if i < len {
        output[i as usize] = source[indices[i as usize] as usize];
    } else if i == len {
        output[i as usize] = 0;
    }
}

/// `source[indices[i]]` for i < len, then a 0: len + 1 elements, whose exclusive scan ends
/// with the total.
pub fn gather(source: &CubeTensor, indices: &CubeTensor, len: u32) -> CubeTensor {
    let output = empty_u32(source, len as usize + 1);
    gather_kernel::launch(
        &source.client,
        grid(blocks(len + 1)),
        cube_dim(),
        source.clone().into_tensor_arg(),
        indices.clone().into_tensor_arg(),
        output.clone().into_tensor_arg(),
        len,
    );
    output
}
