//! The pwgs stream (SPEC.md): what each section holds and how a decoder turns it back into
//! Gaussians. The container syntax itself lives in `pwgs-bitstream`.

pub mod anchor;
pub mod anchor_context;
pub mod classes;
pub mod colour_differences;
pub mod describe;
pub mod entropy;
pub mod gaussian_model;
pub mod header;
pub mod octree;
pub mod plain;
pub mod trees;
pub mod wrap;

use crate::hashing::Hasher;
use pwgs_bitstream::{Container, FieldError, SECTION_OVERHEAD, StreamError, Tag, write_container};

use crate::scene::{Base, Scene};
use anchor::QuantizedAnchors;
use header::{BaseKind, Header};
use plain::PlainGaussians;
use pwgs_core::gaussians::Gaussians;
use wrap::{QuantizedSynthesis, WRAPPER};

/// Why a stream could not be decoded.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum DecodeError {
    #[error(transparent)]
    Container(#[from] StreamError),
    #[error(transparent)]
    Field(#[from] FieldError),
    #[error("the stream has no {0} section")]
    MissingSection(Tag),
    #[error("the stream needs section {0}, which this decoder does not know (written by a newer encoder?)")]
    UnknownCriticalSection(Tag),
    #[error("section {tag}: {problem}")]
    Invalid { tag: Tag, problem: String },
}

impl DecodeError {
    fn invalid(tag: Tag, problem: impl Into<String>) -> Self {
        Self::Invalid { tag, problem: problem.into() }
    }

    fn coded(tag: Tag, error: impl std::fmt::Display) -> Self {
        Self::invalid(tag, format!("coded data: {error}"))
    }
}

/// Critical sections a plain-3DGS stream may hold.
const PLAIN_SECTIONS: [Tag; 11] = [
    Tag::HEAD,
    plain::POSITIONS,
    classes::CLASSES,
    colour_differences::COLOUR_DIFFERENCES,
    trees::ADAPTIVE,
    plain::SCALES,
    plain::ROTATIONS,
    plain::OPACITIES,
    plain::COLORS,
    plain::SH_REST,
    WRAPPER,
];

/// Critical sections an anchor stream may hold.
const ANCHOR_SECTIONS: [Tag; 9] = [
    Tag::HEAD,
    anchor::NETWORKS,
    anchor::ANCHOR_POSITIONS,
    anchor_context::CONTEXT,
    anchor::FEATURES,
    anchor::SCALING,
    anchor::MASKS,
    anchor::OFFSETS,
    WRAPPER,
];

/// What a stream's base holds, quantized, as coded.
#[derive(Debug, Clone, PartialEq)]
pub enum Content {
    Plain(Box<PlainGaussians>),
    Anchors(Box<QuantizedAnchors>),
}

impl Content {
    /// The base this content reconstructs (normative).
    pub fn dequantize(&self) -> Base {
        match self {
            Content::Plain(p) => Base::Plain(p.dequantize()),
            Content::Anchors(a) => Base::Anchors(Box::new(a.dequantize())),
        }
    }
}

/// Content to write: either kind, borrowed ([`encode`] takes `&PlainGaussians`,
/// `&QuantizedAnchors` or `&Content`).
#[derive(Debug, Clone, Copy)]
pub enum ContentRef<'a> {
    Plain(&'a PlainGaussians),
    Anchors(&'a QuantizedAnchors),
}

impl<'a> From<&'a PlainGaussians> for ContentRef<'a> {
    fn from(p: &'a PlainGaussians) -> Self {
        ContentRef::Plain(p)
    }
}

impl<'a> From<&'a QuantizedAnchors> for ContentRef<'a> {
    fn from(a: &'a QuantizedAnchors) -> Self {
        ContentRef::Anchors(a)
    }
}

impl<'a> From<&'a Content> for ContentRef<'a> {
    fn from(c: &'a Content) -> Self {
        match c {
            Content::Plain(p) => ContentRef::Plain(p),
            Content::Anchors(a) => ContentRef::Anchors(a.as_ref()),
        }
    }
}

impl ContentRef<'_> {
    fn base_kind(self) -> BaseKind {
        match self {
            ContentRef::Plain(_) => BaseKind::Plain3dgs,
            ContentRef::Anchors(_) => BaseKind::Anchors,
        }
    }

    /// Gaussians of a plain base, anchors of an anchor base: the header's count.
    fn len(self) -> usize {
        match self {
            ContentRef::Plain(p) => p.len(),
            ContentRef::Anchors(a) => a.len(),
        }
    }

    /// Stream bytes this content needs at least so that a decoder accepts its count (SPEC.md
    /// section 9).
    fn minimum_stream_len(self) -> usize {
        match self {
            ContentRef::Plain(p) => p.len() * BYTES_PER_GAUSSIAN as usize,
            ContentRef::Anchors(a) => {
                let (n, f, k) = (a.len() as u64, a.feature_dim, a.offsets_per_anchor);
                let values = n * anchor::values_per_anchor(f, k);
                let view_work = n * anchor::view_multiply_adds(f, k, a.mlps.each_ref().map(|m| m.hidden));
                let context_work = a.context.as_ref().map_or(0, |c| {
                    n * anchor_context::context_multiply_adds(
                        &c.shape,
                        c.mlp.hidden,
                        anchor_context::predicted_values(f, k),
                    )
                });
                let grid_bits = a.context.as_ref().map_or(0, |c| c.signs.len() as u64);
                let open = a.masks.iter().filter(|&&m| m).count() as u64;
                [
                    n * BYTES_PER_GAUSSIAN,
                    values.div_ceil(anchor::VALUES_PER_BYTE),
                    view_work.max(context_work).div_ceil(anchor::MULTIPLY_ADDS_PER_BYTE),
                    grid_bits.div_ceil(anchor_context::GRID_BITS_PER_BYTE),
                    open * BYTES_PER_GAUSSIAN,
                ]
                .into_iter()
                .max()
                .unwrap_or(0) as usize
            }
        }
    }

    /// The content's sections and the stream length they need at least (SPEC.md section 9, and
    /// 12.7 for the context model's tables, known once its values are written).
    fn write_sections(self) -> Result<(Sections, usize), octree::OctreeError> {
        let (sections, table_symbols) = match self {
            ContentRef::Plain(p) => (p.write_sections()?, 0),
            ContentRef::Anchors(a) => a.write_sections()?,
        };
        let needed = self.minimum_stream_len().max(anchor_context::stream_len_for_table_symbols(table_symbols));
        Ok((sections, needed))
    }
}

/// Writes a complete stream, with the perceptual wrapper when `wrapper` is given. The header's
/// base kind, count and SH degree must match the content.
pub fn encode<'a>(
    header: &Header,
    content: impl Into<ContentRef<'a>>,
    wrapper: Option<&QuantizedSynthesis>,
) -> Result<Vec<u8>, octree::OctreeError> {
    let content = content.into();
    assert_eq!(header.base, content.base_kind(), "header base kind does not match the content");
    assert_eq!(header.gaussian_count as usize, content.len(), "header count does not match the content");
    if let ContentRef::Plain(p) = content {
        assert_eq!(header.sh_degree, p.sh_degree, "header SH degree does not match the content");
    }
    let mut sections = vec![(Tag::HEAD, header.write())];
    let (content_sections, needed) = content.write_sections()?;
    sections.extend(content_sections);
    if let Some(w) = wrapper {
        sections.push((WRAPPER, w.write()));
    }
    let bytes = write_container(&sections);
    // Content far more redundant than any real scene (e.g. hundreds of identical Gaussians)
    // can code to fewer bytes than its counts or context tables need, which decoders refuse
    // (SPEC.md sections 9, 12.7): an optional section of zeros pads such a stream to that length.
    if bytes.len() < needed {
        sections.push((PADDING, vec![0; (needed - bytes.len()).saturating_sub(SECTION_OVERHEAD)]));
        return Ok(write_container(&sections));
    }
    Ok(bytes)
}

/// A stream's sections, tags and payloads, in writing order.
pub(super) type Sections = Vec<(Tag, Vec<u8>)>;

/// The optional section that pads a stream to the length its content needs; decoders skip it.
pub const PADDING: Tag = Tag(*b"pad ");

/// A decoded stream: its header, the quantized content as coded, and the scene it
/// reconstructs.
#[derive(Debug, Clone, PartialEq)]
pub struct Decoded {
    pub header: Header,
    pub content: Content,
    pub scene: Scene,
}

/// Parses, verifies and decodes a stream, checking in SPEC.md's order (sections 6.4, 12.5).
pub fn decode(bytes: &[u8]) -> Result<Decoded, DecodeError> {
    let (container, header) = parse(bytes)?;
    let known: &[Tag] = match header.base {
        BaseKind::Plain3dgs => &PLAIN_SECTIONS,
        BaseKind::Anchors => &ANCHOR_SECTIONS,
    };
    for section in &container.sections {
        if section.tag.is_critical() && !known.contains(&section.tag) {
            return Err(DecodeError::UnknownCriticalSection(section.tag));
        }
    }
    check_count_against_length(&header, bytes.len())?;
    let count = header.gaussian_count as usize;
    let content = match header.base {
        BaseKind::Plain3dgs => {
            Content::Plain(Box::new(PlainGaussians::read_sections(&container, count, header.sh_degree)?))
        }
        BaseKind::Anchors => {
            Content::Anchors(Box::new(QuantizedAnchors::read_sections(&container, count, bytes.len())?))
        }
    };
    let wrapper = match container.section(WRAPPER) {
        Some(section) => Some(QuantizedSynthesis::read(section.payload, container.minor)?.dequantize()),
        None => None,
    };
    let scene = Scene { base: content.dequantize(), wrapper, frame: header.frame(), background: header.background };
    Ok(Decoded { header, content, scene })
}

/// SPEC.md section 9: a stream may declare at most one Gaussian per [`BYTES_PER_GAUSSIAN`] bytes
/// of its length. Every symbol decoded and every byte allocated afterwards is proportional to
/// the count, so this bounds a decoder's work and memory by the size of what it was handed (an
/// adaptive bit can cost far less than a bit, so the coded data alone would let a few KB
/// declare millions).
fn check_count_against_length(header: &Header, len: usize) -> Result<(), DecodeError> {
    let count = u64::from(header.gaussian_count);
    if count * BYTES_PER_GAUSSIAN > len as u64 {
        return Err(DecodeError::invalid(
            Tag::HEAD,
            format!(
                "gaussian count {count} exceeds half the stream's length of {len} bytes (at least \
                 {BYTES_PER_GAUSSIAN} bytes per Gaussian)"
            ),
        ));
    }
    Ok(())
}

/// Stream bytes a stream needs at least per Gaussian it declares (per anchor, and per unmasked
/// offset, in an anchor base): SPEC.md section 9's bound, which keeps decoding a 1 MB stream
/// within about a second on a 2-core machine (500,000 Gaussians of degree 3, or octrees of
/// 500,000 points 24 levels deep).
pub const BYTES_PER_GAUSSIAN: u64 = 2;

/// Each section's tag (trailing spaces trimmed) and its size in the stream, tag, length and
/// CRC included, in stream order.
pub fn section_sizes(container: &Container) -> Vec<(String, usize)> {
    container
        .sections
        .iter()
        .map(|s| (String::from_utf8_lossy(&s.tag.0).trim_end().to_string(), s.payload.len() + SECTION_OVERHEAD))
        .collect()
}
/// The container and header of a stream, every CRC verified, without decoding the content.
pub fn parse(bytes: &[u8]) -> Result<(Container<'_>, Header), DecodeError> {
    let container = Container::parse(bytes)?;
    let head = container.section(Tag::HEAD).ok_or(DecodeError::MissingSection(Tag::HEAD))?;
    let header = Header::read(head.payload, container.minor)?;
    Ok((container, header))
}

/// SHA-256 of decoded Gaussians in a canonical byte layout (count, SH degree, then every array
/// as little-endian binary32): equal hashes mean bit-identical attributes.
pub fn attribute_hash(g: &Gaussians) -> String {
    let mut h = Hasher::default();
    h.u64(g.len() as u64);
    h.bytes(&g.sh_degree.to_le_bytes());
    let floats = g.means.iter().flatten().chain(g.log_scales.iter().flatten()).chain(g.rotations.iter().flatten());
    h.floats(floats.chain(&g.opacity_logits).chain(&g.sh));
    h.hex()
}
