//! The shot's `[marker] hide` and `cover`: whether the final frames show the board.
//!
//! ```toml
//! [marker]
//! hide = "cover"          # none (default: the board stays), cover, plate
//! cover = "rug.png"       # cover: the picture laid over the board sheet
//!                         # plate: a still of the table without the board, taken from
//!                         #        where the [diminish] clean plate was (a tripod)
//! ```
//!
//! `hide = "cover"` needs `cover`; `hide = "plate"` needs a clean plate (`[diminish]
//! clean_plate` or `plate_frames`: tracked on the board, it gives the camera pose) and `cover`,
//! the still of the bare table from that same pose (the table under the board is in no picture
//! with the board on it). `cover` is relative to the shot's folder and must stay inside it (no
//! absolute path, no `..`, no link out of it); the flag's (`--cover`) is relative to the
//! working folder. `run` and `preview` take `--hide` and `--cover`, which override the shot's.
//! The pipeline side is [`crate::ar::Hide`].

use std::path::{Component, Path, PathBuf};

use crate::shot::{Shot, ShotError};

/// What replaces the board sheet, by the name the shot and the flags use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum HideName {
    /// The board stays in the frames (what every shot did before `hide` existed).
    #[default]
    None,
    Cover,
    Plate,
}

impl HideName {
    pub const ALL: [HideName; 3] = [HideName::None, HideName::Cover, HideName::Plate];

    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Cover => "cover",
            Self::Plate => "plate",
        }
    }
}

/// A name other than those of [`HideName`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("hide {given:?}: expected none, cover or plate")]
pub struct ParseHideError {
    pub given: String,
}

impl std::str::FromStr for HideName {
    type Err = ParseHideError;
    fn from_str(s: &str) -> Result<Self, ParseHideError> {
        Self::ALL
            .into_iter()
            .find(|h| h.name() == s)
            .ok_or_else(|| ParseHideError { given: s.into() })
    }
}

/// `--hide` and `--cover`, each overriding the shot's.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct HideOverrides {
    pub hide: Option<String>,
    pub cover: Option<PathBuf>,
}

/// The resolved hiding: what, and the picture's file (checked to be a regular file).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct HideConfig {
    pub hide: HideName,
    pub cover: Option<PathBuf>,
}

impl HideConfig {
    /// One line for a take's record (`hide=cover cover=rug.png`).
    pub fn describe(&self) -> String {
        match &self.cover {
            Some(c) => format!("hide={} cover={}", self.hide.name(), c.display()),
            None => format!("hide={}", self.hide.name()),
        }
    }
}

/// A path named in the shot, resolved against its folder, refused when it leaves it
/// (absolute, a `..` component, or a link whose target is outside).
pub fn inside_shot_folder(shot_path: &Path, p: &Path, what: &str) -> Result<PathBuf, ShotError> {
    let bad = |message: String| ShotError::Invalid {
        path: shot_path.into(),
        message,
    };
    if p.components()
        .any(|c| !matches!(c, Component::Normal(_) | Component::CurDir))
    {
        return Err(bad(format!(
            "{what} {}: must be a path inside the shot's folder (no absolute path, no ..)",
            p.display()
        )));
    }
    let full = Shot::resolve(shot_path, p);
    let folder = shot_path.parent().unwrap_or(Path::new("."));
    let folder = if folder.as_os_str().is_empty() {
        Path::new(".")
    } else {
        folder
    };
    if let (Ok(f), Ok(d)) = (full.canonicalize(), folder.canonicalize()) {
        if !f.starts_with(&d) {
            return Err(bad(format!(
                "{what} {}: leads outside the shot's folder (a link to {})",
                p.display(),
                f.display()
            )));
        }
    }
    Ok(full)
}

/// The shot's `[marker] hide` and `cover` with `flags` over them, checked: the name, the
/// picture's presence (a regular file inside the shot's folder) and, for the plate, a clean
/// plate (`has_plate`: the resolved `[diminish]` has one).
pub fn resolve(
    hide: Option<&str>,
    cover: Option<&Path>,
    flags: &HideOverrides,
    shot_path: &Path,
    has_plate: bool,
) -> Result<HideConfig, ShotError> {
    let bad = |message: String| ShotError::Invalid {
        path: shot_path.into(),
        message,
    };
    let (text, from) = match (&flags.hide, hide) {
        (Some(h), _) => (Some(h.as_str()), "--hide"),
        (None, Some(h)) => (Some(h), "[marker] hide"),
        (None, None) => (None, ""),
    };
    let name = match text {
        Some(t) => t
            .parse::<HideName>()
            .map_err(|e| bad(format!("{from}: {e}")))?,
        None => HideName::None,
    };
    let cover = match (&flags.cover, cover) {
        (Some(c), _) => Some((c.clone(), "--cover")),
        (None, Some(c)) => Some((
            inside_shot_folder(shot_path, c, "[marker] cover")?,
            "[marker] cover",
        )),
        (None, None) => None,
    };
    if let Some((path, from)) = &cover {
        match std::fs::metadata(path) {
            Ok(m) if m.is_file() => {}
            Ok(_) => {
                return Err(bad(format!(
                    "{from} {} is not a regular file",
                    path.display()
                )))
            }
            Err(e) => return Err(bad(format!("{from} {}: {e}", path.display()))),
        }
    }
    match name {
        HideName::Cover if cover.is_none() => Err(bad(format!(
            "{from} = \"cover\" needs a picture: [marker] cover = \"FILE\" (--cover FILE)"
        ))),
        HideName::Plate if !has_plate => Err(bad(format!(
            "{from} = \"plate\" needs a clean plate for its camera pose: [diminish] clean_plate = \"FILE\" or plate_frames = N (--clean-plate, --plate-frames)"
        ))),
        HideName::Plate if cover.is_none() => Err(bad(format!(
            "{from} = \"plate\" needs a still of the table without the board, taken from where the clean plate was: [marker] cover = \"FILE\" (--cover FILE)"
        ))),
        _ => Ok(HideConfig {
            hide: name,
            cover: cover.map(|(p, _)| p),
        }),
    }
}

/// Checks the shot's own keys (called by [`Shot`]'s check; a plate is assumed where the
/// shot's `[diminish]` names one).
pub(crate) fn check(shot: &Shot, shot_path: &Path) -> Result<(), ShotError> {
    let has_plate = shot.diminish.clean_plate.is_some() || shot.diminish.plate_frames.is_some();
    resolve(
        shot.marker.hide.as_deref(),
        shot.marker.cover.as_deref(),
        &HideOverrides::default(),
        shot_path,
        has_plate,
    )
    .map(|_| ())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh folder, removed with everything in it when dropped.
    fn folder(name: &str) -> tempfile::TempDir {
        tempfile::Builder::new()
            .prefix(&format!("pa-shot-hide-{name}-"))
            .tempdir()
            .expect("dir")
    }

    #[test]
    fn names_flags_and_paths() {
        let tmp = folder("names");
        let d = tmp.path();
        let shot = d.join("shot.toml");
        std::fs::write(d.join("rug.png"), b"x").expect("write");
        let none = resolve(None, None, &HideOverrides::default(), &shot, false).expect("none");
        assert_eq!(none, HideConfig::default());
        let c = resolve(
            Some("cover"),
            Some(Path::new("rug.png")),
            &HideOverrides::default(),
            &shot,
            false,
        )
        .expect("cover");
        assert_eq!(c.hide, HideName::Cover);
        assert_eq!(c.cover.as_deref(), Some(d.join("rug.png").as_path()));
        // The flag overrides the shot's name.
        let flags = HideOverrides {
            hide: Some("none".into()),
            cover: None,
        };
        let off = resolve(
            Some("cover"),
            Some(Path::new("rug.png")),
            &flags,
            &shot,
            false,
        )
        .expect("off");
        assert_eq!(off.hide, HideName::None);
        let msg = |r: Result<HideConfig, ShotError>| r.expect_err("refused").to_string();
        let e = msg(resolve(
            Some("hidden"),
            None,
            &HideOverrides::default(),
            &shot,
            false,
        ));
        assert!(
            e.contains("[marker] hide") && e.contains("none, cover or plate"),
            "{e}"
        );
        let e = msg(resolve(
            Some("cover"),
            None,
            &HideOverrides::default(),
            &shot,
            false,
        ));
        assert!(e.contains("needs a picture"), "{e}");
        let e = msg(resolve(
            Some("plate"),
            Some(Path::new("rug.png")),
            &HideOverrides::default(),
            &shot,
            false,
        ));
        assert!(e.contains("needs a clean plate"), "{e}");
        let e = msg(resolve(
            Some("plate"),
            None,
            &HideOverrides::default(),
            &shot,
            true,
        ));
        assert!(e.contains("without the board"), "{e}");
        let e = msg(resolve(
            Some("cover"),
            Some(Path::new("missing.png")),
            &HideOverrides::default(),
            &shot,
            false,
        ));
        assert!(e.contains("missing.png"), "{e}");
        std::fs::create_dir_all(d.join("dir.png")).expect("dir");
        let e = msg(resolve(
            Some("cover"),
            Some(Path::new("dir.png")),
            &HideOverrides::default(),
            &shot,
            false,
        ));
        assert!(e.contains("not a regular file"), "{e}");
    }

    fn shot_with(marker_keys: &str) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("shot.toml");
        let text = format!(
            "model = \"prop.glb\"\n[[key_poses]]\nname = \"A\"\nframe = 0\n[camera]\nfov_y_deg = 45.0\n[marker]\n{marker_keys}\n[[marker.tags]]\nid = 0\ncenter_m = [0.0, 0.0]\nsize_m = 0.05\n"
        );
        std::fs::write(&p, text).expect("write");
        std::fs::write(dir.path().join("rug.png"), b"x").expect("write");
        (dir, p)
    }

    #[test]
    fn the_shot_reads_and_checks_its_hide_keys() {
        let (_d, p) = shot_with("hide = \"cover\"\ncover = \"rug.png\"");
        let shot = Shot::load(&p).expect("a shot with a cover");
        assert_eq!(shot.marker.hide.as_deref(), Some("cover"));
        assert!(shot
            .to_toml()
            .expect("toml")
            .contains("cover = \"rug.png\""));
        // Without the keys the TOML is as before.
        let (_d2, p2) = shot_with("");
        let plain = Shot::load(&p2).expect("plain");
        assert!(!plain.to_toml().expect("toml").contains("hide"));
        for (keys, want) in [
            ("hide = \"erase\"", "expected none, cover or plate"),
            ("hide = \"cover\"", "needs a picture"),
            (
                "hide = \"plate\"\ncover = \"rug.png\"",
                "needs a clean plate",
            ),
            (
                "hide = \"cover\"\ncover = \"../rug.png\"",
                "inside the shot's folder",
            ),
            ("hide = \"cover\"\ncover = \"nope.png\"", "nope.png"),
            ("hides = \"cover\"", "hides"),
        ] {
            let (_d, p) = shot_with(keys);
            let e = Shot::load(&p).expect_err(keys).to_string();
            assert!(e.contains(want), "{keys}: {e}");
        }
    }

    #[test]
    fn a_cover_outside_the_shots_folder_is_refused() {
        let tmp = folder("escape");
        let d = tmp.path();
        let shot = d.join("shot.toml");
        let outside_dir = folder("escape-outside");
        let outside = outside_dir.path().join("secret.png");
        std::fs::write(&outside, b"x").expect("write");
        let msg = |p: &Path| {
            resolve(
                Some("cover"),
                Some(p),
                &HideOverrides::default(),
                &shot,
                false,
            )
            .expect_err("refused")
            .to_string()
        };
        let e = msg(Path::new("../pa-shot-hide-escape-outside/secret.png"));
        assert!(e.contains("inside the shot's folder"), "{e}");
        let e = msg(&outside);
        assert!(e.contains("inside the shot's folder"), "{e}");
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(&outside, d.join("link.png")).expect("link");
            let e = msg(Path::new("link.png"));
            assert!(e.contains("outside the shot's folder"), "{e}");
        }
    }
}
