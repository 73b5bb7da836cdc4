//! The `.splat` and `.spz` readers on arbitrary bytes: the first byte picks the format, the
//! rest is the file. Accepted Gaussians must be consistent and finite (the readers' promise),
//! and writing them back in the same format must read again to as many Gaussians.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pwgs_core::gaussians::Gaussians;
use pwgs_core::splat_file::{
    SpzAxes, SpzVersion, gaussians_from_splat_bytes, gaussians_from_spz_bytes, gaussians_to_splat_bytes,
    gaussians_to_spz_bytes,
};

fn check(g: &Gaussians) {
    assert!(g.is_consistent(), "inconsistent arrays");
    let values = g.means.iter().flatten().chain(g.log_scales.iter().flatten()).chain(g.rotations.iter().flatten());
    assert!(values.chain(&g.opacity_logits).chain(&g.sh).all(|v| v.is_finite()), "a non-finite value");
}

fuzz_target!(|data: &[u8]| {
    let Some((&selector, file)) = data.split_first() else { return };
    if selector % 2 == 0 {
        let Ok(g) = gaussians_from_splat_bytes(file) else { return };
        check(&g);
        let again = gaussians_from_splat_bytes(&gaussians_to_splat_bytes(&g)).expect("a written .splat reads");
        assert_eq!(again.len(), g.len());
    } else {
        let Ok(g) = gaussians_from_spz_bytes(file, SpzAxes::Rub) else { return };
        check(&g);
        let again = gaussians_from_spz_bytes(&gaussians_to_spz_bytes(&g, SpzVersion::V3), SpzAxes::Rub)
            .expect("a written .spz reads");
        assert_eq!(again.len(), g.len());
    }
});
