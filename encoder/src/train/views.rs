//! The training views' target images on the training device. A view is uploaded the first
//! time a step draws it and kept there while the views kept so far fit in a byte budget; over
//! the budget it stays on the host and is uploaded at each draw (one image's bytes a step,
//! where a full-resolution capture's images can outgrow the device: 300 views at 1600x1063 hold
//! 6.1 GB as f32).

use burn::tensor::{Device, Tensor, TensorData};
use pwgs_core::camera::Camera;
use pwgs_core::rgb_image::RgbImage;
use pwgs_dataset::scene::View;

/// The default budget: 8 GiB, every view of a 300-view capture at 1600x1063.
pub const DEFAULT_IMAGE_BUDGET: usize = 8 << 30;

/// A view's image: on the device (boxed: a tensor's handle is ten times an image's), or on
/// the host.
enum Target {
    Resident(Box<Tensor<3>>),
    Host(RgbImage),
}

/// The training views: cameras and target images [H, W, 3].
pub struct TrainViews {
    cameras: Vec<Camera>,
    targets: Vec<Target>,
    budget: usize,
    resident_bytes: usize,
    device: Device,
}

/// An image as an [H, W, 3] tensor on `device`.
pub(crate) fn hwc_tensor(image: &RgbImage, device: &Device) -> Tensor<3> {
    let (w, h) = (image.width as usize, image.height as usize);
    Tensor::from_data(TensorData::new(image.data.clone(), [h, w, 3]), device)
}

impl TrainViews {
    /// `views` in order, kept on `device` within `budget` bytes.
    pub fn new(views: &[View], budget: usize, device: &Device) -> Self {
        Self {
            cameras: views.iter().map(|v| v.camera).collect(),
            targets: views.iter().map(|v| Target::Host(v.image.clone())).collect(),
            budget,
            resident_bytes: 0,
            device: device.clone(),
        }
    }

    /// The budget for the views uploaded from now on.
    pub fn set_budget(&mut self, budget: usize) {
        self.budget = budget;
    }

    pub fn len(&self) -> usize {
        self.cameras.len()
    }

    pub fn is_empty(&self) -> bool {
        self.cameras.is_empty()
    }

    pub fn cameras(&self) -> &[Camera] {
        &self.cameras
    }

    /// View `i`'s camera and target image.
    pub fn get(&mut self, i: usize) -> (Camera, Tensor<3>) {
        let target = match &self.targets[i] {
            Target::Resident(t) => (**t).clone(),
            Target::Host(image) => {
                let bytes = image.data.len() * size_of::<f32>();
                let t = hwc_tensor(image, &self.device);
                if self.resident_bytes + bytes <= self.budget {
                    self.targets[i] = Target::Resident(Box::new(t.clone()));
                    self.resident_bytes += bytes;
                }
                t
            }
        };
        (self.cameras[i], target)
    }

    /// Bytes of target images held on the device.
    pub fn resident_bytes(&self) -> usize {
        self.resident_bytes
    }
}

#[cfg(test)]
mod tests {
    use pwgs_core::random::axis_camera;

    use super::*;

    fn view(seed: u32) -> View {
        let camera = axis_camera(4, 3, 5.0, 5.0, 2.0, 1.5);
        let data = (0..36).map(|i| ((i * 7 + seed) % 11) as f32 / 10.0).collect();
        View { name: seed.to_string(), camera, image: RgbImage { width: 4, height: 3, data } }
    }

    /// Over the budget, a view is uploaded at each draw: every view reads back as loaded,
    /// whichever side holds it, and only views within the budget stay on the device.
    #[test]
    fn views_beyond_the_budget_stay_on_the_host_and_read_the_same() {
        let views: Vec<View> = (0..3).map(view).collect();
        let one = 36 * size_of::<f32>();
        let device = Device::flex();
        for (budget, resident) in [(usize::MAX, 3), (2 * one + 1, 2), (one - 1, 0)] {
            let mut t = TrainViews::new(&views, usize::MAX, &device);
            t.set_budget(budget);
            for _ in 0..2 {
                for (i, v) in views.iter().enumerate() {
                    let (camera, target) = t.get(i);
                    assert_eq!(camera, v.camera);
                    assert_eq!(target.dims(), [3, 4, 3]);
                    assert_eq!(crate::train::params::tensor_values(target), v.image.data);
                }
                assert_eq!(t.resident_bytes(), resident * one, "budget {budget}");
            }
        }
    }
}
