//! The rating page in headless Chromium, driven through chromedriver's WebDriver protocol
//! (plain HTTP): a scripted rater types a name, toggles between the two reconstructions, and
//! answers 24 questions as a careful rater would (the ground truth when shown, else the
//! method it prefers); every answer reaches the judgments file and the fit ranks the preferred
//! method first.
//!
//! Needs `chromium` and `chromium-driver` (Debian's packages; `.ci/run` installs them). Without
//! chromedriver the test says it is skipped, except under CI, where that is a failure.

mod common;

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::{request, start_server, study};
use serde_json::{Value, json};

/// Kills the child when the test ends, however it ends.
struct Killed(Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn free_port() -> u16 {
    std::net::TcpListener::bind(("127.0.0.1", 0)).unwrap().local_addr().unwrap().port()
}

/// A WebDriver command; its `value`.
fn webdriver(port: u16, method: &str, path: &str, body: Value) -> Value {
    let (status, reply) = request(port, method, path, &body.to_string());
    let v: Value = serde_json::from_slice(&reply).unwrap_or(Value::Null);
    assert_eq!(status, 200, "{method} {path}: {v}");
    v["value"].clone()
}

/// Polls `script` (a function body) until it returns something other than null.
fn wait_for(port: u16, session: &str, script: &str) -> Value {
    let start = Instant::now();
    loop {
        let v = webdriver(
            port,
            "POST",
            &format!("/session/{session}/execute/sync"),
            json!({ "script": script, "args": [] }),
        );
        if !v.is_null() {
            return v;
        }
        assert!(start.elapsed() < Duration::from_secs(30), "timed out waiting for: {script}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn click(port: u16, session: &str, css: &str) {
    let element = webdriver(
        port,
        "POST",
        &format!("/session/{session}/element"),
        json!({ "using": "css selector", "value": css }),
    );
    let id = element.as_object().and_then(|o| o.values().next()).and_then(Value::as_str).unwrap().to_string();
    webdriver(port, "POST", &format!("/session/{session}/element/{id}/click"), json!({}));
}

#[test]
fn a_scripted_rater_completes_a_session_in_chromium() {
    if Command::new("chromedriver").arg("--version").output().is_err() {
        let ci = std::env::var("CI").is_ok_and(|v| !v.is_empty() && v != "0" && v != "false");
        assert!(!ci, "chromedriver is missing under CI (.ci/run installs chromium-driver)");
        eprintln!("skipped: no chromedriver on PATH (Debian: apt-get install chromium chromium-driver)");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("study");
    study(&root);
    let file = tmp.path().join("judgments.jsonl");
    let (server, port) = start_server(&root, &file);
    let _server = Killed(server);
    let driver_port = free_port();
    let driver = Command::new("chromedriver")
        .arg(format!("--port={driver_port}"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let _driver = Killed(driver);
    let start = Instant::now();
    while std::net::TcpStream::connect(("127.0.0.1", driver_port)).is_err() {
        assert!(start.elapsed() < Duration::from_secs(20), "chromedriver did not start");
        std::thread::sleep(Duration::from_millis(100));
    }
    let args = ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"];
    let capabilities = json!({ "capabilities": { "alwaysMatch": { "goog:chromeOptions": { "args": args } } } });
    let session = webdriver(driver_port, "POST", "/session", capabilities)["sessionId"].as_str().unwrap().to_string();
    let s = session.as_str();
    webdriver(driver_port, "POST", &format!("/session/{s}/url"), json!({ "url": format!("http://127.0.0.1:{port}/") }));
    let name = webdriver(
        driver_port,
        "POST",
        &format!("/session/{s}/element"),
        json!({ "using": "css selector", "value": "#rater" }),
    );
    let name_id = name.as_object().and_then(|o| o.values().next()).and_then(Value::as_str).unwrap().to_string();
    webdriver(driver_port, "POST", &format!("/session/{s}/element/{name_id}/value"), json!({ "text": "bot" }));
    click(driver_port, s, "#start");
    let ready = "return (typeof pair !== 'undefined' && pair && !busy) ? pair : null;";
    for n in 0..24 {
        let pair = wait_for(driver_port, s, ready);
        // Clicking the right image toggles it from A to B.
        click(driver_port, s, "#shown");
        assert_eq!(wait_for(driver_port, s, "return document.getElementById('side').textContent;"), "B");
        let (left, right) = (pair["left"].as_str().unwrap(), pair["right"].as_str().unwrap());
        let pick_left = left == "ground-truth" || (right != "ground-truth" && left == "sharp");
        click(driver_port, s, if pick_left { "#pick-a" } else { "#pick-b" });
        let saved = format!("return document.getElementById('status').textContent.startsWith('{}') ? 1 : null;", n + 1);
        wait_for(driver_port, s, &saved);
    }
    request(driver_port, "DELETE", &format!("/session/{s}"), "");
    let judgments = pwgs_rating::judgments::read(&file).unwrap();
    assert_eq!(judgments.len(), 24);
    assert!(judgments.iter().all(|j| j.rater == "bot"));
    let report = pwgs_rating::fit_study(&file, 400.0, 0.8, None).unwrap();
    let first = report.lines().skip_while(|l| !l.starts_with("method")).nth(1).unwrap();
    assert!(first.starts_with("sharp"), "{report}");
}
