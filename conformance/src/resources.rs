//! Running a tool on a hostile input within the resource bounds every input must keep to: at
//! most 1 GiB of address space (`ulimit -v`, the allocation cap; the process
//! aborts or fails to allocate beyond it) and a bounded CPU time, read from the kernel's
//! accounting of the waited-for child rather than from a wall clock, so that a busy machine
//! does not make the bound flaky. The hostile files' index (`hostile/expected.json`) says
//! what each run must give.

use std::ffi::OsStr;
use std::path::Path;
use std::process::{Command, Output};

use crate::generator::hostile::Outcome;

/// The address-space limit, in KiB as `ulimit -v` takes it: 1 GiB.
pub const MEMORY_LIMIT_KIB: u64 = 1 << 20;

/// CPU seconds a run may take: 1 s for decoding or importing, and 2 s per megapixel rendered
/// (the bounds).
pub fn cpu_bound(rendered_pixels: u64) -> f64 {
    1.0 + 2.0 * rendered_pixels as f64 / 1e6
}

/// A finished run and the CPU time (user + system) it took.
pub struct Limited {
    pub output: Output,
    pub cpu_seconds: f64,
}

/// Runs `program` with `args` under [`MEMORY_LIMIT_KIB`]. glibc's malloc reserves 64 MiB of
/// address space per thread arena, so the number of arenas is capped (at 2) to keep the limit
/// about what the program allocates rather than how many cores the machine has.
///
/// The CPU time is the change in this process's children's time (`/proc/self/stat`), so the
/// caller must not run other children at the same time (one test per test binary).
pub fn run_limited(program: &Path, args: &[&OsStr]) -> Limited {
    let before = children_cpu_seconds();
    let output = Command::new("bash")
        .arg("-c")
        .arg(format!("ulimit -v {MEMORY_LIMIT_KIB} && exec \"$@\""))
        .arg("limited")
        .arg(program)
        .args(args)
        .env("MALLOC_ARENA_MAX", "2")
        .output()
        .expect("bash runs");
    Limited { output, cpu_seconds: children_cpu_seconds() - before }
}

/// User and system time of the waited-for children, fields 16 and 17 of `/proc/self/stat`, in
/// clock ticks of 1/100 s (USER_HZ on Linux).
fn children_cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").expect("/proc/self/stat is readable");
    // The command name (field 2) is in parentheses and may hold spaces: count after it.
    let after_name = &stat[stat.rfind(')').expect("a parenthesized name") + 2..];
    let fields: Vec<&str> = after_name.split_whitespace().collect();
    let ticks = |field: usize| fields[field - 3].parse::<u64>().expect("a tick count");
    (ticks(16) + ticks(17)) as f64 / 100.0
}

/// Whether a run gave `outcome`, within `cpu_limit` seconds; a panic, an abort or a signal
/// is never the expected refusal.
pub fn check_run(file: &str, run: &Limited, outcome: &Outcome, cpu_limit: f64) -> Result<(), String> {
    let stderr = String::from_utf8_lossy(&run.output.stderr);
    let status = run.output.status;
    if run.cpu_seconds > cpu_limit {
        return Err(format!("{file}: took {:.2} s of CPU, more than {cpu_limit:.2} s", run.cpu_seconds));
    }
    if status.code().is_none() || status.code() == Some(101) || stderr.contains("panicked") {
        return Err(format!("{file}: crashed ({status}): {stderr}"));
    }
    match outcome {
        Outcome::Accepted if !status.success() => Err(format!("{file}: refused: {stderr}")),
        Outcome::Refused(_) if status.success() => Err(format!("{file}: accepted, should be refused")),
        Outcome::Refused(text) if !stderr.contains(text.as_str()) => {
            Err(format!("{file}: the error does not contain `{text}`: {stderr}"))
        }
        _ => Ok(()),
    }
}
