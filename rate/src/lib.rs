//! pwrate's library (issue 17): judgments of a human A/B rating study, screened by golden
//! questions ([`judgments`]), and their Bayesian Elo fit ([`elo`]) with a chart ([`chart`]).

pub mod chart;
pub mod elo;
pub mod judgments;
