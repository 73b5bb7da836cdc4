//! Field syntax inside a section payload (SPEC.md section 3): little-endian fixed-width
//! integers, IEEE-754 binary32 floats, and unsigned LEB128 varints (at most 5 bytes, no
//! overlong encodings) with zig-zag for signed values.

/// A field that could not be read or holds a forbidden value: which section, which field, and
/// the payload byte where that field starts.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("section '{section}', field `{field}` at payload byte {offset}: {problem}")]
pub struct FieldError {
    pub section: String,
    pub field: &'static str,
    pub offset: usize,
    pub problem: String,
}

/// Reads fields from one section's payload, naming the section in every error.
pub struct FieldReader<'a> {
    section: &'a str,
    bytes: &'a [u8],
    at: usize,
    /// Where the field being read, or the last one read, starts: errors point there, also
    /// those a caller raises after checking a value it read.
    field_start: usize,
}

impl<'a> FieldReader<'a> {
    pub fn new(section: &'a str, bytes: &'a [u8]) -> Self {
        Self { section, bytes, at: 0, field_start: 0 }
    }

    /// An error in the field being read or the last one read (see `field_start`).
    pub fn error(&self, field: &'static str, problem: impl Into<String>) -> FieldError {
        FieldError { section: self.section.to_string(), field, offset: self.field_start, problem: problem.into() }
    }

    pub fn position(&self) -> usize {
        self.at
    }

    pub fn remaining(&self) -> usize {
        self.bytes.len() - self.at
    }

    /// The next `n` bytes.
    pub fn bytes(&mut self, field: &'static str, n: usize) -> Result<&'a [u8], FieldError> {
        self.field_start = self.at;
        if n > self.remaining() {
            return Err(self.error(field, format!("needs {n} bytes, {} left", self.remaining())));
        }
        let out = &self.bytes[self.at..self.at + n];
        self.at += n;
        Ok(out)
    }

    /// Everything left in the payload.
    pub fn rest(&mut self) -> &'a [u8] {
        self.field_start = self.at;
        let out = &self.bytes[self.at..];
        self.at = self.bytes.len();
        out
    }

    fn array<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], FieldError> {
        Ok(self.bytes(field, N)?.try_into().expect("length checked"))
    }

    pub fn u8(&mut self, field: &'static str) -> Result<u8, FieldError> {
        Ok(self.array::<1>(field)?[0])
    }

    pub fn u16(&mut self, field: &'static str) -> Result<u16, FieldError> {
        Ok(u16::from_le_bytes(self.array(field)?))
    }

    pub fn u32(&mut self, field: &'static str) -> Result<u32, FieldError> {
        Ok(u32::from_le_bytes(self.array(field)?))
    }

    pub fn u64(&mut self, field: &'static str) -> Result<u64, FieldError> {
        Ok(u64::from_le_bytes(self.array(field)?))
    }

    /// A binary32 float that must be finite.
    pub fn f32(&mut self, field: &'static str) -> Result<f32, FieldError> {
        let v = f32::from_le_bytes(self.array(field)?);
        if !v.is_finite() {
            self.at = self.field_start;
            return Err(self.error(field, format!("{v} is not finite")));
        }
        Ok(v)
    }

    /// An unsigned LEB128 value of at most 32 bits.
    pub fn varint(&mut self, field: &'static str) -> Result<u32, FieldError> {
        let start = self.at;
        let mut value: u64 = 0;
        for i in 0..5 {
            // A varint cut short is an error at its first byte, like any other field.
            let byte = self.u8(field).map_err(|e| FieldError { offset: start, ..e })?;
            self.field_start = start;
            value |= u64::from(byte & 0x7f) << (7 * i);
            if byte & 0x80 == 0 {
                if i > 0 && byte == 0 {
                    self.at = start;
                    return Err(self.error(field, "overlong varint"));
                }
                return u32::try_from(value).map_err(|_| {
                    self.at = start;
                    self.error(field, "varint exceeds 32 bits")
                });
            }
        }
        self.at = start;
        Err(self.error(field, "varint longer than 5 bytes"))
    }

    /// A zig-zag coded signed value.
    pub fn signed_varint(&mut self, field: &'static str) -> Result<i32, FieldError> {
        let z = self.varint(field)?;
        Ok(((z >> 1) as i32) ^ -((z & 1) as i32))
    }

    /// Checks that the payload was consumed. A stream of a newer minor version may append
    /// fields a decoder does not know, so `allow_extension` skips them instead.
    pub fn finish(mut self, allow_extension: bool) -> Result<(), FieldError> {
        self.field_start = self.at;
        if self.remaining() > 0 && !allow_extension {
            return Err(self.error("end of section", format!("{} unexpected trailing bytes", self.remaining())));
        }
        self.at = self.bytes.len();
        Ok(())
    }
}

/// Writes fields into a payload with the syntax [`FieldReader`] reads.
#[derive(Default)]
pub struct FieldWriter {
    pub bytes: Vec<u8>,
}

impl FieldWriter {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn u8(&mut self, v: u8) {
        self.bytes.push(v);
    }

    pub fn u16(&mut self, v: u16) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    pub fn u32(&mut self, v: u32) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    pub fn u64(&mut self, v: u64) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    pub fn f32(&mut self, v: f32) {
        assert!(v.is_finite(), "only finite floats are written");
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    pub fn varint(&mut self, mut v: u32) {
        loop {
            let byte = (v & 0x7f) as u8;
            v >>= 7;
            if v == 0 {
                self.bytes.push(byte);
                return;
            }
            self.bytes.push(byte | 0x80);
        }
    }

    pub fn signed_varint(&mut self, v: i32) {
        self.varint(((v << 1) ^ (v >> 31)) as u32);
    }

    pub fn extend(&mut self, bytes: &[u8]) {
        self.bytes.extend_from_slice(bytes);
    }

    pub fn into_bytes(self) -> Vec<u8> {
        self.bytes
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn varints_round_trip_and_reject_overlong_forms() {
        let values = [0u32, 1, 127, 128, 300, 16_383, 16_384, u32::MAX];
        let signed = [0i32, -1, 1, -64, 64, i32::MIN, i32::MAX];
        let mut w = FieldWriter::new();
        values.iter().for_each(|&v| w.varint(v));
        signed.iter().for_each(|&v| w.signed_varint(v));
        w.f32(-2.5);
        let bytes = w.into_bytes();
        let mut r = FieldReader::new("TEST", &bytes);
        for &v in &values {
            assert_eq!(r.varint("v").unwrap(), v);
        }
        for &v in &signed {
            assert_eq!(r.signed_varint("s").unwrap(), v);
        }
        assert_eq!(r.f32("f").unwrap(), -2.5);
        r.finish(false).unwrap();

        for bad in
            [&[0x80u8, 0x00][..], &[0xff, 0xff, 0xff, 0xff, 0x10], &[0x80, 0x80, 0x80, 0x80, 0x80, 0x01], &[0x80]]
        {
            assert!(FieldReader::new("TEST", bad).varint("v").is_err(), "{bad:?} accepted");
        }
        let nan = f32::NAN.to_le_bytes();
        let err = FieldReader::new("TEST", &nan).f32("step").unwrap_err();
        assert!(err.to_string().contains("`step`") && err.to_string().contains("not finite"), "{err}");
    }

    /// Every error points at the first byte of its field: one cut short, one holding a bad
    /// value, and one whose value the caller refuses after reading it.
    #[test]
    fn errors_point_at_the_start_of_their_field() {
        let offset = |bytes: &[u8], read: &dyn Fn(&mut FieldReader) -> Result<(), FieldError>| {
            let mut r = FieldReader::new("TEST", bytes);
            read(&mut r).unwrap_err().offset
        };
        // Two bytes of u16, then a varint cut short in its second byte.
        assert_eq!(offset(&[1, 0, 0x80], &|r| r.u16("a").and(r.varint("b")).map(drop)), 2);
        // A u8, then a NaN.
        let mut nan = vec![7];
        nan.extend(f32::NAN.to_le_bytes());
        assert_eq!(offset(&nan, &|r| r.u8("a").and(r.f32("b")).map(drop)), 1);
        // A caller's check of a two-byte varint after a u8.
        let check = |r: &mut FieldReader| {
            r.u8("a")?;
            let v = r.varint("b")?;
            if v > 10 { Err(r.error("b", "too large")) } else { Ok(()) }
        };
        assert_eq!(offset(&[0, 0x80, 0x01], &check), 1);
        // Trailing bytes are reported where they begin.
        assert_eq!(FieldReader::new("TEST", &[1, 2]).finish(false).unwrap_err().offset, 0);
        let mut r = FieldReader::new("TEST", &[1, 2, 3]);
        r.u8("a").unwrap();
        assert_eq!(r.finish(false).unwrap_err().offset, 1);
    }

    #[test]
    fn trailing_bytes_are_refused_unless_the_minor_version_extends_the_section() {
        let bytes = [1u8, 2, 3];
        let mut r = FieldReader::new("HEAD", &bytes);
        r.u8("kind").unwrap();
        assert!(r.finish(false).is_err());
        let mut r = FieldReader::new("HEAD", &bytes);
        r.u8("kind").unwrap();
        assert!(r.finish(true).is_ok());
    }
}
