//! Keeps freed memory in the process for training, where glibc would hand it back at once.
//!
//! Training frees and allocates tensors of a few megabytes at every step. With glibc's
//! defaults, blocks that size are mapped from the kernel when allocated and unmapped when
//! freed, so each step faults the same pages in again and the kernel zeroes them: 13% of an
//! anchor training step on fern went to page faults (perf), and on the generated scene 150
//! steps took 15.6 s of CPU with 429,137 page faults against 13.8 s and 15,001 with the two
//! tunables below. Glibc reads tunables only when a process starts, so the encoder starts
//! itself again, once, with them set: the same arguments, standard streams and process id.

/// Allocations below 32 MiB (glibc's largest threshold) come from the heap, and up to 1 GiB
/// of freed heap stays with the process.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const TUNABLES: &str = "glibc.malloc.mmap_threshold=33554432:glibc.malloc.trim_threshold=1073741824";

/// Set in the restarted process, so that it does not restart again.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const MARKER: &str = "PWGS_HEAP_TUNED";

/// Restarts the current process with the allocator tunables set (Linux with glibc only), unless
/// it already runs with them. Returns only when it does not restart (other platforms, or the
/// restart failed): the run then goes on with the defaults.
pub fn restart_with_tunables() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    restart();
}

#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn restart() {
    use std::ffi::OsString;
    use std::os::unix::process::CommandExt;
    if std::env::var_os(MARKER).is_some() {
        return;
    }
    let Ok(exe) = std::env::current_exe() else { return };
    let mut tunables = OsString::from(TUNABLES);
    if let Some(user) = std::env::var_os("GLIBC_TUNABLES").filter(|v| !v.is_empty()) {
        // The user's own settings come last, so they win over ours.
        tunables.push(":");
        tunables.push(user);
    }
    // `exec` returns only on failure; the run then goes on with the defaults.
    let _failed = std::process::Command::new(exe)
        .args(std::env::args_os().skip(1))
        .env("GLIBC_TUNABLES", tunables)
        .env(MARKER, "1")
        .exec();
}
