//! The perceptual wrapper's encoder side: the synthesis network f on Burn ([`synthesis`]) and
//! stage 2 of training, where f trains jointly with either base's Gaussians ([`stage`]), and
//! its throughput on a device ([`throughput`]).

pub mod stage;
pub mod synthesis;
pub mod throughput;
