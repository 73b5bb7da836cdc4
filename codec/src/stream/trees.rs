//! Adaptive tree coding of attribute blocks (section `ADPT`, SPEC.md section 6.7): a block
//! coded this way holds, per table slot (class and channel), a range of values and a few
//! thresholds instead of a frequency table. A value is its offset in the range, coded bit by
//! bit from the most significant down, each bit with an adaptive context (SPEC.md 5.3) of its
//! node in a binary tree; the tree is chosen among the slot's few by where the previous value
//! of the same slot (the previous Gaussian of the same class, in octree order: a neighbour)
//! falls among the thresholds.
//!
//! Why: the static tables code each channel's whole histogram, but a scene's attributes drift
//! from region to region and follow their neighbours. On biker at quality 10 with importance
//! classes (`pwenc --from biker.ply --quality 10 --importance-classes --prune-faint`) the stream
//! goes from 1,070,077 to 1,036,304 bytes (-3.2%), the same Gaussians. A throwaway model of
//! this coding on that stream's integers put the gain at 4.3% of the scales', rotations',
//! opacities' and colours' bytes, of which the adaptive bits alone (one tree a slot) give 3%.

use pwgs_bitstream::{FieldError, FieldReader, FieldWriter, Tag};

use super::DecodeError;
use super::entropy::{BitContext, EntropyError, SymbolDecoder, SymbolEncoder, check_range};

pub const ADAPTIVE: Tag = Tag(*b"ADPT");

/// The blocks `ADPT`'s payload can name, bit `k` for the `k`-th.
pub const BLOCKS: [Tag; 5] = [
    super::plain::SCALES,
    super::plain::ROTATIONS,
    super::plain::OPACITIES,
    super::plain::COLORS,
    super::plain::SH_REST,
];

/// Most trees per slot.
pub const MAX_CONTEXTS: u8 = 16;

/// Most nodes (contexts times `2^depth`) over a block's slots: bounds what a decoder holds for
/// a block (8 MiB of counts) whatever a stream claims.
pub const MAX_NODES: u64 = 1 << 20;

/// Fewest values in a slot for which the encoder splits it into several trees: a tree learns
/// its bits from the values it sees, and 8 trees of fewer than 32 values each would learn
/// little (a choice, not measured: the slots of the scenes measured hold thousands).
const SPLIT_FROM: usize = 256;

/// Trees an encoder splits a slot into (by quantiles of the previous values). With the
/// throwaway model on biker's quality-10 integers: 4 trees 1.1%, 8 trees 1.4% and 16 trees
/// 1.2% smaller than 1.
const SPLIT_INTO: usize = 8;

/// The model of one slot: its values `lo .. lo + size`, and the thresholds that choose its
/// tree (tree `k` when `k` thresholds are at most the previous value).
#[derive(Debug, Clone, PartialEq)]
pub struct TreeModel {
    pub lo: i32,
    pub size: u32,
    pub thresholds: Vec<i32>,
}

impl TreeModel {
    /// The model an encoder uses for a slot's `values` (in coding order, so that each one's
    /// previous value is the one before it, 0 for the first); `None` when they span more than
    /// the largest range (the block keeps its frequency tables then). Not normative: a decoder
    /// only reads the result.
    pub fn fit(values: &[i32]) -> Option<Self> {
        let (Some(&lo), Some(&hi)) = (values.iter().min(), values.iter().max()) else {
            return Some(Self { lo: 0, size: 1, thresholds: vec![] });
        };
        let size = u32::try_from(i64::from(hi) - i64::from(lo) + 1).ok()?;
        check_range(lo, size as usize).ok()?;
        let mut thresholds = Vec::new();
        if values.len() >= SPLIT_FROM {
            // The previous values: 0, then all but the last.
            let mut sorted: Vec<i32> = std::iter::once(0).chain(values[..values.len() - 1].iter().copied()).collect();
            sorted.sort_unstable();
            for k in 1..SPLIT_INTO {
                let t = sorted[k * sorted.len() / SPLIT_INTO];
                if thresholds.last().is_none_or(|&last| t > last) {
                    thresholds.push(t);
                }
            }
        }
        Some(Self { lo, size, thresholds })
    }

    /// Bits a value takes: the smallest `d` with `2^d >= size`.
    fn depth(&self) -> u32 {
        u32::BITS - (self.size - 1).leading_zeros()
    }

    fn nodes(&self) -> u64 {
        (self.thresholds.len() as u64 + 1) << self.depth()
    }

    /// Syntax: `lo` signed varint, `size` varint, the number of trees u8, then one threshold
    /// fewer as signed varints.
    pub fn write(&self, w: &mut FieldWriter) {
        w.signed_varint(self.lo);
        w.varint(self.size);
        w.u8(self.thresholds.len() as u8 + 1);
        self.thresholds.iter().for_each(|&t| w.signed_varint(t));
    }

    pub fn read(r: &mut FieldReader) -> Result<Self, FieldError> {
        let lo = r.signed_varint("tree lo")?;
        let size = r.varint("tree size")?;
        check_range(lo, size as usize).map_err(|problem| r.error("tree lo/size", problem))?;
        let trees = r.u8("trees")?;
        if !(1..=MAX_CONTEXTS).contains(&trees) {
            return Err(r.error("trees", format!("{trees} is outside 1..={MAX_CONTEXTS}")));
        }
        let mut thresholds: Vec<i32> = Vec::with_capacity(usize::from(trees) - 1);
        for _ in 1..trees {
            let t = r.signed_varint("threshold")?;
            if let Some(&last) = thresholds.last().filter(|&&last| t <= last) {
                return Err(r.error("threshold", format!("{t} is not above the one before ({last})")));
            }
            thresholds.push(t);
        }
        Ok(Self { lo, size, thresholds })
    }
}

/// The models of a block's slots as they code, in slot order: each slot's node contexts (all
/// fresh) and its previous value (0 before its first).
pub struct Trees {
    slots: Vec<Slot>,
}

struct Slot {
    model: TreeModel,
    nodes: Vec<BitContext>,
    previous: i32,
}

impl Slot {
    /// The nodes of the tree the previous value chooses.
    fn tree(&mut self) -> &mut [BitContext] {
        let k = self.model.thresholds.partition_point(|&t| t <= self.previous);
        let width = 1usize << self.model.depth();
        &mut self.nodes[k * width..][..width]
    }
}

impl Trees {
    /// Reads `slots` models and checks that they hold at most [`MAX_NODES`] nodes together.
    pub fn read(r: &mut FieldReader, slots: usize) -> Result<Self, FieldError> {
        let models = (0..slots).map(|_| TreeModel::read(r)).collect::<Result<Vec<_>, _>>()?;
        let nodes = total_nodes(&models);
        if nodes > MAX_NODES {
            return Err(r.error("trees", format!("the block's trees hold {nodes} nodes, more than 2^20")));
        }
        Ok(Self::new(models))
    }

    pub fn new(models: Vec<TreeModel>) -> Self {
        let slots = models
            .into_iter()
            .map(|model| Slot { nodes: vec![BitContext::default(); model.nodes() as usize], model, previous: 0 })
            .collect();
        Self { slots }
    }

    /// Whether the models stay within [`MAX_NODES`].
    pub fn fit_in_a_block(models: &[TreeModel]) -> bool {
        total_nodes(models) <= MAX_NODES
    }

    /// Codes `value`, which must lie in `slot`'s range.
    pub fn encode(&mut self, coder: &mut SymbolEncoder, slot: usize, value: i32) {
        let s = &mut self.slots[slot];
        let (lo, depth) = (s.model.lo, s.model.depth());
        let offset = u32::try_from(i64::from(value) - i64::from(lo)).expect("a value below its tree's range");
        assert!(offset < s.model.size, "value {value} beyond its tree's range");
        let tree = s.tree();
        let mut node = 1;
        for level in (0..depth).rev() {
            let bit = offset >> level & 1 == 1;
            coder.bit(&mut tree[node], bit);
            node = 2 * node + usize::from(bit);
        }
        s.previous = value;
    }

    pub fn decode(&mut self, coder: &mut SymbolDecoder, slot: usize) -> Result<i32, EntropyError> {
        let s = &mut self.slots[slot];
        let (lo, depth, size) = (s.model.lo, s.model.depth(), s.model.size);
        let tree = s.tree();
        let mut node = 1;
        for _ in 0..depth {
            node = 2 * node + usize::from(coder.bit(&mut tree[node])?);
        }
        let offset = (node - (1 << depth)) as u32;
        if offset >= size {
            return Err(EntropyError::OutsideTree { offset, size });
        }
        s.previous = lo + offset as i32;
        Ok(s.previous)
    }
}

/// The nodes of a block's models together.
fn total_nodes(models: &[TreeModel]) -> u64 {
    models.iter().map(TreeModel::nodes).sum()
}

/// Which blocks `ADPT` (one byte, bit `k` for `BLOCKS[k]`) says are coded with trees; a bit
/// for a block the stream does not hold, or above them, is an error.
pub(super) fn read_payload(payload: &[u8], present: [bool; 5]) -> Result<[bool; 5], DecodeError> {
    let invalid = |problem: String| DecodeError::invalid(ADAPTIVE, problem);
    let &[mask] = payload else {
        return Err(invalid(format!("holds {} bytes; the section holds one", payload.len())));
    };
    if mask >> BLOCKS.len() != 0 {
        return Err(invalid(format!("blocks {mask:#04x}: bits above 4 are reserved")));
    }
    let used: [bool; 5] = std::array::from_fn(|k| mask >> k & 1 == 1);
    if let Some(k) = (0..BLOCKS.len()).find(|&k| used[k] && !present[k]) {
        return Err(invalid(format!("blocks {mask:#04x}: names {}, which the stream does not hold", BLOCKS[k])));
    }
    Ok(used)
}

/// `ADPT`'s payload for the blocks `used`.
pub(super) fn payload(used: [bool; 5]) -> Vec<u8> {
    vec![(0..BLOCKS.len()).filter(|&k| used[k]).map(|k| 1u8 << k).sum()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_round_trip_through_the_trees_of_their_previous_values() {
        let values: Vec<i32> = (0..2000).map(|i: i32| (i * 7919 % 61) - 30 + (i / 500)).collect();
        let model = TreeModel::fit(&values).unwrap();
        assert_eq!((model.lo, model.size, model.thresholds.len()), (-30, 64, 7));
        let mut encoder = SymbolEncoder::new();
        let mut trees = Trees::new(vec![model.clone()]);
        values.iter().for_each(|&v| trees.encode(&mut encoder, 0, v));
        let bytes = encoder.finish();
        let mut w = FieldWriter::new();
        model.write(&mut w);
        let fields = w.into_bytes();
        let mut r = FieldReader::new("TEST", &fields);
        let mut trees = Trees::read(&mut r, 1).unwrap();
        let mut decoder = SymbolDecoder::new(&bytes).unwrap();
        let decoded: Vec<i32> = (0..values.len()).map(|_| trees.decode(&mut decoder, 0).unwrap()).collect();
        decoder.finish().unwrap();
        assert_eq!(decoded, values);
    }

    #[test]
    fn a_one_value_slot_takes_no_bits_and_wide_ones_keep_their_tables() {
        let model = TreeModel::fit(&[5; 100]).unwrap();
        assert_eq!((model.size, model.depth(), model.nodes()), (1, 0, 1));
        let mut encoder = SymbolEncoder::new();
        let mut trees = Trees::new(vec![model]);
        (0..100).for_each(|_| trees.encode(&mut encoder, 0, 5));
        assert!(encoder.finish().is_empty());
        assert_eq!(TreeModel::fit(&[0, 4096]), None);
        assert_eq!(TreeModel::fit(&[-1, 4094]).map(|m| m.depth()), Some(12));
        assert_eq!(TreeModel::fit(&[]), Some(TreeModel { lo: 0, size: 1, thresholds: vec![] }));
    }

    #[test]
    fn hostile_models_and_payloads_are_refused() {
        let read = |fields: &dyn Fn(&mut FieldWriter)| {
            let mut w = FieldWriter::new();
            fields(&mut w);
            let bytes = w.into_bytes();
            Trees::read(&mut FieldReader::new("SCAL", &bytes), 1).map(|_| ()).map_err(|e| e.to_string())
        };
        let model = |lo: i32, size: u32, trees: u8, thresholds: &[i32]| {
            let thresholds = thresholds.to_vec();
            move |w: &mut FieldWriter| {
                w.signed_varint(lo);
                w.varint(size);
                w.u8(trees);
                thresholds.iter().for_each(|&t| w.signed_varint(t));
            }
        };
        assert!(read(&model(0, 4097, 1, &[])).unwrap_err().contains("tree lo/size"));
        assert!(read(&model(0, 8, 0, &[])).unwrap_err().contains("trees"));
        assert!(read(&model(0, 8, 17, &[])).unwrap_err().contains("outside 1..=16"));
        assert!(read(&model(0, 8, 3, &[4, 4])).unwrap_err().contains("not above the one before"));
        // 16 trees of 4096 values: 2^16 nodes, within the bound; 17 slots of them would not be.
        assert!(read(&model(0, 4096, 16, &(0..15).collect::<Vec<_>>())).is_ok());
        let mut w = FieldWriter::new();
        (0..17).for_each(|_| model(0, 4096, 16, &(0..15).collect::<Vec<_>>())(&mut w));
        let bytes = w.into_bytes();
        let err = Trees::read(&mut FieldReader::new("SCAL", &bytes), 17).map(|_| ()).unwrap_err().to_string();
        assert!(err.contains("1114112 nodes, more than 2^20"), "{err}");
        assert!(read_payload(&[0b1_1111], [true; 5]).is_ok());
        assert!(read_payload(&[], [true; 5]).unwrap_err().to_string().contains("holds 0 bytes"));
        assert!(read_payload(&[0x20], [true; 5]).unwrap_err().to_string().contains("reserved"));
        let absent = read_payload(&[0x10], [true, true, true, true, false]).unwrap_err().to_string();
        assert!(absent.contains("names 'SHRS'"), "{absent}");
        assert_eq!(payload([true, false, true, false, false]), vec![0b101]);
    }
}
