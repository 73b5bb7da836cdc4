//! `pwrate fit` end to end on simulated judgments: raters who prefer methods with known Elo
//! strengths, and a careless rater who answers at random, golden questions included. The fit
//! must screen the careless rater out, recover the order, and hold every true Elo difference
//! within its 95% interval.

use std::process::Command;

use pwgs_rating::chart::Z95;
use pwgs_rating::elo::{ELO_PER_UNIT, fit};
use pwgs_rating::judgments::{GROUND_TRUTH, Judgment, screen};

/// A small deterministic generator (SplitMix64) for the simulation.
struct Rng(u64);

impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

const TRUE_ELO: [(&str, f64); 4] = [("base", 0.0), ("wrapper", 120.0), ("anchor", 60.0), ("anchor+wrapper", 250.0)];

fn simulate(seed: u64) -> Vec<Judgment> {
    let mut rng = Rng(seed);
    let mut out = Vec::new();
    let judgment = |rater: &str, left: &str, right: &str, winner: &str| Judgment {
        rater: rater.into(),
        view: "IMG_1.png".into(),
        crop: [0, 0],
        left: left.into(),
        right: right.into(),
        winner: winner.into(),
    };
    for n in 0..2400 {
        let a = (rng.uniform() * 4.0) as usize % 4;
        let b = (a + 1 + (rng.uniform() * 3.0) as usize % 3) % 4;
        let ((left, ea), (right, eb)) = (TRUE_ELO[a], TRUE_ELO[b]);
        let p_left = 1.0 / (1.0 + (-(ea - eb) / ELO_PER_UNIT).exp());
        let rater = ["r1", "r2", "r3"][n % 3];
        let winner = if rng.uniform() < p_left { left } else { right };
        out.push(judgment(rater, left, right, winner));
        if n % 20 == 0 {
            // Golden questions: careful raters see the ground truth; the careless one guesses.
            out.push(judgment(rater, GROUND_TRUTH, left, GROUND_TRUTH));
            let guess = if rng.uniform() < 0.5 { GROUND_TRUTH } else { right };
            out.push(judgment("careless", right, GROUND_TRUTH, guess));
            let flipped = if rng.uniform() < 0.5 { right } else { left };
            out.push(judgment("careless", left, right, flipped));
        }
    }
    out
}

#[test]
fn the_fit_recovers_known_strengths() {
    let judgments = simulate(7);
    let screened = screen(&judgments, 0.8);
    assert_eq!(screened.rejected, vec!["careless".to_string()]);
    let f = fit(&screened.kept, 400.0).unwrap();
    let truth = |name: &str| TRUE_ELO.iter().find(|(m, _)| *m == name).unwrap().1;
    let mut by_fit: Vec<usize> = (0..4).collect();
    by_fit.sort_by(|&a, &b| f.elo[a].total_cmp(&f.elo[b]));
    let names: Vec<&str> = by_fit.iter().map(|&i| f.methods[i].as_str()).collect();
    assert_eq!(names, ["base", "anchor", "wrapper", "anchor+wrapper"], "{:?}", f.elo);
    for i in 0..4 {
        for j in 0..4 {
            if i == j {
                continue;
            }
            let (d, sd) = f.difference(i, j);
            let true_d = truth(&f.methods[i]) - truth(&f.methods[j]);
            assert!(
                (d - true_d).abs() <= Z95 * sd,
                "{} - {}: {d:.1} ± {:.1}, true {true_d}",
                f.methods[i],
                f.methods[j],
                Z95 * sd
            );
        }
    }
    // Each method's Elo above the methods' mean holds the true one within its interval.
    let mean = TRUE_ELO.iter().map(|(_, e)| e).sum::<f64>() / 4.0;
    for i in 0..4 {
        let true_centered = truth(&f.methods[i]) - mean;
        assert!(
            (f.elo[i] - true_centered).abs() <= Z95 * f.sd(i),
            "{}: {:.1} ± {:.1}",
            f.methods[i],
            f.elo[i],
            Z95 * f.sd(i)
        );
    }
    let (strong, weak) = (
        f.methods.iter().position(|m| m == "anchor+wrapper").unwrap(),
        f.methods.iter().position(|m| m == "base").unwrap(),
    );
    assert!(f.probability_stronger(strong, weak) > 0.999);
}

#[test]
fn pwrate_fit_prints_the_table_and_draws_the_chart() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("judgments.jsonl");
    let lines: Vec<String> = simulate(3).iter().map(|j| serde_json::to_string(j).unwrap()).collect();
    std::fs::write(&path, lines.join("\n")).unwrap();
    let chart = tmp.path().join("elo.svg");
    let out = Command::new(env!("CARGO_BIN_EXE_pwrate"))
        .args(["fit", path.to_str().unwrap(), "--chart", chart.to_str().unwrap()])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("rater careless") && stdout.contains("rejected"), "{stdout}");
    let first = stdout.lines().find(|l| l.starts_with("anchor+wrapper") || l.starts_with("base ")).unwrap();
    assert!(first.starts_with("anchor+wrapper"), "the strongest method is listed first: {stdout}");
    assert!(std::fs::read_to_string(&chart).unwrap().contains("anchor+wrapper"));
    // A missing file is a clear error.
    let out = Command::new(env!("CARGO_BIN_EXE_pwrate")).args(["fit", "/nonexistent.jsonl"]).output().unwrap();
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("cannot read"));
}
