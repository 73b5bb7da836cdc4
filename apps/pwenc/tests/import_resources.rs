//! Bounded work and memory for every input: `pwenc --from` on every hostile
//! splat file of the conformance suite (`conformance/hostile/`: degenerate geometry,
//! decompression bombs), each under a 1 GiB address-space limit. With `--effort 0` (the coder
//! alone) within 1 s of CPU time (2 s in all for those it accepts and encodes), refused with
//! its error or encoded as the suite says; at the default effort, which renders the importance
//! views, within 2 s per megapixel of them more, refused or encoded: never a panic, an abort or
//! a hang.
//!
//! One test in this binary: the CPU time of each run is read from this process's children.

use std::ffi::OsStr;
use std::path::Path;

use pwgs_conformance::generator::hostile::{self, Outcome, Tool};
use pwgs_conformance::resources::{check_run, cpu_bound, run_limited};
use pwgs_encoder::plain::importance::MAX_RENDERED_PIXELS;

#[test]
fn every_hostile_splat_file_keeps_to_the_bounds() {
    let pwenc = Path::new(env!("CARGO_BIN_EXE_pwenc"));
    let conformance = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../conformance");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out.pwb");
    let mut failures = Vec::new();
    let mut checked = 0;
    for (name, entry) in hostile::expected(&conformance).unwrap() {
        if entry.tool != Tool::PwencFrom {
            continue;
        }
        let file = conformance.join(hostile::HOSTILE_DIR).join(&name);
        let args = [OsStr::new("--from"), file.as_os_str(), OsStr::new("-o"), out.as_os_str()];
        let run = run_limited(pwenc, &[&args[..], &[OsStr::new("--effort"), OsStr::new("0")]].concat());
        // Importing is bounded by 1 s; encoding what was accepted by as much again.
        let limit = match entry.outcome {
            Outcome::Accepted => 2.0 * cpu_bound(0),
            Outcome::Refused(_) => cpu_bound(0),
        };
        eprintln!("{name}: {:.2} s of CPU", run.cpu_seconds);
        if let Err(e) = check_run(&name, &run, &entry.outcome, limit) {
            failures.push(e);
        }
        // The default effort: either outcome (an empty text is in any error), within the bound
        // with the importance views' pixels.
        let run = run_limited(pwenc, &args);
        let either = if run.output.status.success() { Outcome::Accepted } else { Outcome::Refused(String::new()) };
        eprintln!("{name}: {:.2} s of CPU at the default effort", run.cpu_seconds);
        if let Err(e) = check_run(&name, &run, &either, 2.0 * cpu_bound(MAX_RENDERED_PIXELS)) {
            failures.push(format!("at the default effort: {e}"));
        }
        checked += 1;
    }
    assert!(checked >= 5, "only {checked} hostile splat files");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
