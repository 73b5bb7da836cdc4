//! Runs the conformance suite against this workspace's decoder library. `.ci/run` runs it in
//! the release profile too, so that debug and release decoding are both held to the same
//! pinned hashes.

#[test]
fn the_decoder_conforms_to_every_vector() {
    let vectors = pwgs_conformance::vectors().unwrap();
    assert!(vectors.len() >= 20, "only {} conformance vectors found", vectors.len());
    let mut failures = Vec::new();
    for dir in vectors {
        match pwgs_conformance::check_vector(&dir) {
            Ok(checks) => {
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
            Err(e) => failures.push(format!("{}: {e:#}", dir.display())),
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn the_decoder_refuses_every_invalid_file_with_its_error() {
    let (failures, checked) = pwgs_conformance::check_invalid_dir(&pwgs_conformance::invalid_dir()).unwrap();
    assert!(failures.is_empty(), "{} of {checked} invalid files:\n{}", failures.len(), failures.join("\n"));
    assert!(checked >= 80, "only {checked} invalid files");
}

/// Copies a folder's files into a fresh temporary folder.
fn copy_dir(dir: &std::path::Path, name: &str) -> std::path::PathBuf {
    let tmp = std::env::temp_dir().join(format!("pwgs-conformance-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, tmp.join(path.file_name().unwrap())).unwrap();
    }
    tmp
}

#[test]
fn a_corrupted_vector_fails() {
    let dir = pwgs_conformance::vectors_dir().join("wrap-both-w1");
    let tmp = copy_dir(&dir, "vector");
    // A different expected hash must be caught, for the attributes and for the wrapper.
    let expected = std::fs::read_to_string(tmp.join("expected.json")).unwrap();
    let mut errors = Vec::new();
    for field in ["attribute_sha256", "wrapper_sha256", "noise_sha256"] {
        let changed = expected.replacen(&format!("\"{field}\": \""), &format!("\"{field}\": \"0"), 1);
        assert_ne!(changed, expected, "{field} is not pinned");
        std::fs::write(tmp.join("expected.json"), changed).unwrap();
        errors.push(pwgs_conformance::check_vector(&tmp).unwrap_err().to_string());
    }
    std::fs::remove_dir_all(&tmp).unwrap();
    for e in errors {
        assert!(e.contains("hash"), "{e}");
    }
}

#[test]
fn an_accepted_or_differently_refused_invalid_file_fails() {
    let tmp = copy_dir(&pwgs_conformance::invalid_dir(), "invalid");
    let listing = std::fs::read_to_string(tmp.join("expected.json")).unwrap();
    // A valid stream in place of an invalid one, and an error the decoder does not give.
    std::fs::copy(pwgs_conformance::vectors_dir().join("sh1/stream.pwb"), tmp.join("magic.pwb")).unwrap();
    std::fs::write(tmp.join("expected.json"), listing.replace("not a pwgs stream", "a different message")).unwrap();
    std::fs::copy(tmp.join("major-2.pwb"), tmp.join("unlisted.pwb")).unwrap();
    let (failures, _) = pwgs_conformance::check_invalid_dir(&tmp).unwrap();
    std::fs::remove_dir_all(&tmp).unwrap();
    assert!(failures.iter().any(|f| f.contains("magic.pwb was accepted")), "{failures:?}");
    assert!(failures.iter().any(|f| f.contains("unlisted.pwb: not listed")), "{failures:?}");
}

#[test]
fn noise_pyramids_match_the_pinned_hashes() {
    let n = pwgs_conformance::check_noise_pyramids().unwrap_or_else(|e| panic!("{e:#}"));
    assert!(n >= 4, "only {n} pinned pyramids");
}

/// The clause IDs the README's clause table lists (the first cell of its rows).
fn readme_clauses() -> std::collections::BTreeSet<String> {
    let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).unwrap();
    let table = readme.split("## Clauses").nth(1).unwrap().split("## ").next().unwrap();
    table
        .lines()
        .filter_map(|l| l.strip_prefix("| ")?.split(" |").next())
        .filter(|id| *id != "clause" && !id.starts_with("---"))
        .map(str::to_string)
        .collect()
}

#[test]
fn every_clause_the_suite_names_is_in_the_readme_table() {
    let mut named = std::collections::BTreeSet::new();
    for refusal in pwgs_conformance::invalid::expected_refusals(&pwgs_conformance::invalid_dir()).unwrap().values() {
        named.insert(refusal.clause.clone());
    }
    for dir in pwgs_conformance::vectors().unwrap() {
        let text = std::fs::read_to_string(dir.join("expected.json")).unwrap();
        let expected: pwgs_conformance::expected::ExpectedVector = serde_json::from_str(&text).unwrap();
        named.extend(expected.clauses);
    }
    let listed = readme_clauses();
    let missing: Vec<_> = named.difference(&listed).collect();
    assert!(missing.is_empty(), "clauses missing from README.md's table: {missing:?}");
}
