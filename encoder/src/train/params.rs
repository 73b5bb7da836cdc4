//! The trainable Gaussians as tensors, and their host-side form for the operations that change
//! the number of Gaussians (densification, pruning) or inspect every value (NaN checks).

use burn::tensor::{Device, Tensor, TensorData};
use pwgs_core::gaussians::{Gaussians, MAX_SH_DEGREE, sh_coeff_count};

/// Number of parameter tensors.
pub const PARAM_COUNT: usize = 5;

/// Names of the parameter tensors, in [`SplatParams::to_host`] order, for messages.
pub const PARAM_NAMES: [&str; PARAM_COUNT] = ["means", "log_scales", "rotations", "opacity_logits", "sh"];

/// Gaussian parameters as tensors on the training device (without autodiff). SH is always
/// held at the full degree [`MAX_SH_DEGREE`]; training renders only the active bands.
#[derive(Debug, Clone)]
pub struct SplatParams {
    /// [N, 3]
    pub means: Tensor<2>,
    /// [N, 3]
    pub log_scales: Tensor<2>,
    /// [N, 4]
    pub rotations: Tensor<2>,
    /// [N]
    pub opacity_logits: Tensor<1>,
    /// [N, 16, 3]
    pub sh: Tensor<3>,
}

/// Values per Gaussian of each parameter tensor.
pub const ROW_WIDTHS: [usize; PARAM_COUNT] = [3, 3, 4, 1, sh_coeff_count(MAX_SH_DEGREE) * 3];

/// One parameter (or optimizer moment) as host rows: `data.len() = rows * width`.
#[derive(Debug, Clone, PartialEq)]
pub struct Rows {
    pub data: Vec<f32>,
    pub width: usize,
}

impl Rows {
    pub fn zeros(rows: usize, width: usize) -> Self {
        Self { data: vec![0.0; rows * width], width }
    }

    pub fn len(&self) -> usize {
        self.data.len() / self.width
    }

    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    pub fn row(&self, i: usize) -> &[f32] {
        &self.data[i * self.width..(i + 1) * self.width]
    }

    pub fn row_mut(&mut self, i: usize) -> &mut [f32] {
        &mut self.data[i * self.width..(i + 1) * self.width]
    }
}

pub(crate) fn tensor_values<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data().convert::<f32>().try_into_vec::<f32>().expect("f32 tensor data")
}

/// Builds a tensor of shape [rows, ...] from host rows.
pub(crate) fn rows_tensor<const D: usize>(rows: &Rows, device: &Device) -> Tensor<D> {
    let n = rows.len();
    let shape: Vec<usize> = match D {
        1 => vec![n],
        2 => vec![n, rows.width],
        3 => vec![n, rows.width / 3, 3],
        _ => unreachable!("parameters have rank 1 to 3"),
    };
    Tensor::from_data(TensorData::new(rows.data.clone(), shape), device)
}

impl SplatParams {
    /// Uploads Gaussians, padding SH to the full degree with zeros.
    pub fn from_gaussians(g: &Gaussians, device: &Device) -> Self {
        let full = sh_coeff_count(MAX_SH_DEGREE) * 3;
        let own = g.coeffs_per_channel() * 3;
        let mut sh = Rows::zeros(g.len(), full);
        for i in 0..g.len() {
            sh.row_mut(i)[..own].copy_from_slice(g.sh_of(i));
        }
        let flat = |v: &[[f32; 3]]| Rows { data: v.iter().flatten().copied().collect(), width: 3 };
        Self::from_host(
            &[
                flat(&g.means),
                flat(&g.log_scales),
                Rows { data: g.rotations.iter().flatten().copied().collect(), width: 4 },
                Rows { data: g.opacity_logits.clone(), width: 1 },
                sh,
            ],
            device,
        )
    }

    /// Uploads host rows (in [`PARAM_NAMES`] order).
    pub fn from_host(rows: &[Rows; PARAM_COUNT], device: &Device) -> Self {
        Self {
            means: rows_tensor(&rows[0], device),
            log_scales: rows_tensor(&rows[1], device),
            rotations: rows_tensor(&rows[2], device),
            opacity_logits: rows_tensor(&rows[3], device),
            sh: rows_tensor(&rows[4], device),
        }
    }

    /// Downloads every parameter as host rows (in [`PARAM_NAMES`] order).
    pub fn to_host(&self) -> [Rows; PARAM_COUNT] {
        let values = [
            tensor_values(self.means.clone()),
            tensor_values(self.log_scales.clone()),
            tensor_values(self.rotations.clone()),
            tensor_values(self.opacity_logits.clone()),
            tensor_values(self.sh.clone()),
        ];
        let mut i = 0;
        values.map(|data| {
            let rows = Rows { data, width: ROW_WIDTHS[i] };
            i += 1;
            rows
        })
    }

    pub fn len(&self) -> usize {
        self.means.dims()[0]
    }

    /// The name of the first parameter tensor holding NaN or infinity, computed on the device:
    /// `x - x` is 0 for a finite `x` and NaN otherwise, so each tensor's sum of it is NaN
    /// exactly when the tensor has a non-finite value. Reads five numbers back.
    pub fn first_non_finite(&self) -> Option<&'static str> {
        let probe = |t: Tensor<1>| (t.clone() - t).sum();
        let flat = |t: Tensor<2>| t.flatten::<1>(0, 1);
        let sums = Tensor::cat(
            vec![
                probe(flat(self.means.clone())),
                probe(flat(self.log_scales.clone())),
                probe(flat(self.rotations.clone())),
                probe(self.opacity_logits.clone()),
                probe(self.sh.clone().flatten::<1>(0, 2)),
            ],
            0,
        );
        tensor_values(sums).iter().zip(PARAM_NAMES).find(|(v, _)| v.is_nan()).map(|(_, name)| name)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The Gaussians with SH truncated to `degree`.
    pub fn to_gaussians(&self, degree: u32) -> Gaussians {
        let [means, log_scales, rotations, opacity, sh] = self.to_host();
        let keep = sh_coeff_count(degree) * 3;
        let arrays3 = |r: &Rows| r.data.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        Gaussians {
            means: arrays3(&means),
            log_scales: arrays3(&log_scales),
            rotations: rotations.data.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect(),
            opacity_logits: opacity.data,
            sh_degree: degree,
            sh: (0..sh.len()).flat_map(|i| sh.row(i)[..keep].to_vec()).collect(),
        }
    }
}
