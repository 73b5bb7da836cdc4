//! Helpers shared by the fuzz targets: resealing a mutated stream so that its CRCs hold (from
//! pwgs-bitstream, which the workspace's regression tests use too), and a per-process scratch
//! folder for the loaders that only read files.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Rewrites every CRC of a stream-shaped input, so mutations reach the payload parsers.
pub use pwgs_bitstream::reseal;

/// A folder of this process for the files a harness hands to a path-taking loader: under
/// /dev/shm (memory, no disk wear) when it exists, created on first use. Each harness
/// overwrites the same few file names on every input; `campaign.sh` removes the folders after
/// each run.
pub fn scratch_dir(target: &str) -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let shm = Path::new("/dev/shm");
        let base = if shm.is_dir() { shm.to_path_buf() } else { std::env::temp_dir() };
        let dir = base.join(format!("pwgs-fuzz-{target}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("cannot create {}: {e}", dir.display()));
        dir
    })
}

/// Writes a harness's file, panicking on failure: a scratch folder that cannot be written to is
/// a broken fuzzing setup, not a finding.
pub fn write_scratch(path: &Path, bytes: &[u8]) {
    std::fs::write(path, bytes).unwrap_or_else(|e| panic!("cannot write {}: {e}", path.display()));
}
