//! Writing what a correct encoder does not write: containers of any version with sections
//! edited after the fact (CRCs sealed again, so that the CRC does not catch an edit before the
//! check it targets), attribute blocks with hand-made frequency tables, and coded chunks made of
//! chosen symbol intervals.

use std::num::NonZeroU32;

use constriction::stream::Encode;
use constriction::stream::model::{EncoderModel, EntropyModel};
use constriction::stream::queue::DefaultRangeEncoder;
use pwgs_bitstream::{Container, FieldReader, FieldWriter, MAGIC, Tag};
use pwgs_codec::stream::entropy::{FrequencyTable, PRECISION, SymbolEncoder, TOTAL};

/// A stream as its version and sections (`END ` left out), to edit and seal again.
#[derive(Debug, Clone, PartialEq)]
pub struct Sections {
    pub major: u16,
    pub minor: u16,
    pub list: Vec<(Tag, Vec<u8>)>,
}

impl Sections {
    /// The sections of a stream this generator wrote (panics on an invalid one: a bug here).
    pub fn of(stream: &[u8]) -> Self {
        let c = Container::parse(stream).expect("the generator's own streams are valid containers");
        Self { major: c.major, minor: c.minor, list: c.sections.iter().map(|s| (s.tag, s.payload.to_vec())).collect() }
    }

    /// The payload of the section `tag` (panics when absent: a bug in a case's recipe).
    pub fn payload(&mut self, tag: Tag) -> &mut Vec<u8> {
        let at = self.index(tag);
        &mut self.list[at].1
    }

    /// Where the section `tag` is in the list.
    pub fn index(&self, tag: Tag) -> usize {
        self.list.iter().position(|(t, _)| *t == tag).unwrap_or_else(|| panic!("no section {tag}"))
    }

    pub fn remove(&mut self, tag: Tag) {
        let at = self.index(tag);
        self.list.remove(at);
    }

    /// Inserts a section before the one at `index`.
    pub fn insert(&mut self, index: usize, tag: Tag, payload: Vec<u8>) {
        self.list.insert(index, (tag, payload));
    }

    /// The stream: magic, version, the sections in list order and `END `, every CRC computed
    /// as SPEC.md section 2.1 defines it (the first also covering magic and version).
    pub fn seal(&self) -> Vec<u8> {
        let mut out = self.seal_without_end();
        push_section(&mut out, Tag::END, &[]);
        out
    }

    /// [`Self::seal`] without the closing `END ` section.
    pub fn seal_without_end(&self) -> Vec<u8> {
        let mut out = MAGIC.to_vec();
        out.extend(self.major.to_le_bytes());
        out.extend(self.minor.to_le_bytes());
        for (tag, payload) in &self.list {
            push_section(&mut out, *tag, payload);
        }
        out
    }
}

/// Appends a section; its CRC covers everything from the start of the stream when it is the
/// first section (only magic and version precede it), else the section's own bytes.
fn push_section(out: &mut Vec<u8>, tag: Tag, payload: &[u8]) {
    let start = if out.len() == MAGIC.len() + 4 { 0 } else { out.len() };
    out.extend(tag.0);
    out.extend((payload.len() as u32).to_le_bytes());
    out.extend(payload);
    let crc = crc32c::crc32c(&out[start..]);
    out.extend(crc.to_le_bytes());
}

/// Byte offsets of the sections of a sealed stream (the tag of each), `END ` included.
pub fn section_offsets(stream: &[u8]) -> Vec<usize> {
    let mut offsets = Vec::new();
    let mut at = MAGIC.len() + 4;
    while at + 8 <= stream.len() {
        offsets.push(at);
        let len = u32::from_le_bytes(stream[at + 4..at + 8].try_into().expect("4 bytes"));
        at += 12 + len as usize;
    }
    offsets
}

/// An attribute block's payload split into its fields (SPEC.md section 6.2), each kept as the
/// bytes the stream holds, so a case can replace one and join them again.
#[derive(Debug, Clone, PartialEq)]
pub struct BlockParts {
    pub steps: Vec<u8>,
    pub tables: Vec<Vec<u8>>,
    pub chunk: Vec<u8>,
}

impl BlockParts {
    /// Splits a valid block of `steps` steps and `channels` tables.
    pub fn split(payload: &[u8], steps: usize, channels: usize) -> Self {
        let mut r = FieldReader::new("block", payload);
        let steps = r.bytes("steps", 4 * steps).expect("valid block").to_vec();
        let tables = (0..channels)
            .map(|_| {
                let start = r.position();
                FrequencyTable::read(&mut r).expect("valid table");
                payload[start..r.position()].to_vec()
            })
            .collect();
        Self { steps, tables, chunk: r.rest().to_vec() }
    }

    pub fn join(&self) -> Vec<u8> {
        let mut out = self.steps.clone();
        self.tables.iter().for_each(|t| out.extend(t));
        out.extend(&self.chunk);
        out
    }
}

/// A block payload (SPEC.md section 6.2) with the given tables: `values[i]` are Gaussian i's
/// channel values, in stream order, coded with `tables[channel]` (escaped when outside).
pub fn block(steps: &[f32], tables: &[FrequencyTable], values: &[Vec<i32>]) -> Vec<u8> {
    let mut w = FieldWriter::new();
    steps.iter().for_each(|&s| w.f32(s));
    tables.iter().for_each(|t| t.write(&mut w));
    let mut coder = SymbolEncoder::new();
    for gaussian in values {
        for (table, &v) in tables.iter().zip(gaussian) {
            coder.value(table, v);
        }
    }
    w.extend(&coder.finish());
    w.into_bytes()
}

/// The bytes of one table's syntax (SPEC.md section 5.3) as written, without the checks a
/// [`FrequencyTable`] makes: for tables a decoder must refuse.
pub fn raw_table(lo: i32, n: u32, frequencies: &[u32]) -> Vec<u8> {
    let mut w = FieldWriter::new();
    w.signed_varint(lo);
    w.varint(n);
    frequencies.iter().for_each(|&f| w.varint(f));
    w.into_bytes()
}

/// Frequencies of `n` in-range symbols, (nearly) equal, and the escape taking the rest.
pub fn flat_frequencies(n: u32) -> Vec<u32> {
    let each = (TOTAL - 1) / n;
    let mut frequencies = vec![each; n as usize];
    frequencies.push(TOTAL - each * n);
    frequencies
}

/// The table over `lo .. lo + n` with [`flat_frequencies`].
pub fn flat_table(lo: i32, n: u32) -> FrequencyTable {
    FrequencyTable::from_frequencies(lo, &flat_frequencies(n)).expect("a flat table is valid")
}

/// A symbol given by its interval of the 16-bit cumulative scale: left cumulative and frequency.
#[derive(Debug, Clone, Copy)]
pub struct Interval {
    pub left: u32,
    pub frequency: u32,
}

impl Interval {
    /// Symbol `s` of a table given by its frequencies (in-range symbols, then the escape).
    pub fn of_table(frequencies: &[u32], s: usize) -> Self {
        Self { left: frequencies[..s].iter().sum(), frequency: frequencies[s] }
    }

    /// A raw 16-bit symbol (the halves of an escaped value).
    pub fn raw16(value: u32) -> Self {
        Self { left: value, frequency: 1 }
    }

    /// The escape symbol and the two raw halves of `value`'s zig-zag form (SPEC.md section
    /// 5.3), with no check that the value may be escaped.
    pub fn escaped(frequencies: &[u32], value: i64) -> [Self; 3] {
        let z = ((value << 1) ^ (value >> 63)) as u32;
        [Self::of_table(frequencies, frequencies.len() - 1), Self::raw16(z & 0xffff), Self::raw16(z >> 16)]
    }
}

impl EntropyModel<PRECISION> for Interval {
    type Symbol = ();
    type Probability = u32;
}

impl EncoderModel<PRECISION> for Interval {
    fn left_cumulative_and_probability(&self, _: impl std::borrow::Borrow<()>) -> Option<(u32, NonZeroU32)> {
        Some((self.left, NonZeroU32::new(self.frequency)?))
    }
}

/// A coded chunk (SPEC.md section 5.2) holding exactly these symbols, whatever they mean.
pub fn coded_intervals(symbols: &[Interval]) -> Vec<u8> {
    let mut coder = DefaultRangeEncoder::new();
    for &s in symbols {
        coder.encode_symbol((), s).expect("intervals lie within the 16-bit scale");
    }
    let words = coder.into_compressed().expect("writing to a Vec cannot fail");
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}
