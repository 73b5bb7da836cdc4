//! The pwgs stream container (SPEC.md sections 2 and 3): the magic, the version and its
//! compatibility policy, length-prefixed sections each protected by a CRC-32C, and the
//! little-endian field syntax used inside sections.
//!
//! This crate knows nothing about Gaussians: it turns bytes into verified sections and back.
#![cfg_attr(not(test), deny(clippy::disallowed_methods))]
//! What a section means is the decoder's business (`pwgs-codec`'s `stream` module).

mod container;
mod fields;

pub use container::{Container, SECTION_OVERHEAD, Section, StreamError, Tag, reseal, write_container};
pub use fields::{FieldError, FieldReader, FieldWriter};

/// The first eight bytes of every stream. The high first byte catches 7-bit transports, the
/// CR LF / SUB / LF tail catches newline translation, as in PNG.
pub const MAGIC: [u8; 8] = [0x89, b'P', b'W', b'B', 0x0D, 0x0A, 0x1A, 0x0A];

/// The major version this crate reads and writes. A stream with another major is refused.
pub const MAJOR_VERSION: u16 = 1;

/// The minor version this crate writes. Streams with a higher minor (same major) are read:
/// a minor only appends fields to sections and adds optional sections (SPEC.md section 2.2).
pub const MINOR_VERSION: u16 = 0;

/// Largest payload a section may declare (256 MiB): a bound on what a decoder allocates before
/// it has verified anything.
pub const MAX_SECTION_LEN: u32 = 1 << 28;

/// Most sections a stream may hold.
pub const MAX_SECTIONS: usize = 64;
