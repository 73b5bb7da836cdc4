//! `pwrate serve`: the rating page on 127.0.0.1. The page asks for a pair (`/api/next`), shows
//! the ground truth's crop beside the two methods' crops of it (toggled, blind to their names),
//! and posts the rater's choice (`/api/judgment`), which is appended to the judgments file and
//! synced to disk before the answer: a killed server loses no judgment it acknowledged.
//!
//! One question in ten is golden: one side is the ground truth itself ([`GROUND_TRUTH`]).

use std::fs::OpenOptions;
use std::io::Write;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use anyhow::{Context, Result};
use axum::Json;
use axum::Router;
use axum::extract::{Path, State};
use axum::http::{StatusCode, header};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::{get, post};
use serde::{Deserialize, Serialize};

use crate::judgments::{GROUND_TRUTH, Judgment};
use crate::study::Study;

/// One golden question in this many.
const GOLDEN_EVERY: u64 = 10;

struct AppState {
    study: Study,
    judgments: PathBuf,
    /// SplitMix64 state for the questions (not reproducible on purpose: seeded by the clock).
    rng: Mutex<u64>,
    /// Serializes appends, so that two raters' lines never interleave.
    write: Mutex<()>,
}

impl AppState {
    fn random(&self, below: u64) -> u64 {
        let mut s = self.rng.lock().expect("not poisoned");
        *s = s.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = *s;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        (z ^ (z >> 31)) % below.max(1)
    }
}

/// A question: which of `left` and `right` is closer to the ground truth on this crop.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Question {
    pub view: String,
    pub crop: [u32; 2],
    pub size: u32,
    pub left: String,
    pub right: String,
}

async fn page() -> Html<&'static str> {
    Html(include_str!("page.html"))
}

async fn next(State(state): State<Arc<AppState>>) -> Json<Question> {
    let study = &state.study;
    let pick = state.random(study.views.len() as u64) as usize;
    let (view, &[w, h]) = study.views.iter().nth(pick).expect("a study has views");
    let size = study.crop_side(view).expect("a study view");
    let crop = [state.random(u64::from(w - size) + 1) as u32, state.random(u64::from(h - size) + 1) as u32];
    let m = study.methods.len();
    let i = state.random(m as u64) as usize;
    let first = study.methods[i].clone();
    let second = if state.random(GOLDEN_EVERY) == 0 {
        GROUND_TRUTH.to_string()
    } else {
        // Any other method: a step of 1 to m - 1 from the first.
        study.methods[(i + 1 + state.random(m as u64 - 1) as usize) % m].clone()
    };
    let view = view.clone();
    let (left, right) = if state.random(2) == 0 { (first, second) } else { (second, first) };
    Json(Question { view, crop, size, left, right })
}

async fn image(State(state): State<Arc<AppState>>, Path((method, view)): Path<(String, String)>) -> Response {
    let Some(path) = state.study.image(&method, &view) else {
        return (StatusCode::NOT_FOUND, "no such method or view").into_response();
    };
    match std::fs::read(&path) {
        Ok(bytes) => ([(header::CONTENT_TYPE, "image/png")], bytes).into_response(),
        Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, format!("cannot read {}: {e}", path.display())).into_response(),
    }
}

/// Why a posted judgment does not belong to the study, if it does not.
fn invalid(study: &Study, j: &Judgment) -> Option<String> {
    let known = |m: &str| m == GROUND_TRUTH || study.methods.iter().any(|x| x == m);
    let Some(&[w, h]) = study.views.get(&j.view) else { return Some(format!("no view {}", j.view)) };
    let size = study.crop_side(&j.view)?;
    if j.rater.trim().is_empty() {
        Some("the rater has no name".into())
    } else if !known(&j.left) || !known(&j.right) || j.left == j.right {
        Some("the sides must be two different methods of the study".into())
    } else if j.winner != j.left && j.winner != j.right {
        Some("the winner must be one of the sides".into())
    } else if j.crop[0] > w - size || j.crop[1] > h - size {
        Some("the crop lies outside the view".into())
    } else {
        None
    }
}

async fn judgment(State(state): State<Arc<AppState>>, Json(j): Json<Judgment>) -> Response {
    if let Some(why) = invalid(&state.study, &j) {
        return (StatusCode::BAD_REQUEST, why).into_response();
    }
    let line = match serde_json::to_string(&j) {
        Ok(l) => l + "\n",
        Err(e) => return (StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).into_response(),
    };
    let _guard = state.write.lock().expect("not poisoned");
    let written = OpenOptions::new()
        .create(true)
        .append(true)
        .open(&state.judgments)
        .and_then(|mut f| f.write_all(line.as_bytes()).and_then(|()| f.sync_data()));
    match written {
        Ok(()) => StatusCode::NO_CONTENT.into_response(),
        Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, format!("cannot write {}: {e}", state.judgments.display()))
            .into_response(),
    }
}

/// Serves `study` on 127.0.0.1:`port` (0: any free port), appending judgments to `judgments`;
/// prints the address, then runs until killed.
pub fn serve(study: Study, judgments: PathBuf, port: u16) -> Result<()> {
    let seed = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(1, |d| d.as_nanos() as u64);
    let state = Arc::new(AppState { study, judgments, rng: Mutex::new(seed), write: Mutex::new(()) });
    let app = Router::new()
        .route("/", get(page))
        .route("/api/next", get(next))
        .route("/api/judgment", post(judgment))
        .route("/image/{method}/{view}", get(image))
        .with_state(state);
    let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
    runtime.block_on(async move {
        let listener = tokio::net::TcpListener::bind(("127.0.0.1", port))
            .await
            .with_context(|| format!("cannot listen on 127.0.0.1:{port}"))?;
        println!("listening on http://{}", listener.local_addr()?);
        std::io::stdout().flush()?;
        axum::serve(listener, app).await.context("the server stopped")
    })
}
