//! `camera_json::parse_camera` on arbitrary text. A camera it accepts, written back with
//! `camera_to_json` (what `pwdec` writes), must parse again to the same intrinsics.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pwgs_core::camera_json::{camera_to_json, parse_camera};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(camera) = parse_camera(text) else { return };
    let written = camera_to_json(&camera);
    let again = parse_camera(&written).unwrap_or_else(|e| panic!("a written camera does not parse: {e}\n{written}"));
    assert_eq!(again.intrinsics(), camera.intrinsics());
});
