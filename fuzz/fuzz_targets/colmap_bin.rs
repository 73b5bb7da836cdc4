//! The COLMAP binary readers (`colmap::read_binary`: cameras.bin, images.bin, points3D.bin),
//! then each camera's intrinsics and distortion as the scene loader asks for them.
//!
//! Input: three files, the first two length-prefixed: `u32` little-endian length and bytes of
//! cameras.bin, the same for images.bin, then points3D.bin to the end (lengths past the end
//! are cut short). The loader takes a folder, so the files are written to a scratch folder.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pwgs_dataset::colmap;
use pwgs_fuzz::{scratch_dir, write_scratch};

/// The next length-prefixed part of `rest`, and what follows it.
fn split_part(rest: &[u8]) -> (&[u8], &[u8]) {
    let Some((len, rest)) = rest.split_first_chunk::<4>() else { return (rest, &[]) };
    rest.split_at((u32::from_le_bytes(*len) as usize).min(rest.len()))
}

fuzz_target!(|data: &[u8]| {
    let (cameras, rest) = split_part(data);
    let (images, points) = split_part(rest);
    let dir = scratch_dir("colmap_bin");
    write_scratch(&dir.join("cameras.bin"), cameras);
    write_scratch(&dir.join("images.bin"), images);
    write_scratch(&dir.join("points3D.bin"), points);
    let Ok(model) = colmap::read_binary(dir) else { return };
    for camera in &model.cameras {
        let _ = camera.pinhole();
        let _ = camera.distortion(dir);
    }
});
