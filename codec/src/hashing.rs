//! SHA-256 of decoded arrays in their canonical byte layout (little-endian), as the
//! conformance hashes define them (SPEC.md 7.2, 11, 12.6). Values are packed into blocks and
//! hashed a block at a time: a call into the hash per 4-byte value cost more than decoding
//! them.

use sha2::{Digest, Sha256};

#[derive(Default)]
pub struct Hasher(Sha256);

impl Hasher {
    pub fn bytes(&mut self, bytes: &[u8]) {
        self.0.update(bytes);
    }

    pub fn u64(&mut self, v: u64) {
        self.0.update(v.to_le_bytes());
    }

    /// Each value as little-endian binary32.
    pub fn floats<'a>(&mut self, values: impl IntoIterator<Item = &'a f32>) {
        let mut values = values.into_iter();
        let mut block = [0u8; 4096];
        loop {
            let mut used = 0;
            for (bytes, v) in block.chunks_exact_mut(4).zip(&mut values) {
                bytes.copy_from_slice(&v.to_le_bytes());
                used += 4;
            }
            self.0.update(&block[..used]);
            if used < block.len() {
                return;
            }
        }
    }

    /// The digest in lowercase hex.
    pub fn hex(self) -> String {
        self.0.finalize().iter().map(|b| format!("{b:02x}")).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_hashing_equals_hashing_the_bytes_at_once() {
        let values: Vec<f32> = (0..40_000).map(|i| i as f32 * 0.37).collect();
        let mut h = Hasher::default();
        h.u64(7);
        h.floats(&values);
        h.bytes(&[1, 0, 1]);
        let mut all = 7u64.to_le_bytes().to_vec();
        values.iter().for_each(|v| all.extend(v.to_le_bytes()));
        all.extend([1, 0, 1]);
        let expected: String = Sha256::digest(&all).iter().map(|b| format!("{b:02x}")).collect();
        assert_eq!(h.hex(), expected);
        // SHA-256 of nothing.
        assert_eq!(Hasher::default().hex(), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
    }
}
