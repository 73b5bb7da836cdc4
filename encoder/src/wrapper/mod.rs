//! The perceptual wrapper's encoder side: the synthesis network f on Burn ([`synthesis`]) and
//! stage 2 of training, where f trains jointly with either base's Gaussians ([`stage`]).

pub mod stage;
pub mod synthesis;
