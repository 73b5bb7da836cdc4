//! Round trips of both formats, and every way a file can be broken.

use super::binary::*;
use super::text::*;
use super::*;

/// A model exercising every branch of both formats: several camera models, images with and
/// without 2D points (one name with spaces and non-ASCII), ids above 2^31, awkward floats.
fn sample_model() -> ColmapModel {
    let camera = |id, model, width, height, params: Vec<f64>| ColmapCamera { id, model, width, height, params };
    let point2d = |x, y, point3d_id| Point2D { xy: [x, y], point3d_id };
    let track = |pairs: &[(u32, u32)]| {
        pairs.iter().map(|&(image_id, point2d_idx)| TrackElement { image_id, point2d_idx }).collect()
    };
    ColmapModel {
        cameras: vec![
            camera(1, CameraModel::SimplePinhole, 640, 480, vec![500.25, 320.0, 240.5]),
            camera(2, CameraModel::SimpleRadial, 4032, 3024, vec![3260.5, 2016.0, 1512.0, 0.0198]),
            camera(7, CameraModel::Opencv, 1920, 1080, vec![1000.1, 1001.2, 960.3, 540.4, -0.1, 0.01, 1e-4, -2e-5]),
            camera(
                9,
                CameraModel::ThinPrismFisheye,
                100,
                50,
                (0..12).map(|i| f64::from(i) * 0.1 + 1.0 / 3.0).collect(),
            ),
        ],
        images: vec![
            ColmapImage {
                id: 1,
                qvec: [0.9, 0.1, -0.3, 0.2],
                tvec: [0.1 + 0.2, -5e-324, 1e300],
                camera_id: 2,
                name: "IMG_4026.JPG".into(),
                points2d: vec![point2d(10.5, 20.25, 0), point2d(-1.0, 1e-10, -1), point2d(3.0, 4.0, 5)],
            },
            ColmapImage {
                id: 3,
                qvec: [1.0, 0.0, 0.0, 0.0],
                tvec: [0.0, -0.0, f64::MAX],
                camera_id: 1,
                name: "sub dir/ümlaut 2.png".into(),
                points2d: vec![],
            },
            ColmapImage {
                id: 4_000_000_000,
                qvec: [0.5, 0.5, 0.5, -0.5],
                tvec: [1.0 / 3.0, 2.0, -3.5],
                camera_id: 9,
                name: "x".into(),
                points2d: vec![point2d(0.5, 0.5, 0)],
            },
        ],
        points: vec![
            ColmapPoint {
                id: 0,
                xyz: [1.5, -2.25, 1.0 / 7.0],
                rgb: [0, 128, 255],
                error: 0.75,
                track: track(&[(1, 0), (4_000_000_000, 0)]),
            },
            ColmapPoint { id: 5, xyz: [-1e-7, 3e8, 0.0], rgb: [1, 2, 3], error: 1.25, track: track(&[(1, 2)]) },
            ColmapPoint { id: u64::MAX, xyz: [0.1, 0.2, 0.3], rgb: [9, 9, 9], error: 0.0, track: vec![] },
        ],
    }
}

type Decode = fn(&Path, &[u8]) -> Result<(), DatasetError>;

/// The sample model's binary files, each with its decoder.
fn binary_files(model: &ColmapModel) -> [(&'static str, Vec<u8>, Decode); 3] {
    [
        ("cameras.bin", cameras_to_bin(&model.cameras).unwrap(), |p, b| cameras_from_bin(p, b).map(drop)),
        ("images.bin", images_to_bin(&model.images).unwrap(), |p, b| images_from_bin(p, b).map(drop)),
        ("points3D.bin", points_to_bin(&model.points).unwrap(), |p, b| points_from_bin(p, b).map(drop)),
    ]
}

#[test]
fn binary_round_trip_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let model = sample_model();
    write_binary(&model, dir.path()).unwrap();
    assert_eq!(read_binary(dir.path()).unwrap(), model);
    assert_eq!(read_model(dir.path()).unwrap(), model);
}

#[test]
fn text_round_trip_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let model = sample_model();
    write_text(&model, dir.path()).unwrap();
    assert_eq!(read_text(dir.path()).unwrap(), model);
    assert_eq!(read_model(dir.path()).unwrap(), model, "without cameras.bin, read_model reads text");
}

#[test]
fn empty_model_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    write_binary(&ColmapModel::default(), &dir.path().join("bin")).unwrap();
    write_text(&ColmapModel::default(), &dir.path().join("txt")).unwrap();
    assert_eq!(read_binary(&dir.path().join("bin")).unwrap(), ColmapModel::default());
    assert_eq!(read_text(&dir.path().join("txt")).unwrap(), ColmapModel::default());
}

#[test]
fn non_finite_poses_are_left_to_the_loader() {
    let mut model = sample_model();
    model.images[0].qvec[0] = f64::NAN;
    model.images[0].tvec[2] = f64::NEG_INFINITY;
    type Write = fn(&ColmapModel, &Path) -> Result<(), DatasetError>;
    type Read = fn(&Path) -> Result<ColmapModel, DatasetError>;
    for (write, read) in [(write_binary as Write, read_binary as Read), (write_text, read_text)] {
        let dir = tempfile::tempdir().unwrap();
        write(&model, dir.path()).unwrap();
        let image = &read(dir.path()).unwrap().images[0];
        assert!(image.qvec[0].is_nan());
        assert_eq!(image.tvec[2], f64::NEG_INFINITY);
    }
}

#[test]
fn every_truncation_of_a_binary_file_is_an_error() {
    for (name, bytes, decode) in binary_files(&sample_model()) {
        let path = Path::new(name);
        decode(path, &bytes).unwrap();
        for len in 0..bytes.len() {
            let err = decode(path, &bytes[..len]).expect_err(&format!("{name} cut at {len}")).to_string();
            assert!(err.starts_with(&format!("{name}: byte ")), "{err}");
        }
    }
}

#[test]
fn a_truncated_file_on_disk_is_named() {
    let dir = tempfile::tempdir().unwrap();
    write_binary(&sample_model(), dir.path()).unwrap();
    let path = dir.path().join("points3D.bin");
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() - 3]).unwrap();
    let err = read_model(dir.path()).unwrap_err().to_string();
    assert!(err.contains("points3D.bin") && err.contains("record 3 of 3") && err.contains("file ends"), "{err}");
}

#[test]
fn trailing_bytes_are_an_error() {
    for (name, mut bytes, decode) in binary_files(&sample_model()) {
        bytes.push(0);
        let err = decode(Path::new(name), &bytes).unwrap_err().to_string();
        assert!(err.contains("1 unexpected bytes after the last record"), "{err}");
    }
}

#[test]
fn huge_counts_fail_before_allocating() {
    let huge = (1u64 << 60).to_le_bytes();
    let mut bytes = huge.to_vec();
    bytes.extend([0; 100]);
    for (name, _, decode) in binary_files(&sample_model()) {
        let err = decode(Path::new(name), &bytes).unwrap_err().to_string();
        assert!(err.contains("is 1152921504606846976") && err.contains("100 bytes left"), "{err}");
    }
    // Nested counts: an image without 2D points and a point without a track end with them.
    let model = sample_model();
    let with_huge_tail = |mut bytes: Vec<u8>| {
        let at = bytes.len() - 8;
        bytes[at..].copy_from_slice(&huge);
        bytes
    };
    let images = with_huge_tail(images_to_bin(&model.images[1..2]).unwrap());
    let err = images_from_bin(Path::new("images.bin"), &images).unwrap_err().to_string();
    assert!(err.contains("num_points2D is 1152921504606846976"), "{err}");
    let points = with_huge_tail(points_to_bin(&model.points[2..]).unwrap());
    let err = points_from_bin(Path::new("points3D.bin"), &points).unwrap_err().to_string();
    assert!(err.contains("track_length is 1152921504606846976"), "{err}");
}

#[test]
fn unknown_model_id_names_file_camera_and_id() {
    let mut bytes = cameras_to_bin(&sample_model().cameras[2..3]).unwrap();
    bytes[12..16].copy_from_slice(&42i32.to_le_bytes()); // after the count and the camera id
    let err = cameras_from_bin(Path::new("scene/cameras.bin"), &bytes).unwrap_err().to_string();
    assert!(err.starts_with("scene/cameras.bin: ") && err.contains("camera 7") && err.contains("id 42"), "{err}");
}

#[test]
fn non_utf8_names_are_errors() {
    let model = sample_model();
    let mut bytes = images_to_bin(&model.images).unwrap();
    let at = bytes.windows(3).position(|w| w == b"IMG").unwrap();
    bytes[at] = 0xFF;
    let err = images_from_bin(Path::new("images.bin"), &bytes).unwrap_err().to_string();
    assert!(err.contains("record 1 of 3") && err.contains("not valid UTF-8"), "{err}");

    let dir = tempfile::tempdir().unwrap();
    write_text(&model, dir.path()).unwrap();
    let path = dir.path().join("images.txt");
    let mut bytes = std::fs::read(&path).unwrap();
    let at = bytes.windows(3).position(|w| w == b"IMG").unwrap();
    bytes[at] = 0xFE;
    std::fs::write(&path, bytes).unwrap();
    let err = read_text(dir.path()).unwrap_err().to_string();
    assert!(err.contains("images.txt: line 5: not valid UTF-8"), "{err}");
}

#[test]
fn repeated_ids_are_errors() {
    let model = sample_model();
    let twice = [model.cameras[1].clone(), model.cameras[1].clone()];
    let err = cameras_from_bin(Path::new("cameras.bin"), &cameras_to_bin(&twice).unwrap()).unwrap_err();
    assert!(err.to_string().contains("record 2 of 2: camera id 2 appears more than once"), "{err}");
    let text = points_to_text(&[model.points[0].clone(), model.points[0].clone()]).unwrap();
    let err = points_from_text(Path::new("points3D.txt"), text.as_bytes()).unwrap_err();
    assert!(err.to_string().contains("line 5: point id 0 appears more than once"), "{err}");
}

/// Replaces one line (1-based) of a text file of the sample model and returns the read error.
fn text_error_with_line(file: &str, number: usize, replacement: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    write_text(&sample_model(), dir.path()).unwrap();
    let path = dir.path().join(file);
    let mut lines: Vec<String> = std::fs::read_to_string(&path).unwrap().lines().map(String::from).collect();
    lines[number - 1] = replacement.to_owned();
    std::fs::write(&path, lines.join("\n")).unwrap();
    read_text(dir.path()).unwrap_err().to_string()
}

#[test]
fn bad_text_lines_are_errors_naming_the_line() {
    // Headers: cameras.txt and points3D.txt 3 lines, images.txt 4 lines.
    let cases = [
        (
            "cameras.txt",
            4,
            "1 SIMPLE_PINHOLE 640 480 500 320",
            "cameras.txt: line 4: camera 1 has 2 params, but SIMPLE_PINHOLE takes 3",
        ),
        ("cameras.txt", 5, "2 FANCY 640 480 1 2 3", "cameras.txt: line 5: camera 2 has unknown camera model \"FANCY\""),
        ("cameras.txt", 6, "7 OPENCV 1920", "cameras.txt: line 6: missing HEIGHT"),
        ("images.txt", 5, "1 abc 0 0 0 0 0 0 2 a.png", "images.txt: line 5: QW: cannot parse \"abc\""),
        ("images.txt", 7, "3 1 0 0 0 0 0 0 1", "images.txt: line 7: missing NAME"),
        ("images.txt", 6, "10.5 20.25 0 1 2", "images.txt: line 6: missing 2D point POINT3D_ID"),
        ("points3D.txt", 4, "0 1 2 3 300 0 0 0.5", "points3D.txt: line 4: R: cannot parse \"300\""),
        ("points3D.txt", 5, "5 1 2 3 1 2 3 0.5 1", "points3D.txt: line 5: missing track POINT2D_IDX"),
    ];
    for (file, number, replacement, expected) in cases {
        let err = text_error_with_line(file, number, replacement);
        assert!(err.contains(expected), "expected {expected:?} in {err:?}");
    }
}

#[test]
fn writers_refuse_what_they_cannot_store_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let mut model = sample_model();
    model.cameras[0].params.pop();
    let err = write_binary(&model, dir.path()).unwrap_err().to_string();
    assert!(err.contains("cameras.bin: camera 1 has 2 params, but SIMPLE_PINHOLE takes 3"), "{err}");
    assert!(write_text(&model, dir.path()).is_err());

    let mut model = sample_model();
    model.images[1].name = "a\0b".into();
    assert!(write_binary(&model, dir.path()).unwrap_err().to_string().contains("0 byte"));
    for name in ["", " a", "a\nb", "a\t"] {
        model.images[1].name = name.into();
        assert!(write_text(&model, dir.path()).unwrap_err().to_string().contains("images.txt cannot store"));
    }
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "a refused model leaves no files");
}

#[test]
fn model_ids_names_and_param_counts() {
    for (id, model) in CameraModel::ALL.into_iter().enumerate() {
        assert_eq!(CameraModel::from_id(model.id()), Some(model));
        assert_eq!(model.id() as usize, id);
        assert_eq!(CameraModel::from_name(model.name()), Some(model));
    }
    assert_eq!(CameraModel::from_id(11), None);
    assert_eq!(CameraModel::from_id(-1), None);
    assert_eq!(CameraModel::from_name("pinhole"), None);
    let counts = CameraModel::ALL.map(CameraModel::param_count);
    assert_eq!(counts, [3, 4, 4, 5, 8, 8, 12, 5, 4, 5, 12]);
}

#[test]
fn pinhole_and_distortion_follow_the_model() {
    let path = Path::new("cameras.bin");
    let cameras = sample_model().cameras;
    assert_eq!(cameras[0].pinhole(), [500.25, 500.25, 320.0, 240.5]);
    assert_eq!(cameras[0].distortion(path).unwrap(), Distortion::None);
    assert_eq!(cameras[1].pinhole(), [3260.5, 3260.5, 2016.0, 1512.0]);
    assert_eq!(cameras[1].distortion(path).unwrap(), Distortion::Radial { k1: 0.0198, k2: 0.0 });
    assert_eq!(cameras[2].pinhole(), [1000.1, 1001.2, 960.3, 540.4]);
    let opencv = Distortion::Opencv { k1: -0.1, k2: 0.01, p1: 1e-4, p2: -2e-5 };
    assert_eq!(cameras[2].distortion(path).unwrap(), opencv);
    let radial =
        ColmapCamera { id: 4, model: CameraModel::Radial, width: 8, height: 6, params: vec![5.0, 4.0, 3.0, 0.1, 0.2] };
    assert_eq!(radial.distortion(path).unwrap(), Distortion::Radial { k1: 0.1, k2: 0.2 });

    let err = cameras[3].distortion(path).unwrap_err();
    assert!(matches!(err, DatasetError::Unsupported { .. }), "{err:?}");
    let message = err.to_string();
    assert!(
        message.contains("camera 9 uses the THIN_PRISM_FISHEYE model") && message.contains("image_undistorter"),
        "{message}"
    );

    let short = ColmapCamera { params: vec![1.0], ..cameras[2].clone() };
    assert!(short.pinhole()[1].is_nan());
    assert!(short.distortion(path).is_err());
}

#[test]
fn find_model_dir_prefers_sparse_0() {
    let dir = tempfile::tempdir().unwrap();
    assert_eq!(find_model_dir(dir.path()), None);
    let sparse = dir.path().join("sparse");
    write_text(&sample_model(), &sparse).unwrap();
    assert_eq!(find_model_dir(dir.path()), Some(sparse.clone()));
    std::fs::create_dir(sparse.join("0")).unwrap();
    assert_eq!(find_model_dir(dir.path()), Some(sparse.clone()), "an empty sparse/0 is not a model");
    write_binary(&sample_model(), &sparse.join("0")).unwrap();
    assert_eq!(find_model_dir(dir.path()), Some(sparse.join("0")));
}
