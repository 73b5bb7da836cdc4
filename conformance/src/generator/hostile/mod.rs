//! Hostile inputs (`hostile/`): small files, valid or nearly so, that once made a pwgs tool
//! crash, hang or exhaust memory, one or more per class of problem (rendering memory, the
//! anchor base's work, degenerate geometry in importers, decompression bombs). Each is made here
//! from integers, never copied, and `hostile/expected.json` says which tool reads it and what
//! must happen: the resource tests (`apps/pwdec/tests/resources.rs`,
//! `apps/pwenc/tests/import_resources.rs`) run that tool on it under a 1 GiB address-space limit
//! and hold it to the outcome and to a CPU-time bound.

mod imports_bombs;
mod imports_geometry;
pub mod render_memory;

pub use render_memory::at_one_megabyte;

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::Files;

/// The folder (relative to the conformance crate) and its index file.
pub const HOSTILE_DIR: &str = "hostile";
pub const EXPECTED_FILE: &str = "expected.json";

/// What reading a hostile file must give.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Refused with an error whose message contains this text.
    Refused(String),
    /// Accepted: decoded (and rendered, for a stream with a view) or imported and encoded.
    Accepted,
}

/// Which tool reads the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Tool {
    /// `pwdec FILE --view VIEW -o out.png` with the entry's view, or `pwdec FILE --hash`
    /// without one.
    Pwdec,
    /// `pwenc --from FILE -o out.pwb --effort 0`: the coder alone, so that the outcome is the
    /// file's (at the default effort the importance views may prune what the coder would refuse,
    /// and only the bounds are checked).
    PwencFrom,
}

/// One hostile file and what must happen to it (`hostile/expected.json` maps file names to it).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HostileEntry {
    /// The class of problem: 1 rendering memory, 2 anchor work, 3 degenerate geometry, 4
    /// decompression bombs.
    pub class: u8,
    pub tool: Tool,
    /// A camera file in the same folder to render, for `pwdec`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub view: Option<String>,
    pub outcome: Outcome,
    pub description: String,
}

/// A generated hostile file with its entry.
pub struct Hostile {
    pub file: String,
    pub entry: HostileEntry,
    pub bytes: Vec<u8>,
}

/// Every hostile file with its entry, in the order of the classes.
pub fn hostile() -> Vec<Hostile> {
    let mut all = render_memory::files();
    all.extend(imports_geometry::files());
    all.extend(imports_bombs::files());
    all
}

/// The folder's files: the hostile files, the cameras they are rendered from and the index.
pub fn files() -> anyhow::Result<Files> {
    let mut files = Files::new();
    let mut expected = BTreeMap::new();
    for h in hostile() {
        anyhow::ensure!(expected.insert(h.file.clone(), h.entry).is_none(), "hostile file {} made twice", h.file);
        files.insert(Path::new(HOSTILE_DIR).join(&h.file), h.bytes);
    }
    for (name, bytes) in render_memory::views() {
        files.insert(Path::new(HOSTILE_DIR).join(name), bytes);
    }
    files.insert(Path::new(HOSTILE_DIR).join(EXPECTED_FILE), super::json(&expected)?);
    Ok(files)
}

/// `hostile/expected.json` of the conformance folder `root`.
pub fn expected(root: &Path) -> anyhow::Result<BTreeMap<String, HostileEntry>> {
    let path = root.join(HOSTILE_DIR).join(EXPECTED_FILE);
    let text = std::fs::read_to_string(&path).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    Ok(serde_json::from_str(&text)?)
}
