//! `stream::decode` on streams whose payloads are arbitrary: the input is resealed (every CRC
//! recomputed) first, so mutations reach the header, octree, attribute and wrapper parsers
//! instead of failing the container's CRC check.
//!
//! A stream that decodes must re-encode (`stream::encode`) to a stream that decodes to the
//! same attributes and wrapper and re-encodes to the same bytes; and a tiny view of it must
//! render (through the wrapper when there is one) to finite pixels.
#![no_main]

use pwgs_render::show::SceneRender;
use glam::Vec3;
use libfuzzer_sys::fuzz_target;
use pwgs_core::camera::{Camera, Intrinsics};
use pwgs_codec::stream::wrap::{QuantizedSynthesis, WRAPPER};
use pwgs_codec::stream::{self, Decoded};
use pwgs_fuzz::reseal;

fuzz_target!(|data: &[u8]| {
    let mut bytes = data.to_vec();
    reseal(&mut bytes);
    let Ok(decoded) = stream::decode(&bytes) else { return };
    check_reencoding(&bytes, &decoded);
    render_tiny_view(&decoded);
});

fn check_reencoding(bytes: &[u8], decoded: &Decoded) {
    let (container, _) = stream::parse(bytes).expect("a decoded stream parses");
    let wrapper = container
        .section(WRAPPER)
        .map(|s| QuantizedSynthesis::read(s.payload, container.minor).expect("a decoded stream's wrapper reads again"));
    let encode =
        |d: &Decoded| stream::encode(&d.header, &d.content, wrapper.as_ref()).expect("decoded content is encodable");
    let encoded = encode(decoded);
    let again = stream::decode(&encoded).expect("a re-encoded stream decodes");
    assert_eq!(again.scene.attribute_hash(), decoded.scene.attribute_hash(), "attributes changed");
    assert_eq!(again.scene.wrapper, decoded.scene.wrapper, "wrapper changed");
    assert_eq!(encode(&again), encoded, "re-encoding is not a fixed point");
}

/// An 8x6 view from in front of the scene's normalization frame, 3 scales back.
fn render_tiny_view(decoded: &Decoded) {
    let header = &decoded.header;
    let center = Vec3::from(header.center);
    let intrinsics = Intrinsics { width: 8, height: 6, fx: 8.0, fy: 8.0, cx: 4.0, cy: 3.0 };
    let eye = center + Vec3::new(0.0, 0.0, -3.0 * header.scale);
    let Ok(camera) = Camera::look_at(intrinsics, eye, center, Vec3::NEG_Y) else { return };
    // A view past the blend-work limit is refused, as pwdec refuses it.
    let Ok(shown) = decoded.scene.render(&camera, &decoded.scene.render_options(), true) else { return };
    assert!(shown.image.data.iter().all(|v| v.is_finite()), "a rendered pixel is not finite");
    assert!(shown.residual.iter().flatten().all(|v| v.is_finite()), "a wrapper residual is not finite");
}
