//! Invalid camera files (SPEC.md annex A and decision 12): a valid camera of either form with
//! one field broken.

use pwgs_core::camera_json::camera_to_json;
use serde_json::{Value, json};

use super::Refusal;
use super::content;

/// The front camera in the pwgs form, as a JSON value to edit.
fn pwgs_form() -> Value {
    serde_json::from_str(&camera_to_json(&content::camera("front"))).expect("the decoder writes valid JSON")
}

/// A nerfstudio frame looking down the world's -z axis from z = 4.
fn nerfstudio_form() -> Value {
    json!({
        "transform_matrix": [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 4.0], [0.0, 0.0, 0.0, 1.0]],
        "w": 64, "h": 48, "fl_x": 58.0
    })
}

fn refusal(file: &str, clause: &'static str, error: &str, description: &str, value: Value) -> Refusal {
    let mut text = serde_json::to_string_pretty(&value).expect("JSON values serialize");
    text.push('\n');
    Refusal {
        file: format!("{file}.json"),
        clause,
        error: error.into(),
        description: description.into(),
        bytes: text.into_bytes(),
    }
}

pub fn refusals() -> Vec<Refusal> {
    let with = |mut value: Value, pointer: &str, new: Value| {
        *value.pointer_mut(pointer).expect("the field exists") = new;
        value
    };
    let mut no_focal = nerfstudio_form();
    no_focal.as_object_mut().expect("an object").remove("fl_x");
    vec![
        refusal(
            "camera-width-0",
            "SA-size",
            "`width` = 0 is not an image size in 1..=65535",
            "A pwgs camera 0 pixels wide.",
            with(pwgs_form(), "/width", json!(0)),
        ),
        refusal(
            "camera-height-65536",
            "SA-size",
            "`height` = 65536 is not an image size in 1..=65535",
            "A pwgs camera 65536 pixels high (decision 12: sizes 1..=65535).",
            with(pwgs_form(), "/height", json!(65536)),
        ),
        refusal(
            "camera-nerfstudio-fractional-width",
            "SA-size",
            "`w` = 63.5 is not an image size in 1..=65535",
            "A nerfstudio frame 63.5 pixels wide.",
            with(nerfstudio_form(), "/w", json!(63.5)),
        ),
        refusal(
            "camera-scaled-rotation",
            "SA-rotation",
            "rotation is not orthonormal with determinant +1",
            "A pwgs camera whose rotation is scaled by 2.",
            with(
                pwgs_form(),
                "/camera_to_world",
                json!([[2.0, 0.0, 0.0, 0.0], [0.0, 2.0, 0.0, 0.0], [0.0, 0.0, 2.0, -4.0], [0.0, 0.0, 0.0, 1.0]]),
            ),
        ),
        refusal(
            "camera-reflection",
            "SA-rotation",
            "rotation is not orthonormal with determinant +1",
            "A pwgs camera whose rotation has determinant -1.",
            with(
                pwgs_form(),
                "/camera_to_world",
                json!([[-1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, -4.0], [0.0, 0.0, 0.0, 1.0]]),
            ),
        ),
        refusal(
            "camera-last-row",
            "SA-last-row",
            "camera-to-world matrix has last row [0.0, 0.0, 1.0, 1.0]",
            "A pwgs camera whose matrix's last row is [0, 0, 1, 1].",
            with(pwgs_form(), "/camera_to_world/3", json!([0.0, 0.0, 1.0, 1.0])),
        ),
        refusal(
            "camera-focal-zero",
            "SA-focal",
            "intrinsic `fx` = 0 must be finite and positive",
            "A pwgs camera with fx = 0.",
            with(pwgs_form(), "/fx", json!(0.0)),
        ),
        refusal(
            "camera-no-focal",
            "SA-no-focal",
            "no focal length (`fl_x` or `camera_angle_x`)",
            "A nerfstudio frame with neither fl_x nor camera_angle_x.",
            no_focal,
        ),
        refusal("camera-not-an-object", "SA-not-object", "expected a JSON object", "A JSON array.", json!([1, 2, 3])),
        refusal(
            "camera-neither-form",
            "SA-form",
            "expected either width/height/fx/fy/cx/cy/camera_to_world",
            "A pwgs camera without its width.",
            {
                let mut v = pwgs_form();
                v.as_object_mut().expect("an object").remove("width");
                v
            },
        ),
        matrix_infinite(),
        refusal(
            "camera-principal-point-overflow",
            "SA-principal-point",
            "`cx` = 1e39 is outside the range of a 32-bit float",
            "A pwgs camera with cx = 1e39, beyond binary32.",
            with(pwgs_form(), "/cx", json!(1e39)),
        ),
    ]
}

/// A pwgs camera whose translation x is written `1e400`: JSON has no infinity, but the number
/// parses to one.
fn matrix_infinite() -> Refusal {
    let mut value = pwgs_form();
    *value.pointer_mut("/camera_to_world/0/3").expect("the matrix") = json!(123_456_789.5);
    let mut r = refusal(
        "camera-matrix-infinite",
        "SA-matrix-finite",
        "not a camera: number out of range at line 7",
        "A pwgs camera whose translation x is 1e400.",
        value,
    );
    let text = String::from_utf8(r.bytes).expect("JSON is UTF-8");
    r.bytes = text.replace("123456789.5", "1e400").into_bytes();
    r
}
