//! The encoder's restart with glibc's allocator tunables. Its own test binary with one test:
//! the restart replaces the whole process (the test harness included), which then runs this
//! test again, now with the tunables set.

#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[test]
fn the_process_restarts_once_with_the_heap_tunables() {
    pwgs_encoder::train::heap::restart_with_tunables();
    // Only the restarted process gets here; a second call must not restart it again.
    pwgs_encoder::train::heap::restart_with_tunables();
    let tunables = std::env::var("GLIBC_TUNABLES").expect("the restarted process has GLIBC_TUNABLES");
    assert!(tunables.starts_with("glibc.malloc.mmap_threshold=33554432:"), "{tunables}");
    assert!(tunables.contains("glibc.malloc.trim_threshold=1073741824"), "{tunables}");
}
