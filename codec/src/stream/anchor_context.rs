//! `ACTX`, the anchors' context model (SPEC.md section 12.7): a binary context grid over the
//! anchors' octree cube ([`crate::context_grid`]) and a small MLP that turns each anchor's
//! context into a quantized-Gaussian model (section 5.4) for every one of its values. With it,
//! `AFEA`, `ASCL` and `AOFF` carry no models of their own, and their chunks are decoded
//! together, anchor by anchor, so that each anchor's network is evaluated once.
//!
//! The network's weights are quantized to power-of-two steps and evaluated in binary32 in a
//! fixed order, the context is exact, and the outputs are snapped to the model grids, so every
//! decoder derives the same tables.

use std::collections::HashMap;

use pwgs_bitstream::{FieldError, FieldReader, FieldWriter, Tag};
use rayon::prelude::*;

use super::DecodeError;
use super::anchor::{QuantizedAnchors, QuantizedMlp, bounded, check_multiply_adds, exponent, within};
use super::entropy::{BitContext, EntropyError, FrequencyTable, SymbolDecoder, SymbolEncoder};
use super::gaussian_model::{GaussianModel, MAX_MEAN, MEAN_DENOMINATOR, SCALE_OFFSET};
use crate::anchor::Mlp;
use crate::context_grid::{ContextGridShape, Corner};

pub const CONTEXT: Tag = Tag(*b"ACTX");

/// Limits on the grid and network a stream may declare (SPEC.md section 12.7).
pub const MAX_LEVELS: usize = 16;
pub const MAX_LEVEL_LOG2: u8 = 24;
pub const TABLE_LOG2: std::ops::RangeInclusive<u8> = 4..=22;
pub const MAX_CHANNELS: u8 = 8;
pub const MAX_CONTEXT_HIDDEN: usize = 128;

/// Grid signs a stream may hold per byte of its length (SPEC.md section 12.7): bounds a
/// decoder's work on a grid whose adaptive bits cost almost nothing.
pub const GRID_BITS_PER_BYTE: u64 = 64;

/// A context model as the stream holds it.
#[derive(Debug, Clone, PartialEq)]
pub struct QuantizedContext {
    pub shape: ContextGridShape,
    /// The grid's entries, entry-major (`channels` per entry), true for +1.
    pub signs: Vec<bool>,
    /// Inputs: levels x channels; outputs: 2 V, V = F + 6 + 3K (means, then log2 scales).
    pub mlp: QuantizedMlp,
}

/// Values an anchor's network predicts: F features, 6 scaling values, 3K offsets.
pub fn predicted_values(feature_dim: usize, offsets: usize) -> usize {
    feature_dim + 6 + 3 * offsets
}

/// Multiply-adds of one anchor's context and network (SPEC.md section 12.7): `8 I` for the
/// context (at most 8 weighted corners per input) and `H (I + 2 V)` for the network, with `I`
/// the context's length and `V` the values it predicts.
pub fn context_multiply_adds(shape: &ContextGridShape, hidden: usize, values: usize) -> u64 {
    let inputs = shape.context_len() as u64;
    8 * inputs + hidden as u64 * (inputs + 2 * values as u64)
}

/// The quantized-Gaussian model of a value from the network's outputs for its mean `u` (in
/// quantization units) and its log2 scale `s` (in units): `M = floor(64 u + 1/2)` and `J =
/// floor(8 s + 1/2) + 96`, each clamped to its range (binary64, every operation exact).
pub fn snap(u: f32, s: f32) -> GaussianModel {
    let limit = f64::from(MAX_MEAN);
    let mean = (f64::from(u) * f64::from(MEAN_DENOMINATOR) + 0.5).floor();
    let scale = (f64::from(s) * 8.0 + 0.5).floor() + f64::from(SCALE_OFFSET);
    // A NaN (impossible from finite weights, but free to rule out) snaps to 0 and the
    // smallest scale.
    let mean = if mean.is_nan() { 0.0 } else { mean.clamp(-limit, limit) };
    let scale = if scale.is_nan() { 0.0 } else { scale.clamp(0.0, 255.0) };
    GaussianModel { mean: mean as i32, scale: scale as u8 }
}

/// Per anchor, the models of its values, and their tables (built once per fractional mean and
/// scale: a table moves with the integer part of its mean).
pub struct AnchorModels<'a> {
    context: &'a QuantizedContext,
    mlp: Mlp,
    depth: u8,
    feature_dim: usize,
    offsets: usize,
    values: usize,
    corners: Vec<Corner>,
    hidden: Vec<f32>,
    out: Vec<f32>,
    tables: HashMap<(i32, u8), FrequencyTable>,
}

impl<'a> AnchorModels<'a> {
    /// The models of anchors of `feature_dim` features and `offsets` offsets on an octree of
    /// `depth` levels.
    pub fn new(context: &'a QuantizedContext, depth: u8, feature_dim: usize, offsets: usize) -> Self {
        let values = predicted_values(feature_dim, offsets);
        let mlp = context.mlp.dequantize(context.shape.context_len(), 2 * values);
        Self {
            context,
            hidden: vec![0.0; mlp.hidden],
            out: vec![0.0; 2 * values],
            mlp,
            depth,
            feature_dim,
            offsets,
            values,
            corners: Vec::new(),
            tables: HashMap::new(),
        }
    }

    /// Evaluates the network for the anchor at octree coordinates `q`, and builds the tables
    /// of its values that no anchor before it needed.
    pub fn evaluate(&mut self, q: [u32; 3]) {
        self.corners.clear();
        self.context.shape.corners(q, self.depth, &mut self.corners);
        let input = self.context.shape.context(&self.corners, &self.context.signs);
        self.mlp.forward(&input, &mut self.hidden, &mut self.out);
        self.build_new_tables();
    }

    /// Builds the anchor's new tables on every core. A stream may need every table there is,
    /// 64 fractions x 256 scales of up to 4,096 symbols (107 MB), from a few hundred anchors:
    /// built one at a time as values ask for them, they took 1.1 s (release) on one core, a
    /// constant on top of any stream's decoding. Tables are pure functions of their key, so the
    /// order they are built in changes nothing.
    fn build_new_tables(&mut self) {
        let mut keys: Vec<(i32, u8)> =
            (0..self.values).map(|t| table_key(self.model(t)).1).filter(|k| !self.tables.contains_key(k)).collect();
        if keys.len() < 2 {
            return;
        }
        keys.sort_unstable();
        keys.dedup();
        let built: Vec<_> = keys
            .into_par_iter()
            .map(|(fraction, scale)| ((fraction, scale), GaussianModel { mean: fraction, scale }.table()))
            .collect();
        self.tables.extend(built);
    }

    /// The model of value `t` (features, then scaling, then offsets 3j + a) of the anchor last
    /// evaluated.
    pub fn model(&self, t: usize) -> GaussianModel {
        snap(self.out[t], self.out[self.values + t])
    }

    /// The table of value `t` and how far it moves.
    fn table(&mut self, t: usize) -> (&FrequencyTable, i32) {
        let (whole, (fraction, scale)) = table_key(self.model(t));
        let table =
            self.tables.entry((fraction, scale)).or_insert_with(|| GaussianModel { mean: fraction, scale }.table());
        (table, whole)
    }

    pub fn encode(&mut self, coder: &mut SymbolEncoder, t: usize, value: i32) {
        let (table, shift) = self.table(t);
        coder.shifted_value(table, shift, value);
    }

    pub fn decode(&mut self, coder: &mut SymbolDecoder, t: usize) -> Result<i32, EntropyError> {
        let (table, shift) = self.table(t);
        coder.shifted_value(table, shift)
    }
}

/// How far a model's table moves (the whole part of its mean) and the key of the table: its
/// mean's fraction (in 64ths) and its scale.
fn table_key(model: GaussianModel) -> (i32, (i32, u8)) {
    (model.mean.div_euclid(MEAN_DENOMINATOR), (model.mean.rem_euclid(MEAN_DENOMINATOR), model.scale))
}

impl QuantizedContext {
    /// `ACTX`'s payload, for anchors on an octree of `depth` levels.
    pub fn write(&self, depth: u8) -> Vec<u8> {
        let mut w = FieldWriter::new();
        w.varint(self.shape.levels.len() as u32);
        self.shape.levels.iter().for_each(|&r| w.u8(r));
        w.varint(self.shape.planes.len() as u32);
        self.shape.planes.iter().for_each(|&r| w.u8(r));
        w.u8(self.shape.table_log2);
        w.varint(u32::from(self.shape.channels));
        let m = &self.mlp;
        w.varint(m.hidden as u32);
        w.u8(m.weight_exponent as u8);
        w.u8(m.bias_exponent as u8);
        let tensors = [&m.w1, &m.b1, &m.w2, &m.b2];
        let models: Vec<GaussianModel> = tensors.iter().map(|t| GaussianModel::fit(t)).collect();
        models.iter().for_each(|g| g.write(&mut w));
        let mut coder = SymbolEncoder::new();
        let c = usize::from(self.shape.channels);
        let mut contexts = vec![BitContext::default(); c];
        debug_assert_eq!(self.signs.len(), self.shape.entries(depth) as usize * c);
        for (i, &sign) in self.signs.iter().enumerate() {
            coder.bit(&mut contexts[i % c], sign);
        }
        for (values, model) in tensors.iter().zip(&models) {
            let table = model.table();
            values.iter().for_each(|&v| coder.value(&table, v));
        }
        w.extend(&coder.finish());
        w.into_bytes()
    }

    /// Reads `ACTX` for `count` anchors of `values` predicted values on an octree of `depth`,
    /// in a stream of `stream_len` bytes (the grid may hold at most 64 entries per byte of it,
    /// and the network cost at most [`super::anchor::MULTIPLY_ADDS_PER_BYTE`] per byte over the anchors).
    pub fn read(
        payload: &[u8],
        depth: u8,
        values: usize,
        (count, stream_len): (usize, usize),
    ) -> Result<Self, DecodeError> {
        let mut r = FieldReader::new("ACTX", payload);
        let levels = bounded(&mut r, "levels", MAX_LEVELS)?;
        let levels = (0..levels).map(|_| level(&mut r, "level")).collect::<Result<Vec<u8>, FieldError>>()?;
        let planes = within(&mut r, "plane levels", 0..=MAX_LEVELS)?;
        let planes = (0..planes).map(|_| level(&mut r, "plane level")).collect::<Result<Vec<u8>, FieldError>>()?;
        let table_log2 = r.u8("table log2")?;
        if !TABLE_LOG2.contains(&table_log2) {
            return Err(r.error("table log2", format!("{table_log2} is outside {TABLE_LOG2:?}")).into());
        }
        let channels = bounded(&mut r, "channels", usize::from(MAX_CHANNELS))? as u8;
        let shape = ContextGridShape { levels, planes, table_log2, channels };
        let bits = u64::from(shape.entries(depth)) * u64::from(channels);
        if bits > GRID_BITS_PER_BYTE * stream_len as u64 {
            return Err(DecodeError::invalid(
                CONTEXT,
                format!(
                    "a grid of {bits} bits exceeds the stream's length of {stream_len} bytes (at most 64 per byte)"
                ),
            ));
        }
        let hidden = bounded(&mut r, "hidden width", MAX_CONTEXT_HIDDEN)?;
        let work = context_multiply_adds(&shape, hidden, values);
        check_multiply_adds(CONTEXT, count, work, stream_len)?;
        let (weight_exponent, bias_exponent) =
            (exponent(&mut r, "weight step exponent")?, exponent(&mut r, "bias step exponent")?);
        let inputs = shape.context_len();
        let sizes = [hidden * inputs, hidden, 2 * values * hidden, 2 * values];
        let tables =
            (0..4).map(|_| GaussianModel::read(&mut r).map(GaussianModel::table)).collect::<Result<Vec<_>, _>>()?;
        let coded = |e| DecodeError::coded(CONTEXT, e);
        let mut coder = SymbolDecoder::new(r.rest()).map_err(coded)?;
        let c = usize::from(channels);
        let mut contexts = vec![BitContext::default(); c];
        let signs = (0..bits as usize)
            .map(|i| coder.bit(&mut contexts[i % c]))
            .collect::<Result<Vec<bool>, _>>()
            .map_err(coded)?;
        let mut tensors = Vec::with_capacity(4);
        for (&size, table) in sizes.iter().zip(&tables) {
            tensors.push((0..size).map(|_| coder.value(table)).collect::<Result<Vec<i32>, _>>().map_err(coded)?);
        }
        coder.finish().map_err(coded)?;
        let [w1, b1, w2, b2]: [Vec<i32>; 4] = tensors.try_into().expect("four tensors");
        Ok(Self { shape, signs, mlp: QuantizedMlp { hidden, weight_exponent, bias_exponent, w1, b1, w2, b2 } })
    }
}

/// A level's resolution log2, 1 to [`MAX_LEVEL_LOG2`].
fn level(r: &mut FieldReader, field: &'static str) -> Result<u8, FieldError> {
    let v = r.u8(field)?;
    match (1..=MAX_LEVEL_LOG2).contains(&v) {
        true => Ok(v),
        false => Err(r.error(field, format!("{v} is outside 1..={MAX_LEVEL_LOG2}"))),
    }
}

/// What `AFEA`, `ASCL` and `AOFF` hold once decoded, with or without a context model.
pub(super) struct AttributeBlocks {
    /// Steps of features, scaling and offsets.
    pub steps: [f32; 3],
    /// N x F.
    pub features: Vec<i32>,
    /// N x 6.
    pub scaling: Vec<i32>,
    /// N x 3K, 0 where masked.
    pub offsets: Vec<i32>,
}

/// The three sections with a context model.
pub(super) const BLOCKS: [Tag; 3] = [super::anchor::FEATURES, super::anchor::SCALING, super::anchor::OFFSETS];

/// Writes the three sections: each its step, then one chunk; anchor by anchor (in `order`),
/// its features into `AFEA`, its scaling into `ASCL`, the offsets of its open masks into
/// `AOFF`, each value with its model.
pub(super) fn write_blocks(models: &mut AnchorModels, anchors: &QuantizedAnchors, order: &[usize]) -> [Vec<u8>; 3] {
    let (f, k) = (models.feature_dim, models.offsets);
    let mut coders = [SymbolEncoder::new(), SymbolEncoder::new(), SymbolEncoder::new()];
    for &i in order {
        models.evaluate(anchors.positions[i]);
        for c in 0..f {
            models.encode(&mut coders[0], c, anchors.features[i * f + c]);
        }
        for c in 0..6 {
            models.encode(&mut coders[1], f + c, anchors.scaling[i][c]);
        }
        for j in (0..k).filter(|&j| anchors.masks[i * k + j]) {
            for a in 0..3 {
                models.encode(&mut coders[2], f + 6 + 3 * j + a, anchors.offsets[(i * k + j) * 3 + a]);
            }
        }
    }
    let mut out = coders.map(|coder| coder.finish());
    let steps = [anchors.feature_step, anchors.scaling_step, anchors.offset_step];
    for (bytes, step) in out.iter_mut().zip(steps) {
        let mut w = FieldWriter::new();
        w.f32(step);
        w.extend(bytes);
        *bytes = w.into_bytes();
    }
    out
}

/// Reads the three sections (as [`write_blocks`] writes them) for anchors at `positions` in
/// stream order, with masks N x K.
pub(super) fn read_blocks(
    payloads: [&[u8]; 3],
    models: &mut AnchorModels,
    positions: &[[u32; 3]],
    masks: &[bool],
) -> Result<AttributeBlocks, DecodeError> {
    let n = positions.len();
    let (f, k) = (models.feature_dim, models.offsets);
    let mut steps = [0.0; 3];
    let mut coders = Vec::with_capacity(3);
    for (((tag, name), payload), step) in BLOCKS.iter().zip(["AFEA", "ASCL", "AOFF"]).zip(payloads).zip(&mut steps) {
        let mut r = FieldReader::new(name, payload);
        *step = super::plain::read_step(&mut r)?;
        coders.push(SymbolDecoder::new(r.rest()).map_err(|e| DecodeError::coded(*tag, e))?);
    }
    let mut blocks = AttributeBlocks {
        steps,
        features: Vec::with_capacity(n * f),
        scaling: Vec::with_capacity(n * 6),
        offsets: vec![0; n * k * 3],
    };
    let coded = |b: usize| move |e| DecodeError::coded(BLOCKS[b], e);
    for (i, &q) in positions.iter().enumerate() {
        models.evaluate(q);
        for c in 0..f {
            blocks.features.push(models.decode(&mut coders[0], c).map_err(coded(0))?);
        }
        for c in 0..6 {
            blocks.scaling.push(models.decode(&mut coders[1], f + c).map_err(coded(1))?);
        }
        for j in (0..k).filter(|&j| masks[i * k + j]) {
            for a in 0..3 {
                blocks.offsets[(i * k + j) * 3 + a] =
                    models.decode(&mut coders[2], f + 6 + 3 * j + a).map_err(coded(2))?;
            }
        }
    }
    for (b, coder) in coders.into_iter().enumerate() {
        coder.finish().map_err(coded(b))?;
    }
    Ok(blocks)
}
