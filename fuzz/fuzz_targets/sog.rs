//! The SOG reader (`splat_file::gaussians_from_sog_bytes`) on arbitrary bytes as a `.sog`
//! archive (a zip of `meta.json` and lossless WebP images). The input is resealed first: the
//! CRC-32 of every stored entry a central-directory record describes is recomputed over its
//! bytes, in that record and in the entry's local header, so that mutations of `meta.json` and
//! of the images reach the SOG parser instead of failing the zip's checksum.
//!
//! Accepted Gaussians must be consistent and finite (the reader drops those a null codebook
//! entry or an overflowing position makes non-finite). The campaign's `-rss_limit_mb` and
//! `-malloc_limit_mb` catch any decompression or decoding the reader fails to bound.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pwgs_core::splat_file::gaussians_from_sog_bytes;

fuzz_target!(|data: &[u8]| {
    let mut bytes = data.to_vec();
    reseal_zip(&mut bytes);
    let Ok(g) = gaussians_from_sog_bytes(&bytes) else { return };
    assert!(g.is_consistent(), "inconsistent arrays");
    let values = g.means.iter().flatten().chain(g.log_scales.iter().flatten()).chain(g.rotations.iter().flatten());
    assert!(values.chain(&g.opacity_logits).chain(&g.sh).all(|v| v.is_finite()), "a non-finite value");
});

const CENTRAL_SIGNATURE: [u8; 4] = [0x50, 0x4b, 0x01, 0x02];
const LOCAL_SIGNATURE: [u8; 4] = [0x50, 0x4b, 0x03, 0x04];

/// Rewrites the CRC-32 of each stored (method 0) entry whose central-directory record and local
/// header both lie within the input; anything else is left for the reader to refuse.
fn reseal_zip(bytes: &mut [u8]) {
    let u16_at = |b: &[u8], at: usize| b.get(at..at + 2).map(|s| usize::from(u16::from_le_bytes([s[0], s[1]])));
    let u32_at = |b: &[u8], at: usize| b.get(at..at + 4).map(|s| u32::from_le_bytes([s[0], s[1], s[2], s[3]]) as usize);
    let mut from = 0;
    while let Some(found) = bytes[from..].windows(4).position(|w| w == CENTRAL_SIGNATURE) {
        let record = from + found;
        from = record + 4;
        let (Some(0), Some(size), Some(local)) =
            (u16_at(bytes, record + 10), u32_at(bytes, record + 20), u32_at(bytes, record + 42))
        else {
            continue;
        };
        if bytes.get(local..local + 4) != Some(LOCAL_SIGNATURE.as_slice()) {
            continue;
        }
        let (Some(name), Some(extra)) = (u16_at(bytes, local + 26), u16_at(bytes, local + 28)) else { continue };
        let start = local + 30 + name + extra;
        let Some(entry) = bytes.get(start..start.saturating_add(size)) else { continue };
        let crc = crc32(entry).to_le_bytes();
        bytes[record + 16..record + 20].copy_from_slice(&crc);
        bytes[local + 14..local + 18].copy_from_slice(&crc);
    }
}

/// CRC-32 (the IEEE polynomial zip uses), bit by bit: fuzz inputs are small.
fn crc32(data: &[u8]) -> u32 {
    let step = |crc: u32, _| if crc & 1 == 1 { crc >> 1 ^ 0xedb8_8320 } else { crc >> 1 };
    !data.iter().fold(!0u32, |crc, &byte| (0..8).fold(crc ^ u32::from(byte), step))
}
