//! From a loaded [`Shot`] to what the pipeline and the tracker take: the marker board, the
//! camera at the frames' size (the calibration fitted to it, or an ideal pinhole with the
//! shot's field of view), and the size to ask a camera for. Shared by `propsalive run` and
//! `propsalive preview` (and `track`, for [`fit_intrinsics`]).
//!
//! Nothing here prints: a calibration scaled to the frames comes back as a [`Scaled`] note
//! for the caller to say.

use std::path::{Path, PathBuf};

use pa_camera::{CameraModel, Intrinsics};
use pa_track::board::BoardTag;
use pa_track::{Board, ImageTarget, TagFamily, TrackTarget};

use crate::shot::{Shot, ShotError};

/// The marker board of a shot (`[marker]`).
pub fn board_from_shot(shot: &Shot, shot_path: &Path) -> Result<Board, ShotError> {
    let family: TagFamily = shot
        .marker
        .family
        .parse()
        .map_err(|source| ShotError::Family {
            shot: shot_path.to_path_buf(),
            source,
        })?;
    let layout = pa_track::family_layout(family)?;
    let mut tags = Vec::new();
    for t in &shot.marker.tags {
        if t.id >= layout.id_count {
            return Err(ShotError::TagId {
                shot: shot_path.to_path_buf(),
                id: t.id,
                family,
                id_count: layout.id_count,
            });
        }
        tags.push(BoardTag {
            id: t.id,
            center_m: glam::DVec2::new(t.center_m[0], t.center_m[1]),
            size_m: t.size_m,
            rotation_rad: 0.0,
        });
    }
    Ok(Board { family, tags })
}

/// The shot's marker picture (`[marker] image`, resolved against the shot's folder and
/// refused when it leaves it) and its printed width in metres; `None` for a board of tags.
pub fn marker_picture(shot: &Shot, shot_path: &Path) -> Result<Option<(PathBuf, f64)>, ShotError> {
    match (&shot.marker.image, shot.marker.width_m) {
        (Some(p), Some(width_m)) => Ok(Some((
            crate::shot_hide::inside_shot_folder(shot_path, p, "[marker] image")?,
            width_m,
        ))),
        _ => Ok(None),
    }
}

/// What the tracker follows for a shot: its board, its picture, or both in one marker frame
/// (the picture's; `board` may then be empty).
pub fn track_target(board: Board, picture: Option<ImageTarget>) -> TrackTarget {
    match picture {
        None => TrackTarget::Board(board),
        Some(image) if board.tags.is_empty() => TrackTarget::Image(Box::new(image)),
        Some(image) => TrackTarget::ImageAndBoard {
            image: Box::new(image),
            board,
        },
    }
}

/// A calibration scaled to frames of the same aspect ratio: the note the caller says.
#[derive(Debug, Clone, PartialEq)]
pub struct Scaled {
    pub frame_name: String,
    pub width: u32,
    pub height: u32,
    pub calib_name: String,
    pub calib_width: u32,
    pub calib_height: u32,
}

impl std::fmt::Display for Scaled {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "note: {} is {}x{} but the calibration {} is for {}x{}; scaling the intrinsics by {:.4} (same aspect ratio)",
            self.frame_name,
            self.width,
            self.height,
            self.calib_name,
            self.calib_width,
            self.calib_height,
            self.width as f64 / self.calib_width as f64
        )
    }
}

/// Intrinsics fitted to a frame size, and the note when they were scaled.
#[derive(Debug, Clone, PartialEq)]
pub struct Fitted<T> {
    pub value: T,
    pub scaled: Option<Scaled>,
}

/// Intrinsics fitted to a frame size: equal, scaled (same aspect ratio, with a [`Scaled`]
/// note) or refused. `calib_name` and `frame_name` name both in the messages.
pub fn fit_intrinsics(
    k: &Intrinsics,
    width: u32,
    height: u32,
    calib_name: &str,
    frame_name: &str,
) -> Result<Fitted<Intrinsics>, ShotError> {
    if k.width == width && k.height == height {
        return Ok(Fitted {
            value: *k,
            scaled: None,
        });
    }
    let a_cal = k.width as f64 / k.height as f64;
    let a_img = width as f64 / height as f64;
    if ((a_cal - a_img) / a_cal).abs() > 0.005 {
        return Err(ShotError::AspectRatio {
            frame_name: frame_name.to_string(),
            width,
            height,
            calib_name: calib_name.to_string(),
            calib_width: k.width,
            calib_height: k.height,
            frame_aspect: a_img,
            calib_aspect: a_cal,
        });
    }
    Ok(Fitted {
        value: k.scaled_to(width, height),
        scaled: Some(Scaled {
            frame_name: frame_name.to_string(),
            width,
            height,
            calib_name: calib_name.to_string(),
            calib_width: k.width,
            calib_height: k.height,
        }),
    })
}

/// The shot's camera at a frame size: its calibration (scaled to the size when the aspect
/// ratio agrees), or an ideal pinhole with its vertical field of view. `frame_desc` names the
/// frames in messages.
pub fn camera_for_shot(
    shot: &Shot,
    shot_path: &Path,
    width: u32,
    height: u32,
    frame_desc: &str,
) -> Result<Fitted<CameraModel>, ShotError> {
    match (&shot.camera.calibration, shot.camera.fov_y_deg) {
        (Some(c), _) => {
            let path = Shot::resolve(shot_path, c);
            let model = load_calibration(&path)?;
            let k = fit_intrinsics(
                &model.intrinsics,
                width,
                height,
                &path.display().to_string(),
                frame_desc,
            )?;
            Ok(Fitted {
                value: CameraModel {
                    intrinsics: k.value,
                    distortion: model.distortion,
                },
                scaled: k.scaled,
            })
        }
        (None, Some(fov)) => {
            if !(fov.is_finite() && fov > 1.0 && fov < 179.0) {
                return Err(ShotError::FieldOfView {
                    shot: shot_path.to_path_buf(),
                    fov,
                });
            }
            Ok(Fitted {
                value: CameraModel::pinhole(Intrinsics::from_fov_y(
                    fov.to_radians(),
                    width,
                    height,
                )?),
                scaled: None,
            })
        }
        (None, None) => Err(ShotError::NoCamera {
            shot: shot_path.to_path_buf(),
        }),
    }
}

/// The frame size to ask a camera for when none is given: the shot's calibration size, else
/// 1280x720.
pub fn camera_request(shot: &Shot, shot_path: &Path) -> Result<(u32, u32), ShotError> {
    if let Some(c) = &shot.camera.calibration {
        let path = Shot::resolve(shot_path, c);
        let model = load_calibration(&path)?;
        return Ok((model.intrinsics.width, model.intrinsics.height));
    }
    Ok((1280, 720))
}

fn load_calibration(path: &Path) -> Result<CameraModel, ShotError> {
    pa_camera::calib::load_calibration(path).map_err(|source| ShotError::Calibration {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn shot(text: &str) -> (tempfile::TempDir, PathBuf, Shot) {
        let dir = tempfile::tempdir().expect("tmp");
        let path = dir.path().join("shot.toml");
        std::fs::write(&path, text).expect("write");
        let shot = Shot::load(&path).expect("shot");
        (dir, path, shot)
    }

    const SHOT: &str = r#"
model = "prop.glb"
fps = 24
[camera]
fov_y_deg = 50
[marker]
family = "tag36h11"
tags = [{ id = 3, center_m = [0.0, 0.0], size_m = 0.08 }]
[[key_poses]]
name = "A"
frame = 0
"#;

    #[test]
    fn board_and_pinhole_camera_from_a_shot() {
        let (_dir, path, mut shot) = shot(SHOT);
        let board = board_from_shot(&shot, &path).expect("board");
        assert_eq!(board.tags.len(), 1);
        assert_eq!(board.tags[0].id, 3);
        let cam = camera_for_shot(&shot, &path, 640, 480, "the stills").expect("camera");
        assert!(cam.scaled.is_none());
        assert_eq!(
            (cam.value.intrinsics.width, cam.value.intrinsics.height),
            (640, 480)
        );
        assert_eq!(camera_request(&shot, &path).expect("size"), (1280, 720));
        shot.marker.tags[0].id = 100_000;
        let err = board_from_shot(&shot, &path).expect_err("no such id");
        assert!(
            err.to_string().starts_with(&format!(
                "{}: tag id 100000 does not exist in ",
                path.display()
            )),
            "{err}"
        );
        shot.marker.family = "tag99".into();
        let err = board_from_shot(&shot, &path).expect_err("no such family");
        assert_eq!(
            err.to_string(),
            format!("{}: [marker] family", path.display())
        );
        shot.camera.fov_y_deg = Some(180.0);
        let err = camera_for_shot(&shot, &path, 640, 480, "x").expect_err("fov");
        assert_eq!(
            err.to_string(),
            format!(
                "{}: [camera] fov_y_deg must be in (1, 179), got 180",
                path.display()
            )
        );
        shot.camera.fov_y_deg = None;
        let err = camera_for_shot(&shot, &path, 640, 480, "x").expect_err("none");
        assert_eq!(
            err.to_string(),
            format!(
                "{}: [camera] needs calibration or fov_y_deg",
                path.display()
            )
        );
        shot.camera.calibration = Some("missing.yaml".into());
        let err = camera_request(&shot, &path).expect_err("missing calibration");
        assert_eq!(
            err.to_string(),
            format!(
                "loading the calibration {}",
                path.with_file_name("missing.yaml").display()
            )
        );
    }

    #[test]
    fn intrinsics_fit_the_frames_or_are_refused() {
        let k = Intrinsics::from_fov_y(0.8, 640, 480).expect("k");
        let same = fit_intrinsics(&k, 640, 480, "c.yaml", "f.png").expect("same");
        assert_eq!((same.value, same.scaled), (k, None));
        let half = fit_intrinsics(&k, 320, 240, "c.yaml", "f.png").expect("scaled");
        assert_eq!(half.value, k.scaled_to(320, 240));
        assert_eq!(
            half.scaled.map(|s| s.to_string()).as_deref(),
            Some("note: f.png is 320x240 but the calibration c.yaml is for 640x480; scaling the intrinsics by 0.5000 (same aspect ratio)")
        );
        let err = fit_intrinsics(&k, 640, 360, "c.yaml", "f.png").expect_err("aspect");
        assert_eq!(
            err.to_string(),
            "f.png is 640x360 but the calibration c.yaml is for 640x480 (aspect 1.7778 vs 1.3333): a different aspect ratio means a crop or another camera mode; calibrate at this resolution"
        );
    }
}
