//! The metric weights as the encoder's tests find them: `../shared/weights` first, then where
//! `pwenc` looks. Weights found nowhere skip a test outside CI and fail it in CI (see
//! `shared_data`); weights found but unreadable or corrupt always fail it.

use std::path::PathBuf;

use pwgs_encoder::metrics::weights::{WeightsError, default_dirs};

use crate::shared_data;

/// Where the tests look for weight files.
pub fn search_dirs() -> Vec<PathBuf> {
    let mut dirs = vec![shared_data::shared_dir().join("weights")];
    dirs.extend(default_dirs());
    dirs
}

/// What a metric's `load` gave: the metric, or `None` (after [`shared_data::absent`]) when the
/// weights are missing; any other error fails the test.
pub fn loaded<T>(result: Result<T, WeightsError>) -> Option<T> {
    match result {
        Ok(value) => Some(value),
        Err(missing @ WeightsError::Missing { .. }) => {
            shared_data::absent(missing);
            None
        }
        Err(e) => panic!("the weights are present but do not load: {e}"),
    }
}
