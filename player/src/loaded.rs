//! A stream opened in the player: its decoded scene and what the info panel shows of it.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use pwgs_codec::scene::Scene;
use pwgs_codec::stream::{self, header::Header, section_sizes};

/// A decoded stream.
pub struct LoadedStream {
    pub path: PathBuf,
    pub bytes: usize,
    pub version: (u16, u16),
    pub header: Header,
    /// Tag and size of each section, in stream order.
    pub sections: Vec<(String, usize)>,
    pub scene: Scene,
}

impl LoadedStream {
    /// Reads and decodes `path`; every failure names the file.
    pub fn open(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
        let decoded = stream::decode(&bytes).with_context(|| format!("cannot decode {}", path.display()))?;
        let (container, _) = stream::parse(&bytes).with_context(|| format!("cannot parse {}", path.display()))?;
        Ok(Self {
            path: path.to_path_buf(),
            bytes: bytes.len(),
            version: (container.major, container.minor),
            sections: section_sizes(&container),
            header: decoded.header,
            scene: decoded.scene,
        })
    }

    /// Lines for the info panel: header, sections and the wrapper's configuration.
    pub fn describe(&self) -> Vec<String> {
        let h = &self.header;
        let mut lines = vec![
            format!("{} ({} bytes), version {}.{}", self.path.display(), self.bytes, self.version.0, self.version.1),
            format!(
                "base: {}, {} {}",
                h.base.name(),
                h.gaussian_count,
                match h.base {
                    stream::header::BaseKind::Plain3dgs => "Gaussians",
                    stream::header::BaseKind::Anchors => "anchors",
                }
            ),
            format!("SH degree {}, background {:?}", h.sh_degree, h.background),
            format!("normalization: center {:?}, scale {}", h.center, h.scale),
        ];
        lines.extend(self.sections.iter().map(|(tag, size)| {
            format!("  {tag:<4} {size:>10} bytes  {:5.1}%", 100.0 * *size as f64 / self.bytes as f64)
        }));
        lines.push(match &self.scene.wrapper {
            Some(w) => format!(
                "wrapper: width {}, noise {}, Plücker {}, seed {:#018x}",
                w.config.width,
                if w.config.noise { "on" } else { "off" },
                if w.config.plucker { "on" } else { "off" },
                w.config.seed
            ),
            None => "no wrapper".to_string(),
        });
        lines
    }
}
