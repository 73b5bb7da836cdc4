//! Container syntax: `MAGIC, major u16, minor u16, section*` where a section is
//! `tag [4], length u32, payload [length], crc32c u32` and the CRC covers tag, length and
//! payload; the first section's CRC also covers the magic and the version, so no byte of a
//! stream is unprotected. The first section is `HEAD`, the last is `END ` (empty), nothing
//! follows it.

use crate::{MAGIC, MAJOR_VERSION, MAX_SECTION_LEN, MAX_SECTIONS, MINOR_VERSION};

/// Bytes a section takes besides its payload: tag, length and CRC.
pub const SECTION_OVERHEAD: usize = 12;

/// A four-byte section tag. An upper-case first byte marks a critical section (a decoder that
/// does not know it must refuse the stream); a lower-case first byte an optional one (skipped).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Tag(pub [u8; 4]);

impl Tag {
    pub const HEAD: Tag = Tag(*b"HEAD");
    pub const END: Tag = Tag(*b"END ");

    /// Tags are printable ASCII letters, digits or spaces, starting with a letter.
    pub fn is_well_formed(&self) -> bool {
        self.0[0].is_ascii_alphabetic() && self.0.iter().all(|b| b.is_ascii_alphanumeric() || *b == b' ')
    }

    pub fn is_critical(&self) -> bool {
        self.0[0].is_ascii_uppercase()
    }
}

impl std::fmt::Display for Tag {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.is_well_formed() {
            write!(f, "'{}'", String::from_utf8_lossy(&self.0))
        } else {
            write!(f, "{:02x?}", self.0)
        }
    }
}

/// Why a byte string is not a readable stream. Offsets are from the start of the file.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum StreamError {
    #[error("not a pwgs stream (the file does not start with the pwgs magic bytes)")]
    NotAStream,
    #[error("stream is version {major}.{minor}; this decoder reads major version {MAJOR_VERSION} only")]
    UnsupportedVersion { major: u16, minor: u16 },
    #[error("stream is truncated: {what} at byte {offset} runs past the end of the file ({len} bytes)")]
    Truncated { what: &'static str, offset: usize, len: usize },
    #[error("section tag {tag} at byte {offset} is malformed")]
    BadTag { tag: Tag, offset: usize },
    #[error("section {tag} at byte {offset} declares {len} bytes, more than the {MAX_SECTION_LEN} a section may hold")]
    SectionTooLarge { tag: Tag, offset: usize, len: u32 },
    #[error("section {tag} at byte {offset} is corrupt: CRC-32C {found:08x}, expected {expected:08x}")]
    BadCrc { tag: Tag, offset: usize, found: u32, expected: u32 },
    #[error("the first section is {found}, expected 'HEAD'")]
    MissingHead { found: Tag },
    #[error("section {tag} appears twice (at byte {offset})")]
    Duplicate { tag: Tag, offset: usize },
    #[error("the 'END ' section must be empty")]
    NonEmptyEnd,
    #[error("{extra} bytes follow the 'END ' section")]
    TrailingBytes { extra: usize },
    #[error("the stream has more than {MAX_SECTIONS} sections")]
    TooManySections,
}

/// One verified section: its tag, its payload and where the section starts in the file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Section<'a> {
    pub tag: Tag,
    pub payload: &'a [u8],
    pub offset: usize,
}

/// A parsed stream: its version and its sections in file order (`HEAD` first, `END ` left out).
#[derive(Debug, Clone, PartialEq)]
pub struct Container<'a> {
    pub major: u16,
    pub minor: u16,
    pub sections: Vec<Section<'a>>,
}

impl<'a> Container<'a> {
    /// Parses and verifies the whole container: magic, major version, every section's bounds and
    /// CRC, `HEAD` first, `END ` last, no duplicate tags, nothing after `END `.
    pub fn parse(bytes: &'a [u8]) -> Result<Self, StreamError> {
        if bytes.len() < MAGIC.len() || bytes[..MAGIC.len()] != MAGIC {
            return Err(StreamError::NotAStream);
        }
        let mut at = MAGIC.len();
        let version = take(bytes, at, 4, "the version")?;
        let major = u16::from_le_bytes([version[0], version[1]]);
        let minor = u16::from_le_bytes([version[2], version[3]]);
        if major != MAJOR_VERSION {
            return Err(StreamError::UnsupportedVersion { major, minor });
        }
        at += 4;
        let mut sections: Vec<Section<'a>> = Vec::new();
        loop {
            let offset = at;
            let head = take(bytes, at, 8, "a section header")?;
            let tag = Tag([head[0], head[1], head[2], head[3]]);
            let len = u32::from_le_bytes([head[4], head[5], head[6], head[7]]);
            if !tag.is_well_formed() {
                return Err(StreamError::BadTag { tag, offset });
            }
            if len > MAX_SECTION_LEN {
                return Err(StreamError::SectionTooLarge { tag, offset, len });
            }
            let payload = take(bytes, at + 8, len as usize, "a section payload")?;
            let crc_bytes = take(bytes, at + 8 + len as usize, 4, "a section CRC")?;
            let expected = u32::from_le_bytes([crc_bytes[0], crc_bytes[1], crc_bytes[2], crc_bytes[3]]);
            let covered_from = if sections.is_empty() { 0 } else { at };
            let found = crc32c::crc32c(&bytes[covered_from..at + 8 + len as usize]);
            if found != expected {
                return Err(StreamError::BadCrc { tag, offset, found, expected });
            }
            at += 12 + len as usize;
            if sections.is_empty() && tag != Tag::HEAD {
                return Err(StreamError::MissingHead { found: tag });
            }
            if tag == Tag::END {
                if len != 0 {
                    return Err(StreamError::NonEmptyEnd);
                }
                break;
            }
            if sections.iter().any(|s| s.tag == tag) {
                return Err(StreamError::Duplicate { tag, offset });
            }
            if sections.len() == MAX_SECTIONS {
                return Err(StreamError::TooManySections);
            }
            sections.push(Section { tag, payload, offset });
        }
        if at != bytes.len() {
            return Err(StreamError::TrailingBytes { extra: bytes.len() - at });
        }
        Ok(Self { major, minor, sections })
    }

    /// The section with this tag, if present.
    pub fn section(&self, tag: Tag) -> Option<&Section<'a>> {
        self.sections.iter().find(|s| s.tag == tag)
    }
}

/// Rewrites the CRC-32C of every complete section of a stream-shaped input (SPEC.md 2.1: a CRC
/// covers its section's tag, length and payload, and the first section's also covers the
/// magic and the version). For tools that edit or mutate streams (fuzzing, hand-made test
/// streams): without it a mutated stream fails its CRC check and never reaches the payload
/// parsers. Sections are walked by their declared lengths; the walk stops at the first one that
/// runs past the end, which is left as it is.
pub fn reseal(bytes: &mut [u8]) {
    let preamble = MAGIC.len() + 4;
    let mut at = preamble;
    while let Some(len) = bytes.get(at + 4..at + 8) {
        let len = u32::from_le_bytes([len[0], len[1], len[2], len[3]]) as usize;
        let crc_at = at + 8 + len;
        let Some(crc_field) = crc_at.checked_add(4).filter(|&end| end <= bytes.len()) else { return };
        let covered_from = if at == preamble { 0 } else { at };
        let crc = crc32c::crc32c(&bytes[covered_from..crc_at]);
        bytes[crc_at..crc_field].copy_from_slice(&crc.to_le_bytes());
        at = crc_field;
    }
}

/// `len` bytes at `at`, or a truncation error naming what was being read.
fn take<'a>(bytes: &'a [u8], at: usize, len: usize, what: &'static str) -> Result<&'a [u8], StreamError> {
    at.checked_add(len).and_then(|end| bytes.get(at..end)).ok_or(StreamError::Truncated {
        what,
        offset: at,
        len: bytes.len(),
    })
}

/// Writes a stream of this crate's version: the magic, the version, the sections in the order
/// given (the caller puts `HEAD` first) and the closing `END `.
///
/// Panics if a tag is malformed, repeated, `END `, or a payload exceeds [`MAX_SECTION_LEN`]:
/// those are programming errors of the writer, not properties of input data.
pub fn write_container(sections: &[(Tag, Vec<u8>)]) -> Vec<u8> {
    assert!(sections.first().is_some_and(|(tag, _)| *tag == Tag::HEAD), "the first section must be HEAD");
    assert!(sections.len() <= MAX_SECTIONS, "too many sections");
    let total: usize = sections.iter().map(|(_, p)| p.len() + SECTION_OVERHEAD).sum();
    let mut out = Vec::with_capacity(MAGIC.len() + 4 + total + SECTION_OVERHEAD);
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&MAJOR_VERSION.to_le_bytes());
    out.extend_from_slice(&MINOR_VERSION.to_le_bytes());
    for (i, (tag, payload)) in sections.iter().enumerate() {
        assert!(tag.is_well_formed() && *tag != Tag::END, "bad section tag {tag}");
        assert!(sections[..i].iter().all(|(t, _)| t != tag), "section {tag} written twice");
        let crc_from = if i == 0 { 0 } else { out.len() };
        push_section(&mut out, *tag, payload, crc_from);
    }
    let end_at = out.len();
    push_section(&mut out, Tag::END, &[], end_at);
    out
}

/// Appends a section whose CRC covers `out[crc_from..]` plus the section itself.
fn push_section(out: &mut Vec<u8>, tag: Tag, payload: &[u8], crc_from: usize) {
    let len = u32::try_from(payload.len()).ok().filter(|&l| l <= MAX_SECTION_LEN).expect("section payload too large");
    let start = crc_from;
    out.extend_from_slice(&tag.0);
    out.extend_from_slice(&len.to_le_bytes());
    out.extend_from_slice(payload);
    let crc = crc32c::crc32c(&out[start..]);
    out.extend_from_slice(&crc.to_le_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reseal_restores_every_crc_including_the_first_sections_wider_one() {
        let preamble = MAGIC.len() + 4;
        let original = write_container(&[(Tag::HEAD, vec![1, 2, 3]), (Tag(*b"POSN"), vec![7; 20])]);
        let mut mutated = original.clone();
        mutated[preamble + 8] = 9; // a HEAD payload byte
        assert!(Container::parse(&mutated).is_err());
        reseal(&mut mutated);
        let container = Container::parse(&mutated).expect("resealed stream parses");
        assert_eq!(container.sections[0].payload, [9, 2, 3]);
        let head_end = preamble + 8 + 3 + 4;
        assert_ne!(mutated[head_end - 4..head_end], original[head_end - 4..head_end], "HEAD's CRC is rewritten");
        assert_eq!(mutated[head_end..], original[head_end..], "the other sections' CRCs still hold");
        // A section running past the end is left alone.
        let mut truncated = original[..original.len() - 2].to_vec();
        let before = truncated.clone();
        reseal(&mut truncated);
        assert_eq!(truncated, before);
    }

    fn sample() -> Vec<u8> {
        write_container(&[(Tag::HEAD, vec![1, 2, 3]), (Tag(*b"POSN"), vec![9; 40]), (Tag(*b"note"), b"hi".to_vec())])
    }

    #[test]
    fn round_trip() {
        let bytes = sample();
        let c = Container::parse(&bytes).unwrap();
        assert_eq!((c.major, c.minor), (MAJOR_VERSION, MINOR_VERSION));
        let tags: Vec<Tag> = c.sections.iter().map(|s| s.tag).collect();
        assert_eq!(tags, [Tag::HEAD, Tag(*b"POSN"), Tag(*b"note")]);
        assert_eq!(c.section(Tag(*b"POSN")).unwrap().payload, &[9; 40][..]);
        assert!(!Tag(*b"note").is_critical() && Tag::HEAD.is_critical());
    }

    #[test]
    fn every_truncation_is_an_error() {
        let bytes = sample();
        for len in 0..bytes.len() {
            assert!(Container::parse(&bytes[..len]).is_err(), "prefix of {len} bytes accepted");
        }
    }

    #[test]
    fn every_single_bit_flip_is_detected() {
        let bytes = sample();
        for i in 0..bytes.len() * 8 {
            let mut b = bytes.clone();
            b[i / 8] ^= 1 << (i % 8);
            assert!(Container::parse(&b).is_err(), "flip of bit {i} accepted");
        }
    }

    #[test]
    fn version_and_structure_errors_are_named() {
        let mut b = sample();
        b[8] = 2;
        assert_eq!(Container::parse(&b), Err(StreamError::UnsupportedVersion { major: 2, minor: MINOR_VERSION }));
        let mut b = sample();
        b.push(0);
        assert_eq!(Container::parse(&b), Err(StreamError::TrailingBytes { extra: 1 }));
        let body = write_container(&[(Tag::HEAD, vec![])]);
        // A stream whose first section is not HEAD: rewrite the tag and fix its CRC.
        let mut b = body.clone();
        b[12..16].copy_from_slice(b"POSN");
        let crc = crc32c::crc32c(&b[..20]);
        b[20..24].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(Container::parse(&b), Err(StreamError::MissingHead { found: Tag(*b"POSN") }));
        // A huge declared length is refused before anything is read or allocated.
        let mut b = body;
        b[16..20].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(matches!(Container::parse(&b), Err(StreamError::SectionTooLarge { .. })));
        let msg = Container::parse(b"PK\x03\x04 not ours").unwrap_err().to_string();
        assert!(msg.contains("not a pwgs stream"), "{msg}");
    }
}
