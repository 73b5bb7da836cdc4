//! The scene normalization: the frame a scene's coordinates are normalized to (the stream
//! header's center and scale), in which the wrapper's Plücker moments are taken.

use glam::Vec3;

/// A scene's normalization: normalized = (world - center) / scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneFrame {
    pub center: Vec3,
    pub scale: f32,
}
