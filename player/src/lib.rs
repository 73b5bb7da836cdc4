//! pwplay, the interactive player of pwgs streams: the decoder's GPU renderer
//! ([`pwgs_render::gpu`]) in an eframe/egui window on the same wgpu device, and a headless
//! mode through the same path. No codec logic lives here: decoding, rendering and the wrapper
//! are the decoder library's.

pub mod app;
pub mod dataset_views;
pub mod file_dialog;
pub mod headless;
pub mod loaded;
pub mod orbit;
pub mod view_mode;
