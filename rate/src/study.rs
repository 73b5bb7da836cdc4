//! A rating study on disk: `STUDY/gt/` holds the ground truth (PNG per view) and every other
//! folder of `STUDY/` is a method holding a render of each of those views under the same name,
//! as `pwenc --eval DIR` writes them (its own `gt/` inside is ignored). Copying or linking two
//! runs' eval folders beside one `gt/` makes a study.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail, ensure};

use crate::judgments::GROUND_TRUTH;

/// Largest side of the square crops shown (the protocol: 512 x 512).
pub const CROP: u32 = 512;

/// The views and methods of a study, checked once at start.
#[derive(Debug, Clone, PartialEq)]
pub struct Study {
    pub root: PathBuf,
    /// View file names with their size, sorted.
    pub views: BTreeMap<String, [u32; 2]>,
    /// Method folder names, sorted.
    pub methods: Vec<String>,
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
    /// Scans `root`: every method must hold every ground-truth view, at the same size.
    pub fn open(root: &Path) -> Result<Self> {
        let gt = root.join("gt");
        let mut views = BTreeMap::new();
        for name in pngs(&gt).with_context(|| format!("{} has no gt/ folder of ground-truth PNGs", root.display()))? {
            let size = image::image_dimensions(gt.join(&name)).with_context(|| format!("cannot read gt/{name}"))?;
            views.insert(name, [size.0, size.1]);
        }
        ensure!(!views.is_empty(), "{} has no ground-truth views", gt.display());
        let mut methods = Vec::new();
        for entry in std::fs::read_dir(root).with_context(|| format!("cannot read {}", root.display()))? {
            let entry = entry?;
            let name = entry.file_name().to_string_lossy().into_owned();
            if !entry.path().is_dir() || name == "gt" {
                continue;
            }
            if name == GROUND_TRUTH {
                bail!("a method folder may not be named `{GROUND_TRUTH}`: golden questions use that name");
            }
            for (view, size) in &views {
                let path = entry.path().join(view);
                let got = image::image_dimensions(&path).with_context(|| format!("method {name} lacks {view}"))?;
                ensure!(
                    [got.0, got.1] == *size,
                    "{name}/{view} is {}x{}, the ground truth {}x{}",
                    got.0,
                    got.1,
                    size[0],
                    size[1]
                );
            }
            methods.push(name);
        }
        methods.sort();
        ensure!(methods.len() >= 2, "a study needs two methods or more beside gt/ ({} found)", methods.len());
        Ok(Self { root: root.to_path_buf(), views, methods })
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
            GROUND_TRUTH => Some(self.root.join("gt").join(view)),
            m if self.methods.iter().any(|x| x == m) => Some(self.root.join(m).join(view)),
            _ => None,
        }
    }
}
