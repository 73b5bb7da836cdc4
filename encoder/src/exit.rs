//! How the command-line programs end: an error is printed as one line with its whole chain of
//! causes (`{:#}`), without a backtrace, and the exit status says failure.

use std::process::ExitCode;

/// The exit status for a program's result, printing the error if there is one.
pub fn report(result: anyhow::Result<()>) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error:#}");
            ExitCode::FAILURE
        }
    }
}
