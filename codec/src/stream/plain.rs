//! The plain-3DGS content of a stream (SPEC.md section 6): positions on an octree-coded grid
//! and every other attribute uniformly quantized with a step chosen by the encoder, each
//! channel entropy-coded with its own frequency table; optionally with importance classes
//! ([`ImportanceClasses`]), which scale the steps per Gaussian and code a table per class.

use pwgs_bitstream::{Container, FieldError, FieldReader, FieldWriter, Tag};
use rayon::prelude::*;

use super::classes::{CLASSES, ImportanceClasses};
use super::colour_differences::{self, COLOUR_DIFFERENCES};
use super::entropy::{EntropyError, FrequencyTable, MAX_MAGNITUDE, SymbolDecoder, SymbolEncoder};
use super::gaussian_model::GaussianModel;
use super::octree::{self, MAX_DEPTH, OctreeError};
use super::trees::{self, ADAPTIVE, TreeModel, Trees};
use super::{DecodeError, Sections};
use pwgs_core::gaussians::{Gaussians, sh_band, sh_coeff_count};

pub const POSITIONS: Tag = Tag(*b"POSN");
pub const SCALES: Tag = Tag(*b"SCAL");
pub const ROTATIONS: Tag = Tag(*b"ROTN");
pub const OPACITIES: Tag = Tag(*b"OPAC");
pub const COLORS: Tag = Tag(*b"COLR");
pub const SH_REST: Tag = Tag(*b"SHRS");

/// The grid positions live on: `origin + q * cell` per axis, `q < 2^depth`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionGrid {
    pub origin: [f32; 3],
    pub cell: f32,
    pub depth: u8,
}

impl PositionGrid {
    /// Normative reconstruction: computed in binary64 (exact product, one rounding of the sum)
    /// and rounded once to binary32.
    pub fn position(&self, q: [u32; 3]) -> [f32; 3] {
        self.refined_position(q, 0)
    }

    /// The position of `q` on the grid `refine` levels finer (cells `cell / 2^refine`, exact in
    /// binary64; with `depth + refine <= 24` the product is exact too).
    pub fn refined_position(&self, q: [u32; 3], refine: u8) -> [f32; 3] {
        let cell = f64::from(self.cell) / f64::from(1u32 << refine);
        std::array::from_fn(|a| (f64::from(self.origin[a]) + f64::from(q[a]) * cell) as f32)
    }
}

/// A rotation coded as its "smallest three": the unit quaternion (w, x, y, z) with its largest
/// component made positive; `largest` is that component's index, `rest` the other three in
/// index order, quantized.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuantizedRotation {
    pub largest: u8,
    pub rest: [i32; 3],
}

impl QuantizedRotation {
    /// Normative reconstruction: the three components `q * step`, the largest
    /// `sqrt(max(0, 1 - (a*a + b*b + c*c)))`, all in binary32 in this order.
    pub fn quaternion(&self, step: f32) -> [f32; 4] {
        let rest = self.rest.map(|q| q as f32 * step);
        let sum = rest[0] * rest[0] + rest[1] * rest[1] + rest[2] * rest[2];
        let largest = (1.0 - sum).max(0.0).sqrt();
        let mut out = [0.0; 4];
        let mut others = rest.into_iter();
        for (i, c) in out.iter_mut().enumerate() {
            *c = if i == self.largest as usize { largest } else { others.next().expect("three others") };
        }
        out
    }
}

/// Quantized plain 3D Gaussians: exactly what a plain-3DGS stream stores.
#[derive(Debug, Clone, PartialEq)]
pub struct PlainGaussians {
    /// `POSN`'s grid.
    pub grid: PositionGrid,
    /// Grid coordinates, on `grid` refined by the classes' `refine` levels when there are
    /// classes (and then canonical: each class's dropped bits at the centre, see
    /// [`ImportanceClasses::snap`]).
    pub positions: Vec<[u32; 3]>,
    pub classes: Option<ImportanceClasses>,
    pub scale_step: f32,
    pub log_scales: Vec<[i32; 3]>,
    pub rotation_step: f32,
    pub rotations: Vec<QuantizedRotation>,
    pub opacity_step: f32,
    pub opacity_logits: Vec<i32>,
    pub sh_degree: u32,
    pub dc_step: f32,
    pub sh_dc: Vec<[i32; 3]>,
    /// Step of each SH band 1..=degree.
    pub band_steps: Vec<f32>,
    /// Per Gaussian, `(sh_coeff_count(degree) - 1) * 3` values, [coefficient][rgb].
    pub sh_rest: Vec<i32>,
    /// Code every colour triple as (r - g, g, b - g) (section `CDIF`, SPEC.md 6.6); see
    /// [`Self::colour_differences_fit`].
    pub colour_differences: bool,
    /// Code each attribute block with adaptive trees where that is smaller than with its
    /// tables (section `ADPT`, SPEC.md 6.7; the section is written whichever blocks use them).
    pub adaptive: bool,
}

impl PlainGaussians {
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    fn rest_per_gaussian(&self) -> usize {
        (sh_coeff_count(self.sh_degree) - 1) * 3
    }

    /// Levels the importance classes refine `POSN`'s grid by (0 without classes).
    pub fn refine(&self) -> u8 {
        self.classes.as_ref().map_or(0, |c| c.refine)
    }

    /// Whether the colours can be coded as differences: every difference within the values'
    /// limit.
    pub fn colour_differences_fit(&self) -> bool {
        colour_differences::fit(self.sh_dc.as_flattened()) && colour_differences::fit(&self.sh_rest)
    }

    /// The Gaussians this content decodes to (normative reconstruction, SPEC.md sections 6
    /// and 6.5).
    pub fn dequantize(&self) -> Gaussians {
        let n = self.len();
        let rest = self.rest_per_gaussian();
        let step = |i: usize, s: f32| self.classes.as_ref().map_or(s, |c| c.step(i, s));
        let mut sh = Vec::with_capacity(n * (rest + 3));
        for i in 0..n {
            let dc_step = step(i, self.dc_step);
            sh.extend(self.sh_dc[i].map(|q| q as f32 * dc_step));
            for (j, &q) in self.sh_rest[i * rest..(i + 1) * rest].iter().enumerate() {
                sh.push(q as f32 * step(i, self.band_steps[sh_band(1 + j / 3) - 1]));
            }
        }
        let refine = self.refine();
        Gaussians {
            means: self.positions.iter().map(|&q| self.grid.refined_position(q, refine)).collect(),
            log_scales: (0..n).map(|i| self.log_scales[i].map(|v| v as f32 * step(i, self.scale_step))).collect(),
            rotations: (0..n).map(|i| self.rotations[i].quaternion(step(i, self.rotation_step))).collect(),
            opacity_logits: (0..n).map(|i| self.opacity_logits[i] as f32 * step(i, self.opacity_step)).collect(),
            sh_degree: self.sh_degree,
            sh,
        }
    }

    /// The sections of this content, attributes in the order the octree lists positions.
    pub(super) fn write_sections(&self) -> Result<Sections, OctreeError> {
        let refine = self.refine();
        let coarse: Vec<[u32; 3]> = self.positions.iter().map(|q| q.map(|c| c >> refine)).collect();
        let (positions, order) = write_positions(&self.grid, &coarse)?;
        let mut sections = vec![(POSITIONS, positions)];
        if let Some(classes) = &self.classes {
            sections.push((CLASSES, classes.write(&self.positions, &order)));
        }
        let classes = self.classes.as_ref();
        // Each block with tables, and with trees when those are asked for, fit, and smaller.
        let mut adaptive = [false; 5];
        let mut block = |tag: Tag, steps: &[f32], channels: usize, value: &dyn Fn(usize, usize) -> i32| {
            let write = |models| {
                let mut w = FieldWriter::new();
                steps.iter().for_each(|&s| w.f32(s));
                write_block(&mut w, models, (&order, classes), channels, value).then(|| w.into_bytes())
            };
            let tables = write(Models::Tables).expect("tables hold any values");
            let k = trees::BLOCKS.iter().position(|&b| b == tag).expect("an attribute block");
            match self.adaptive.then(|| write(Models::Trees)).flatten().filter(|t| t.len() < tables.len()) {
                Some(trees) => {
                    adaptive[k] = true;
                    (tag, trees)
                }
                None => (tag, tables),
            }
        };
        sections.push(block(SCALES, &[self.scale_step], 3, &|i, c| self.log_scales[i][c]));
        sections.push(block(ROTATIONS, &[self.rotation_step], 4, &|i, c| {
            let r = &self.rotations[i];
            if c == 0 { i32::from(r.largest) } else { r.rest[c - 1] }
        }));
        sections.push(block(OPACITIES, &[self.opacity_step], 1, &|i, _| self.opacity_logits[i]));
        let rest = self.rest_per_gaussian();
        let triple = |v: &[i32], c: usize| -> i32 {
            let t = &v[c / 3 * 3..][..3];
            if self.colour_differences { colour_differences::coded([t[0], t[1], t[2]], c % 3) } else { t[c % 3] }
        };
        if self.colour_differences {
            assert!(self.colour_differences_fit(), "colour differences beyond 2^24");
            sections.push((COLOUR_DIFFERENCES, vec![]));
        }
        sections.push(block(COLORS, &[self.dc_step], 3, &|i, c| triple(&self.sh_dc[i], c)));
        if rest > 0 {
            sections.push(block(SH_REST, &self.band_steps, rest, &|i, c| triple(&self.sh_rest[i * rest..], c)));
        }
        if self.adaptive {
            sections.push((ADAPTIVE, trees::payload(adaptive)));
        }
        Ok(sections)
    }

    /// Reads and decodes the content sections, checking in SPEC.md's order (section 6.4):
    /// which sections are present, then positions, then the attribute blocks. `count` must
    /// already be bounded by the stream's size. The attribute sections decode in parallel;
    /// the first failing one in section order is reported, and the result does not depend on
    /// the thread count.
    pub(super) fn read_sections(container: &Container, count: usize, sh_degree: u32) -> Result<Self, DecodeError> {
        let payload = |tag: Tag| container.section(tag).map(|s| s.payload).ok_or(DecodeError::MissingSection(tag));
        let rest = (sh_coeff_count(sh_degree) - 1) * 3;
        // (tag, steps, channels, value check) of every block; SHRS has no channels at degree 0.
        let any: ValueCheck = |_, _| Ok(());
        let blocks: [(Tag, usize, usize, ValueCheck); 5] = [
            (SCALES, 1, 3, any),
            (ROTATIONS, 1, 4, check_rotation_index),
            (OPACITIES, 1, 1, any),
            (COLORS, 1, 3, any),
            (SH_REST, sh_degree as usize, rest, any),
        ];
        let positions_payload = payload(POSITIONS)?;
        // A block without channels has no section.
        let block_payloads = blocks
            .iter()
            .map(|&(tag, _, channels, _)| if channels == 0 { Ok(None) } else { payload(tag).map(Some) })
            .collect::<Result<Vec<_>, _>>()?;
        if rest == 0 && container.section(SH_REST).is_some() {
            return Err(DecodeError::invalid(SH_REST, "present, but the SH degree is 0 (the section must be absent)"));
        }
        let (grid, mut positions) = read_positions(POSITIONS, positions_payload, count)?;
        let classes = match container.section(CLASSES) {
            Some(s) => Some(ImportanceClasses::read(s.payload, grid.depth, &mut positions)?),
            None => None,
        };
        let adaptive = match container.section(ADAPTIVE) {
            Some(s) => Some(trees::read_payload(s.payload, [true, true, true, true, rest > 0])?),
            None => None,
        };
        let models = |k: usize| match adaptive {
            Some(used) if used[k] => Models::Trees,
            _ => Models::Tables,
        };
        let rows = Rows { count, classes: classes.as_ref() };
        let decoded: Vec<Result<Block, DecodeError>> = (blocks.par_iter().enumerate())
            .zip(block_payloads)
            .map(|((k, &(tag, steps, channels, check)), bytes)| match bytes {
                Some(bytes) => read_block(tag, bytes, (models(k), steps, channels, check), rows),
                None => Ok((vec![], vec![])),
            })
            .collect();
        let Ok([scales, rotations, opacities, colors, sh_rest]) = <[_; 5]>::try_from(decoded) else {
            unreachable!("one result per block")
        };
        let (scale_steps, scales) = scales?;
        let (rotation_steps, rotation_values) = rotations?;
        let (opacity_steps, opacity_logits) = opacities?;
        let (dc_steps, mut colors) = colors?;
        let (band_steps, mut sh_rest) = sh_rest?;
        let differences = container.section(COLOUR_DIFFERENCES);
        if let Some(section) = differences {
            colour_differences::check_payload(section.payload)?;
            colour_differences::undo(COLORS, &mut colors)?;
            colour_differences::undo(SH_REST, &mut sh_rest)?;
        }
        let rotations = rotation_values
            .chunks_exact(4)
            .map(|r| QuantizedRotation { largest: r[0] as u8, rest: [r[1], r[2], r[3]] })
            .collect();
        let triples = |v: Vec<i32>| v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect::<Vec<_>>();
        Ok(Self {
            grid,
            positions,
            classes,
            scale_step: scale_steps[0],
            log_scales: triples(scales),
            rotation_step: rotation_steps[0],
            rotations,
            opacity_step: opacity_steps[0],
            opacity_logits,
            sh_degree,
            dc_step: dc_steps[0],
            sh_dc: triples(colors),
            band_steps,
            sh_rest,
            colour_differences: differences.is_some(),
            adaptive: adaptive.is_some(),
        })
    }
}

/// The payload of a positions section (`POSN`, `APOS`): the grid, then the octree, and the
/// order in which a decoder lists the points (`order[i]` indexes `positions`).
pub(super) fn write_positions(
    grid: &PositionGrid,
    positions: &[[u32; 3]],
) -> Result<(Vec<u8>, Vec<usize>), OctreeError> {
    let (coded, order) = octree::encode(positions, grid.depth)?;
    let mut w = FieldWriter::new();
    grid.origin.iter().for_each(|&c| w.f32(c));
    w.f32(grid.cell);
    w.u8(grid.depth);
    w.extend(&coded);
    Ok((w.into_bytes(), order))
}

/// Reads a positions section holding exactly `count` points.
pub(super) fn read_positions(
    tag: Tag,
    payload: &[u8],
    count: usize,
) -> Result<(PositionGrid, Vec<[u32; 3]>), DecodeError> {
    let name = String::from_utf8_lossy(&tag.0).into_owned();
    let mut r = FieldReader::new(&name, payload);
    let origin = [r.f32("origin x")?, r.f32("origin y")?, r.f32("origin z")?];
    let cell = r.f32("cell")?;
    if !(cell > 0.0) {
        return Err(r.error("cell", format!("{cell} is not positive")).into());
    }
    let depth = r.u8("depth")?;
    if !(1..=MAX_DEPTH).contains(&depth) {
        return Err(r.error("depth", format!("{depth} is outside 1..={MAX_DEPTH}")).into());
    }
    let far =
        origin.iter().map(|o| f64::from(o.abs())).fold(0.0, f64::max) + f64::from(cell) * f64::from(1u32 << depth);
    if !(far < f64::from(f32::MAX)) {
        return Err(r.error("cell", format!("a {depth}-level grid of cell {cell} reaches beyond binary32")).into());
    }
    let positions = octree::decode(r.rest(), depth, count).map_err(|e| DecodeError::coded(tag, e))?;
    Ok((PositionGrid { origin, cell, depth }, positions))
}

/// A decoded attribute block: its steps and its values, Gaussian-major.
pub(super) type Block = (Vec<f32>, Vec<i32>);

/// A constraint on a block's values, checked as each is decoded: `(channel, value)`.
pub(super) type ValueCheck = fn(usize, i32) -> Result<(), String>;

/// ROTN's channel 0 is the index of the largest quaternion component (SPEC.md section 6.2).
fn check_rotation_index(channel: usize, value: i32) -> Result<(), String> {
    match channel != 0 || (0..=3).contains(&value) {
        true => Ok(()),
        false => Err(format!("largest-component index {value} is not 0..=3")),
    }
}

/// How a block's channels are modelled: a frequency table each (SPEC.md section 5.3, the plain
/// base), a quantized Gaussian each (section 5.4, the anchor base), or adaptive trees (section
/// 6.7, the plain base with `ADPT`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Models {
    Tables,
    Gaussians,
    Trees,
}

/// A block's models as they code its values, one per slot (class and channel).
enum Coders {
    Tables(Vec<FrequencyTable>),
    Trees(Trees),
}

impl Models {
    /// Fits the model of each slot to its values (in coding order) and writes them; `None`
    /// (and nothing written) when trees cannot hold them.
    fn fit_and_write(self, w: &mut FieldWriter, slots: &[Vec<i32>]) -> Option<Coders> {
        let mut tables = |fit: fn(&mut FieldWriter, &[i32]) -> FrequencyTable| {
            Some(Coders::Tables(slots.iter().map(|values| fit(w, values)).collect()))
        };
        match self {
            Models::Tables => tables(|w, values| {
                let table = FrequencyTable::fit(values);
                table.write(w);
                table
            }),
            Models::Gaussians => tables(|w, values| {
                let model = GaussianModel::fit(values);
                model.write(w);
                model.table()
            }),
            Models::Trees => {
                let models = slots.iter().map(|v| TreeModel::fit(v)).collect::<Option<Vec<TreeModel>>>()?;
                if !Trees::fit_in_a_block(&models) {
                    return None;
                }
                models.iter().for_each(|m| m.write(w));
                Some(Coders::Trees(Trees::new(models)))
            }
        }
    }

    fn read(self, r: &mut FieldReader, slots: usize) -> Result<Coders, FieldError> {
        match self {
            Models::Tables => {
                Ok(Coders::Tables((0..slots).map(|_| FrequencyTable::read(r)).collect::<Result<_, _>>()?))
            }
            Models::Gaussians => Ok(Coders::Tables(
                (0..slots).map(|_| GaussianModel::read(r).map(GaussianModel::table)).collect::<Result<_, _>>()?,
            )),
            Models::Trees => Trees::read(r, slots).map(Coders::Trees),
        }
    }
}

impl Coders {
    fn encode(&mut self, coder: &mut SymbolEncoder, slot: usize, value: i32) {
        match self {
            Coders::Tables(tables) => coder.value(&tables[slot], value),
            Coders::Trees(trees) => trees.encode(coder, slot, value),
        }
    }

    fn decode(&mut self, coder: &mut SymbolDecoder, slot: usize) -> Result<i32, EntropyError> {
        match self {
            Coders::Tables(tables) => coder.value(&tables[slot]),
            Coders::Trees(trees) => trees.decode(coder, slot),
        }
    }
}

/// Block syntax: one model per channel (per class and channel, class-major, with importance
/// classes), then the range-coded values, row by row (in `order`), channel by channel, each
/// with its row's class's model. False, with nothing written, when trees cannot hold the
/// values (a range wider than a tree's, or too many nodes).
pub(super) fn write_block(
    w: &mut FieldWriter,
    models: Models,
    (order, classes): (&[usize], Option<&ImportanceClasses>),
    channels: usize,
    value: &dyn Fn(usize, usize) -> i32,
) -> bool {
    let class_of = |i: usize| classes.map_or(0, |c| usize::from(c.of[i]));
    let groups = classes.map_or(1, |c| c.factors.len());
    let mut slots = vec![Vec::new(); groups * channels];
    for &i in order {
        for c in 0..channels {
            slots[class_of(i) * channels + c].push(value(i, c));
        }
    }
    let Some(mut coders) = models.fit_and_write(w, &slots) else { return false };
    let mut coder = SymbolEncoder::new();
    for &i in order {
        for c in 0..channels {
            coders.encode(&mut coder, class_of(i) * channels + c, value(i, c));
        }
    }
    w.extend(&coder.finish());
    true
}

/// Whether a step is usable: positive, and small enough that every quantized value (below
/// 2^24 in magnitude) times it stays finite.
fn usable_step(s: f32) -> bool {
    s > 0.0 && (s * MAX_MAGNITUDE as f32).is_finite()
}

/// A block's step field: finite and [usable](usable_step).
pub(super) fn read_step(r: &mut FieldReader) -> Result<f32, FieldError> {
    let s = r.f32("step")?;
    match usable_step(s) {
        true => Ok(s),
        false => Err(r.error("step", format!("{s} is not positive or too large"))),
    }
}

/// The rows of a block: how many, and their classes when the stream has importance classes.
#[derive(Debug, Clone, Copy)]
pub(super) struct Rows<'a> {
    pub count: usize,
    pub classes: Option<&'a ImportanceClasses>,
}

impl Rows<'_> {
    pub(super) fn plain(count: usize) -> Self {
        Self { count, classes: None }
    }
}

/// Reads `steps` step sizes (each finite and positive, also times every class's factor) and a
/// block of `channels` channels for `rows`, each value passing `check` as it is decoded.
pub(super) fn read_block(
    tag: Tag,
    payload: &[u8],
    (models, steps, channels, check): (Models, usize, usize, ValueCheck),
    rows: Rows,
) -> Result<Block, DecodeError> {
    let name = String::from_utf8_lossy(&tag.0).into_owned();
    let mut r = FieldReader::new(&name, payload);
    let step_values = (0..steps).map(|_| read_step(&mut r)).collect::<Result<Vec<f32>, FieldError>>()?;
    let factors = rows.classes.map_or(&[][..], |c| &c.factors);
    for (&s, (k, &f)) in step_values.iter().flat_map(|s| std::iter::repeat(s).zip(factors.iter().enumerate())) {
        if !usable_step(s * f) {
            let problem = format!("{s} times class {k}'s factor {f} is not positive or too large");
            return Err(r.error("step", problem).into());
        }
    }
    let groups = factors.len().max(1);
    let mut coders = models.read(&mut r, groups * channels)?;
    let coded = |e: EntropyError| DecodeError::coded(tag, e);
    let mut coder = SymbolDecoder::new(r.rest()).map_err(coded)?;
    let mut values = Vec::with_capacity(rows.count * channels);
    for i in 0..rows.count {
        let class = rows.classes.map_or(0, |c| usize::from(c.of[i]));
        for channel in 0..channels {
            let value = coders.decode(&mut coder, class * channels + channel).map_err(coded)?;
            check(channel, value).map_err(|problem| DecodeError::invalid(tag, problem))?;
            values.push(value);
        }
    }
    coder.finish().map_err(coded)?;
    Ok((step_values, values))
}
