//! The pwgs decoder library: everything a decoder needs to turn a stream into pixels, and
//! the normative computations the encoder calls instead of re-implementing them.

pub mod anchor;
pub mod anchor_export;
pub mod cli_values;
pub mod context_grid;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod portable_math;
pub mod random_scene;
pub mod raster;
pub mod scene;
pub mod stream;
pub mod wrapper;

/// `println!` for the command-line programs' messages, except that a closed standard output
/// (`pwdec info s.pwb | head -1`, `pwenc ... | head`) is not an error: the job goes on and
/// writes its files, where `println!` would panic halfway.
#[macro_export]
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}
