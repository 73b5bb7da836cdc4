//! A stream described for people (`pwdec info`): its version, header and sections, and what its
//! optional sections configure (the context model, importance classes, tree coding, the
//! wrapper). Every CRC is verified; the stream is decoded at most once, and only when it holds
//! a context model or importance classes, whose sizes come from the decoded positions.

use pwgs_bitstream::SECTION_OVERHEAD;

use super::anchor_context::CONTEXT;
use super::classes::CLASSES;
use super::header::BaseKind;
use super::trees::{ADAPTIVE, BLOCKS};
use super::wrap::{QuantizedSynthesis, WRAPPER};
use super::{Content, DecodeError, decode, parse};

/// The lines describing the stream `bytes`, in the order `pwdec info` prints them.
pub fn describe(bytes: &[u8]) -> Result<Vec<String>, DecodeError> {
    let (container, header) = parse(bytes)?;
    let mut lines = vec![
        format!("version       {}.{}", container.major, container.minor),
        format!("base          {}", header.base.name()),
        match header.base {
            BaseKind::Plain3dgs => format!("gaussians     {}", header.gaussian_count),
            BaseKind::Anchors => format!("anchors       {}", header.gaussian_count),
        },
        format!("sh degree     {}", header.sh_degree),
        format!("normalization center {:?}, scale {}", header.center, header.scale),
        format!("background    {:?}", header.background),
        "sections      (bytes incl. 12 bytes of tag, length and CRC)".to_string(),
    ];
    for s in &container.sections {
        let share = 100.0 * (s.payload.len() + SECTION_OVERHEAD) as f64 / bytes.len() as f64;
        let kind = if s.tag.is_critical() { "" } else { "  (optional)" };
        lines.push(format!("  {}  {:>10}  {share:5.1}%{kind}", s.tag, s.payload.len() + SECTION_OVERHEAD));
    }
    if container.section(CONTEXT).is_some() || container.section(CLASSES).is_some() {
        match decode(bytes)?.content {
            Content::Anchors(a) => {
                if let Some(c) = &a.context {
                    lines.push(format!(
                        "context       levels {:?}, plane levels {:?} (2^r cells per axis), 2^{} entries per hashed \
                         grid, {} channels: {} entries; network width {}, steps 2^{} / 2^{}",
                        c.shape.levels,
                        c.shape.planes,
                        c.shape.table_log2,
                        c.shape.channels,
                        c.shape.entries(a.grid.depth),
                        c.mlp.hidden,
                        c.mlp.weight_exponent,
                        c.mlp.bias_exponent
                    ));
                }
            }
            Content::Plain(p) => {
                if let Some(c) = &p.classes {
                    let counts: Vec<usize> =
                        (0..c.factors.len()).map(|k| c.of.iter().filter(|&&x| usize::from(x) == k).count()).collect();
                    lines.push(format!(
                        "importance    {} classes, Gaussians per class {counts:?}; position grid {} levels finer than \
                         POSN's, levels dropped per class {:?}",
                        c.factors.len(),
                        c.refine,
                        c.drops
                    ));
                }
            }
        }
    }
    if let Some(section) = container.section(ADAPTIVE) {
        // The payload's bits as stored (checked when the stream is decoded, not here).
        let mask = section.payload.first().copied().unwrap_or(0);
        let named: Vec<String> =
            BLOCKS.iter().enumerate().filter(|&(k, _)| mask >> k & 1 == 1).map(|(_, tag)| tag.to_string()).collect();
        let named = if named.is_empty() { "no block".to_string() } else { named.join(", ") };
        lines.push(format!("tree coding   {named} (ADPT: adaptive trees; the other blocks with frequency tables)"));
    }
    if let Some(section) = container.section(WRAPPER) {
        let w = QuantizedSynthesis::read(section.payload, container.minor)?;
        let c = w.config;
        lines.push(format!(
            "wrapper       width {}, noise {}, plücker {}, seed {:#018x}, steps 2^{} / 2^{} ({} parameters)",
            c.width,
            if c.noise { "on" } else { "off" },
            if c.plucker { "on" } else { "off" },
            c.seed,
            w.weight_exponent,
            w.bias_exponent,
            w.values.len()
        ));
    }
    Ok(lines)
}
