//! The models of the anchors' values (SPEC.md 12.7): the context network turns where an
//! anchor is into a quantized-Gaussian model per value, and the tables of those models are
//! built once each, within the stream's budget of table symbols.

use rayon::prelude::*;

use super::super::entropy::{EntropyError, FrequencyTable, SymbolDecoder, SymbolEncoder};
use super::super::gaussian_model::{GaussianModel, MAX_MEAN, MEAN_DENOMINATOR, SCALE_OFFSET};
use super::{QuantizedContext, predicted_values};
use crate::anchor::MlpEvaluator;

/// The quantized-Gaussian model of a value from the network's outputs for its mean `u` (in
/// quantization units) and its log2 scale `s` (in units): `M = floor(64 u + 1/2)` and `J =
/// floor(8 s + 1/2) + 96`, each clamped to its range (binary64, every operation exact).
pub fn snap(u: f32, s: f32) -> GaussianModel {
    // A NaN (impossible from finite weights, but free to rule out) snaps to 0 and the
    // smallest scale.
    let mean = match u.is_nan() {
        true => 0,
        false => floor_clamped(f64::from(u) * f64::from(MEAN_DENOMINATOR) + 0.5, -MAX_MEAN, MAX_MEAN),
    };
    let scale = match s.is_nan() {
        true => 0,
        false => floor_clamped(f64::from(s) * 8.0 + 0.5, -SCALE_OFFSET, 255 - SCALE_OFFSET) + SCALE_OFFSET,
    };
    GaussianModel { mean, scale: scale as u8 }
}

/// `floor(x)` clamped to `lo ..= hi`, for `x` not NaN. Exact: within the range, truncating `x`
/// to an integer is exact and one comparison turns truncation into floor; this avoids the libm
/// call `f64::floor` makes where SSE4.1 is not assumed, twice per value decoded.
fn floor_clamped(x: f64, lo: i32, hi: i32) -> i32 {
    if x >= f64::from(hi) {
        hi
    } else if x < f64::from(lo) {
        lo
    } else {
        let t = x as i32;
        t - i32::from(f64::from(t) > x)
    }
}

/// In-range symbols the tables of a stream's context model may hold together (SPEC.md
/// section 12.7): `2^20 + 8 L` for a stream of `L` bytes. Every table costs a normal CDF per
/// symbol to build; all 16,384 there are hold 28M symbols (about 0.9 s of one core), which a
/// stream of a few KB could otherwise ask for. Real streams need far fewer (the README's demo:
/// 5,148 tables of 308,602 symbols in 105,859 bytes), within the fixed part.
pub fn table_symbol_budget(stream_len: usize) -> u64 {
    TABLE_SYMBOLS_FIXED + TABLE_SYMBOLS_PER_BYTE * stream_len as u64
}

pub const TABLE_SYMBOLS_FIXED: u64 = 1 << 20;
pub const TABLE_SYMBOLS_PER_BYTE: u64 = 8;

/// The least stream length whose table budget holds `symbols`.
pub fn stream_len_for_table_symbols(symbols: u64) -> usize {
    symbols.saturating_sub(TABLE_SYMBOLS_FIXED).div_ceil(TABLE_SYMBOLS_PER_BYTE) as usize
}

/// An anchor whose models need more table symbols than the budget leaves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TableBudgetExceeded {
    /// The symbols the tables would hold with this anchor's.
    pub needed: u64,
    pub budget: u64,
}

/// Tables a context model can ask for: 64 fractions of a mean times 256 scales.
const TABLE_KEYS: usize = MEAN_DENOMINATOR as usize * 256;

/// A stream's context network: the models of anchors' values from their positions. It depends
/// on nothing decoded, so a decoder may evaluate anchors ahead of their values, on every core.
pub struct ContextNetwork<'a> {
    context: &'a QuantizedContext,
    mlp: MlpEvaluator,
    hidden: usize,
    depth: u8,
    values: usize,
}

impl<'a> ContextNetwork<'a> {
    /// The network of anchors of `feature_dim` features and `offsets` offsets on an octree of
    /// `depth` levels.
    pub fn new(context: &'a QuantizedContext, depth: u8, (feature_dim, offsets): (usize, usize)) -> Self {
        let values = predicted_values(feature_dim, offsets);
        let mlp = context.mlp.dequantize(context.shape.context_len(), 2 * values);
        Self { context, mlp: mlp.evaluator(), hidden: mlp.hidden, depth, values }
    }

    /// Values per anchor, V.
    pub fn values(&self) -> usize {
        self.values
    }

    /// The models of the values of the anchors at octree coordinates `positions`, anchor by
    /// anchor (V each), into `models`, on every core.
    pub fn models(&self, positions: &[[u32; 3]], models: &mut Vec<GaussianModel>) {
        let (context, values) = (self.context, self.values);
        models.resize(positions.len() * values, GaussianModel { mean: 0, scale: 0 });
        let scratch = || (Vec::new(), vec![0.0; self.hidden], vec![0.0; 2 * values]);
        models.par_chunks_mut(values).zip(positions).for_each_init(scratch, |(corners, hidden, out), (models, &q)| {
            corners.clear();
            context.shape.corners(q, self.depth, corners);
            let input = context.shape.context(corners, &context.signs);
            self.mlp.forward(&input, hidden, out);
            for (t, model) in models.iter_mut().enumerate() {
                *model = snap(out[t], out[values + t]);
            }
        });
    }
}

/// The tables the anchors' models need, each built once per fractional mean and scale (a
/// table moves with the integer part of its mean), within a budget of symbols checked anchor
/// by anchor, in stream order, as SPEC.md 12.7 counts it.
pub struct ContextTables {
    /// By key ([`table_key`]), the tables built so far.
    tables: Vec<Option<FrequencyTable>>,
    /// Their in-range symbols, and the most they may hold.
    symbols: u64,
    budget: u64,
}

impl ContextTables {
    /// No tables yet, and a budget of `budget` symbols ([`table_symbol_budget`] for a decoder,
    /// `u64::MAX` for a writer).
    pub fn new(budget: u64) -> Self {
        Self { tables: (0..TABLE_KEYS).map(|_| None).collect(), symbols: 0, budget }
    }

    /// The in-range symbols of the tables built so far.
    pub fn symbols(&self) -> u64 {
        self.symbols
    }

    /// Builds the tables of one anchor's `models` that no anchor before it needed, on every
    /// core (a stream may need every table there is from a few hundred anchors), unless they
    /// would pass the budget. Tables are pure functions of their key, so the order they are
    /// built in changes nothing.
    pub fn add(&mut self, models: &[GaussianModel]) -> Result<(), TableBudgetExceeded> {
        let mut keys: Vec<usize> =
            models.iter().map(|&m| table_key(m).1).filter(|&k| self.tables[k].is_none()).collect();
        if keys.is_empty() {
            return Ok(());
        }
        keys.sort_unstable();
        keys.dedup();
        let new: u64 = keys.iter().map(|&k| u64::from(key_model(k).table_symbols())).sum();
        let needed = self.symbols + new;
        if needed > self.budget {
            return Err(TableBudgetExceeded { needed, budget: self.budget });
        }
        self.symbols = needed;
        let built: Vec<_> = keys.into_par_iter().map(|k| (k, key_model(k).table())).collect();
        for (k, table) in built {
            self.tables[k] = Some(table);
        }
        Ok(())
    }

    /// The table of `model` and how far it moves.
    fn table(&self, model: GaussianModel) -> (&FrequencyTable, i32) {
        let (whole, key) = table_key(model);
        let table = self.tables[key].as_ref().expect("adding an anchor builds the tables of its models");
        (table, whole)
    }

    /// Codes `value` with the table of `model`, which [`Self::add`] has built.
    pub fn encode(&self, coder: &mut SymbolEncoder, model: GaussianModel, value: i32) {
        let (table, shift) = self.table(model);
        coder.shifted_value(table, shift, value);
    }

    pub fn decode(&self, coder: &mut SymbolDecoder, model: GaussianModel) -> Result<i32, EntropyError> {
        let (table, shift) = self.table(model);
        coder.shifted_value(table, shift)
    }
}

/// How far a model's table moves (the whole part of its mean) and the key of the table: its
/// mean's fraction (in 64ths) times 256 plus its scale.
fn table_key(model: GaussianModel) -> (i32, usize) {
    let fraction = model.mean.rem_euclid(MEAN_DENOMINATOR) as usize;
    (model.mean.div_euclid(MEAN_DENOMINATOR), fraction * 256 + usize::from(model.scale))
}

/// The model whose table a key names (mean below one unit).
fn key_model(key: usize) -> GaussianModel {
    GaussianModel { mean: (key / 256) as i32, scale: (key % 256) as u8 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::context_grid::ContextGridShape;
    use crate::stream::anchor::QuantizedMlp;
    use pwgs_core::random::SplitMix64;

    /// `snap` as SPEC.md 12.7 writes it, with `floor`.
    fn snap_by_floor(u: f32, s: f32) -> GaussianModel {
        let mean = (f64::from(u) * 64.0 + 0.5).floor();
        let scale = (f64::from(s) * 8.0 + 0.5).floor() + 96.0;
        let mean = if mean.is_nan() { 0.0 } else { mean.clamp(-f64::from(MAX_MEAN), f64::from(MAX_MEAN)) };
        let scale = if scale.is_nan() { 0.0 } else { scale.clamp(0.0, 255.0) };
        GaussianModel { mean: mean as i32, scale: scale as u8 }
    }

    #[test]
    fn snapping_is_floor_then_clamp() {
        let mut rng = SplitMix64(17);
        let mut values: Vec<f32> = vec![
            0.0,
            -0.0,
            0.5 / 64.0,
            -0.5 / 64.0,
            -1.5,
            1e-30,
            -1e-30,
            8.0e6,
            -8.0e6,
            1e30,
            -1e30,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -12.0625,
            19.9375,
            20.0,
            -12.1,
            8388608.0,
            -8388608.5,
        ];
        // Around every boundary of both grids, and anywhere.
        values.extend((-2000..2000).map(|i| i as f32 / 128.0));
        values.extend((0..20_000).map(|_| f32::from_bits(rng.next_u64() as u32)));
        values.extend((0..20_000).map(|_| (rng.next_u64() as i64 as f64 / 2f64.powi(40)) as f32));
        for &u in &values {
            for &s in &values[..64] {
                assert_eq!(snap(u, s), snap_by_floor(u, s), "u {u} s {s}");
                assert_eq!(snap(s, u), snap_by_floor(s, u), "u {s} s {u}");
            }
        }
    }

    /// A context of one level and 2 channels with a random network over `values` outputs.
    fn context(seed: u64, values: usize) -> QuantizedContext {
        let mut rng = SplitMix64(seed);
        let shape = ContextGridShape { levels: vec![2], planes: vec![], table_log2: 8, channels: 2 };
        let signs = (0..shape.entries(4) * 2).map(|_| rng.next_u64() & 1 == 1).collect();
        let mut draw = |n: usize, spread: u64| {
            (0..n).map(|_| (rng.next_u64() % (2 * spread + 1)) as i32 - spread as i32).collect()
        };
        let (inputs, hidden) = (shape.context_len(), 11);
        let mlp = QuantizedMlp {
            hidden,
            weight_exponent: -3,
            bias_exponent: -2,
            w1: draw(hidden * inputs, 16),
            b1: draw(hidden, 8),
            w2: draw(2 * values * hidden, 40),
            b2: draw(2 * values, 40),
        };
        QuantizedContext { shape, signs, mlp }
    }

    /// `n` anchors on an octree of depth 4, x fastest.
    fn positions(n: u32) -> Vec<[u32; 3]> {
        (0..n).map(|i| [i % 16, (i / 16) % 16, i / 256]).collect()
    }

    #[test]
    fn the_models_of_many_anchors_are_those_of_each_alone() {
        let context = context(5, predicted_values(9, 2));
        let network = ContextNetwork::new(&context, 4, (9, 2));
        let positions = positions(300);
        let mut all = Vec::new();
        network.models(&positions, &mut all);
        let mut one = Vec::new();
        let mut scales = std::collections::BTreeSet::new();
        for (i, &q) in positions.iter().enumerate() {
            network.models(&[q], &mut one);
            assert_eq!(one[..], all[i * network.values()..][..network.values()], "anchor {i}");
            scales.extend(one.iter().map(|m| m.scale));
        }
        assert!(scales.len() > 20, "the models vary: {scales:?}");
    }

    #[test]
    fn tables_past_the_budget_are_refused_before_they_are_built() {
        let context = context(6, predicted_values(9, 2));
        let network = ContextNetwork::new(&context, 4, (9, 2));
        let positions = positions(200);
        let mut models = Vec::new();
        network.models(&positions, &mut models);
        let run = |budget: u64| -> Result<u64, (usize, TableBudgetExceeded)> {
            let mut tables = ContextTables::new(budget);
            for (i, anchor) in models.chunks_exact(network.values()).enumerate() {
                tables.add(anchor).map_err(|e| (i, e))?;
            }
            Ok(tables.symbols())
        };
        let all = run(u64::MAX).unwrap();
        assert!(all > 1000, "{all} symbols");
        assert_eq!(run(all), Ok(all), "a budget of exactly the symbols needed holds them");
        let (anchor, e) = run(all - 1).unwrap_err();
        assert_eq!(e.budget, all - 1);
        assert_eq!(e.needed, all, "the last anchor needing a new table passes the budget");
        // The refusal comes at the first anchor that passes a smaller budget, with what it needed.
        let (early, e) = run(all / 2).unwrap_err();
        assert!(early < anchor && e.needed > all / 2 && e.needed <= all, "{early} {e:?}");
    }

    #[test]
    fn the_symbol_budget_and_the_length_it_needs_agree() {
        assert_eq!(table_symbol_budget(0), 1 << 20);
        assert_eq!(table_symbol_budget(1000), (1 << 20) + 8000);
        assert_eq!(stream_len_for_table_symbols(1 << 20), 0);
        assert_eq!(stream_len_for_table_symbols((1 << 20) + 1), 1);
        for symbols in [(1u64 << 20) + 8, (1 << 20) + 9, 28_079_360] {
            let len = stream_len_for_table_symbols(symbols);
            assert!(table_symbol_budget(len) >= symbols && table_symbol_budget(len - 1) < symbols);
        }
    }
}
