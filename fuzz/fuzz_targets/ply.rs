//! The PLY reader: `gaussians_from_bytes` (INRIA layout) and `point_cloud_from_bytes` on
//! arbitrary bytes. Gaussians it accepts hold only finite values, and writing them with
//! `gaussians_to_bytes` must read back to the same Gaussians with nothing dropped.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pwgs_core::ply::{gaussians_from_bytes, gaussians_to_bytes, point_cloud_from_bytes};

fuzz_target!(|data: &[u8]| {
    let _ = point_cloud_from_bytes(data);
    let Ok(read) = gaussians_from_bytes(data) else { return };
    let again = gaussians_from_bytes(&gaussians_to_bytes(&read.gaussians)).expect("written Gaussians read back");
    assert_eq!((again.dropped_non_finite, again.clamped_opacities), (0, 0));
    assert_eq!(again.gaussians, read.gaussians, "Gaussians do not survive a write and a read");
});
