//! Entropy coding (SPEC.md section 5): a range coder (constriction's, 32-bit words) driven by
//! three kinds of integer probability models, all at 16-bit precision:
//!
//! - [`FrequencyTable`]: a static categorical table over a contiguous range of integers plus an
//!   escape symbol, its frequencies carried in the stream;
//! - [`BitContext`]: an adaptive binary model updated from integer counts;
//! - 16-bit raw values (uniform), used for escaped integers.
//!
//! Every probability is an integer computed with integer arithmetic, so encoder and decoder
//! build bit-identical models on every machine (docs/architecture.md section 3, rule 1).

use constriction::stream::model::{DecoderModel, EncoderModel, EntropyModel};
use constriction::stream::queue::{DefaultRangeEncoder, RangeDecoder};
use constriction::stream::{Decode, Encode};
use constriction::{Queue, backends::ReadWords};
use pwgs_bitstream::{FieldError, FieldReader, FieldWriter};
use std::cell::Cell;
use std::num::NonZeroU32;
use std::rc::Rc;

/// Bits of precision of every probability model.
pub const PRECISION: usize = 16;
/// Sum of the frequencies of a table.
pub const TOTAL: u32 = 1 << PRECISION;
/// Most in-range symbols a table may have (the escape symbol comes on top).
pub const MAX_TABLE_SYMBOLS: u32 = 4096;
/// Quantized values are integers of magnitude below 2^24, so `q as f32 * step` is exact in `q`.
/// This holds for in-range and escaped values alike: a table covers at most
/// `-(2^24 - 1) ..= 2^24 - 1`.
pub const MAX_MAGNITUDE: i32 = 1 << 24;
/// Bounds of an adaptive bit probability, in units of 2^-16: a bit never costs less than
/// ~0.0056 bits, which bounds how many symbols a section of a given size can produce.
const BIT_PROBABILITY_MIN: u32 = 256;
const BIT_PROBABILITY_MAX: u32 = TOTAL - 256;
/// Counts of a [`BitContext`] are halved when their sum exceeds this, to stay adaptive.
const BIT_COUNT_LIMIT: u32 = 254;
/// Words the range decoder may request past the end of the data before the data counts as
/// corrupt: the encoder drops trailing zero words of its final two-word state, so a correct
/// stream needs at most two.
const OVERRUN_ALLOWANCE: u32 = 2;

/// Why entropy-coded data could not be decoded.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum EntropyError {
    #[error("coded data length {0} is not a multiple of 4 bytes")]
    Unaligned(usize),
    #[error("coded data ends before all symbols were decoded")]
    Exhausted,
    #[error("coded data is invalid")]
    Invalid,
    #[error("escaped value {0} is outside +/-2^24")]
    EscapeOutOfRange(i64),
    #[error("escaped value {0} lies inside the table's range (it must be coded as its own symbol)")]
    EscapeInRange(i64),
    #[error("tree symbol {offset} is outside the tree's {size} values")]
    OutsideTree { offset: u32, size: u32 },
    #[error("{0} unread bytes after the last symbol")]
    Unread(usize),
}

/// A static categorical model over `lo .. lo + n` plus one escape symbol (index `n`): a value
/// outside the range is coded as the escape followed by its zig-zag form in two raw 16-bit
/// halves (low half first).
#[derive(Debug, Clone, PartialEq)]
pub struct FrequencyTable {
    lo: i32,
    /// Cumulative frequencies, `n + 2` entries from 0 to [`TOTAL`].
    cdf: Vec<u32>,
}

impl FrequencyTable {
    /// Builds a table from its frequencies (`n` in-range symbols then the escape), each at least
    /// 1, summing to [`TOTAL`], over `lo .. lo + n` within `-(2^24 - 1) ..= 2^24 - 1`.
    pub fn from_frequencies(lo: i32, frequencies: &[u32]) -> Result<Self, String> {
        let n = frequencies.len().checked_sub(1).ok_or("a table needs the escape frequency")?;
        check_range(lo, n)?;
        let mut cdf = Vec::with_capacity(frequencies.len() + 1);
        let mut sum = 0u32;
        cdf.push(0);
        for &f in frequencies {
            if f == 0 {
                return Err("a frequency is 0 (the minimum is 1)".into());
            }
            sum = sum.saturating_add(f);
            cdf.push(sum);
        }
        if sum != TOTAL {
            return Err(format!("frequencies sum to {sum}, expected {TOTAL}"));
        }
        Ok(Self { lo, cdf })
    }

    /// The table an encoder uses for these values: a window of at most [`MAX_TABLE_SYMBOLS`]
    /// consecutive integers holding as many values as possible, frequencies proportional to the
    /// counts with a minimum of 1. Not normative: a decoder only reads the result.
    pub fn fit(values: &[i32]) -> Self {
        let mut sorted = values.to_vec();
        sorted.sort_unstable();
        let (lo, n) = best_window(&sorted);
        let mut counts = vec![0u64; n as usize + 1];
        for &v in values {
            let i = i64::from(v) - i64::from(lo);
            let slot = if (0..i64::from(n)).contains(&i) { i as usize } else { n as usize };
            counts[slot] += 1;
        }
        Self::from_frequencies(lo, &normalize(&counts)).expect("normalized counts form a valid table")
    }

    pub fn symbols(&self) -> u32 {
        self.cdf.len() as u32 - 2
    }

    fn escape(&self) -> u32 {
        self.symbols()
    }

    fn frequencies(&self) -> impl Iterator<Item = u32> + '_ {
        self.cdf.windows(2).map(|w| w[1] - w[0])
    }

    /// Syntax: `lo` signed varint, `n` varint, then `n + 1` frequencies as varints.
    pub fn write(&self, w: &mut FieldWriter) {
        w.signed_varint(self.lo);
        w.varint(self.symbols());
        self.frequencies().for_each(|f| w.varint(f));
    }

    pub fn read(r: &mut FieldReader) -> Result<Self, FieldError> {
        let lo = r.signed_varint("table lo")?;
        let n = r.varint("table size")?;
        check_range(lo, n as usize).map_err(|problem| r.error("table lo/size", problem))?;
        let frequencies = (0..=n).map(|_| r.varint("table frequency")).collect::<Result<Vec<_>, _>>()?;
        Self::from_frequencies(lo, &frequencies).map_err(|problem| r.error("table frequencies", problem))
    }

    /// Ideal code length of a value in bits (for rate reports; not normative).
    #[expect(clippy::disallowed_methods, reason = "a rate report only: no stream depends on it")]
    pub fn cost_bits(&self, value: i32) -> f64 {
        let (symbol, escaped) = self.symbol_of(value);
        let p = f64::from(self.cdf[symbol as usize + 1] - self.cdf[symbol as usize]) / f64::from(TOTAL);
        -p.log2() + if escaped { 32.0 } else { 0.0 }
    }

    fn symbol_of(&self, value: i32) -> (u32, bool) {
        self.symbol_of_shifted(value, 0)
    }

    /// The symbol of `value` in the table moved by `shift`, and whether it is the escape.
    fn symbol_of_shifted(&self, value: i32, shift: i32) -> (u32, bool) {
        let i = i64::from(value) - i64::from(self.lo) - i64::from(shift);
        if (0..i64::from(self.symbols())).contains(&i) { (i as u32, false) } else { (self.escape(), true) }
    }
}

/// Checks that a table of `n` symbols from `lo` is within the spec's bounds: 1 to
/// [`MAX_TABLE_SYMBOLS`] symbols covering values of magnitude below 2^24. Computed in i64: `lo`
/// comes from the stream and may be near `i32::MAX`.
pub(super) fn check_range(lo: i32, n: usize) -> Result<(), String> {
    if n == 0 || n > MAX_TABLE_SYMBOLS as usize {
        return Err(format!("{n} symbols, expected 1..={MAX_TABLE_SYMBOLS}"));
    }
    let end = i64::from(lo) + n as i64;
    if i64::from(lo) <= -i64::from(MAX_MAGNITUDE) || end > i64::from(MAX_MAGNITUDE) {
        return Err(format!("range {lo}..{end} reaches beyond +/-(2^24 - 1)"));
    }
    Ok(())
}

/// The window `[lo, lo + n)` of at most [`MAX_TABLE_SYMBOLS`] integers covering the most of
/// `sorted` (two pointers over the sorted values).
fn best_window(sorted: &[i32]) -> (i32, u32) {
    let Some((&first, &last)) = sorted.first().zip(sorted.last()) else { return (0, 1) };
    let span = i64::from(last) - i64::from(first) + 1;
    if span <= i64::from(MAX_TABLE_SYMBOLS) {
        return (first, span as u32);
    }
    let (mut best_lo, mut best_count, mut j) = (first, 0usize, 0usize);
    for i in 0..sorted.len() {
        let end = i64::from(sorted[i]) + i64::from(MAX_TABLE_SYMBOLS);
        j = j.max(i);
        while j < sorted.len() && i64::from(sorted[j]) < end {
            j += 1;
        }
        if j - i > best_count {
            (best_lo, best_count) = (sorted[i], j - i);
        }
    }
    (best_lo, MAX_TABLE_SYMBOLS)
}

/// Counts (any scale) to frequencies of at least 1 summing to [`TOTAL`]: 1 for every slot plus a
/// share of the rest proportional to the count, the rounding remainder going to the largest.
fn normalize(counts: &[u64]) -> Vec<u32> {
    let total: u64 = counts.iter().sum::<u64>().max(1);
    let spare = u64::from(TOTAL) - counts.len() as u64;
    let mut freqs: Vec<u32> = counts.iter().map(|&c| 1 + (c * spare / total) as u32).collect();
    let sum: u32 = freqs.iter().sum();
    let largest = (0..counts.len()).max_by_key(|&i| (counts[i], std::cmp::Reverse(i))).expect("non-empty");
    freqs[largest] += TOTAL - sum;
    freqs
}

/// An adaptive binary model: counts of zeros and ones seen in this context, turned into a
/// probability by the Krichevsky-Trofimov rule in 16-bit fixed point and clamped away from 0
/// and 1. Normative: SPEC.md section 5.3.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BitContext {
    /// Both stay below 255: their sum is halved once it passes [`BIT_COUNT_LIMIT`].
    zeros: u8,
    ones: u8,
}

impl BitContext {
    /// Probability of a one, in units of 2^-16.
    fn p_one(&self) -> u32 {
        u32::from(P_ONE[usize::from(self.zeros)][usize::from(self.ones)])
    }

    fn update(&mut self, bit: bool) {
        if bit {
            self.ones += 1;
        } else {
            self.zeros += 1;
        }
        if u32::from(self.zeros) + u32::from(self.ones) > BIT_COUNT_LIMIT {
            self.zeros = self.zeros.div_ceil(2);
            self.ones = self.ones.div_ceil(2);
        }
    }
}

/// The probability of a one for every pair of counts, `floor(2^16 (2 ones + 1) / (2 (zeros +
/// ones) + 2))` clamped, computed at compile time: a division per adaptive bit took a tenth of
/// decoding a deep octree.
static P_ONE: [[u16; 256]; 256] = p_one_table();

const fn p_one_table() -> [[u16; 256]; 256] {
    let mut table = [[0; 256]; 256];
    let mut zeros = 0;
    while zeros < 256 {
        let mut ones = 0;
        while ones < 256 {
            let p = (TOTAL * (2 * ones + 1)) / (2 * (zeros + ones) + 2);
            let p = if p < BIT_PROBABILITY_MIN {
                BIT_PROBABILITY_MIN
            } else if p > BIT_PROBABILITY_MAX {
                BIT_PROBABILITY_MAX
            } else {
                p
            };
            table[zeros as usize][ones as usize] = p as u16;
            ones += 1;
        }
        zeros += 1;
    }
    table
}

/// One model as constriction sees it: a symbol's left cumulative and frequency, and the inverse.
struct Model<'a>(ModelKind<'a>);

enum ModelKind<'a> {
    Table(&'a FrequencyTable),
    Bit(u32),
    Raw16,
}

impl EntropyModel<PRECISION> for Model<'_> {
    type Symbol = u32;
    type Probability = u32;
}

impl EncoderModel<PRECISION> for Model<'_> {
    fn left_cumulative_and_probability(&self, symbol: impl std::borrow::Borrow<u32>) -> Option<(u32, NonZeroU32)> {
        let s = *symbol.borrow();
        let (left, freq) = match &self.0 {
            ModelKind::Table(t) => {
                let (a, b) = (*t.cdf.get(s as usize)?, *t.cdf.get(s as usize + 1)?);
                (a, b - a)
            }
            ModelKind::Bit(p1) => match s {
                0 => (0, TOTAL - p1),
                1 => (TOTAL - p1, *p1),
                _ => return None,
            },
            ModelKind::Raw16 => (s, 1),
        };
        Some((left, NonZeroU32::new(freq)?))
    }
}

impl DecoderModel<PRECISION> for Model<'_> {
    fn quantile_function(&self, quantile: u32) -> (u32, u32, NonZeroU32) {
        let (symbol, left, freq) = match &self.0 {
            ModelKind::Table(t) => {
                let s = t.cdf.partition_point(|&c| c <= quantile) - 1;
                (s as u32, t.cdf[s], t.cdf[s + 1] - t.cdf[s])
            }
            ModelKind::Bit(p1) if quantile < TOTAL - p1 => (0, 0, TOTAL - p1),
            ModelKind::Bit(p1) => (1, TOTAL - p1, *p1),
            ModelKind::Raw16 => (quantile, quantile, 1),
        };
        (symbol, left, NonZeroU32::new(freq).expect("every model frequency is at least 1"))
    }
}

/// Writes symbols into one range-coded chunk.
pub struct SymbolEncoder {
    coder: DefaultRangeEncoder,
}

impl Default for SymbolEncoder {
    fn default() -> Self {
        Self::new()
    }
}

impl SymbolEncoder {
    pub fn new() -> Self {
        Self { coder: DefaultRangeEncoder::new() }
    }

    fn put(&mut self, symbol: u32, model: Model) {
        self.coder.encode_symbol(symbol, model).expect("every symbol of these models has a nonzero frequency");
    }

    /// Codes a value with a table (escaping it when out of range). Panics if the value's
    /// magnitude reaches 2^24: quantizers must keep values inside the spec's range.
    pub fn value(&mut self, table: &FrequencyTable, value: i32) {
        self.shifted_value(table, 0, value);
    }

    /// Codes a value with `table` moved by `shift` (its range `lo + shift ..`): the table of a
    /// Gaussian model whose mean is `shift` units further (SPEC.md section 5.4). An escape
    /// codes the value itself.
    pub fn shifted_value(&mut self, table: &FrequencyTable, shift: i32, value: i32) {
        assert!(value.abs() < MAX_MAGNITUDE, "quantized value {value} out of the spec's range");
        let (symbol, escaped) = table.symbol_of_shifted(value, shift);
        self.put(symbol, Model(ModelKind::Table(table)));
        if escaped {
            let z = ((value << 1) ^ (value >> 31)) as u32;
            self.put(z & 0xffff, Model(ModelKind::Raw16));
            self.put(z >> 16, Model(ModelKind::Raw16));
        }
    }

    /// Codes a bit with an adaptive context and updates the context.
    pub fn bit(&mut self, context: &mut BitContext, bit: bool) {
        self.put(u32::from(bit), Model(ModelKind::Bit(context.p_one())));
        context.update(bit);
    }

    /// The coded bytes: the range coder's 32-bit words, little-endian.
    pub fn finish(self) -> Vec<u8> {
        let words = self.coder.into_compressed().expect("writing to a Vec cannot fail");
        words.iter().flat_map(|w| w.to_le_bytes()).collect()
    }
}

/// How far a [`WordReader`] got: bytes read, and words requested past the end.
#[derive(Debug, Clone, Copy, Default)]
struct Progress {
    read: usize,
    overrun: u32,
}

/// Reads 32-bit little-endian words from a byte slice, counting reads past its end.
struct WordReader<'a> {
    bytes: &'a [u8],
    /// Shared with the [`SymbolDecoder`], which cannot reach into constriction's decoder.
    progress: Rc<Cell<Progress>>,
}

impl ReadWords<u32, Queue> for WordReader<'_> {
    type ReadError = std::convert::Infallible;

    fn read(&mut self) -> Result<Option<u32>, Self::ReadError> {
        let mut p = self.progress.get();
        let word = self.bytes.get(p.read..).and_then(|rest| rest.first_chunk::<4>()).copied();
        match word {
            Some(_) => p.read += 4,
            None => p.overrun = p.overrun.saturating_add(1),
        }
        self.progress.set(p);
        Ok(word.map(u32::from_le_bytes))
    }
}

/// Reads symbols from one range-coded chunk, with the models the encoder used.
pub struct SymbolDecoder<'a> {
    coder: RangeDecoder<u32, u64, WordReader<'a>>,
    progress: Rc<Cell<Progress>>,
    len: usize,
    /// Whether any symbol was decoded: a chunk that holds none must be empty.
    started: bool,
}

impl<'a> SymbolDecoder<'a> {
    pub fn new(bytes: &'a [u8]) -> Result<Self, EntropyError> {
        if !bytes.len().is_multiple_of(4) {
            return Err(EntropyError::Unaligned(bytes.len()));
        }
        let progress = Rc::new(Cell::new(Progress::default()));
        let reader = WordReader { bytes, progress: Rc::clone(&progress) };
        let coder = RangeDecoder::with_backend(reader).map_err(|_| EntropyError::Invalid)?;
        Ok(Self { coder, progress, len: bytes.len(), started: false })
    }

    fn get(&mut self, model: Model) -> Result<u32, EntropyError> {
        self.started = true;
        let symbol = self.coder.decode_symbol(model).map_err(|_| EntropyError::Invalid)?;
        if self.overrun() > OVERRUN_ALLOWANCE {
            return Err(EntropyError::Exhausted);
        }
        Ok(symbol)
    }

    pub fn value(&mut self, table: &FrequencyTable) -> Result<i32, EntropyError> {
        self.shifted_value(table, 0)
    }

    /// Decodes a value coded with [`SymbolEncoder::shifted_value`]. The caller keeps the moved
    /// range within ±(2^24 - 1) (SPEC.md section 5.4 bounds a model's mean).
    pub fn shifted_value(&mut self, table: &FrequencyTable, shift: i32) -> Result<i32, EntropyError> {
        let symbol = self.get(Model(ModelKind::Table(table)))?;
        if symbol != table.escape() {
            return Ok(table.lo + shift + symbol as i32);
        }
        let low = self.get(Model(ModelKind::Raw16))?;
        let high = self.get(Model(ModelKind::Raw16))?;
        let z = low | (high << 16);
        let value = i64::from(z >> 1) ^ -i64::from(z & 1);
        if value.abs() >= i64::from(MAX_MAGNITUDE) {
            return Err(EntropyError::EscapeOutOfRange(value));
        }
        if !table.symbol_of_shifted(value as i32, shift).1 {
            return Err(EntropyError::EscapeInRange(value));
        }
        Ok(value as i32)
    }

    pub fn bit(&mut self, context: &mut BitContext) -> Result<bool, EntropyError> {
        let bit = self.get(Model(ModelKind::Bit(context.p_one())))? == 1;
        context.update(bit);
        Ok(bit)
    }

    /// Words requested past the end of the data so far (at most 2 for a correct stream).
    pub fn overrun(&self) -> u32 {
        self.progress.get().overrun
    }

    /// Ends the chunk after its last symbol (SPEC.md section 5.2): a chunk holds only what its
    /// symbols need, so every word must have been read, and a chunk from which nothing was
    /// decoded must be empty (an encoder writes no word then). Trailing data is refused
    /// rather than ignored, so a section ending in a chunk has no room for appended fields.
    pub fn finish(self) -> Result<(), EntropyError> {
        let read = if self.started { self.progress.get().read } else { 0 };
        match self.len - read {
            0 => Ok(()),
            unread => Err(EntropyError::Unread(unread)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pwgs_core::random::SplitMix64;

    #[test]
    fn tables_round_trip_values_in_and_out_of_range() {
        let mut rng = SplitMix64(7);
        let mut values: Vec<i32> = (0..5000).map(|_| rng.uniform(-20.0, 20.0) as i32).collect();
        values.extend([-(MAX_MAGNITUDE - 1), MAX_MAGNITUDE - 1, 100_000, -3_000_000]);
        let mut table = FrequencyTable::fit(&values[..4000]);
        // Re-read the table through its syntax, as a decoder would.
        let mut w = FieldWriter::new();
        table.write(&mut w);
        let bytes = w.into_bytes();
        let mut r = FieldReader::new("TEST", &bytes);
        let read = FrequencyTable::read(&mut r).unwrap();
        assert_eq!(read, table);
        table = read;
        let mut enc = SymbolEncoder::new();
        values.iter().for_each(|&v| enc.value(&table, v));
        let coded = enc.finish();
        let mut dec = SymbolDecoder::new(&coded).unwrap();
        for &v in &values {
            assert_eq!(dec.value(&table).unwrap(), v);
        }
        assert!(dec.overrun() <= OVERRUN_ALLOWANCE);
        // The rate is close to the ideal code length.
        let ideal: f64 = values.iter().map(|&v| table.cost_bits(v)).sum();
        assert!((coded.len() * 8) as f64 <= ideal * 1.01 + 64.0, "{} bytes for {ideal} bits", coded.len());
    }

    #[test]
    fn fit_keeps_the_densest_window_and_minimum_frequencies() {
        let mut values: Vec<i32> = (0..10_000).map(|i| i % 5000).collect();
        values.push(-1_000_000);
        let t = FrequencyTable::fit(&values);
        assert_eq!(t.symbols(), MAX_TABLE_SYMBOLS);
        assert_eq!(t.lo, 0);
        assert!(t.frequencies().all(|f| f >= 1));
        assert_eq!(t.frequencies().sum::<u32>(), TOTAL);
    }

    #[test]
    fn invalid_tables_are_refused() {
        assert!(FrequencyTable::from_frequencies(0, &[TOTAL]).is_err(), "no in-range symbol");
        assert!(FrequencyTable::from_frequencies(0, &[TOTAL, 0]).is_err(), "zero frequency");
        assert!(FrequencyTable::from_frequencies(0, &[TOTAL - 2, 1]).is_err(), "wrong sum");
        assert!(FrequencyTable::from_frequencies(MAX_MAGNITUDE - 1, &[TOTAL - 2, 1, 1]).is_err(), "range");
        assert!(FrequencyTable::from_frequencies(-3, &[TOTAL - 2, 1, 1]).is_ok());
        // The extremes: every in-range value must have |v| < 2^24, and `lo + n` must not wrap.
        assert!(FrequencyTable::from_frequencies(-MAX_MAGNITUDE, &[TOTAL - 1, 1]).is_err(), "|lo| = 2^24");
        assert!(FrequencyTable::from_frequencies(-(MAX_MAGNITUDE - 1), &[TOTAL - 1, 1]).is_ok());
        assert!(FrequencyTable::from_frequencies(MAX_MAGNITUDE - 2, &[TOTAL - 2, 1, 1]).is_ok());
        for n in [1usize, 2, 4096] {
            let mut freqs = vec![1; n + 1];
            freqs[0] = TOTAL - n as u32;
            let lo = i32::MAX - n as i32 + 1;
            let error = FrequencyTable::from_frequencies(lo, &freqs).unwrap_err();
            assert!(error.contains("beyond"), "{error}");
        }
    }

    /// Codes `values` with `table` and returns the chunk.
    fn chunk(table: &FrequencyTable, values: &[i32]) -> Vec<u8> {
        let mut enc = SymbolEncoder::new();
        values.iter().for_each(|&v| enc.value(table, v));
        enc.finish()
    }

    #[test]
    fn chunks_are_consumed_exactly() {
        let mut rng = SplitMix64(5);
        let table = FrequencyTable::fit(&(-40..40).collect::<Vec<_>>());
        assert!(chunk(&table, &[]).is_empty(), "no symbols, no words");
        assert!(SymbolDecoder::new(&[]).unwrap().finish().is_ok());
        assert_eq!(
            SymbolDecoder::new(&[0; 8]).unwrap().finish(),
            Err(EntropyError::Unread(8)),
            "symbols expected none"
        );
        for len in [1usize, 2, 3, 5, 17, 100, 1000, 5000] {
            for spread in [1.0, 30.0, 1e5] {
                let values: Vec<i32> = (0..len).map(|_| rng.uniform(-spread, spread) as i32).collect();
                let coded = chunk(&table, &values);
                let mut dec = SymbolDecoder::new(&coded).unwrap();
                values.iter().for_each(|&v| assert_eq!(dec.value(&table).unwrap(), v));
                let overrun = dec.overrun();
                assert!(overrun <= 1, "constriction writes 1 or 2 words of final state");
                assert_eq!(dec.finish(), Ok(()), "{len} values of spread {spread}");
                // An appended zero word is read in place of a word past the end (the same value,
                // so the same symbols) or, when there was none, left unread: an error.
                let mut padded = coded.clone();
                padded.extend([0; 4]);
                let mut dec = SymbolDecoder::new(&padded).unwrap();
                values.iter().for_each(|&v| assert_eq!(dec.value(&table).unwrap(), v));
                let expected = if overrun == 1 { Ok(()) } else { Err(EntropyError::Unread(4)) };
                assert_eq!(dec.finish(), expected, "{len} values of spread {spread}");
            }
        }
    }

    #[test]
    fn an_escaped_value_inside_the_range_is_refused() {
        let table = FrequencyTable::from_frequencies(-2, &[TOTAL - 4, 1, 1, 1, 1]).unwrap();
        // The escape symbol, then the zig-zag form of 1 (inside -2..2) in two raw halves.
        let mut enc = SymbolEncoder::new();
        enc.put(table.escape(), Model(ModelKind::Table(&table)));
        enc.put(2, Model(ModelKind::Raw16));
        enc.put(0, Model(ModelKind::Raw16));
        let coded = enc.finish();
        assert_eq!(SymbolDecoder::new(&coded).unwrap().value(&table), Err(EntropyError::EscapeInRange(1)));
        // The same value escaped from a table that does not cover it decodes.
        let narrow = FrequencyTable::from_frequencies(5, &[TOTAL - 1, 1]).unwrap();
        let coded = chunk(&narrow, &[1]);
        assert_eq!(SymbolDecoder::new(&coded).unwrap().value(&narrow), Ok(1));
    }

    #[test]
    fn adaptive_bits_round_trip_and_learn() {
        let mut rng = SplitMix64(3);
        let bits: Vec<bool> = (0..20_000).map(|_| rng.uniform(0.0, 1.0) < 0.05).collect();
        let mut ctx = BitContext::default();
        let mut enc = SymbolEncoder::new();
        bits.iter().for_each(|&b| enc.bit(&mut ctx, b));
        let coded = enc.finish();
        let mut ctx = BitContext::default();
        let mut dec = SymbolDecoder::new(&coded).unwrap();
        for &b in &bits {
            assert_eq!(dec.bit(&mut ctx).unwrap(), b);
        }
        // Entropy of p = 0.05 is 0.286 bits; the adaptive model gets within 10% of it.
        let bits_per_symbol = (coded.len() * 8) as f64 / bits.len() as f64;
        assert!(bits_per_symbol < 0.286 * 1.1, "{bits_per_symbol}");
    }

    #[test]
    fn bit_probabilities_follow_spec_5_3() {
        // Fresh: 1/2; after a one, 3/4; after 254 zeros, the floor of 256.
        let mut ctx = BitContext::default();
        assert_eq!(ctx.p_one(), 32768);
        ctx.update(true);
        assert_eq!(ctx.p_one(), 49152);
        let mut ctx = BitContext::default();
        (0..254).for_each(|_| ctx.update(false));
        assert_eq!((ctx.zeros, ctx.p_one()), (254, 256));
        // The 255th count halves both, rounding up: 254 zeros and a one become 127 and 1.
        ctx.update(true);
        assert_eq!((ctx.zeros, ctx.ones), (127, 1));
        // Every reachable pair, against the formula.
        for zeros in 0..=255u32 {
            for ones in 0..=255 - zeros {
                let p = (65536 * (2 * ones + 1) / (2 * (zeros + ones) + 2)).clamp(256, 65280);
                let ctx = BitContext { zeros: zeros as u8, ones: ones as u8 };
                assert_eq!(ctx.p_one(), p, "{zeros} zeros, {ones} ones");
            }
        }
    }

    #[test]
    fn garbage_never_panics_and_running_dry_is_detected() {
        let table = FrequencyTable::fit(&[0, 1, 2, 2, 3]);
        let mut rng = SplitMix64(11);
        for len in [0usize, 4, 8, 64] {
            let bytes: Vec<u8> = (0..len).map(|_| rng.uniform(0.0, 256.0) as u8).collect();
            let Ok(mut dec) = SymbolDecoder::new(&bytes) else { continue };
            let mut ctx = BitContext::default();
            let mut outcome = Ok(());
            for _ in 0..100_000 {
                if let Err(e) = dec.value(&table).and_then(|_| dec.bit(&mut ctx).map(|_| ())) {
                    outcome = Err(e);
                    break;
                }
            }
            assert!(outcome.is_err(), "{len} random bytes decoded 100k symbols");
        }
        assert_eq!(SymbolDecoder::new(&[1, 2, 3]).err(), Some(EntropyError::Unaligned(3)));
    }
}
