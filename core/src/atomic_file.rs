//! Writing files so that a failure never leaves a half-written file where a good one was.

use std::path::Path;

/// Writes `bytes` next to `path` and renames it into place.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let tmp = partial_path(path)?;
    let result = std::fs::write(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, path));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Checks, without touching `path`, that [`write_atomically`] could write it: `path` is not a
/// folder, and its folder exists and takes a new file. For programs that would otherwise find
/// out only after a long computation.
pub fn check_writable(path: &Path) -> std::io::Result<()> {
    if path.is_dir() {
        return Err(std::io::Error::other("is a folder"));
    }
    let tmp = partial_path(path)?;
    std::fs::write(&tmp, []).and_then(|()| std::fs::remove_file(&tmp))
}

/// The temporary file [`write_atomically`] writes before renaming it to `path`.
fn partial_path(path: &Path) -> std::io::Result<std::path::PathBuf> {
    let file_name = path.file_name().ok_or_else(|| std::io::Error::other("path has no file name"))?;
    Ok(path.with_file_name(format!(".{}.partial", file_name.to_string_lossy())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writability_is_checked_without_leaving_a_file() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("out.pwb");
        check_writable(&path).unwrap();
        assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 0);
        std::fs::write(&path, b"kept").unwrap();
        check_writable(&path).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"kept");
        assert!(check_writable(&tmp.path().join("missing/out.pwb")).is_err());
        assert!(check_writable(tmp.path()).is_err());
    }
}
