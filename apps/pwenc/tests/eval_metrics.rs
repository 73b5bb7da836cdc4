//! `pwenc --eval --eval-metrics`: the perceptual metrics per test view and their mean in the
//! report, agreeing with `pweval` on the saved renders. Needs the metric weights (see
//! `shared_weights` for when their absence skips).

#[path = "../../../render/tests/shared_data/mod.rs"]
mod shared_data;
#[path = "../../../encoder/tests/shared_weights/mod.rs"]
mod shared_weights;

use std::process::{Command, Output};

use burn::tensor::Device;
use pwgs_encoder::metrics::dists::Dists;
use serde_json::Value;

fn run(program: &str, args: &[&str]) -> Output {
    Command::new(program).args(args).output().unwrap()
}

fn success(out: Output) -> Output {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    out
}

#[test]
fn eval_reports_perceptual_metrics_per_view_and_their_mean() {
    let dirs = shared_weights::search_dirs();
    if shared_weights::loaded(Dists::load(&dirs, &Device::flex())).is_none() {
        return;
    }
    let weights = dirs.iter().find(|d| d.join("dists_alpha_beta.safetensors").is_file()).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let dir = |name: &str| tmp.path().join(name).to_str().unwrap().to_string();
    let pwenc = env!("CARGO_BIN_EXE_pwenc");
    success(run(pwenc, &["generate-scene", &dir("scene"), "--width", "64", "--height", "64", "--views", "9"]));
    let metrics = ["--eval-metrics", "lpips,dists,wd", "--eval-wd-log2-sigma", "3"];
    let mut args =
        vec![dir("scene"), "--base".into(), "3dgs".into(), "--no-wrapper".into(), "--iters".into(), "5".into()];
    args.extend(["--eval".into(), dir("eval")]);
    args.extend(["--weights".into(), weights.to_str().unwrap().into(), "--report".into(), dir("r.json")]);
    args.extend(metrics.iter().map(|s| s.to_string()));
    let out = success(run(pwenc, &args.iter().map(String::as_str).collect::<Vec<_>>()));
    assert!(String::from_utf8_lossy(&out.stdout).contains("DISTS"), "the log line names the metrics");

    let report: Value = serde_json::from_slice(&std::fs::read(dir("r.json")).unwrap()).unwrap();
    let views = report["views"].as_array().unwrap();
    assert!(!views.is_empty());
    let gt = format!("{}/gt", dir("eval"));
    let pweval_args = [
        &dir("eval"),
        &gt,
        "--metric",
        "lpips,dists,wd",
        "--log2-sigma",
        "3",
        "--weights",
        weights.to_str().unwrap(),
        "--json",
    ];
    let pweval: Value =
        serde_json::from_slice(&success(run(env!("CARGO_BIN_EXE_pweval"), &pweval_args)).stdout).unwrap();
    for name in ["lpips", "dists", "wd"] {
        let values: Vec<f64> = views.iter().map(|v| v[name].as_f64().unwrap()).collect();
        assert!(values.iter().all(|v| v.is_finite() && *v >= 0.0), "{name}: {values:?}");
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        assert!((report["mean"][name].as_f64().unwrap() - mean).abs() < 1e-12, "{name}: the mean of the views");
        // pweval scores the saved 8-bit PNGs, pwenc the float renders: close, not equal.
        for (view, image) in views.iter().zip(pweval["images"].as_array().unwrap()) {
            let (ours, theirs) = (view[name].as_f64().unwrap(), image[name].as_f64().unwrap());
            assert!(
                (ours - theirs).abs() <= 0.02 * theirs.abs() + 1e-3,
                "{name} of {}: {ours} vs {theirs}",
                view["name"]
            );
        }
    }

    // PSNR and SSIM are always there; asking for them again is refused.
    let out = run(pwenc, &[&dir("scene"), "--iters", "1", "--eval", &dir("e2"), "--eval-metrics", "psnr"]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("always reported"));
}
