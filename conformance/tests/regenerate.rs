//! The committed synthetic vectors and invalid files are exactly what the generator makes
//! today: a change in the stream writer, the decoder or the generator shows up here as a
//! difference, never silently. Renders are the exception: rendering is not bit-normative
//! (SPEC.md section 8), so the committed PNGs are held to the render tolerance instead (by the
//! runner, `tests/vectors.rs`).

use std::path::Path;

#[test]
fn committed_files_match_a_fresh_generation() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let files = pwgs_conformance::generator::generate().unwrap_or_else(|e| panic!("{e:#}"));
    let mut differences = Vec::new();
    for (path, bytes) in &files {
        let is_png = path.extension().is_some_and(|e| e == "png");
        match std::fs::read(root.join(path)) {
            Ok(committed) if is_png || &committed == bytes => {}
            Ok(_) => differences.push(format!("{} differs", path.display())),
            Err(e) => differences.push(format!("{}: {e}", path.display())),
        }
    }
    for path in pwgs_conformance::generator::stale_files(root, &files).unwrap() {
        differences.push(format!("{} is not generated", path.display()));
    }
    assert!(
        differences.is_empty(),
        "regenerate with `cargo run -p pwgs-conformance --bin regenerate` if the change is intended:\n{}",
        differences.join("\n")
    );
}
