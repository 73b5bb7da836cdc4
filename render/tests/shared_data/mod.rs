//! Test data from `../shared`, the folder beside the checkout (captured scenes, trained splats,
//! metric weights and calibration images, reference renders). Every crate's tests that use it
//! include this one file by path, since the crates share no test-support crate.
//!
//! Data that is absent skips the test, saying so, on a developer's machine, and fails it in CI
//! (`CI` set, as CI services set it): CI runs with `../shared`, so absent data there means the
//! test would pass without checking anything. Data that is present but fails to load is the
//! test's failure everywhere, never a skip: the tests unwrap their loads.
#![allow(dead_code)] // each test binary uses a part

use std::fmt::Display;
use std::path::{Path, PathBuf};

/// `../shared`: beside the workspace root, the nearest folder above this crate holding a
/// `Cargo.lock`.
pub fn shared_dir() -> PathBuf {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    let root = manifest.ancestors().find(|dir| dir.join("Cargo.lock").is_file()).unwrap_or(manifest);
    root.parent().unwrap_or(root).join("shared")
}

/// Whether this is a CI run: `CI` set to anything but empty, `0` or `false`.
pub fn in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| !matches!(v.as_str(), "" | "0" | "false"))
}

/// `../shared/<relative>` when it exists; when not, reports it with [`absent`] and gives `None`.
pub fn path(relative: &str) -> Option<PathBuf> {
    let path = shared_dir().join(relative);
    if path.exists() {
        Some(path)
    } else {
        absent(format_args!("{} not found", path.display()));
        None
    }
}

/// Reports absent test data: outside CI, prints that the test is skipped (the caller then
/// returns); in CI, fails the test.
pub fn absent(what: impl Display) {
    if in_ci() {
        panic!("{what}; CI must run with the shared data beside the checkout (CI is set)");
    }
    eprintln!("skipped: {what} (the shared data is not beside the checkout)");
}
