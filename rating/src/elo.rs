//! Bayesian Elo: a Bradley-Terry model of pairwise judgments with a Gaussian prior, fitted by
//! Newton's method to its posterior mode, with the Laplace approximation (the inverse of the
//! negative Hessian there) as the posterior's covariance. A method's strength s (natural
//! log-odds units) makes it win against another with probability σ(s_a - s_b); Elo is
//! s x 400 / ln 10, so 400 Elo points are 10:1 odds.
//!
//! The prior N(0, τ²) on every strength keeps a method that always wins finite; the judgments
//! only identify differences, so strengths are reported relative to the methods' mean.

use anyhow::{Result, bail, ensure};
use nalgebra::{DMatrix, DVector};

use crate::judgments::Judgment;

/// Elo points per natural log-odds unit.
pub const ELO_PER_UNIT: f64 = 400.0 / std::f64::consts::LN_10;

/// The fitted strengths, one per method (sorted by name).
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    pub methods: Vec<String>,
    /// Posterior mode, in Elo above the methods' mean.
    pub elo: Vec<f64>,
    /// Posterior covariance of those centered values, in Elo².
    pub covariance: DMatrix<f64>,
    /// Judgments the fit used.
    pub judgments: usize,
}

impl Fit {
    /// Standard deviation of method `i`'s Elo.
    pub fn sd(&self, i: usize) -> f64 {
        self.covariance[(i, i)].sqrt()
    }

    /// Mean and standard deviation of Elo(i) - Elo(j) under the posterior.
    pub fn difference(&self, i: usize, j: usize) -> (f64, f64) {
        let c = &self.covariance;
        let var = c[(i, i)] + c[(j, j)] - 2.0 * c[(i, j)];
        (self.elo[i] - self.elo[j], var.max(0.0).sqrt())
    }

    /// The posterior probability that method `i` is the stronger of `i` and `j`.
    pub fn probability_stronger(&self, i: usize, j: usize) -> f64 {
        let (mean, sd) = self.difference(i, j);
        if sd == 0.0 {
            return if mean > 0.0 {
                1.0
            } else if mean < 0.0 {
                0.0
            } else {
                0.5
            };
        }
        0.5 * (1.0 + libm::erf(mean / (sd * std::f64::consts::SQRT_2)))
    }

    /// The chance that a rater prefers `i` to `j` on one comparison, at the posterior mode.
    pub fn win_probability(&self, i: usize, j: usize) -> f64 {
        1.0 / (1.0 + (-(self.elo[i] - self.elo[j]) / ELO_PER_UNIT).exp())
    }
}

/// Fits the judgments (none golden) with a prior standard deviation of `prior_elo` Elo points
/// on every method's strength.
pub fn fit(judgments: &[Judgment], prior_elo: f64) -> Result<Fit> {
    ensure!(prior_elo > 0.0 && prior_elo.is_finite(), "the prior's width must be a positive number of Elo points");
    let mut methods: Vec<String> = judgments.iter().flat_map(|j| [j.left.clone(), j.right.clone()]).collect();
    methods.sort();
    methods.dedup();
    if methods.len() < 2 {
        bail!("a fit needs judgments between at least two methods ({} found)", methods.len());
    }
    let index = |name: &str| methods.binary_search_by(|m| m.as_str().cmp(name)).expect("listed");
    let games: Vec<(usize, usize)> = judgments.iter().map(|j| (index(&j.winner), index(j.loser()))).collect();
    let m = methods.len();
    let precision = (ELO_PER_UNIT / prior_elo).powi(2);
    let mut s = DVector::<f64>::zeros(m);
    let mut hessian = DMatrix::<f64>::zeros(m, m);
    for _ in 0..100 {
        let mut gradient = -&s * precision;
        hessian = DMatrix::from_diagonal_element(m, m, -precision);
        for &(w, l) in &games {
            let p = 1.0 / (1.0 + (-(s[w] - s[l])).exp());
            gradient[w] += 1.0 - p;
            gradient[l] -= 1.0 - p;
            let curvature = p * (1.0 - p);
            hessian[(w, w)] -= curvature;
            hessian[(l, l)] -= curvature;
            hessian[(w, l)] += curvature;
            hessian[(l, w)] += curvature;
        }
        // The posterior is log-concave: -H is positive definite, and Newton's step solves
        // (-H) step = gradient.
        let Some(cholesky) = (-&hessian).cholesky() else { bail!("the posterior's curvature is not positive") };
        let step = cholesky.solve(&gradient);
        s += &step;
        if step.amax() < 1e-12 {
            break;
        }
    }
    let Some(inverse) = (-&hessian).try_inverse() else { bail!("the posterior's curvature is singular") };
    // Reported relative to the methods' mean: the judgments only tell differences, and the
    // prior's uncertainty about the common level would otherwise widen every interval alike.
    let centering = DMatrix::<f64>::identity(m, m) - DMatrix::from_element(m, m, 1.0 / m as f64);
    let centered = &centering * s;
    Ok(Fit {
        methods,
        elo: centered.iter().map(|v| v * ELO_PER_UNIT).collect(),
        covariance: &centering * inverse * centering.transpose() * (ELO_PER_UNIT * ELO_PER_UNIT),
        judgments: games.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn game(winner: &str, loser: &str) -> Judgment {
        Judgment {
            rater: "r".into(),
            view: "v".into(),
            crop: [0, 0],
            left: winner.into(),
            right: loser.into(),
            winner: winner.into(),
        }
    }

    #[test]
    fn even_records_give_equal_strengths_and_a_winner_ranks_first() {
        let even: Vec<Judgment> = (0..20).flat_map(|_| [game("a", "b"), game("b", "a")]).collect();
        let f = fit(&even, 400.0).unwrap();
        assert!(f.elo[0].abs() < 1e-9 && f.elo[1].abs() < 1e-9, "{:?}", f.elo);
        assert!((f.probability_stronger(0, 1) - 0.5).abs() < 1e-9);
        // 30 wins to 10: odds 3, about 191 Elo apart, shrunk a little by the prior.
        let mut lopsided: Vec<Judgment> = (0..30).map(|_| game("a", "b")).collect();
        lopsided.extend((0..10).map(|_| game("b", "a")));
        let f = fit(&lopsided, 400.0).unwrap();
        let (d, sd) = f.difference(0, 1);
        assert!(d > 150.0 && d < 191.0, "{d}");
        assert!(sd > 50.0 && sd < 150.0, "{sd}");
        assert!(f.probability_stronger(0, 1) > 0.95);
        assert!((f.win_probability(0, 1) + f.win_probability(1, 0) - 1.0).abs() < 1e-12);
        // A method that always wins stays finite under the prior.
        let f = fit(&(0..10).map(|_| game("a", "b")).collect::<Vec<_>>(), 400.0).unwrap();
        assert!(f.elo.iter().all(|e| e.is_finite()));
        assert!(fit(&[], 400.0).is_err() && fit(&lopsided, 0.0).is_err());
    }
}
