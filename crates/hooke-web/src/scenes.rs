//! The scenes the page offers: the shipped scene files, compiled into the module (a page has
//! no file system), built by the same code as `hooke run`'s.

use std::path::Path;

use hooke_core::scene::{Scene, SceneFile};

/// One offered scene: its file name under `scenes/` and the file's text.
#[derive(Clone, Copy, Debug)]
pub struct Offered {
    pub file: &'static str,
    pub text: &'static str,
}

macro_rules! offered {
    ($($file:literal),* $(,)?) => {
        [$(Offered { file: $file, text: include_str!(concat!("../../../scenes/", $file)) }),*]
    };
}

/// The paper's Fig. 2, 3 and 4 first, then the other scenes that need no mesh file.
pub const SCENES: [Offered; 10] = offered![
    "cloth-pinned.toml",
    "self-collision.toml",
    "wind-and-balls.toml",
    "cloth-on-ball.toml",
    "stiff-cloth-on-ball.toml",
    "cloth-on-bar.toml",
    "ball-through-curtain.toml",
    "curtain-on-handles.toml",
    "tearing.toml",
    "irregular-pinned.toml",
];

impl Offered {
    /// The scene's name: its file name without `.toml`.
    pub fn name(&self) -> &'static str {
        self.file.trim_end_matches(".toml")
    }

    /// The file's `description`.
    pub fn description(&self) -> Result<String, String> {
        Ok(self.parse()?.description.unwrap_or_default())
    }

    fn parse(&self) -> Result<SceneFile, String> {
        SceneFile::parse(self.text, &self.path()).map_err(|e| e.to_string())
    }

    fn path(&self) -> String {
        format!("scenes/{}", self.file)
    }

    /// Checks and builds the scene, as `hooke run` does.
    pub fn build(&self) -> Result<Scene, String> {
        self.parse()?
            .build(Path::new(&self.path()), false)
            .map_err(|e| e.to_string())
    }
}

/// The offered scene called `name`.
pub fn find(name: &str) -> Result<Offered, String> {
    SCENES
        .into_iter()
        .find(|s| s.name() == name)
        .ok_or_else(|| {
            let names: Vec<_> = SCENES.iter().map(Offered::name).collect();
            format!("no scene {name:?}; the page offers {}", names.join(", "))
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_offered_scene_builds_under_its_file_name() {
        for offered in SCENES {
            let scene = offered.build().expect("the shipped scene builds");
            assert_eq!(scene.name, offered.name());
            assert!(!offered.description().expect("parses").is_empty());
        }
    }

    #[test]
    fn an_unknown_scene_names_the_offered_ones() {
        let error = find("nope").expect_err("no such scene");
        assert!(error.contains("cloth-pinned"), "{error}");
    }
}
