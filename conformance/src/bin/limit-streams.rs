//! Writes the streams of 1,000,000 bytes at SPEC.md section 9's per-byte limits (the most
//! Gaussians, values and octree nodes a 1 MB stream may hold), the cameras to view them from
//! and their index, into the folder named on the command line: for measuring a decoder's time
//! and memory on the heaviest 1 MB inputs (`pwdec FILE --hash`, `pwdec FILE --view
//! view-1920x1080.json -o out.png`).

use std::path::PathBuf;

use anyhow::{Context, Result};
use pwgs_conformance::generator::hostile::{at_one_megabyte, render_memory::views};

fn main() -> Result<()> {
    let dir = PathBuf::from(std::env::args().nth(1).context("usage: limit-streams DIR")?);
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let files = at_one_megabyte().into_iter().map(|h| (h.file, h.bytes)).chain(views());
    for (name, bytes) in files {
        let path = dir.join(&name);
        std::fs::write(&path, bytes).with_context(|| format!("cannot write {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
