//! `pwrate serve` end to end over HTTP (no browser): the page, questions that belong to the
//! study, images, judgments appended durably (a killed server keeps every acknowledged one) and
//! refused when they do not belong to the study; then `pwrate fit` reads what was written.

mod common;

use std::process::Command;

use common::{request, start_server, study};

#[test]
fn the_server_asks_serves_and_keeps_judgments() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("study");
    study(&root);
    let file = tmp.path().join("judgments.jsonl");
    let (mut server, port) = start_server(&root, &file);
    let (status, page) = request(port, "GET", "/", "");
    assert_eq!(status, 200);
    assert!(String::from_utf8_lossy(&page).contains("id=\"pick-a\""));
    let mut golden = 0;
    let mut saved = 0;
    for _ in 0..60 {
        let (status, body) = request(port, "GET", "/api/next", "");
        assert_eq!(status, 200);
        let q: serde_json::Value = serde_json::from_slice(&body).unwrap();
        let (left, right) = (q["left"].as_str().unwrap(), q["right"].as_str().unwrap());
        assert_ne!(left, right);
        assert_eq!(q["size"], 64, "crops are 512 or the view's shorter side");
        assert!(q["crop"][0].as_u64().unwrap() <= 32 && q["crop"][1] == 0);
        golden += usize::from(left == "ground-truth" || right == "ground-truth");
        let view = q["view"].as_str().unwrap();
        let (status, png) = request(port, "GET", &format!("/image/{left}/{view}"), "");
        assert_eq!((status, &png[1..4]), (200, &b"PNG"[..]));
        // The tester knows the ground truth when shown it, and prefers the sharp method.
        let winner = [left, right].into_iter().find(|&m| m == "ground-truth" || m == "sharp").unwrap_or(left);
        let winner = if left == "ground-truth" || right == "ground-truth" { "ground-truth" } else { winner };
        let judgment = serde_json::json!({ "rater": "tester", "view": view, "crop": q["crop"], "left": left,
                                           "right": right, "winner": winner });
        assert_eq!(request(port, "POST", "/api/judgment", &judgment.to_string()).0, 204);
        saved += 1;
    }
    assert!(golden > 0 && golden < 30, "about one question in ten is golden: {golden}");
    // What does not belong to the study is refused, and nothing outside it is served.
    let stray = serde_json::json!({ "rater": "tester", "view": "a.png", "crop": [0, 0], "left": "sharp",
                                    "right": "blurry", "winner": "other" });
    assert_eq!(request(port, "POST", "/api/judgment", &stray.to_string()).0, 400);
    let outside = serde_json::json!({ "rater": "tester", "view": "a.png", "crop": [40, 0], "left": "sharp",
                                      "right": "blurry", "winner": "sharp" });
    assert_eq!(request(port, "POST", "/api/judgment", &outside.to_string()).0, 400);
    assert_eq!(request(port, "GET", "/image/gt/..%2F..%2Fjudgments.jsonl", "").0, 404);
    assert_eq!(request(port, "GET", "/image/nobody/a.png", "").0, 404);

    // Killed without warning, the server has kept every acknowledged judgment.
    server.kill().unwrap();
    server.wait().unwrap();
    let lines = pwgs_rating::judgments::read(&file).unwrap();
    assert_eq!(lines.len(), saved);
    let out = Command::new(env!("CARGO_BIN_EXE_pwrate")).args(["fit", file.to_str().unwrap()]).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.lines().nth(3).unwrap_or("").starts_with("sharp"), "the tester preferred sharp: {stdout}");
}

#[test]
fn a_study_without_ground_truth_or_methods_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let run = |dir: &std::path::Path| {
        Command::new(env!("CARGO_BIN_EXE_pwrate"))
            .args(["serve", dir.to_str().unwrap(), "--judgments", "/dev/null", "--port", "0"])
            .output()
            .unwrap()
    };
    let out = run(tmp.path());
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("gt/"));
    study(tmp.path());
    std::fs::remove_file(tmp.path().join("sharp/b.png")).unwrap();
    let out = run(tmp.path());
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("sharp lacks b.png"));
}

/// Two runs' eval folders (renders, and the ground truth in gt/) are a study as they are.
#[test]
fn runs_eval_folders_are_rated_as_they_are() {
    let tmp = tempfile::tempdir().unwrap();
    study(tmp.path());
    // Eval folders: each run's renders, with the ground truth inside as pwenc --eval writes it.
    for run in ["blurry", "sharp"] {
        let gt = tmp.path().join(run).join("gt");
        std::fs::create_dir_all(&gt).unwrap();
        for v in ["a.png", "b.png"] {
            std::fs::copy(tmp.path().join("gt").join(v), gt.join(v)).unwrap();
        }
    }
    let runs = [("old".to_string(), tmp.path().join("blurry")), ("new".to_string(), tmp.path().join("sharp"))];
    let s = pwgs_rating::study::Study::of_runs(&runs).unwrap();
    assert_eq!(s.methods, ["new", "old"]);
    assert_eq!(s.image("old", "a.png").unwrap(), tmp.path().join("blurry/a.png"));
    assert_eq!(s.image("ground-truth", "b.png").unwrap(), tmp.path().join("blurry/gt/b.png"));
    assert!(s.image("old", "c.png").is_none() && s.image("gt", "a.png").is_none());
    let out = Command::new(env!("CARGO_BIN_EXE_pwrate"))
        .args(["serve", "--judgments", "/dev/null", "--run", "only=x"])
        .output()
        .unwrap();
    assert!(!out.status.success(), "one run is not a study");
    let out = Command::new(env!("CARGO_BIN_EXE_pwrate"))
        .args(["serve", "--judgments", "/dev/null", "--run", "x"])
        .output()
        .unwrap();
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("NAME=EVAL_DIR"));
}
