//! What the suite pins, as the `expected.json` files spell it: the generator writes these
//! structures and the runner reads them back.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

/// `vectors/NAME/expected.json`: what a conforming decoder makes of one valid stream.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExpectedVector {
    #[serde(default)]
    pub description: String,
    /// SPEC.md clauses the vector exercises (see the clause table in README.md).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub clauses: Vec<String>,
    pub stream: String,
    pub version: [u16; 2],
    pub gaussians: u32,
    pub sh_degree: u32,
    /// SPEC.md section 7.2.
    pub attribute_sha256: String,
    /// Whether the stream carries a perceptual wrapper (renders then go through it).
    #[serde(default)]
    pub wrapper: bool,
    /// SHA-256 of the wrapper's dequantized parameters in stream order, little-endian binary32
    /// (SPEC.md section 11.4), when the stream carries one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wrapper_sha256: Option<String>,
    pub renders: Vec<ExpectedRender>,
}

/// One camera and the image a decoder shows for it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExpectedRender {
    pub camera: String,
    pub image: String,
    /// SHA-256 of the noise pyramid (SPEC.md section 11.1) of the wrapper's seed at this
    /// camera's size, when the wrapper takes the noise input.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_sha256: Option<String>,
}

/// `invalid/expected.json`: for every file, the refusal it must produce.
pub type ExpectedRefusals = BTreeMap<String, ExpectedRefusal>;

/// Why one invalid file must be refused.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExpectedRefusal {
    /// The SPEC.md clause the file breaks (README.md lists the clause IDs).
    pub clause: String,
    /// What the decoder's error message must contain: it names the section and field, then the
    /// problem. Parts separated by " … " must appear in this order (the parts leave out what
    /// may vary between decoders' wordings, such as byte offsets).
    pub error: String,
    pub description: String,
}
