//! Runs the conformance suite against this workspace's decoder library. `.ci/run` runs it in
//! the release profile too, so that debug and release decoding are both held to the same
//! pinned hashes.

#[test]
fn the_decoder_conforms_to_every_vector() {
    let vectors = pwgs_conformance::vectors().unwrap();
    assert!(!vectors.is_empty(), "no conformance vectors found");
    for dir in vectors {
        let checks = pwgs_conformance::check_vector(&dir).unwrap_or_else(|e| panic!("{}: {e:#}", dir.display()));
        for c in checks {
            eprintln!(
                "{}: {} max diff {}, {:.3}% within 1",
                dir.display(),
                c.image,
                c.max_difference,
                c.within_one * 100.0
            );
        }
    }
}

#[test]
fn a_corrupted_vector_fails() {
    let dir = &pwgs_conformance::vectors().unwrap()[0];
    let tmp = std::env::temp_dir().join(format!("pwgs-conformance-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, tmp.join(path.file_name().unwrap())).unwrap();
    }
    // A different expected hash must be caught.
    let expected = std::fs::read_to_string(tmp.join("expected.json")).unwrap();
    let changed = expected.replacen("\"attribute_sha256\": \"", "\"attribute_sha256\": \"0", 1);
    std::fs::write(tmp.join("expected.json"), changed).unwrap();
    let err = pwgs_conformance::check_vector(&tmp).unwrap_err().to_string();
    std::fs::remove_dir_all(&tmp).unwrap();
    assert!(err.contains("hash"), "{err}");
}

#[test]
fn noise_pyramids_match_the_pinned_hashes() {
    let n = pwgs_conformance::check_noise_pyramids().unwrap_or_else(|e| panic!("{e:#}"));
    assert!(n >= 4, "only {n} pinned pyramids");
}
