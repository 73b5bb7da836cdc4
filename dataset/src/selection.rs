//! A set of a scene's views named on a command line (`pwdec --views`, `pwenc compare --views`,
//! `pwenc --from MODEL --views`): the scene folder, which of its views, at which downscale.
//! Only the cameras are read ([`load_cameras`]), not the pictures.

use std::path::PathBuf;

use crate::{DatasetError, LoadOptions, NamedCamera, load_cameras};

/// Which of a scene's views.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ViewSplit {
    Test,
    Train,
    All,
}

impl std::str::FromStr for ViewSplit {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        [Self::Test, Self::Train, Self::All]
            .into_iter()
            .find(|split| split.name() == s)
            .ok_or_else(|| format!("`{s}` is not a split: test, train or all"))
    }
}

impl ViewSplit {
    pub fn name(self) -> &'static str {
        match self {
            Self::Test => "test",
            Self::Train => "train",
            Self::All => "all",
        }
    }
}

/// Some views of a scene folder, their cameras at the images' size after `downscale`.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneViews {
    pub scene: PathBuf,
    pub split: ViewSplit,
    pub downscale: u32,
}

impl SceneViews {
    /// The cameras of the chosen views, training views first, in the scene's order; an error
    /// when the split holds none (a scene without its own split has a test view every 8th).
    pub fn cameras(&self) -> Result<Vec<NamedCamera>, DatasetError> {
        let options = LoadOptions { downscale: self.downscale, ..Default::default() };
        let loaded = load_cameras(&self.scene, &options)?;
        let cameras = match self.split {
            ViewSplit::Test => loaded.test,
            ViewSplit::Train => loaded.train,
            ViewSplit::All => loaded.train.into_iter().chain(loaded.test).collect(),
        };
        if cameras.is_empty() {
            let problem = format!("the scene has no {} views", self.split.name());
            return Err(DatasetError::malformed(&self.scene, problem));
        }
        Ok(cameras)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{SyntheticOptions, generate};

    #[test]
    fn splits_select_the_views_load_cameras_splits() {
        let dir = tempfile::tempdir().unwrap();
        // Nine views: the 1st and 9th are the test views (a view in 8 without the scene's own split).
        generate(dir.path(), &SyntheticOptions { width: 64, height: 48, views: 9, seed: 7, points: 100 }).unwrap();
        let views = |split| SceneViews { scene: dir.path().to_path_buf(), split, downscale: 1 }.cameras().unwrap();
        let (train, test, all) = (views(ViewSplit::Train), views(ViewSplit::Test), views(ViewSplit::All));
        assert_eq!((train.len(), test.len()), (7, 2));
        assert_eq!(all.len(), train.len() + test.len());
        assert_eq!(all[0].name, train[0].name);
        assert_eq!(all[train.len()].name, test[0].name);
        let halved = SceneViews { scene: dir.path().to_path_buf(), split: ViewSplit::Test, downscale: 2 };
        let halved = halved.cameras().unwrap();
        assert_eq!((halved[0].camera.width, halved[0].camera.height), (32, 24));
        assert_eq!((test[0].camera.width, test[0].camera.height), (64, 48));
    }

    #[test]
    fn splits_parse_by_name_only() {
        for split in [ViewSplit::Test, ViewSplit::Train, ViewSplit::All] {
            assert_eq!(split.name().parse::<ViewSplit>(), Ok(split));
        }
        assert!("Test".parse::<ViewSplit>().unwrap_err().contains("test, train or all"));
    }

    #[test]
    fn a_missing_scene_is_an_error_naming_it() {
        let views = SceneViews { scene: "/no/such/scene".into(), split: ViewSplit::All, downscale: 1 };
        let error = views.cameras().unwrap_err().to_string();
        assert!(error.contains("/no/such/scene"), "{error}");
    }
}
