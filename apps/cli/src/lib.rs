//! What pwgs's command-line programs share: how they end (one line per error, an exit status
//! that says failure) and parsers of values several of them take. Only the programs under
//! `apps/` depend on it; the libraries below them know nothing of command lines.

pub mod values;

use std::process::ExitCode;

/// The exit status for a program's result, printing the error if there is one: one line with
/// its whole chain of causes (`{:#}`), without a backtrace.
pub fn report(result: anyhow::Result<()>) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error:#}");
            ExitCode::FAILURE
        }
    }
}
