//! `stream::octree::decode` on arbitrary coded data. Points that decode must encode back to
//! data that decodes to the same points (they come out in Morton order, the encoder's order).
//!
//! Input: the depth (u8, taken mod 26 so that 0 and 25 test the bounds), the point count (u16
//! little-endian, at most 4096), then the coded data: a `POSN` payload minus its first 16 bytes,
//! behind the first three, is a valid input.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pwgs_codec::stream::octree::{self, MAX_DEPTH};

const MAX_POINTS: usize = 4096;

fuzz_target!(|data: &[u8]| {
    let [depth, count_lo, count_hi, coded @ ..] = data else { return };
    let depth = depth % (MAX_DEPTH + 2);
    let count = usize::from(u16::from_le_bytes([*count_lo, *count_hi])).min(MAX_POINTS);
    let Ok(points) = octree::decode(coded, depth, count) else { return };
    let (recoded, _) = octree::encode(&points, depth).expect("decoded points are encodable");
    assert_eq!(octree::decode(&recoded, depth, count), Ok(points), "decoded points do not survive re-encoding");
});
