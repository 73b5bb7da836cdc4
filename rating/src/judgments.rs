//! Judgments as the rating page stores them: one JSON object per line, appended as each is
//! made, so that a killed server loses at most the line being written (a torn last line is
//! reported, not silently dropped).
//!
//! A judgment names the two methods shown beside the ground truth and the one the rater found
//! closer to it. Golden questions show the ground truth itself as one side ([`GROUND_TRUTH`]);
//! a rater who does not pick it often enough is screened out with all their judgments.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};

/// The name a golden question gives the ground truth when it stands as one of the two sides.
pub const GROUND_TRUTH: &str = "ground-truth";

/// One rater's choice between two renders of the same crop.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Judgment {
    pub rater: String,
    /// The view and the crop's top-left corner it was shown on.
    pub view: String,
    pub crop: [u32; 2],
    /// The methods on the left and on the right.
    pub left: String,
    pub right: String,
    /// The side picked as closer to the ground truth: `left` or `right`'s method name.
    pub winner: String,
}

impl Judgment {
    /// Whether one side was the ground truth.
    pub fn is_golden(&self) -> bool {
        self.left == GROUND_TRUTH || self.right == GROUND_TRUTH
    }

    /// The side not picked.
    pub fn loser(&self) -> &str {
        if self.winner == self.left { &self.right } else { &self.left }
    }
}

/// Reads a judgments file; a malformed line is an error naming it.
pub fn read(path: &Path) -> Result<Vec<Judgment>> {
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let j: Judgment =
            serde_json::from_str(line).with_context(|| format!("{} line {}: not a judgment", path.display(), i + 1))?;
        if j.left == j.right || (j.winner != j.left && j.winner != j.right) {
            bail!("{} line {}: the winner must be one of two different sides", path.display(), i + 1);
        }
        out.push(j);
    }
    Ok(out)
}

/// What screening kept.
#[derive(Debug, Clone, PartialEq)]
pub struct Screened {
    /// The comparisons between methods of the raters who passed.
    pub kept: Vec<Judgment>,
    /// Per rater: golden questions answered and answered right.
    pub golden: BTreeMap<String, (usize, usize)>,
    /// Raters whose golden accuracy fell below the threshold.
    pub rejected: Vec<String>,
}

/// Drops every judgment of raters who picked the ground truth in fewer than `min_accuracy` of
/// their golden questions (raters with none pass), and the golden questions themselves.
pub fn screen(judgments: &[Judgment], min_accuracy: f64) -> Screened {
    let mut golden: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    for j in judgments.iter().filter(|j| j.is_golden()) {
        let entry = golden.entry(j.rater.clone()).or_default();
        entry.0 += 1;
        entry.1 += usize::from(j.winner == GROUND_TRUTH);
    }
    let rejected: Vec<String> = golden
        .iter()
        .filter(|(_, (asked, right))| (*right as f64) < min_accuracy * *asked as f64)
        .map(|(r, _)| r.clone())
        .collect();
    let kept = judgments.iter().filter(|j| !j.is_golden() && !rejected.contains(&j.rater)).cloned().collect();
    Screened { kept, golden, rejected }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn judgment(rater: &str, left: &str, right: &str, winner: &str) -> Judgment {
        Judgment {
            rater: rater.into(),
            view: "v".into(),
            crop: [0, 0],
            left: left.into(),
            right: right.into(),
            winner: winner.into(),
        }
    }

    #[test]
    fn raters_who_miss_golden_questions_are_screened_out() {
        let all = vec![
            judgment("good", "a", GROUND_TRUTH, GROUND_TRUTH),
            judgment("good", "a", "b", "a"),
            judgment("careless", GROUND_TRUTH, "b", "b"),
            judgment("careless", GROUND_TRUTH, "a", GROUND_TRUTH),
            judgment("careless", "a", "b", "b"),
            judgment("silent", "b", "a", "b"),
        ];
        let s = screen(&all, 0.8);
        assert_eq!(s.rejected, vec!["careless".to_string()], "1 of 2 golden answers right");
        assert_eq!(s.golden["good"], (1, 1));
        assert_eq!(s.kept, vec![all[1].clone(), all[5].clone()]);
        assert_eq!(all[5].loser(), "a");
    }

    #[test]
    fn malformed_lines_are_named() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("j.jsonl");
        let good = serde_json::to_string(&judgment("r", "a", "b", "a")).unwrap();
        std::fs::write(&path, format!("{good}\n\n{good}\n")).unwrap();
        assert_eq!(read(&path).unwrap().len(), 2);
        std::fs::write(&path, format!("{good}\n{{\"rater\": \"r\"\n")).unwrap();
        let e = format!("{:#}", read(&path).unwrap_err());
        assert!(e.contains("line 2"), "{e}");
        let bad_winner = serde_json::to_string(&judgment("r", "a", "b", "c")).unwrap();
        std::fs::write(&path, bad_winner).unwrap();
        assert!(format!("{:#}", read(&path).unwrap_err()).contains("line 1"));
    }
}
