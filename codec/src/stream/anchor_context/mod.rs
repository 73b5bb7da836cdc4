//! `ACTX`, the anchors' context model (SPEC.md section 12.7): a binary context grid over the
//! anchors' octree cube ([`crate::context_grid`]) and a small MLP that turns each anchor's
//! context into a quantized-Gaussian model (section 5.4) for every one of its values. With it,
//! `AFEA`, `ASCL` and `AOFF` carry no models of their own, and their chunks are decoded
//! together, anchor by anchor, so that each anchor's network is evaluated once.
//!
//! The network's weights are quantized to power-of-two steps and evaluated in binary32 in a
//! fixed order, the context is exact, and the outputs are snapped to the model grids, so every
//! decoder derives the same tables.

mod blocks;
mod models;

use pwgs_bitstream::{FieldError, FieldReader, FieldWriter, Tag};

use super::DecodeError;
use super::anchor::{QuantizedMlp, bounded, check_multiply_adds, exponent, within};
use super::entropy::{BitContext, SymbolDecoder, SymbolEncoder};
use super::gaussian_model::GaussianModel;
use crate::context_grid::ContextGridShape;

pub(super) use blocks::{AttributeBlocks, read_blocks, write_blocks};
pub use models::{
    ContextNetwork, ContextTables, TABLE_SYMBOLS_FIXED, TABLE_SYMBOLS_PER_BYTE, TableBudgetExceeded, snap,
    stream_len_for_table_symbols, table_symbol_budget,
};

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
