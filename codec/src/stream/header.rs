//! The `HEAD` section (SPEC.md section 4): what kind of base the stream holds, how many
//! Gaussians, the scene normalization and the render settings.

use pwgs_bitstream::{FieldError, FieldReader, FieldWriter, MINOR_VERSION};

use pwgs_core::gaussians::MAX_SH_DEGREE;

/// Most Gaussians a stream may declare (a bound on what a decoder allocates).
pub use pwgs_core::gaussians::MAX_GAUSSIANS;

/// The base representation a stream holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BaseKind {
    /// Plain 3D Gaussians (SPEC.md section 6).
    Plain3dgs,
    /// Anchors and the MLPs that derive each view's Gaussians (SPEC.md section 12).
    Anchors,
}

impl BaseKind {
    fn code(self) -> u8 {
        match self {
            BaseKind::Plain3dgs => 0,
            BaseKind::Anchors => 1,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            BaseKind::Plain3dgs => "3dgs",
            BaseKind::Anchors => "anchor",
        }
    }
}

/// The decoded `HEAD` section.
#[derive(Debug, Clone, PartialEq)]
pub struct Header {
    pub base: BaseKind,
    /// Gaussians of a plain base, anchors of an anchor base.
    pub gaussian_count: u32,
    pub sh_degree: u32,
    /// Scene normalization (docs/architecture.md section 1.5): world = center + scale * normalized.
    pub center: [f32; 3],
    pub scale: f32,
    /// Color behind all Gaussians, each channel in [0, 1].
    pub background: [f32; 3],
}

impl Header {
    /// The scene normalization as the wrapper's Plücker embeddings use it.
    pub fn frame(&self) -> pwgs_core::frame::SceneFrame {
        pwgs_core::frame::SceneFrame { center: glam::Vec3::from(self.center), scale: self.scale }
    }

    pub fn write(&self) -> Vec<u8> {
        let mut w = FieldWriter::new();
        w.u8(self.base.code());
        w.u32(self.gaussian_count);
        w.u8(self.sh_degree as u8);
        self.center.iter().for_each(|&c| w.f32(c));
        w.f32(self.scale);
        self.background.iter().for_each(|&c| w.f32(c));
        w.into_bytes()
    }

    /// Reads the section; fields appended by a newer minor version are skipped.
    pub fn read(payload: &[u8], minor: u16) -> Result<Self, FieldError> {
        let mut r = FieldReader::new("HEAD", payload);
        let base = match r.u8("base")? {
            0 => BaseKind::Plain3dgs,
            1 => BaseKind::Anchors,
            other => return Err(r.error("base", format!("unknown base kind {other}"))),
        };
        let gaussian_count = r.u32("gaussian count")?;
        if gaussian_count > MAX_GAUSSIANS {
            return Err(r.error("gaussian count", format!("{gaussian_count} exceeds the limit of {MAX_GAUSSIANS}")));
        }
        let sh_degree = u32::from(r.u8("sh degree")?);
        if sh_degree > MAX_SH_DEGREE {
            return Err(r.error("sh degree", format!("{sh_degree} exceeds {MAX_SH_DEGREE}")));
        }
        if base == BaseKind::Anchors && sh_degree != 0 {
            return Err(r.error("sh degree", format!("{sh_degree} is not 0 (the anchor base's MLPs give colors)")));
        }
        let center = [r.f32("center x")?, r.f32("center y")?, r.f32("center z")?];
        let scale = r.f32("scale")?;
        if !(scale > 0.0) {
            return Err(r.error("scale", format!("{scale} is not positive")));
        }
        let mut background = [0.0; 3];
        for c in &mut background {
            *c = r.f32("background")?;
            if !(0.0..=1.0).contains(c) {
                return Err(r.error("background", format!("{c} is outside [0, 1]")));
            }
        }
        r.finish(minor > MINOR_VERSION)?;
        Ok(Self { base, gaussian_count, sh_degree, center, scale, background })
    }
}
