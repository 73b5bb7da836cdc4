//! A rating study on disk: the ground truth (a PNG per view) and, per method, a render of each
//! of those views under the same name. Either a study folder (`STUDY/gt/` and one folder per
//! method beside it), or the eval folders of runs as `pwenc --eval DIR` writes them (renders in
//! `DIR`, the ground truth as training saw it in `DIR/gt/`), rated against the first run's
//! ground truth: any two runs of a scene can be rated as they are.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail, ensure};

use crate::judgments::GROUND_TRUTH;

/// Largest side of the square crops shown (the protocol: 512 x 512).
pub const CROP: u32 = 512;

/// The views and methods of a study, checked once at start.
#[derive(Debug, Clone, PartialEq)]
pub struct Study {
    /// The ground truth's folder.
    pub truth: PathBuf,
    /// View file names with their size, sorted.
    pub views: BTreeMap<String, [u32; 2]>,
    /// Method names, sorted.
    pub methods: Vec<String>,
    /// Each method's folder, in the order of `methods`.
    pub folders: Vec<PathBuf>,
}

fn pngs(dir: &Path) -> Result<Vec<String>> {
    let mut names = Vec::new();
    for entry in std::fs::read_dir(dir).with_context(|| format!("cannot read {}", dir.display()))? {
        let entry = entry?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if entry.file_type()?.is_file() && name.to_ascii_lowercase().ends_with(".png") {
            names.push(name);
        }
    }
    names.sort();
    Ok(names)
}

impl Study {
    /// A study folder: `root/gt/` and every other folder of `root` a method.
    pub fn open(root: &Path) -> Result<Self> {
        let mut methods = Vec::new();
        for entry in std::fs::read_dir(root).with_context(|| format!("cannot read {}", root.display()))? {
            let entry = entry?;
            let name = entry.file_name().to_string_lossy().into_owned();
            if entry.path().is_dir() && name != "gt" {
                methods.push((name, entry.path()));
            }
        }
        Self::new(root.join("gt"), methods)
    }

    /// Runs' eval folders, named: rated against the first one's `gt/`.
    pub fn of_runs(runs: &[(String, PathBuf)]) -> Result<Self> {
        let Some((_, first)) = runs.first() else { bail!("no runs to rate") };
        Self::new(first.join("gt"), runs.to_vec())
    }

    /// Checks that every method holds every ground-truth view, at the same size.
    fn new(truth: PathBuf, mut methods: Vec<(String, PathBuf)>) -> Result<Self> {
        let mut views = BTreeMap::new();
        let names =
            pngs(&truth).with_context(|| format!("no gt/ folder of ground-truth PNGs at {}", truth.display()))?;
        for name in names {
            let size = image::image_dimensions(truth.join(&name)).with_context(|| format!("cannot read gt/{name}"))?;
            views.insert(name, [size.0, size.1]);
        }
        ensure!(!views.is_empty(), "{} has no ground-truth views", truth.display());
        methods.sort();
        for (i, (name, folder)) in methods.iter().enumerate() {
            ensure!(name != GROUND_TRUTH, "a method may not be named `{GROUND_TRUTH}`: golden questions use that name");
            ensure!(i == 0 || methods[i - 1].0 != *name, "two methods are named {name}");
            for (view, size) in &views {
                let got = image::image_dimensions(folder.join(view))
                    .with_context(|| format!("method {name} lacks {view}"))?;
                let [w, h] = *size;
                ensure!([got.0, got.1] == *size, "{name}/{view} is {}x{}, the ground truth {w}x{h}", got.0, got.1);
            }
        }
        ensure!(methods.len() >= 2, "a study needs two methods or more ({} found)", methods.len());
        let (methods, folders) = methods.into_iter().unzip();
        Ok(Self { truth, views, methods, folders })
    }

    /// The side of the square crops of a view: 512, or the view's shorter side.
    pub fn crop_side(&self, view: &str) -> Option<u32> {
        self.views.get(view).map(|&[w, h]| CROP.min(w).min(h))
    }

    /// The file a method's (or the ground truth's) view is read from, if both are the study's.
    pub fn image(&self, method: &str, view: &str) -> Option<PathBuf> {
        if !self.views.contains_key(view) {
            return None;
        }
        match method {
            GROUND_TRUTH => Some(self.truth.join(view)),
            m => self.methods.iter().position(|x| x == m).map(|i| self.folders[i].join(view)),
        }
    }
}
