//! `pwenc --from MODEL --effort 0..9`: how hard an import works for a smaller stream at its
//! quality, as codecs' presets do (zstd's levels, `cwebp -m`). Each level is a fixed set of the
//! import's tools; the individual options add tools to it. The default and the levels up to 3
//! come from the measured table in docs/results/splat-formats.md ("Effort levels"), the levels
//! above from what each tool brought there ("What each tool brings") and its time.

/// The tools of an import ([`ModelImport`](super::ModelImport)'s switches).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tools {
    /// Importance classes (SPEC.md section 6.5).
    pub importance: bool,
    /// Drop the Gaussians too faint to pay for their bytes in any importance view.
    pub prune_faint: bool,
    /// Search the balance of the steps for the model.
    pub search_steps: bool,
    /// Refit the shapes to the quantized positions: this many epochs.
    pub refit_shapes: Option<usize>,
    /// Refit the colours to the quantized geometry: this many conjugate-gradient iterations.
    pub refit_colours: Option<usize>,
}

/// The level `pwenc --from` takes by default: the smallest streams within about 30 s for a
/// 150,000-Gaussian model on 2 cores.
pub const DEFAULT_EFFORT: u8 = 2;
pub const MAX_EFFORT: u8 = 9;

impl Tools {
    /// Uniform steps: no tool.
    pub const NONE: Self =
        Self { importance: false, prune_faint: false, search_steps: false, refit_shapes: None, refit_colours: None };

    /// The tools of `effort` (levels above [`MAX_EFFORT`] are [`MAX_EFFORT`]): 0 uniform steps,
    /// 1 importance classes, 2 with pruning, 3 and 4 with a colour refit of 2 and 8
    /// iterations, 5 with the step search, 6 and 7 with a shape refit of 6 and 12 epochs, 8
    /// with 16 colour iterations, 9 with 24 shape epochs. The colour refit needs all 57
    /// importance views at 512x512: on every third of them at 256x256 (a tenth of the time) it
    /// fits those views and codes guitar and biker larger at a lower PSNR than level 2. (On
    /// biker at quality 11, 8 colour iterations reach 57.81 dB on the orbit after quantizing,
    /// 16 reach 57.87 dB in twice the time.)
    pub fn of_effort(effort: u8) -> Self {
        let effort = effort.min(MAX_EFFORT);
        let at = |level: u8| effort >= level;
        let refit_colours = match effort {
            0..=2 => None,
            3 => Some(2),
            4..=7 => Some(8),
            _ => Some(16),
        };
        let refit_shapes = match effort {
            0..=5 => None,
            6 => Some(6),
            7 | 8 => Some(12),
            _ => Some(24),
        };
        Self { importance: at(1), prune_faint: at(2), search_steps: at(5), refit_shapes, refit_colours }
    }

    /// These tools and `more`'s together (the larger count where both refit).
    pub fn with(self, more: Self) -> Self {
        Self {
            importance: self.importance || more.importance || more != Self::NONE,
            prune_faint: self.prune_faint || more.prune_faint,
            search_steps: self.search_steps || more.search_steps,
            refit_shapes: self.refit_shapes.max(more.refit_shapes),
            refit_colours: self.refit_colours.max(more.refit_colours),
        }
    }

    /// Without the refits (which fit the Gaussians a quality keeps, not those a target size
    /// keeps).
    pub fn without_refits(self) -> Self {
        Self { refit_shapes: None, refit_colours: None, ..self }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_level_adds_to_the_one_below() {
        let mut below = Tools::of_effort(0);
        assert_eq!(below, Tools::NONE);
        for effort in 1..=MAX_EFFORT {
            let tools = Tools::of_effort(effort);
            assert_ne!(tools, below, "level {effort} adds nothing");
            // Nothing of the level below is lost, and no count shrinks.
            assert_eq!(tools.with(below), tools, "level {effort} drops a tool of {}", effort - 1);
            below = tools;
        }
        assert_eq!(Tools::of_effort(200), Tools::of_effort(MAX_EFFORT));
    }

    #[test]
    fn any_tool_given_brings_the_classes_it_needs() {
        let search = Tools { search_steps: true, ..Tools::NONE };
        let tools = Tools::of_effort(0).with(search);
        assert!(tools.importance && tools.search_steps && !tools.prune_faint);
        let more = Tools::of_effort(3).with(Tools { refit_colours: Some(8), ..Tools::NONE });
        assert_eq!(more.refit_colours, Some(8));
        let pruned = Tools::of_effort(3).with(Tools { prune_faint: true, ..Tools::NONE });
        assert_eq!(pruned, Tools::of_effort(3));
        assert_eq!(
            Tools::of_effort(8).without_refits(),
            Tools { refit_shapes: None, refit_colours: None, ..Tools::of_effort(8) }
        );
    }
}
