//! Checking the decoder library against the invalid files of `invalid/`: each stream (`.pwb`)
//! must be refused by `stream::decode`, each camera file (`.json`) by `parse_camera`, with an
//! error whose message contains the substring `invalid/expected.json` lists for it.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use pwgs_codec::stream;
use pwgs_core::camera_json::parse_camera;

use crate::expected::{ExpectedRefusal, ExpectedRefusals};

/// Name of the file listing the refusals, inside the invalid folder.
pub const EXPECTED_FILE: &str = "expected.json";

/// The folder holding the invalid files.
pub fn invalid_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("invalid")
}

/// The refusals `invalid/expected.json` lists, by file name.
pub fn expected_refusals(dir: &Path) -> Result<ExpectedRefusals> {
    let path = dir.join(EXPECTED_FILE);
    let text = std::fs::read_to_string(&path).with_context(|| format!("cannot read {}", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{}", path.display()))
}

/// The error the decoder library gives for one invalid file, or an error saying it accepted it.
pub fn refusal_of(name: &str, bytes: &[u8]) -> Result<String> {
    let outcome = if name.ends_with(".pwb") {
        stream::decode(bytes).map(|_| ()).map_err(|e| e.to_string())
    } else if name.ends_with(".json") {
        let text = std::str::from_utf8(bytes).context("a camera file must be UTF-8")?;
        parse_camera(text).map(|_| ()).map_err(|e| e.to_string())
    } else {
        bail!("{name}: neither a stream (.pwb) nor a camera file (.json)");
    };
    match outcome {
        Ok(()) => bail!("{name} was accepted"),
        Err(message) => Ok(message),
    }
}

/// Separates the parts of an expected error that must appear in order.
pub const PART_SEPARATOR: &str = " … ";

/// Whether `message` contains the parts of `pattern` in order.
pub fn matches(message: &str, pattern: &str) -> bool {
    let mut rest = message;
    for part in pattern.split(PART_SEPARATOR) {
        match rest.find(part) {
            Some(at) => rest = &rest[at + part.len()..],
            None => return false,
        }
    }
    true
}

/// Checks that `bytes` are refused with the expected error.
pub fn check_refusal(name: &str, bytes: &[u8], expected: &ExpectedRefusal) -> Result<()> {
    let message = refusal_of(name, bytes)?;
    if !matches(&message, &expected.error) {
        bail!(
            "{name} ({}): refused with \"{message}\", expected a message containing \"{}\"",
            expected.clause,
            expected.error
        );
    }
    Ok(())
}

/// Checks every file of `dir` against its listed refusal, and that the listing and the folder
/// hold the same files. Returns one line per failure (empty when all pass) and the number of
/// files checked.
pub fn check_invalid_dir(dir: &Path) -> Result<(Vec<String>, usize)> {
    let expected = expected_refusals(dir)?;
    let mut failures = Vec::new();
    let mut on_disk = Vec::new();
    for entry in std::fs::read_dir(dir)? {
        let name = entry?.file_name().to_string_lossy().into_owned();
        // Dotfiles (the folder's .gitignore) are not part of the suite.
        if name != EXPECTED_FILE && !name.starts_with('.') {
            on_disk.push(name);
        }
    }
    for name in &on_disk {
        if !expected.contains_key(name) {
            failures.push(format!("{name}: not listed in {EXPECTED_FILE}"));
        }
    }
    for (name, refusal) in &expected {
        let outcome = std::fs::read(dir.join(name))
            .with_context(|| format!("{name}: listed but cannot be read"))
            .and_then(|bytes| check_refusal(name, &bytes, refusal));
        if let Err(e) = outcome {
            failures.push(format!("{e:#}"));
        }
    }
    Ok((failures, expected.len()))
}
