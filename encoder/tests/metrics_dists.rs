//! DISTS against the official values of `shared/metrics-calib/README.md`: the five IQA-PyTorch
//! calibration pairs and the DISTS authors' r0/r1 example. Needs the weights and the
//! calibration images (see `shared_weights` and `shared_data` for when their absence skips).

#[path = "../../render/tests/shared_data/mod.rs"]
mod shared_data;
mod shared_weights;

use std::path::PathBuf;

use burn::tensor::Device;
use pwgs_core::rgb_image::RgbImage;
use pwgs_encoder::metrics::dists::Dists;
use pwgs_encoder::metrics::image_tensor::image_tensor;

fn image(path: PathBuf) -> RgbImage {
    RgbImage::load(&path, [0.0; 3]).unwrap()
}

#[test]
fn dists_reproduces_the_official_values() {
    let device = Device::flex();
    let Some(calib) = shared_data::path("metrics-calib") else { return };
    let Some(dists) = shared_weights::loaded(Dists::load(&shared_weights::search_dirs(), &device)) else { return };
    let mut pairs: Vec<(String, PathBuf, PathBuf, f64)> =
        [("I03", 0.4742), ("I04", 0.1424), ("I06", 0.06825), ("I08", 0.02867), ("I19", 0.3123)]
            .iter()
            .map(|&(id, v)| {
                (id.to_string(), calib.join(format!("dist/{id}.bmp")), calib.join(format!("ref/{id}.bmp")), v)
            })
            .collect();
    pairs.push(("r0/r1".to_string(), calib.join("r0.png"), calib.join("r1.png"), 0.3347));
    let mut failures = Vec::new();
    for (id, a, b, official) in pairs {
        let start = std::time::Instant::now();
        let value = dists
            .distance(image_tensor(&image(a), &device), image_tensor(&image(b), &device))
            .into_scalar::<f32>() as f64;
        println!(
            "DISTS {id}: {value:.5} (official {official}, difference {:+.1e}, {:.1} s)",
            value - official,
            start.elapsed().as_secs_f64()
        );
        // The official values are printed to 4 significant digits.
        if (value - official).abs() > 5e-4 {
            failures.push(format!("{id}: {value} vs {official}"));
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}
