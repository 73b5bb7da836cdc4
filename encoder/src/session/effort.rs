//! `pwenc --from MODEL --effort 0..9`: how hard an import works for a smaller stream at its
//! quality, as codecs' presets do (zstd's levels, `cwebp -m`). Each level is a fixed set of the
//! import's tools; the individual options add tools to it. The levels up to 5 come from the
//! measured table in docs/results/splat-formats.md ("Effort levels"), those above from what
//! each tool brought there ("What each tool brings") and its time.

use crate::plain::colour_refit::{ColourRefit, FULL_REFIT};

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
    /// Refit the colours to the quantized geometry, this hard.
    pub refit_colours: Option<ColourRefit>,
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
    /// 1 importance classes, 2 with pruning, 3 with a colour refit of 2 iterations, 4 of 8, 5
    /// of 8 rounded in quarters ([`FULL_REFIT`]), 6 to 9 with a shape refit of 1, 2, 3 and 6
    /// epochs (each followed by the refit's rounding turns). Each level's time and bytes are in
    /// docs/results/splat-formats.md ("Effort levels"): more shape epochs gain little (biker at
    /// quality 11: 57.08 dB on the orbit after 1 epoch, 57.12 after 6, the same bytes), and
    /// neither 12 nor 24 epochs nor 16 colour iterations gained over 6 epochs and 8 iterations
    /// (guitar and biker within 0.2 dB, in twice the time). No level searches the steps: the
    /// search scores its views before the refits and coarsens what they would have made up
    /// for (a level 9 with it coded guitar 4.6% larger at equal PSNR than level 5 without it).
    /// The colour refit needs its views dense ([`crate::plain::importance::class_cameras`]): on
    /// every other one of the 57 upper views (before the views below were added) it fitted those
    /// views and coded biker larger at a lower PSNR than without a refit.
    pub fn of_effort(effort: u8) -> Self {
        let effort = effort.min(MAX_EFFORT);
        let at = |level: u8| effort >= level;
        let refit_colours = match effort {
            0..=2 => None,
            3 => Some(ColourRefit { iterations: 2, rounding_turns: 1 }),
            4 => Some(ColourRefit { iterations: 8, rounding_turns: 1 }),
            _ => Some(FULL_REFIT),
        };
        let refit_shapes = match effort {
            0..=5 => None,
            6 => Some(1),
            7 => Some(2),
            8 => Some(3),
            _ => Some(6),
        };
        Self { importance: at(1), prune_faint: at(2), search_steps: false, refit_shapes, refit_colours }
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
        let more = Tools::of_effort(3).with(Tools { refit_colours: Some(FULL_REFIT), ..Tools::NONE });
        assert_eq!(more.refit_colours, Some(FULL_REFIT));
        let pruned = Tools::of_effort(3).with(Tools { prune_faint: true, ..Tools::NONE });
        assert_eq!(pruned, Tools::of_effort(3));
        assert_eq!(
            Tools::of_effort(8).without_refits(),
            Tools { refit_shapes: None, refit_colours: None, ..Tools::of_effort(8) }
        );
    }
}
