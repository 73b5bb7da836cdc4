//! The anchor content of a stream (SPEC.md section 12, base = 1): anchor positions on an
//! octree-coded voxel grid, each anchor's feature, scaling, offsets and masks quantized and
//! coded as attribute blocks (the plain base's syntax), and the three MLPs that derive the
//! neural Gaussians, quantized to power-of-two steps so that every decoder evaluates exactly
//! the weights the encoder finalized with.

use pwgs_bitstream::{Container, FieldError, FieldReader, FieldWriter, Tag};

use super::anchor_context::{AttributeBlocks, CONTEXT, QuantizedContext, predicted_values, read_blocks, write_blocks};
use super::entropy::{FrequencyTable, SymbolDecoder, SymbolEncoder};
use super::gaussian_model::GaussianModel;
use super::octree::OctreeError;
use super::plain::{Models, PositionGrid, Rows, ValueCheck, read_block, read_positions, write_block, write_positions};
use super::wrap::{MAX_EXPONENT, MIN_EXPONENT, power_of_two, quantize_to_step};
use super::{BYTES_PER_GAUSSIAN, DecodeError, Sections};
use crate::anchor::{AnchorModel, Mlp};

pub const ANCHOR_POSITIONS: Tag = Tag(*b"APOS");
pub const FEATURES: Tag = Tag(*b"AFEA");
pub const SCALING: Tag = Tag(*b"ASCL");
pub const OFFSETS: Tag = Tag(*b"AOFF");
pub const MASKS: Tag = Tag(*b"AMSK");
pub const NETWORKS: Tag = Tag(*b"AMLP");

/// Limits on the shape a stream may declare (SPEC.md section 12.1).
pub const MAX_FEATURES: usize = 256;
pub const MAX_OFFSETS: usize = 64;
pub const MAX_HIDDEN: usize = 256;

/// Quantized values a stream may hold per byte of its length, on average (SPEC.md section 9):
/// with the anchor count this bounds a decoder's work by the size of the stream.
pub const VALUES_PER_BYTE: u64 = 32;

/// The values one anchor holds: F features, 6 scaling values, 3K offsets and K masks.
pub fn values_per_anchor(feature_dim: usize, offsets: usize) -> u64 {
    (feature_dim + 6 + 4 * offsets) as u64
}

/// Multiply-adds the networks of a stream may cost per byte of its length (SPEC.md section 9):
/// the view networks per anchor and view (12.1), the context network per anchor (12.7). With
/// the count bound, a decoder's work on a view is proportional to the stream's size, whatever
/// the widths it declares (a 1 MB stream costs at most about 2^30 multiply-adds per view).
pub const MULTIPLY_ADDS_PER_BYTE: u64 = 1024;

/// The multiply-add bound of `tag`'s networks (SPEC.md 12.1, 12.7): `count` anchors of `work`
/// each in a stream of `stream_len` bytes, else the error naming the section.
pub(super) fn check_multiply_adds(tag: Tag, count: usize, work: u64, stream_len: usize) -> Result<(), DecodeError> {
    match fits_per_byte(count, work, MULTIPLY_ADDS_PER_BYTE, stream_len) {
        true => Ok(()),
        false => Err(DecodeError::invalid(
            tag,
            format!(
                "{count} anchors of {work} multiply-adds each exceed the stream's length of {stream_len} bytes (at \
                 most {MULTIPLY_ADDS_PER_BYTE} multiply-adds per byte)"
            ),
        )),
    }
}

/// Multiply-adds of the three view networks for one anchor (SPEC.md section 12.1): network m
/// has `F + 4` inputs, `H_m` hidden units and `O_m` = K, 3K, 7K outputs.
pub fn view_multiply_adds(feature_dim: usize, offsets: usize, hidden: [usize; 3]) -> u64 {
    hidden.iter().zip([1, 3, 7]).map(|(&h, o)| h as u64 * (feature_dim + 4 + o * offsets) as u64).sum()
}

/// Whether `count` units of `each` fit in a stream of `stream_len` bytes at `per_byte` (computed
/// exactly: the products fit in u128).
pub(super) fn fits_per_byte(count: usize, each: u64, per_byte: u64, stream_len: usize) -> bool {
    count as u128 * u128::from(each) <= u128::from(per_byte) * stream_len as u128
}

/// One MLP as the stream holds it: `w1, b1, w2, b2` (row-major [output][input]) as integers,
/// weights times 2^weight_exponent and biases times 2^bias_exponent.
#[derive(Debug, Clone, PartialEq)]
pub struct QuantizedMlp {
    pub hidden: usize,
    pub weight_exponent: i8,
    pub bias_exponent: i8,
    pub w1: Vec<i32>,
    pub b1: Vec<i32>,
    pub w2: Vec<i32>,
    pub b2: Vec<i32>,
}

impl QuantizedMlp {
    /// Rounds every parameter of `mlp` to the nearest multiple of its step.
    pub fn quantize(mlp: &Mlp, weight_exponent: i8, bias_exponent: i8) -> Self {
        let q = |values: &[f32], e: i8| {
            let step = power_of_two(e);
            values.iter().map(|&v| quantize_to_step(v, step)).collect()
        };
        Self {
            hidden: mlp.hidden,
            weight_exponent,
            bias_exponent,
            w1: q(&mlp.w1, weight_exponent),
            b1: q(&mlp.b1, bias_exponent),
            w2: q(&mlp.w2, weight_exponent),
            b2: q(&mlp.b2, bias_exponent),
        }
    }

    /// Normative reconstruction: `f32(q) * 2^e` (exact).
    pub fn dequantize(&self, inputs: usize, outputs: usize) -> Mlp {
        let d = |values: &[i32], e: i8| {
            let step = power_of_two(e);
            values.iter().map(|&q| q as f32 * step).collect()
        };
        Mlp {
            inputs,
            hidden: self.hidden,
            outputs,
            w1: d(&self.w1, self.weight_exponent),
            b1: d(&self.b1, self.bias_exponent),
            w2: d(&self.w2, self.weight_exponent),
            b2: d(&self.b2, self.bias_exponent),
        }
    }

    fn tensors(&self) -> [&Vec<i32>; 4] {
        [&self.w1, &self.b1, &self.w2, &self.b2]
    }
}

/// Quantized anchors: exactly what an anchor stream stores, anchors in the order the octree
/// lists them.
#[derive(Debug, Clone, PartialEq)]
pub struct QuantizedAnchors {
    pub grid: PositionGrid,
    pub positions: Vec<[u32; 3]>,
    /// Feature length F.
    pub feature_dim: usize,
    /// Neural Gaussians per anchor, K.
    pub offsets_per_anchor: usize,
    pub feature_step: f32,
    /// N x F.
    pub features: Vec<i32>,
    pub scaling_step: f32,
    pub scaling: Vec<[i32; 6]>,
    pub offset_step: f32,
    /// N x 3K; those of masked neural Gaussians are 0 (the stream does not hold them).
    pub offsets: Vec<i32>,
    /// N x K.
    pub masks: Vec<bool>,
    /// Opacity (K outputs), color (3K) and covariance (7K), each with F + 4 inputs.
    pub mlps: [QuantizedMlp; 3],
    /// The context model that codes features, scaling and offsets, if any (else each channel
    /// has its own model).
    pub context: Option<QuantizedContext>,
}

impl QuantizedAnchors {
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Outputs of the opacity, color and covariance MLPs.
    fn outputs(&self) -> [usize; 3] {
        let k = self.offsets_per_anchor;
        [k, 3 * k, 7 * k]
    }

    /// The model this content decodes to (normative reconstruction, SPEC.md section 12).
    pub fn dequantize(&self) -> AnchorModel {
        let scaled = |values: &[i32], step: f32| values.iter().map(|&q| q as f32 * step).collect::<Vec<f32>>();
        let [opacity, color, covariance] =
            std::array::from_fn(|i| self.mlps[i].dequantize(self.feature_dim + 4, self.outputs()[i]));
        AnchorModel {
            feature_dim: self.feature_dim,
            offsets_per_anchor: self.offsets_per_anchor,
            positions: self.positions.iter().map(|&q| self.grid.position(q)).collect(),
            features: scaled(&self.features, self.feature_step),
            scaling: self.scaling.iter().map(|s| s.map(|q| q as f32 * self.scaling_step)).collect(),
            offsets: scaled(&self.offsets, self.offset_step),
            masks: self.masks.clone(),
            opacity,
            color,
            covariance,
        }
    }

    /// The sections of this content, every per-anchor value in the octree's order, and the
    /// in-range symbols of the context model's tables (0 without one).
    pub(super) fn write_sections(&self) -> Result<(Sections, u64), OctreeError> {
        let (positions, order) = write_positions(&self.grid, &self.positions)?;
        let (f, k) = (self.feature_dim, self.offsets_per_anchor);
        let block = |models, steps: &[f32], channels: usize, value: &dyn Fn(usize, usize) -> i32| {
            let mut w = FieldWriter::new();
            steps.iter().for_each(|&s| w.f32(s));
            write_block(&mut w, models, (&order, None), channels, value);
            w.into_bytes()
        };
        let masks = (MASKS, block(Models::Tables, &[], k, &|i, c| i32::from(self.masks[i * k + c])));
        let Some(context) = &self.context else {
            let sections = vec![
                (NETWORKS, self.write_networks()),
                (ANCHOR_POSITIONS, positions),
                (FEATURES, block(Models::Gaussians, &[self.feature_step], f, &|i, c| self.features[i * f + c])),
                (SCALING, block(Models::Gaussians, &[self.scaling_step], 6, &|i, c| self.scaling[i][c])),
                masks,
                (OFFSETS, self.write_offsets(&order)),
            ];
            return Ok((sections, 0));
        };
        let ([features, scaling, offsets], table_symbols) = write_blocks(context, self.grid.depth, self, &order);
        let sections = vec![
            (NETWORKS, self.write_networks()),
            (ANCHOR_POSITIONS, positions),
            (CONTEXT, context.write(self.grid.depth)),
            (FEATURES, features),
            (SCALING, scaling),
            masks,
            (OFFSETS, offsets),
        ];
        Ok((sections, table_symbols))
    }

    /// `AOFF`: the offsets of the unmasked neural Gaussians only, anchor by anchor (in `order`),
    /// offset by offset, one table per axis.
    fn write_offsets(&self, order: &[usize]) -> Vec<u8> {
        let k = self.offsets_per_anchor;
        let open: Vec<usize> =
            order.iter().flat_map(|&i| (0..k).map(move |j| i * k + j)).filter(|&r| self.masks[r]).collect();
        let mut w = FieldWriter::new();
        w.f32(self.offset_step);
        write_block(&mut w, Models::Gaussians, (&open, None), 3, &|r, a| self.offsets[r * 3 + a]);
        w.into_bytes()
    }

    /// `AMLP`: the shape, the step exponents, one quantized-Gaussian model per tensor, then
    /// every parameter in one coded chunk, tensor by tensor.
    fn write_networks(&self) -> Vec<u8> {
        let mut w = FieldWriter::new();
        w.varint(self.feature_dim as u32);
        w.varint(self.offsets_per_anchor as u32);
        for m in &self.mlps {
            w.varint(m.hidden as u32);
            w.u8(m.weight_exponent as u8);
            w.u8(m.bias_exponent as u8);
        }
        let tensors: Vec<&Vec<i32>> = self.mlps.iter().flat_map(|m| m.tensors()).collect();
        let models: Vec<GaussianModel> = tensors.iter().map(|t| GaussianModel::fit(t)).collect();
        models.iter().for_each(|m| m.write(&mut w));
        let tables: Vec<FrequencyTable> = models.iter().map(|m| m.table()).collect();
        let mut coder = SymbolEncoder::new();
        for (values, table) in tensors.iter().zip(&tables) {
            values.iter().for_each(|&v| coder.value(table, v));
        }
        w.extend(&coder.finish());
        w.into_bytes()
    }

    /// Reads and decodes the content sections in SPEC.md's order (section 12.5): presence of
    /// every section, `AMLP`, the bound on the anchor count, positions, then the blocks.
    pub(super) fn read_sections(container: &Container, count: usize, stream_len: usize) -> Result<Self, DecodeError> {
        let payload = |tag: Tag| container.section(tag).map(|s| s.payload).ok_or(DecodeError::MissingSection(tag));
        let payloads = [NETWORKS, ANCHOR_POSITIONS, FEATURES, SCALING, MASKS, OFFSETS].map(payload);
        let [networks, positions, features, scaling, masks, offsets] = payloads;
        let (networks, positions, features, scaling, masks, offsets) =
            (networks?, positions?, features?, scaling?, masks?, offsets?);
        let (feature_dim, k, mlps) = read_networks(networks)?;
        if !fits_per_byte(count, values_per_anchor(feature_dim, k), VALUES_PER_BYTE, stream_len) {
            return Err(DecodeError::invalid(
                NETWORKS,
                format!(
                    "{count} anchors of {} values each exceed the stream's length of {stream_len} bytes \
                     (at most {VALUES_PER_BYTE} values per byte)",
                    values_per_anchor(feature_dim, k)
                ),
            ));
        }
        let work = view_multiply_adds(feature_dim, k, mlps.each_ref().map(|m| m.hidden));
        check_multiply_adds(NETWORKS, count, work, stream_len)?;
        let (grid, positions) = read_positions(ANCHOR_POSITIONS, positions, count)?;
        let read_masks = || -> Result<Vec<bool>, DecodeError> {
            let (_, masks) = read_block(MASKS, masks, (Models::Tables, 0, k, check_mask), Rows::plain(count))?;
            let masks: Vec<bool> = masks.into_iter().map(|m| m == 1).collect();
            let open = masks.iter().filter(|&&m| m).count();
            // Neural Gaussians a view may show: as many as a plain stream of this length may
            // hold Gaussians (SPEC.md 12.3), so that what rendering them takes is bounded by the
            // stream's size.
            if !fits_per_byte(open, BYTES_PER_GAUSSIAN, 1, stream_len) {
                return Err(DecodeError::invalid(
                    MASKS,
                    format!(
                        "{open} unmasked offsets exceed half the stream's length of {stream_len} bytes \
                         (at least {BYTES_PER_GAUSSIAN} bytes per unmasked offset)"
                    ),
                ));
            }
            Ok(masks)
        };
        let (context, masks, blocks) = match container.section(CONTEXT) {
            // With ACTX: the masks first, then the three blocks together (SPEC.md 12.7).
            Some(section) => {
                let values = predicted_values(feature_dim, k);
                let context = QuantizedContext::read(section.payload, grid.depth, values, (count, stream_len))?;
                let masks = read_masks()?;
                let blocks = read_blocks(
                    [features, scaling, offsets],
                    (&context, grid.depth, (feature_dim, k)),
                    (&positions, &masks),
                    stream_len,
                )?;
                (Some(context), masks, blocks)
            }
            None => {
                let any: ValueCheck = |_, _| Ok(());
                let gaussians = |channels| (Models::Gaussians, 1, channels, any);
                let (feature_steps, features) =
                    read_block(FEATURES, features, gaussians(feature_dim), Rows::plain(count))?;
                let (scaling_steps, scaling) = read_block(SCALING, scaling, gaussians(6), Rows::plain(count))?;
                let masks = read_masks()?;
                let open = masks.iter().filter(|&&m| m).count();
                let (offset_steps, open_offsets) = read_block(OFFSETS, offsets, gaussians(3), Rows::plain(open))?;
                // Masked neural Gaussians have no offsets in the stream: they are 0.
                let mut offsets = vec![0; count * k * 3];
                let mut coded = open_offsets.chunks_exact(3);
                for (r, _) in masks.iter().enumerate().filter(|(_, m)| **m) {
                    offsets[r * 3..r * 3 + 3].copy_from_slice(coded.next().expect("one triple per open mask"));
                }
                let steps = [feature_steps[0], scaling_steps[0], offset_steps[0]];
                (None, masks, AttributeBlocks { steps, features, scaling, offsets })
            }
        };
        let [feature_step, scaling_step, offset_step] = blocks.steps;
        Ok(Self {
            grid,
            positions,
            feature_dim,
            offsets_per_anchor: k,
            feature_step,
            features: blocks.features,
            scaling_step,
            scaling: blocks.scaling.chunks_exact(6).map(|c| std::array::from_fn(|i| c[i])).collect(),
            offset_step,
            offsets: blocks.offsets,
            masks,
            mlps,
            context,
        })
    }
}

/// A mask is 0 (the neural Gaussian is never shown) or 1.
fn check_mask(_: usize, value: i32) -> Result<(), String> {
    match value {
        0 | 1 => Ok(()),
        other => Err(format!("mask value {other} is not 0 or 1")),
    }
}

fn read_networks(payload: &[u8]) -> Result<(usize, usize, [QuantizedMlp; 3]), DecodeError> {
    let mut r = FieldReader::new("AMLP", payload);
    let feature_dim = bounded(&mut r, "feature dimension", MAX_FEATURES)?;
    let k = bounded(&mut r, "offsets per anchor", MAX_OFFSETS)?;
    let mut shapes = [(0usize, 0i8, 0i8); 3];
    for shape in &mut shapes {
        let hidden = bounded(&mut r, "hidden width", MAX_HIDDEN)?;
        *shape = (hidden, exponent(&mut r, "weight step exponent")?, exponent(&mut r, "bias step exponent")?);
    }
    let inputs = feature_dim + 4;
    let sizes: Vec<usize> = shapes
        .iter()
        .zip([k, 3 * k, 7 * k])
        .flat_map(|(&(hidden, _, _), outputs)| [hidden * inputs, hidden, outputs * hidden, outputs])
        .collect();
    let tables = (0..sizes.len())
        .map(|_| GaussianModel::read(&mut r).map(GaussianModel::table))
        .collect::<Result<Vec<_>, FieldError>>()?;
    let coded = |e| DecodeError::coded(NETWORKS, e);
    let mut coder = SymbolDecoder::new(r.rest()).map_err(coded)?;
    let mut tensors = Vec::with_capacity(sizes.len());
    for (&size, table) in sizes.iter().zip(&tables) {
        // Table values stay below 2^24 in magnitude, so `q * 2^e` is exact.
        tensors.push((0..size).map(|_| coder.value(table)).collect::<Result<Vec<i32>, _>>().map_err(coded)?);
    }
    coder.finish().map_err(coded)?;
    let mut tensors = tensors.into_iter();
    let mlps = shapes.map(|(hidden, weight_exponent, bias_exponent)| {
        let mut next = || tensors.next().expect("four tensors per MLP");
        QuantizedMlp { hidden, weight_exponent, bias_exponent, w1: next(), b1: next(), w2: next(), b2: next() }
    });
    Ok((feature_dim, k, mlps))
}

/// A varint field that must be 1 to `max`.
pub(super) fn bounded(r: &mut FieldReader, field: &'static str, max: usize) -> Result<usize, FieldError> {
    within(r, field, 1..=max)
}

/// A varint count in `range`.
pub(super) fn within(
    r: &mut FieldReader,
    field: &'static str,
    range: std::ops::RangeInclusive<usize>,
) -> Result<usize, FieldError> {
    let v = r.varint(field)? as usize;
    match range.contains(&v) {
        true => Ok(v),
        false => Err(r.error(field, format!("{v} is outside {range:?}"))),
    }
}

/// A step exponent (i8), -30 to 0.
pub(super) fn exponent(r: &mut FieldReader, field: &'static str) -> Result<i8, FieldError> {
    let e = r.u8(field)? as i8;
    match (MIN_EXPONENT..=MAX_EXPONENT).contains(&e) {
        true => Ok(e),
        false => Err(r.error(field, format!("{e} is outside {MIN_EXPONENT}..={MAX_EXPONENT}"))),
    }
}
