//! The player's window (eframe/egui on wgpu): a stream's views rendered by the decoder's GPU
//! renderer on the window's own device, with orbit and fly controls, the dataset's cameras and
//! ground truth, the wrapper's views, the stream's sections and the render's timings.

use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, channel};
use std::time::Instant;

use anyhow::{Context, Result};
use eframe::egui;
use pwgs_core::camera::Camera;
use pwgs_core::rgb_image::RgbImage;
use pwgs_render::gpu::{GpuRenderer, GpuScene, StageTimes};

use crate::dataset_views::DatasetViews;
use crate::file_dialog::{Choice, FileDialog};
use crate::headless::describe_times;
use crate::loaded::LoadedStream;
use crate::orbit::Orbit;
use crate::view_mode::{Painter, Renderer, ViewMode, picture};

/// What the window starts with.
#[derive(Debug, Clone, Default)]
pub struct PlayerOptions {
    pub stream: Option<PathBuf>,
    pub scene: Option<PathBuf>,
    /// Image downscale of `scene` (as at encoding).
    pub downscale: u32,
    /// The world's up for the free camera (the stream does not say; COLMAP captures have -y,
    /// Blender and nerfstudio ones +z).
    pub up: glam::Vec3,
    /// Save a screenshot of the whole window here once the first view is shown, then close
    /// (for scripted checks of the real window).
    pub window_screenshot: Option<PathBuf>,
    pub renderer: Renderer,
}

/// Opens the player's window and runs until it is closed.
pub fn run(options: PlayerOptions) -> Result<()> {
    let native = eframe::NativeOptions {
        renderer: eframe::Renderer::Wgpu,
        viewport: egui::ViewportBuilder::default().with_inner_size([1100.0, 700.0]).with_title("pwplay"),
        ..Default::default()
    };
    eframe::run_native("pwplay", native, Box::new(move |cc| Ok(Box::new(Player::new(cc, options)?))))
        .map_err(|e| anyhow::anyhow!("the player's window failed: {e}"))
}

/// The last rendered picture and what made it.
struct Shown {
    texture: egui::TextureHandle,
    key: RenderKey,
    times: StageTimes,
    /// The picture as rendered, for the screenshot button.
    image: RgbImage,
}

/// Everything a picture depends on: a new one is rendered only when this changes.
#[derive(Debug, Clone, Copy, PartialEq)]
struct RenderKey {
    orbit: Orbit,
    view: Option<usize>,
    width: u32,
    height: u32,
    mode: ViewMode,
    gain: f32,
    split: f32,
    generation: u64,
}

struct Player {
    gpu: GpuRenderer,
    /// The open stream, and its Gaussians on the GPU unless the CPU renders the pictures.
    stream: Option<(LoadedStream, Option<GpuScene>)>,
    /// A stream being decoded on another thread.
    loading: Option<(PathBuf, Receiver<Result<LoadedStream>>)>,
    /// Bumped for every stream opened, so that its first picture is rendered.
    generation: u64,
    dataset: Option<DatasetViews>,
    view: Option<usize>,
    orbit: Orbit,
    mode: ViewMode,
    render_scale: f32,
    residual_gain: f32,
    /// Ground truth left of this fraction of the width, the render right of it.
    split: f32,
    shown: Option<Shown>,
    last_frame: Option<Instant>,
    /// Frames per second of the window, averaged; meaningful while `continuous` is on.
    fps: f32,
    /// Re-render every frame (egui otherwise repaints only on input): for measuring frame rates.
    continuous: bool,
    message: String,
    path_field: String,
    file_dialog: FileDialog,
    screenshot_path: String,
    window_screenshot: Option<PathBuf>,
    renderer: Renderer,
}

impl Player {
    fn new(cc: &eframe::CreationContext, options: PlayerOptions) -> Result<Self> {
        let state = cc.wgpu_render_state.as_ref().ok_or_else(|| anyhow::anyhow!("eframe started without wgpu"))?;
        let gpu = GpuRenderer::with_device(state.device.clone(), state.queue.clone(), state.adapter.get_info())?;
        let dataset = match &options.scene {
            Some(dir) => Some(DatasetViews::load(dir, options.downscale)?),
            None => None,
        };
        let mut player = Self {
            gpu,
            stream: None,
            loading: None,
            generation: 0,
            view: dataset.as_ref().map(|_| 0),
            dataset,
            orbit: Orbit::around(glam::Vec3::ZERO, 1.0, options.up),
            mode: ViewMode::Shown,
            render_scale: 1.0,
            residual_gain: crate::headless::RESIDUAL_GAIN,
            split: 0.5,
            shown: None,
            last_frame: None,
            fps: 0.0,
            continuous: false,
            message: String::new(),
            path_field: options.stream.as_ref().map(|p| p.display().to_string()).unwrap_or_default(),
            file_dialog: FileDialog::default(),
            screenshot_path: "pwplay-screenshot.png".into(),
            window_screenshot: options.window_screenshot,
            renderer: options.renderer,
        };
        if let Some(path) = options.stream {
            player.open(path, &cc.egui_ctx);
        }
        Ok(player)
    }

    /// Starts decoding `path` on another thread; the window shows a spinner meanwhile.
    fn open(&mut self, path: PathBuf, ctx: &egui::Context) {
        let (sender, receiver) = channel();
        let (ctx, source) = (ctx.clone(), path.clone());
        std::thread::spawn(move || {
            // The window may have closed; then no one waits for the stream.
            let _ = sender.send(LoadedStream::open(&source));
            ctx.request_repaint();
        });
        self.message = format!("decoding {}", path.display());
        self.loading = Some((path, receiver));
    }

    /// Takes a decoded stream when it is ready.
    fn poll_loading(&mut self, ctx: &egui::Context) {
        let Some((path, receiver)) = &self.loading else { return };
        let Ok(result) = receiver.try_recv() else { return };
        // The CPU renderer needs nothing on the GPU.
        let on_cpu = self.renderer.on_cpu(&self.gpu);
        let prepared = result.and_then(|stream| {
            let prepared = (!on_cpu)
                .then(|| self.gpu.prepare(&stream.scene))
                .transpose()
                .with_context(|| format!("cannot show {}", path.display()))?;
            Ok((stream, prepared))
        });
        match prepared {
            Ok((stream, prepared)) => {
                self.orbit = match (&self.dataset, self.view) {
                    (Some(d), Some(i)) => d.orbit(i),
                    _ => Orbit::for_scene(&stream.scene, self.orbit.up),
                };
                self.message = format!("opened {}", path.display());
                self.stream = Some((stream, prepared));
                self.generation += 1;
            }
            Err(e) => {
                self.message = format!("error: {e:#}");
                // A scripted window check must not wait forever for a picture that will
                // not come: it gets the error frame instead.
                if let Some(path) = self.window_screenshot.take() {
                    request_window_screenshot(ctx, path);
                }
            }
        }
        self.loading = None;
    }

    fn side_panel(&mut self, ui: &mut egui::Ui) {
        ui.heading("pwplay");
        ui.horizontal(|ui| {
            ui.text_edit_singleline(&mut self.path_field);
            if ui.button("Open").clicked() && !self.path_field.is_empty() {
                self.open(PathBuf::from(self.path_field.clone()), ui.ctx());
            }
            if ui.add_enabled(!self.file_dialog.is_open(), egui::Button::new("Browse…")).clicked() {
                self.file_dialog.open(Path::new(&self.path_field), ui.ctx());
            }
        });
        match self.file_dialog.poll() {
            Some(Choice::Chosen(path)) => {
                self.path_field = path.display().to_string();
                self.open(path, ui.ctx());
            }
            Some(Choice::None) => {
                self.message = "no file chosen (the file dialog needs the XDG desktop portal or zenity; \
                                the path field and dropping a file always work)"
                    .into()
            }
            None => {}
        }
        ui.label("or drop a .pwb file on the window");
        if self.loading.is_some() {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label(&self.message);
            });
        } else if !self.message.is_empty() {
            ui.label(&self.message);
        }
        ui.separator();
        let has_wrapper = self.stream.as_ref().is_some_and(|(s, _)| s.scene.wrapper.is_some());
        for mode in ViewMode::ALL {
            ui.add_enabled_ui(has_wrapper || !mode.needs_wrapper(), |ui| {
                ui.radio_value(&mut self.mode, mode, mode.label());
            });
        }
        if self.mode == ViewMode::Residual {
            ui.add(egui::Slider::new(&mut self.residual_gain, 1.0..=16.0).text("residual gain"));
        }
        ui.add(egui::Slider::new(&mut self.render_scale, 0.25..=1.0).text("render scale"));
        self.up_choice(ui);
        if let Some(dataset) = &self.dataset {
            let names = dataset.names();
            let selected = self.view.map_or("free camera".to_string(), |i| names[i].clone());
            let mut view = self.view;
            egui::ComboBox::from_label("dataset camera").selected_text(selected).show_ui(ui, |ui| {
                ui.selectable_value(&mut view, None, "free camera");
                for (i, name) in names.iter().enumerate() {
                    ui.selectable_value(&mut view, Some(i), name);
                }
            });
            if view != self.view {
                self.view = view;
                if let Some(i) = view {
                    self.orbit = dataset.orbit(i);
                }
            }
            if self.view.is_some() {
                ui.add(egui::Slider::new(&mut self.split, 0.0..=1.0).text("ground truth | render"));
            }
        }
        ui.separator();
        ui.checkbox(&mut self.continuous, "render every frame");
        if self.continuous {
            ui.label(format!("{:.1} frames/s (window)", self.fps));
        }
        if let Some(s) = &self.shown {
            let per_second = 1.0 / s.times.total().as_secs_f64().max(1e-9);
            ui.label(format!("{}x{}, {per_second:.1} pictures/s", s.key.width, s.key.height));
            ui.label(describe_times(&s.times));
        }
        ui.label(self.renderer.describe(&self.gpu));
        ui.horizontal(|ui| {
            ui.text_edit_singleline(&mut self.screenshot_path);
            if ui.button("Screenshot").clicked()
                && let Some(s) = &self.shown
            {
                self.message = match s.image.save_png(Path::new(&self.screenshot_path)) {
                    Ok(()) => format!("wrote {}", self.screenshot_path),
                    Err(e) => format!("error: {e}"),
                };
            }
        });
        if let Some((stream, _)) = &self.stream {
            ui.separator();
            egui::ScrollArea::vertical().show(ui, |ui| {
                for line in stream.describe() {
                    ui.monospace(line);
                }
            });
        }
    }

    /// The world's up of the free camera: choosing one restarts the orbit around the stream's
    /// center.
    fn up_choice(&mut self, ui: &mut egui::Ui) {
        const UPS: [(&str, glam::Vec3); 4] = [
            ("-y (COLMAP, OpenCV)", glam::Vec3::NEG_Y),
            ("+z (Blender, nerfstudio)", glam::Vec3::Z),
            ("+y", glam::Vec3::Y),
            ("-z", glam::Vec3::NEG_Z),
        ];
        let current = UPS.iter().find(|(_, v)| (*v - self.orbit.up).length() < 1e-3).map_or("custom", |(name, _)| name);
        let mut chosen = None;
        egui::ComboBox::from_label("up").selected_text(current).show_ui(ui, |ui| {
            for (name, v) in UPS {
                if ui.selectable_label(current == name, name).clicked() {
                    chosen = Some(v);
                }
            }
        });
        if let Some(up) = chosen {
            self.orbit = match &self.stream {
                Some((s, _)) => Orbit::for_scene(&s.scene, up),
                None => Orbit::around(self.orbit.target, self.orbit.distance, up),
            };
            self.view = None;
        }
    }

    /// Applies the mouse and keyboard to the orbit.
    fn steer(&mut self, ui: &egui::Ui, response: &egui::Response) {
        let before = self.orbit;
        let drag = response.drag_delta();
        if response.dragged_by(egui::PointerButton::Primary) {
            self.orbit.rotate(-drag.x * 0.005, -drag.y * 0.005);
        }
        if response.dragged_by(egui::PointerButton::Secondary) {
            self.orbit.pan(-drag.x * 0.002, drag.y * 0.002);
        }
        let (scroll, keys) = ui.input(|i| {
            let key = |k: egui::Key| if i.key_down(k) { 1.0f32 } else { 0.0 };
            let keys = [
                key(egui::Key::W) - key(egui::Key::S),
                key(egui::Key::D) - key(egui::Key::A),
                key(egui::Key::E) - key(egui::Key::Q),
            ];
            (i.smooth_scroll_delta.y, keys)
        });
        if response.hovered() && scroll != 0.0 {
            self.orbit.zoom((-scroll * 0.002).exp());
        }
        if keys != [0.0; 3] {
            self.orbit.fly(keys[0] * 0.02, keys[1] * 0.02, keys[2] * 0.02);
            ui.ctx().request_repaint();
        }
        if self.orbit != before {
            self.view = None;
        }
    }

    /// The camera of the picture for an area of `size` points.
    fn camera(&self, size: egui::Vec2) -> Option<Camera> {
        let scaled = |v: f32| ((v * self.render_scale).round() as u32).max(1);
        match (&self.dataset, self.view) {
            (Some(d), Some(i)) => {
                let c = d.camera(i);
                c.resized(scaled(c.width as f32), scaled(c.height as f32)).ok()
            }
            _ => self.orbit.camera(scaled(size.x), scaled(size.y)).ok(),
        }
    }

    fn central(&mut self, ui: &mut egui::Ui) {
        let Some((stream, prepared)) = &self.stream else {
            ui.centered_and_justified(|ui| {
                ui.label("open a stream: pwplay SCENE.pwb, the path field, Browse…, or drop a file")
            });
            return;
        };
        let size = ui.available_size();
        let Some(camera) = self.camera(size) else { return };
        let key = RenderKey {
            orbit: self.orbit,
            view: self.view,
            width: camera.width,
            height: camera.height,
            mode: self.mode,
            gain: self.residual_gain,
            split: self.split,
            generation: self.generation,
        };
        if self.continuous || self.shown.as_ref().is_none_or(|s| s.key != key) {
            let painter = match prepared {
                Some(prepared) => Painter::Gpu(&self.gpu, prepared),
                None => Painter::Cpu,
            };
            match picture(painter, &stream.scene, &camera, self.mode, self.residual_gain) {
                Ok((mut image, times)) => {
                    if let (Some(d), Some(i)) = (&self.dataset, self.view) {
                        d.overlay_ground_truth(i, &mut image, self.split);
                    }
                    let color = egui::ColorImage::from_rgb(
                        [image.width as usize, image.height as usize],
                        image.to_rgb8().as_raw(),
                    );
                    let texture = match self.shown.take() {
                        Some(mut s) => {
                            s.texture.set(color, egui::TextureOptions::LINEAR);
                            s.texture
                        }
                        None => ui.ctx().load_texture("view", color, egui::TextureOptions::LINEAR),
                    };
                    self.shown = Some(Shown { texture, key, times, image });
                }
                Err(e) => self.message = format!("error: {e}"),
            }
        }
        let Some(shown) = &self.shown else { return };
        let aspect = shown.key.width as f32 / shown.key.height as f32;
        let fit = egui::vec2(size.x.min(size.y * aspect), size.y.min(size.x / aspect));
        let response = ui
            .centered_and_justified(|ui| {
                ui.add(egui::Image::new((shown.texture.id(), fit)).sense(egui::Sense::click_and_drag()))
            })
            .inner;
        self.steer(ui, &response);
        if self.continuous {
            ui.ctx().request_repaint();
        }
        if let Some(path) = self.window_screenshot.take() {
            request_window_screenshot(ui.ctx(), path);
        }
    }
}

/// Saves the next frame of the whole window to `path`, then closes the window.
fn request_window_screenshot(ctx: &egui::Context, path: PathBuf) {
    let closer = ctx.clone();
    ctx.request_screenshot(move |image| {
        let [w, h] = image.size;
        let data = image.pixels.iter().flat_map(|c| [c.r(), c.g(), c.b()].map(|v| f32::from(v) / 255.0)).collect();
        let shot = RgbImage { width: w as u32, height: h as u32, data };
        match shot.save_png(&path) {
            Ok(()) => eprintln!("wrote {} ({w}x{h})", path.display()),
            Err(e) => eprintln!("error: cannot write the window's screenshot: {e}"),
        }
        closer.send_viewport_cmd(egui::ViewportCommand::Close);
    });
    ctx.request_repaint();
}

impl eframe::App for Player {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let now = Instant::now();
        if let Some(last) = self.last_frame {
            let dt = now.duration_since(last).as_secs_f32().max(1e-6);
            self.fps = 0.9 * self.fps + 0.1 / dt;
        }
        self.last_frame = Some(now);
        self.poll_loading(ui.ctx());
        let dropped = ui.input(|i| i.raw.dropped_files.first().map(|f| f.path().to_path_buf()));
        if let Some(path) = dropped {
            self.path_field = path.display().to_string();
            self.open(path, ui.ctx());
        }
        egui::Panel::left("controls").default_size(340.0).show(ui, |ui| self.side_panel(ui));
        egui::CentralPanel::default().show(ui, |ui| self.central(ui));
    }
}
