//! `AFEA`, `ASCL` and `AOFF` with a context model (SPEC.md 12.7): each its step, then one
//! coded chunk; the three are coded together, anchor by anchor, every value with the model its
//! anchor's network predicts.

use pwgs_bitstream::{FieldReader, FieldWriter, Tag};

use super::super::DecodeError;
use super::super::anchor::{FEATURES, OFFSETS, QuantizedAnchors, SCALING};
use super::super::entropy::{SymbolDecoder, SymbolEncoder};
use super::models::{
    ContextNetwork, ContextTables, TABLE_SYMBOLS_FIXED, TABLE_SYMBOLS_PER_BYTE, TableBudgetExceeded,
    table_symbol_budget,
};
use super::{CONTEXT, QuantizedContext};

/// Anchors whose models are evaluated together, on every core: while a decoder decodes the
/// values of one batch, it evaluates the next batch's networks.
const BATCH: usize = 256;

/// What `AFEA`, `ASCL` and `AOFF` hold once decoded, with or without a context model.
pub(in crate::stream) struct AttributeBlocks {
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
const BLOCKS: [Tag; 3] = [FEATURES, SCALING, OFFSETS];

/// Anchor `i`'s coded values in coding order, as (block, value `t` of the anchor's models,
/// index in the block's array): its F features, its 6 scaling values, then the 3 offsets of
/// each of its open masks (of `masks`, N x K).
fn coded_values(i: usize, (f, k): (usize, usize), masks: &[bool]) -> impl Iterator<Item = (usize, usize, usize)> + '_ {
    let features = (0..f).map(move |c| (0, c, i * f + c));
    let scaling = (0..6).map(move |c| (1, f + c, i * 6 + c));
    let open = (0..k).filter(move |&j| masks[i * k + j]);
    let offsets = open.flat_map(move |j| (0..3).map(move |a| (2, f + 6 + 3 * j + a, (i * k + j) * 3 + a)));
    features.chain(scaling).chain(offsets)
}

/// Writes the three sections of `anchors` (anchor by anchor in `order`) with `context` on an
/// octree of `depth` levels; also gives the in-range symbols of the tables they needed.
pub(in crate::stream) fn write_blocks(
    context: &QuantizedContext,
    depth: u8,
    anchors: &QuantizedAnchors,
    order: &[usize],
) -> ([Vec<u8>; 3], u64) {
    let (f, k) = (anchors.feature_dim, anchors.offsets_per_anchor);
    let network = ContextNetwork::new(context, depth, (f, k));
    let mut tables = ContextTables::new(u64::MAX);
    let arrays = [&anchors.features[..], anchors.scaling.as_flattened(), &anchors.offsets[..]];
    let mut coders = [SymbolEncoder::new(), SymbolEncoder::new(), SymbolEncoder::new()];
    let mut models = Vec::new();
    for batch in order.chunks(BATCH) {
        network.models(&batch.iter().map(|&i| anchors.positions[i]).collect::<Vec<_>>(), &mut models);
        for (&i, anchor) in batch.iter().zip(models.chunks_exact(network.values())) {
            tables.add(anchor).expect("a writer's table budget is unlimited");
            for (b, t, slot) in coded_values(i, (f, k), &anchors.masks) {
                tables.encode(&mut coders[b], anchor[t], arrays[b][slot]);
            }
        }
    }
    let steps = [anchors.feature_step, anchors.scaling_step, anchors.offset_step];
    let sections = std::array::from_fn(|b| {
        let mut w = FieldWriter::new();
        w.f32(steps[b]);
        w.extend(&std::mem::take(&mut coders[b]).finish());
        w.into_bytes()
    });
    (sections, tables.symbols())
}

/// Reads the three sections (as [`write_blocks`] writes them) of anchors at `positions` (in
/// stream order) of F and K values with masks N x K, with `context` on an octree of `depth`
/// levels, in a stream of `stream_len` bytes (the tables' budget).
pub(in crate::stream) fn read_blocks(
    payloads: [&[u8]; 3],
    (context, depth, (f, k)): (&QuantizedContext, u8, (usize, usize)),
    (positions, masks): (&[[u32; 3]], &[bool]),
    stream_len: usize,
) -> Result<AttributeBlocks, DecodeError> {
    let n = positions.len();
    let mut steps = [0.0; 3];
    let mut coders = Vec::with_capacity(3);
    for (((tag, name), payload), step) in BLOCKS.iter().zip(["AFEA", "ASCL", "AOFF"]).zip(payloads).zip(&mut steps) {
        let mut r = FieldReader::new(name, payload);
        *step = super::super::plain::read_step(&mut r)?;
        coders.push(SymbolDecoder::new(r.rest()).map_err(|e| DecodeError::coded(*tag, e))?);
    }
    let mut arrays = [vec![0; n * f], vec![0; n * 6], vec![0; n * k * 3]];
    let network = ContextNetwork::new(context, depth, (f, k));
    let mut tables = ContextTables::new(table_symbol_budget(stream_len));
    let coded = |b: usize| move |e| DecodeError::coded(BLOCKS[b], e);
    let batches: Vec<&[[u32; 3]]> = positions.chunks(BATCH).collect();
    let (mut current, mut next) = (Vec::new(), Vec::new());
    if let Some(first) = batches.first() {
        network.models(first, &mut current);
    }
    for b in 0..batches.len() {
        // The decoders stay on this thread (they are not `Send`); the next batch's networks
        // are evaluated on the pool meanwhile.
        rayon::in_place_scope(|scope| -> Result<(), DecodeError> {
            if let Some(following) = batches.get(b + 1) {
                let (network, next) = (&network, &mut next);
                scope.spawn(move |_| network.models(following, next));
            }
            for (j, anchor) in current.chunks_exact(network.values()).enumerate() {
                tables.add(anchor).map_err(|e| table_budget_error(e, stream_len))?;
                for (block, t, slot) in coded_values(b * BATCH + j, (f, k), masks) {
                    arrays[block][slot] = tables.decode(&mut coders[block], anchor[t]).map_err(coded(block))?;
                }
            }
            Ok(())
        })?;
        std::mem::swap(&mut current, &mut next);
    }
    for (b, coder) in coders.into_iter().enumerate() {
        coder.finish().map_err(coded(b))?;
    }
    let [features, scaling, offsets] = arrays;
    Ok(AttributeBlocks { steps, features, scaling, offsets })
}

/// The error of a stream whose anchors need more table symbols than its length allows.
fn table_budget_error(e: TableBudgetExceeded, stream_len: usize) -> DecodeError {
    DecodeError::invalid(
        CONTEXT,
        format!(
            "the anchors' models need tables of {} symbols, more than the {} a stream of {stream_len} bytes may \
             build ({TABLE_SYMBOLS_FIXED} and {TABLE_SYMBOLS_PER_BYTE} per byte)",
            e.needed, e.budget
        ),
    )
}
