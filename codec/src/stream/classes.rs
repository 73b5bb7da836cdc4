//! Importance classes of a plain-3DGS stream (section `IMPC`, SPEC.md section 6.5): each
//! Gaussian belongs to a class, and a class scales every attribute step by its own factor and
//! leaves its finest position bits uncoded. An encoder puts the Gaussians that show little in
//! any view into coarse classes, where error costs little, and spends the bytes on those that
//! show.
//!
//! Positions: `POSN` codes each Gaussian's cell on a grid `R` levels coarser than the one its
//! mean lies on; `IMPC` then codes, per Gaussian, the `R - drop` refinement levels its class
//! keeps (three adaptive bits a level); the `drop` levels below are the centre of the cell.

use pwgs_bitstream::{FieldReader, FieldWriter, Tag};

use super::DecodeError;
use super::entropy::{BitContext, EntropyError, SymbolDecoder, SymbolEncoder};
use super::octree::MAX_DEPTH;

pub const CLASSES: Tag = Tag(*b"IMPC");
/// Most classes a stream may define.
pub const MAX_CLASSES: usize = 16;

/// The importance classes of a plain stream's Gaussians.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportanceClasses {
    /// Levels `R` by which the position grid is finer than `POSN`'s.
    pub refine: u8,
    /// Per class: the factor of every attribute step.
    pub factors: Vec<f32>,
    /// Per class: how many of the finest grid levels it does not code (at most `refine`).
    pub drops: Vec<u8>,
    /// Per Gaussian: its class.
    pub of: Vec<u8>,
}

impl ImportanceClasses {
    /// The step Gaussian `i`'s values of a block with step `step` are reconstructed with
    /// (normative: one binary32 product).
    pub fn step(&self, i: usize, step: f32) -> f32 {
        step * self.factors[usize::from(self.of[i])]
    }

    /// A fine-grid coordinate as class `class` reconstructs it: its dropped bits replaced by
    /// the centre of the cell they span (`1` followed by zeros; nothing when none is dropped).
    pub fn snap(&self, class: u8, q: u32) -> u32 {
        let drop = self.drops[usize::from(class)];
        match drop {
            0 => q,
            d => (q >> d << d) | 1 << (d - 1),
        }
    }

    /// Payload of `IMPC`: the fields, then per Gaussian in decoding order (`order[i]` indexes
    /// `of` and `positions`) its class and its kept refinement bits. `positions` are on the fine
    /// grid.
    pub(super) fn write(&self, positions: &[[u32; 3]], order: &[usize]) -> Vec<u8> {
        let count = self.factors.len();
        assert!((2..=MAX_CLASSES).contains(&count) && self.drops.len() == count, "{count} classes");
        assert!(self.drops.iter().all(|&d| d <= self.refine), "a class drops more levels than refined");
        assert_eq!(self.of.len(), positions.len(), "one class per Gaussian");
        assert!(
            positions
                .iter()
                .zip(&self.of)
                .all(|(q, &k)| usize::from(k) < count && q.iter().all(|&c| self.snap(k, c) == c)),
            "a position's dropped levels are not at their centre (ImportanceClasses::snap)"
        );
        let mut w = FieldWriter::new();
        w.u8(self.factors.len() as u8);
        w.u8(self.refine);
        self.factors.iter().for_each(|&f| w.f32(f));
        self.drops.iter().for_each(|&d| w.u8(d));
        let mut class_contexts = ClassContexts::new(self.factors.len());
        let mut contexts = vec![BitContext::default(); usize::from(self.refine) * 3];
        let mut coder = SymbolEncoder::new();
        for &i in order {
            let class = self.of[i];
            class_contexts.write(&mut coder, class);
            let kept = self.refine - self.drops[usize::from(class)];
            for level in 0..kept {
                for (a, &q) in positions[i].iter().enumerate() {
                    let bit = q >> (self.refine - 1 - level) & 1 == 1;
                    coder.bit(&mut contexts[usize::from(level) * 3 + a], bit);
                }
            }
        }
        w.extend(&coder.finish());
        w.into_bytes()
    }

    /// Reads `IMPC` for the Gaussians of `positions` (`POSN`'s grid of `depth` levels) and
    /// refines them in place to the fine grid.
    pub(super) fn read(payload: &[u8], depth: u8, positions: &mut [[u32; 3]]) -> Result<Self, DecodeError> {
        let mut r = FieldReader::new("IMPC", payload);
        let count = usize::from(r.u8("classes")?);
        if !(2..=MAX_CLASSES).contains(&count) {
            return Err(r.error("classes", format!("{count} is outside 2..={MAX_CLASSES}")).into());
        }
        let refine = r.u8("refine")?;
        if u32::from(depth) + u32::from(refine) > u32::from(MAX_DEPTH) {
            let problem = format!("{refine} levels below POSN's {depth} exceed {MAX_DEPTH}");
            return Err(r.error("refine", problem).into());
        }
        let mut factors = Vec::with_capacity(count);
        for _ in 0..count {
            let f = r.f32("factor")?;
            if !(f > 0.0) {
                return Err(r.error("factor", format!("{f} is not positive")).into());
            }
            factors.push(f);
        }
        let mut drops = Vec::with_capacity(count);
        for _ in 0..count {
            let d = r.u8("drop")?;
            if d > refine {
                return Err(r.error("drop", format!("{d} exceeds refine {refine}")).into());
            }
            drops.push(d);
        }
        let coded = |e| DecodeError::coded(CLASSES, e);
        let mut coder = SymbolDecoder::new(r.rest()).map_err(coded)?;
        let mut class_contexts = ClassContexts::new(count);
        let mut contexts = vec![BitContext::default(); usize::from(refine) * 3];
        let mut of = Vec::with_capacity(positions.len());
        let mut classes = Self { refine, factors, drops, of: vec![] };
        for p in positions.iter_mut() {
            let class = class_contexts.read(&mut coder).map_err(coded)?;
            let kept = refine - classes.drops[usize::from(class)];
            let mut offset = [0u32; 3];
            for level in 0..kept {
                for (a, o) in offset.iter_mut().enumerate() {
                    let bit = coder.bit(&mut contexts[usize::from(level) * 3 + a]).map_err(coded)?;
                    *o = *o << 1 | u32::from(bit);
                }
            }
            *p = std::array::from_fn(|a| classes.snap(class, (p[a] << kept | offset[a]) << (refine - kept)));
            of.push(class);
        }
        coder.finish().map_err(coded)?;
        classes.of = of;
        Ok(classes)
    }
}

/// The classes' coding: class `k` as `k` one-bits and a zero-bit (none after the last class),
/// bit `j` with the adaptive context of (the previous Gaussian's class, `j`). Gaussians next to
/// each other in the octree's order are near in space and mostly alike in how much they show.
struct ClassContexts {
    count: usize,
    previous: u8,
    bits: Vec<BitContext>,
}

impl ClassContexts {
    fn new(count: usize) -> Self {
        Self { count, previous: 0, bits: vec![BitContext::default(); count * (count - 1)] }
    }

    fn context(&mut self, j: usize) -> &mut BitContext {
        &mut self.bits[usize::from(self.previous) * (self.count - 1) + j]
    }

    fn write(&mut self, coder: &mut SymbolEncoder, class: u8) {
        for j in 0..(usize::from(class) + 1).min(self.count - 1) {
            coder.bit(self.context(j), j < usize::from(class));
        }
        self.previous = class;
    }

    fn read(&mut self, coder: &mut SymbolDecoder) -> Result<u8, EntropyError> {
        let mut class = 0;
        while usize::from(class) < self.count - 1 && coder.bit(self.context(usize::from(class)))? {
            class += 1;
        }
        self.previous = class;
        Ok(class)
    }
}
