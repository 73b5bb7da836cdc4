//! `--target-bytes` on the anchor base: a trained anchor stream cut to a budget keeps the
//! anchors that show most, fits the budget, and decodes to exactly the anchors it kept.

use pwgs_codec::scene::{Base, Scene};
use pwgs_codec::stream::{self, header::BaseKind, header::Header};
use pwgs_core::camera::Camera;
use pwgs_dataset::synthetic::{SyntheticOptions, generate};
use pwgs_dataset::{LoadOptions, load_scene};
use pwgs_encoder::anchor::init::{AnchorShape, initial_model};
use pwgs_encoder::anchor::quantize::{AnchorSteps, quantize};
use pwgs_encoder::anchor::train::AnchorTrainer;
use pwgs_encoder::anchor::trim::{anchor_importance, fit_anchors, keep_anchors};
use pwgs_encoder::metrics::evaluate::{MeanScore, evaluate};

#[test]
fn anchor_streams_are_cut_to_size_keeping_what_shows_most() {
    let tmp = tempfile::tempdir().unwrap();
    generate(tmp.path(), &SyntheticOptions { width: 64, height: 48, views: 10, seed: 7, points: 1200 }).unwrap();
    let data = load_scene(tmp.path(), &LoadOptions::default()).unwrap();
    let shape = AnchorShape { feature_dim: 8, offsets_per_anchor: 4, voxel: 0.05 * data.normalization.scale };
    let (initial, grid) = initial_model(data.points.as_ref().unwrap(), shape, 0).unwrap();
    let steps = AnchorSteps::default();
    let mut trainer = AnchorTrainer::new(&initial, &data, 150, [0.0; 3], 0, &burn::tensor::Device::flex())
        .unwrap()
        .with_quantization_noise(steps, 15);
    while trainer.iteration < trainer.iterations {
        trainer.step().unwrap();
    }
    let content = quantize(&trainer.model(), &grid, &steps).unwrap();
    let n = content.len();
    let header = Header {
        base: BaseKind::Anchors,
        gaussian_count: n as u32,
        sh_degree: 0,
        center: data.normalization.center.to_array(),
        scale: data.normalization.scale,
        background: [0.0; 3],
    };
    let cameras: Vec<Camera> = data.train.iter().map(|v| v.camera).collect();
    let full = stream::encode(&header, &content, None).unwrap();

    // A budget the stream meets changes nothing.
    let (same, bytes, dropped) = fit_anchors(content.clone(), &header, None, full.len(), &cameras).unwrap();
    assert_eq!((same.len(), dropped), (n, 0));
    assert_eq!(bytes, full);

    // Two thirds of the bytes: the stream fits, lands close to the budget, and decodes to the
    // anchors kept, the ones that show most.
    let target = full.len() * 2 / 3;
    let (kept, bytes, dropped) = fit_anchors(content.clone(), &header, None, target, &cameras).unwrap();
    let per_anchor = full.len() / n;
    eprintln!("{n} anchors, {} bytes; target {target}: {} kept, {} bytes", full.len(), kept.len(), bytes.len());
    assert!(bytes.len() <= target && bytes.len() + 4 * per_anchor >= target, "{} bytes", bytes.len());
    assert_eq!(kept.len() + dropped, n);
    assert!(dropped > 0);
    let decoded = stream::decode(&bytes).unwrap();
    let stream::Content::Anchors(stored) = &decoded.content else { panic!("an anchor stream") };
    // The stream lists anchors in its octree's order: compare them sorted.
    let sorted = |mut p: Vec<[u32; 3]>| {
        p.sort_unstable();
        p
    };
    assert_eq!(sorted(stored.positions.clone()), sorted(kept.positions.clone()));
    assert_eq!(stored.mlps, kept.mlps);
    let importance = anchor_importance(&content.dequantize(), &cameras);
    let index_of = |p: &[u32; 3]| content.positions.iter().position(|q| q == p).unwrap();
    let kept_min = kept.positions.iter().map(|p| importance[index_of(p)]).fold(f64::INFINITY, f64::min);
    let dropped_max = content
        .positions
        .iter()
        .enumerate()
        .filter(|(_, p)| !kept.positions.contains(p))
        .map(|(i, _)| importance[i])
        .fold(0.0, f64::max);
    assert!(kept_min >= dropped_max, "kept {kept_min} < dropped {dropped_max}");

    // What shows least costs least: the same count of anchors taken from the other end of the
    // ranking renders the test views far worse.
    let mut ranked: Vec<usize> = (0..n).collect();
    ranked.sort_by(|&a, &b| importance[a].total_cmp(&importance[b]));
    let mut least = ranked[..kept.len()].to_vec();
    least.sort_unstable();
    let psnr = |c: &stream::anchor::QuantizedAnchors| {
        let scene = Scene {
            base: Base::Anchors(Box::new(c.dequantize())),
            wrapper: None,
            frame: data.normalization.frame(),
            background: [0.0; 3],
        };
        MeanScore::of(&evaluate(&scene, &data.test, None, None).unwrap()).psnr
    };
    let (whole, best, worst) = (psnr(&content), psnr(&kept), psnr(&keep_anchors(&content, &least)));
    eprintln!("test PSNR: all {whole:.2}, most important {best:.2}, least important {worst:.2} dB");
    assert!(best > worst + 1.0, "{best:.2} against {worst:.2}");

    // A budget below the stream of no anchor at all is refused, naming the minimum.
    let err = fit_anchors(content, &header, None, 10, &cameras).unwrap_err().to_string();
    assert!(err.contains("impossible") && err.contains("without any anchor"), "{err}");
}
