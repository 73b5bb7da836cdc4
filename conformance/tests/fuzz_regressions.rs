//! Every input the fuzz campaigns found for `decode` (`fuzz/regressions/decode/`), held to the
//! harness's property in the dev and the release profile: resealed, it is refused with an
//! error, or it decodes and re-encodes to a stream that decodes to the same attributes.

use std::path::Path;

use pwgs_codec::stream;
use pwgs_codec::stream::wrap::{QuantizedSynthesis, WRAPPER};

#[test]
fn decode_regressions_keep_the_harness_property() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/regressions/decode");
    let mut files: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).collect();
    files.sort();
    assert!(!files.is_empty(), "no regression files in {}", dir.display());
    for file in files {
        let mut bytes = std::fs::read(&file).unwrap();
        pwgs_bitstream::reseal(&mut bytes);
        let decoded = match stream::decode(&bytes) {
            Ok(decoded) => decoded,
            Err(error) => {
                assert!(!error.to_string().is_empty(), "{}", file.display());
                continue;
            }
        };
        let (container, _) = stream::parse(&bytes).unwrap();
        let wrapper = container.section(WRAPPER).map(|s| QuantizedSynthesis::read(s.payload, container.minor).unwrap());
        let encoded = stream::encode(&decoded.header, &decoded.content, wrapper.as_ref()).unwrap();
        let again = stream::decode(&encoded).unwrap_or_else(|e| panic!("{}: re-encoded stream: {e}", file.display()));
        assert_eq!(again.scene.attribute_hash(), decoded.scene.attribute_hash(), "{}", file.display());
    }
}
