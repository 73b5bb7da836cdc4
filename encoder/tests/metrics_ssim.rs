//! SSIM and PSNR against the reference test vector of `shared/metrics-calib/README.md`, and the
//! SSIM gradient against central finite differences of an independent float64 SSIM.

use burn::tensor::{Device, Tensor, TensorData};
use pwgs_core::rgb_image::RgbImage;
use pwgs_encoder::metrics::psnr::{mse, psnr};
use pwgs_encoder::metrics::ssim::{SsimConvention, ssim};

const H: usize = 32;
const W: usize = 40;

/// The reference pair in float64, planar [3, H, W]: img1 = 0.5 + 0.4 sin(0.3x + 0.2y + c),
/// img2 = clip(img1 + 0.1 cos(0.7x - 0.5y + 2c), 0, 1).
fn reference_pair() -> (Vec<f64>, Vec<f64>) {
    let mut a = Vec::with_capacity(3 * H * W);
    let mut b = Vec::with_capacity(3 * H * W);
    for c in 0..3 {
        for y in 0..H {
            for x in 0..W {
                let (xf, yf, cf) = (x as f64, y as f64, c as f64);
                let v = 0.5 + 0.4 * (0.3 * xf + 0.2 * yf + cf).sin();
                a.push(v);
                b.push((v + 0.1 * (0.7 * xf - 0.5 * yf + 2.0 * cf).cos()).clamp(0.0, 1.0));
            }
        }
    }
    (a, b)
}

fn tensor(planar: &[f64], device: &Device) -> Tensor<4> {
    let values: Vec<f32> = planar.iter().map(|&v| v as f32).collect();
    Tensor::<4>::from_data(TensorData::new(values, [1, 3, H, W]), device)
}

fn scalar(t: Tensor<1>) -> f64 {
    t.into_scalar::<f32>() as f64
}

/// SSIM written out directly: every window summed in float64, out-of-image pixels read as zero.
/// `valid` keeps only windows inside the image. Shares nothing with the Burn version.
fn ssim_f64(a: &[f64], b: &[f64], valid: bool) -> f64 {
    let g: Vec<f64> = (0..11).map(|i| (-((i as f64 - 5.0).powi(2)) / 4.5).exp()).collect();
    let norm: f64 = g.iter().sum();
    let at = |img: &[f64], c: usize, y: isize, x: isize| {
        if y < 0 || x < 0 || y >= H as isize || x >= W as isize {
            0.0
        } else {
            img[(c * H + y as usize) * W + x as usize]
        }
    };
    let (c1, c2) = (1e-4, 9e-4);
    let (mut total, mut count) = (0.0, 0usize);
    let (lo, hi_y, hi_x) = if valid { (5, H - 5, W - 5) } else { (0, H, W) };
    for c in 0..3 {
        for y in lo..hi_y {
            for x in lo..hi_x {
                let mut m = [0.0f64; 5];
                for dy in 0..11 {
                    for dx in 0..11 {
                        let w = g[dy] * g[dx] / (norm * norm);
                        let (yy, xx) = (y as isize + dy as isize - 5, x as isize + dx as isize - 5);
                        let (p, q) = (at(a, c, yy, xx), at(b, c, yy, xx));
                        for (s, v) in m.iter_mut().zip([p, q, p * p, q * q, p * q]) {
                            *s += w * v;
                        }
                    }
                }
                let [ma, mb, aa, bb, ab] = m;
                let num = (2.0 * ma * mb + c1) * (2.0 * (ab - ma * mb) + c2);
                let den = (ma * ma + mb * mb + c1) * (aa - ma * ma + bb - mb * mb + c2);
                total += num / den;
                count += 1;
            }
        }
    }
    total / count as f64
}

#[test]
fn ssim_matches_the_reference_vector_in_both_conventions() {
    let (a, b) = reference_pair();
    let device = Device::flex();
    for (convention, expected) in [(SsimConvention::Valid, 0.8756655182), (SsimConvention::ZeroPadded, 0.8958516639)] {
        let value = scalar(ssim(tensor(&a, &device), tensor(&b, &device), convention));
        println!("SSIM {convention:?}: {value:.10} (reference {expected})");
        assert!((value - expected).abs() < 1e-6, "{convention:?}: {value} vs {expected}");
    }
    // The float64 reference used for the gradient check below is itself right.
    assert!((ssim_f64(&a, &b, true) - 0.8756655182).abs() < 1e-9);
    assert!((ssim_f64(&a, &b, false) - 0.8958516639).abs() < 1e-9);
}

#[test]
fn identical_images_score_one() {
    let (a, _) = reference_pair();
    let device = Device::flex();
    let value = scalar(ssim(tensor(&a, &device), tensor(&a, &device), SsimConvention::ZeroPadded));
    assert!((value - 1.0).abs() < 1e-6, "{value}");
}

#[test]
fn ssim_gradient_matches_finite_differences() {
    let (a, b) = reference_pair();
    let device = Device::flex().autodiff();
    for (convention, valid) in [(SsimConvention::ZeroPadded, false), (SsimConvention::Valid, true)] {
        let input = tensor(&a, &device).require_grad();
        let loss = ssim(input.clone(), tensor(&b, &device), convention);
        let grads = loss.backward();
        let grad: Vec<f32> = input.grad(&grads).unwrap().into_data().convert::<f32>().try_into_vec::<f32>().unwrap();
        // Corners, edges, the border band the valid convention drops, and the interior, in
        // every channel.
        let pixels = [(0, 0), (0, 17), (31, 39), (4, 4), (5, 5), (16, 20), (20, 34), (27, 2)];
        let scale = grad.iter().fold(0.0f32, |m, g| m.max(g.abs())) as f64;
        let mut worst = 0.0f64;
        for c in 0..3 {
            for &(y, x) in &pixels {
                let i = (c * H + y) * W + x;
                let step = 1e-5;
                let (mut plus, mut minus) = (a.clone(), a.clone());
                plus[i] += step;
                minus[i] -= step;
                let fd = (ssim_f64(&plus, &b, valid) - ssim_f64(&minus, &b, valid)) / (2.0 * step);
                let ad = grad[i] as f64;
                worst = worst.max((ad - fd).abs() / scale);
                assert!((ad - fd).abs() <= 1e-4 * scale, "{convention:?} c{c} y{y} x{x}: autodiff {ad:e}, fd {fd:e}");
            }
        }
        println!("{convention:?}: largest |autodiff - fd| / max|grad| = {worst:.2e}");
    }
}

#[test]
fn psnr_matches_the_reference_vector() {
    let (a, b) = reference_pair();
    let interleave = |planar: &[f64]| RgbImage {
        width: W as u32,
        height: H as u32,
        data: (0..H * W).flat_map(|p| (0..3).map(move |c| planar[c * H * W + p] as f32)).collect(),
    };
    let (a, b) = (interleave(&a), interleave(&b));
    let m = mse(&a, &b);
    assert!((m - 4.9998993874e-03).abs() < 1e-6 * 4.9998993874e-03, "MSE {m}");
    let p = psnr(&a, &b);
    println!("MSE {m:.10e} (reference 4.9998993874e-03), PSNR {p:.8} dB (reference 23.01038735)");
    assert!((p - 23.01038735).abs() < 1e-6 * 23.01038735, "PSNR {p}");
}
