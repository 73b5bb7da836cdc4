//! Moving the anchor trainer's values between host rows and tensors: MLPs in the decoder's
//! row-major [out][in] layout as [in, out] tensors, and per-anchor tensors rebuilt when anchors
//! are grown and pruned.

use burn::tensor::{Device, Tensor, TensorData};
use pwgs_codec::anchor::Mlp;

use crate::train::params::tensor_values;

pub fn host_tensor(values: &[f32], shape: [usize; 2], device: &Device) -> Tensor<2> {
    Tensor::from_data(TensorData::new(values.to_vec(), shape), device)
}

/// Row-major [out][in] weights as an [in, out] tensor, and back.
pub fn transposed(values: &[f32], outputs: usize, inputs: usize) -> Vec<f32> {
    (0..inputs * outputs).map(|j| values[(j % outputs) * inputs + j / outputs]).collect()
}

pub fn mlp_tensors(m: &Mlp, device: &Device) -> [Tensor<2>; 4] {
    [
        host_tensor(&transposed(&m.w1, m.hidden, m.inputs), [m.inputs, m.hidden], device),
        host_tensor(&m.b1, [1, m.hidden], device),
        host_tensor(&transposed(&m.w2, m.outputs, m.hidden), [m.hidden, m.outputs], device),
        host_tensor(&m.b2, [1, m.outputs], device),
    ]
}

pub fn mlp_of(t: &[Tensor<2>]) -> Mlp {
    let [inputs, hidden] = t[0].dims();
    let outputs = t[2].dims()[1];
    Mlp {
        inputs,
        hidden,
        outputs,
        w1: transposed(&tensor_values(t[0].clone()), inputs, hidden),
        b1: tensor_values(t[1].clone()),
        w2: transposed(&tensor_values(t[2].clone()), hidden, outputs),
        b2: tensor_values(t[3].clone()),
    }
}

/// Rows `keep` of `t`, then the rows of `added` (flat, of `t`'s width).
pub fn kept_and_added(t: &Tensor<2>, keep: &[usize], added: &[f32]) -> Tensor<2> {
    let width = t.dims()[1];
    let values = tensor_values(t.clone());
    let mut rows: Vec<f32> = keep.iter().flat_map(|&r| values[r * width..(r + 1) * width].iter().copied()).collect();
    rows.extend_from_slice(added);
    host_tensor(&rows, [rows.len() / width, width], &t.device())
}
