//! Wasserstein Distortion on feature arrays (no VGG) against the test vectors of
//! `shared/metrics-calib/README.md` (PyTorch-port conventions), in float64 and in float32.

use burn::tensor::{DType, Device, Tensor, TensorData};
use pwgs_encoder::metrics::sigma_map::SigmaMap;
use pwgs_encoder::metrics::wasserstein::{lowpass, wasserstein_distortion};

const DTYPES: [DType; 2] = [DType::F64, DType::F32];

fn tensor(values: Vec<f64>, shape: [usize; 4], device: &Device, dtype: DType) -> Tensor<4> {
    Tensor::from_data(TensorData::new(values, shape), (device, dtype))
}

fn values<const D: usize>(t: Tensor<D>) -> Vec<f64> {
    t.into_data().convert::<f64>().try_into_vec::<f64>().unwrap()
}

fn assert_relative(value: f64, expected: f64, tolerance: f64, what: &str) {
    let error = ((value - expected) / expected).abs();
    println!("{what}: {value:.12e} (reference {expected:.12e}, relative error {error:.1e})");
    assert!(error <= tolerance, "{what}: {value} vs {expected}");
}

#[test]
fn lowpass_vectors() {
    let device = Device::flex();
    for dtype in DTYPES {
        let x = tensor((0..9).map(f64::from).collect(), [1, 1, 3, 3], &device, dtype);
        assert_eq!(values(lowpass(x.clone(), 1)), [0.75, 1.5, 1.5, 2.5, 4.0, 3.5, 3.0, 4.5, 3.75], "LP1 {dtype:?}");
        assert_eq!(values(lowpass(x, 2)), [0.75, 1.5, 3.0, 3.75], "LP2 {dtype:?}");
    }
}

/// T1: a[0,y,x] = 4y + x, b = a mirrored left to right, log2σ = 2 everywhere.
fn t1(device: &Device, dtype: DType) -> (Tensor<4>, Tensor<4>) {
    let a = (0..16).map(f64::from).collect();
    let b = (0..16).map(|i| f64::from(4 * (i / 4) + 3 - i % 4)).collect();
    (tensor(a, [1, 1, 4, 4], device, dtype), tensor(b, [1, 1, 4, 4], device, dtype))
}

#[test]
fn t1_value_and_gradient() {
    const EXPECTED_GRADIENT: [f64; 16] = [
        -0.0016647962,
        -0.0016847801,
        -0.0010306852,
        -0.0006650249,
        -0.0069068646,
        -0.0053582164,
        -0.0029921814,
        -0.0016966677,
        -0.0141097122,
        -0.0104191999,
        -0.0057679927,
        -0.0031354681,
        -0.0099821326,
        -0.0071761816,
        -0.0038898832,
        -0.0020706775,
    ];
    let device = Device::flex().autodiff();
    for dtype in DTYPES {
        let (a, b) = t1(&device, dtype);
        let a = a.require_grad();
        let wd = wasserstein_distortion(a.clone(), b, &SigmaMap::constant(4, 4, 2.0));
        let grads = wd.backward();
        assert_relative(values(wd)[0], 0.05331807661717393, 1e-6, &format!("T1 {dtype:?}"));
        let gradient = values(a.grad(&grads).unwrap());
        let worst = gradient.iter().zip(EXPECTED_GRADIENT).map(|(g, e)| (g - e).abs()).fold(0.0, f64::max);
        println!("T1 gradient {dtype:?}: largest absolute error {worst:.1e}");
        assert!(worst <= 1e-5, "T1 gradient {dtype:?}: {gradient:?}");
    }
}

/// T2/T3 arrays (2 x 9 x 7): idx = c·63 + y·7 + x, A = (37·idx mod 101)/100,
/// B = ((73·idx + 19) mod 103)/102.
fn t2(device: &Device, dtype: DType) -> (Tensor<4>, Tensor<4>) {
    let a = (0..126).map(|i| f64::from((37 * i) % 101) / 100.0).collect();
    let b = (0..126).map(|i| f64::from((73 * i + 19) % 103) / 102.0).collect();
    (tensor(a, [1, 2, 9, 7], device, dtype), tensor(b, [1, 2, 9, 7], device, dtype))
}

#[test]
fn t2_constant_sigma() {
    let device = Device::flex();
    let cases = [
        (0.0, 0.160991383656),
        (0.5, 0.090179617849),
        (1.0, 0.019367852041),
        (1.5, 0.009898047283),
        (2.0, 0.000725757089),
        (3.0, 0.001106531516),
        (4.5, 0.000384835448),
    ];
    for dtype in DTYPES {
        for (log2_sigma, expected) in cases {
            let (a, b) = t2(&device, dtype);
            let wd = wasserstein_distortion(a, b, &SigmaMap::constant(9, 7, log2_sigma));
            // The references are given to 12 decimals, i.e. 1e-9 relative at the smallest.
            assert_relative(values(wd)[0], expected, 1e-6, &format!("T2 {dtype:?} log2σ={log2_sigma}"));
        }
    }
}

#[test]
fn t3_spatially_varying_sigma() {
    let device = Device::flex();
    let map = SigmaMap {
        height: 9,
        width: 7,
        values: (0..63)
            .map(|i| f64::from((i / 7 - 4) * (i / 7 - 4) + (i % 7 - 3) * (i % 7 - 3)).sqrt().min(5.0))
            .collect(),
    };
    for dtype in DTYPES {
        let (a, b) = t2(&device, dtype);
        assert_relative(values(wasserstein_distortion(a, b, &map))[0], 0.003920617249, 1e-6, &format!("T3 {dtype:?}"));
    }
}

#[test]
fn identical_arrays_give_zero() {
    let device = Device::flex();
    let (a, _) = t2(&device, DType::F32);
    for log2_sigma in [0.0, 2.5, 5.0] {
        let wd = wasserstein_distortion(a.clone(), a.clone(), &SigmaMap::constant(9, 7, log2_sigma));
        assert_eq!(values(wd)[0], 0.0);
    }
}
