//! Writes the generated vectors and invalid files into this crate's folders (README.md: how to
//! regenerate), and removes the files of those folders that the generator no longer makes. The
//! hand-made vectors are left alone.

use std::path::Path;

use anyhow::{Context, Result};

fn main() -> Result<()> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let files = pwgs_conformance::generator::generate()?;
    for path in pwgs_conformance::generator::stale_files(root, &files)? {
        std::fs::remove_file(root.join(&path)).with_context(|| format!("cannot remove {}", path.display()))?;
    }
    for (path, bytes) in &files {
        let path = root.join(path);
        std::fs::create_dir_all(path.parent().expect("files lie in folders"))?;
        std::fs::write(&path, bytes).with_context(|| format!("cannot write {}", path.display()))?;
    }
    println!("wrote {} files", files.len());
    Ok(())
}
