//! The shot's `[scan]` table: the scan pass before a take (`propsalive run --scan`).
//!
//! ```toml
//! [scan]
//! input = "scan"   # a folder of stills or a video circling the key prop (relative to the shot)
//! ```
//!
//! The animator circles the key prop once with the camera; those frames are tracked and fed to
//! the pipeline's texture memory only ([`crate::ar::ArPipeline::remember`]). The path is
//! relative to the shot's folder and must stay inside it (no `..`, not absolute).

use std::path::{Component, Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::shot::ShotError;

/// The `[scan]` table as written.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct ShotScan {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub input: Option<PathBuf>,
}

impl ShotScan {
    pub fn is_empty(&self) -> bool {
        self.input.is_none()
    }

    /// The scan input resolved against the shot file `shot_path`, or None without one.
    /// Refused (naming the shot file) when the path is absolute or leaves the shot's folder.
    pub fn resolve(&self, shot_path: &Path) -> Result<Option<PathBuf>, ShotError> {
        let Some(p) = &self.input else {
            return Ok(None);
        };
        let escapes = p.is_absolute()
            || p.components().any(|c| {
                matches!(
                    c,
                    Component::ParentDir | Component::RootDir | Component::Prefix(_)
                )
            });
        if escapes || p.as_os_str().is_empty() {
            return Err(ShotError::Invalid {
                path: shot_path.into(),
                message: format!(
                    "[scan] input = {:?} must be a path inside the shot's folder (relative, no \"..\")",
                    p.display().to_string()
                ),
            });
        }
        Ok(Some(shot_path.parent().unwrap_or(Path::new(".")).join(p)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scan_paths_stay_inside_the_shot_folder() {
        let shot = Path::new("/takes/shot1/shot.toml");
        let s = |p: &str| ShotScan {
            input: Some(p.into()),
        };
        assert_eq!(ShotScan::default().resolve(shot).unwrap(), None);
        assert_eq!(
            s("scan").resolve(shot).unwrap(),
            Some(PathBuf::from("/takes/shot1/scan"))
        );
        assert_eq!(
            s("scans/orbit.mp4").resolve(shot).unwrap(),
            Some(PathBuf::from("/takes/shot1/scans/orbit.mp4"))
        );
        for bad in ["../other", "/etc/scan", "a/../../b", ""] {
            let e = s(bad).resolve(shot).unwrap_err().to_string();
            assert!(
                e.contains("shot.toml") && e.contains("[scan] input"),
                "{bad}: {e}"
            );
        }
    }

    #[test]
    fn the_scan_table_is_read_from_a_shot() {
        let text = "model = \"m.glb\"\n[[key_poses]]\nname = \"k\"\nframe = 0\n[camera]\nfov_y_deg = 45.0\n[marker]\n[[marker.tags]]\nid = 0\ncenter_m = [0.0, 0.0]\nsize_m = 0.05\n[scan]\ninput = \"orbit\"\n";
        let shot = crate::shot::Shot::parse(text, Path::new("/s/shot.toml")).unwrap();
        assert_eq!(shot.scan.input, Some(PathBuf::from("orbit")));
        let bad = text.replace("input", "inptu");
        let e = crate::shot::Shot::parse(&bad, Path::new("/s/shot.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("scan.inptu"), "{e}");
    }
}
