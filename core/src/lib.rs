//! The ground floor of pwgs: scenes of Gaussians and cameras, the files they come in and go
//! out as (PLY, compressed PLY, SPZ, SOG, `.splat`, camera JSON, PNG), the scene frame and the
//! deterministic random numbers. Every other crate builds on it; it depends on none of them.

pub mod atomic_file;
pub mod camera;
pub mod camera_json;
pub mod frame;
pub mod gaussians;
pub mod ply;
pub mod random;
pub mod rgb_image;
pub mod splat_file;

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
