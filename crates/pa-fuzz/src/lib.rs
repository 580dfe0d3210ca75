//! Fuzz targets for Props Alive's file inputs, as plain functions of the input bytes.
//!
//! Each target feeds the bytes to the same entry point the `propsalive` binary uses for that
//! kind of file, then exercises what it returned the way the binary would. A target returns
//! normally on any input; a panic, an abort or a hang is a bug (in the crate named by the
//! panic's location). The targets:
//!
//! | target | entry point | then |
//! |---|---|---|
//! | [`gltf`] | `pa_model::Model::from_slice` (default limits, images decoded) | animation sampling at a few times, rest and sampled poses skinned, bounds, OBJ/STL/GLB export |
//! | [`shot`] | `pa_pipeline::shot::Shot::load` on a file | what `propsalive run` derives: key pose, `marker_from_prop`, the board, the fov camera, the MP4 frame rate |
//! | [`calibration`] | `pa_camera::calib::parse_calibration` as OpenCV YAML, TOML and JSON | projection, unprojection, scaling, writing back |
//! | [`mp4`] | `pa_video::VideoReader::open` on a file, then `next_frame` | up to [`MP4_MAX_FRAMES`] frames |
//! | [`still`] | what `propsalive run` does with a still: `pa_video::still::still_dimensions` and `read_still` (default budget) | `to_rgba8`, `to_rgba16`, `to_luma8` |
//!
//! Two drivers run them: `tests/mutation.rs` (a bounded, deterministic mutation test over the
//! committed seed corpus `corpus/<target>/` and every regression file `regressions/<target>/`,
//! part of `cargo test`), and the AFL binaries of the separate cargo project `fuzz/` at the
//! repository root (see `fuzz/README.md`).
//!
//! Targets that need a path write the input to a scratch folder of this process and thread
//! (`$TMPDIR/pa-fuzz-<pid>/<n>/`, or under [`set_scratch_root`]); [`cleanup`] removes the
//! calling thread's folder.

pub mod harness;
pub mod mutate;

use std::cell::Cell;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::OnceLock;

use glam::DVec3;

/// A fuzz target: consumes any bytes, returns normally unless it found a bug.
pub type Target = fn(&[u8]);

/// Every target, by name (the name is also its corpus and regression folder).
pub const TARGETS: &[(&str, Target)] = &[
    ("gltf", gltf),
    ("shot", shot),
    ("calibration", calibration),
    ("mp4", mp4),
    ("still", still),
];

/// The target called `name`.
pub fn target(name: &str) -> Option<Target> {
    TARGETS.iter().find(|(n, _)| *n == name).map(|&(_, t)| t)
}

/// Most frames the [`mp4`] target decodes from one input.
pub const MP4_MAX_FRAMES: usize = 12;

// --- scratch files ---------------------------------------------------------------------------

static NEXT_THREAD: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    static THREAD_NO: Cell<usize> = const { Cell::new(usize::MAX) };
}

static SCRATCH_ROOT: OnceLock<PathBuf> = OnceLock::new();

/// Sets the folder under which the threads' scratch folders are made, instead of
/// `$TMPDIR/pa-fuzz-<pid>`; only before the first target runs (later calls are ignored). The
/// AFL binaries use one folder per fuzzing campaign: AFL kills its target processes rather
/// than letting them finish, so they never clean up, and a new process would otherwise leave
/// a new folder.
pub fn set_scratch_root(dir: PathBuf) {
    let _ = SCRATCH_ROOT.set(dir);
}

/// The calling thread's scratch folder (not created).
pub fn scratch_dir() -> PathBuf {
    let n = THREAD_NO.with(|c| {
        if c.get() == usize::MAX {
            c.set(NEXT_THREAD.fetch_add(1, Ordering::Relaxed));
        }
        c.get()
    });
    SCRATCH_ROOT
        .get_or_init(|| std::env::temp_dir().join(format!("pa-fuzz-{}", std::process::id())))
        .join(n.to_string())
}

/// Writes `data` to `name` in the calling thread's scratch folder. A failure here is the
/// harness's, not the target's: it panics with a message saying so.
fn scratch_file(name: &str, data: &[u8]) -> PathBuf {
    let dir = scratch_dir();
    let path = dir.join(name);
    // Unlink, then create: truncating a file that holds data makes ext4 flush it (its
    // `auto_da_alloc`), about a millisecond a call; a new file costs tens of microseconds.
    let _ = std::fs::remove_file(&path);
    if let Err(e) = std::fs::create_dir_all(&dir).and_then(|()| std::fs::write(&path, data)) {
        panic!(
            "pa-fuzz harness: cannot write the scratch file {}: {e}",
            path.display()
        );
    }
    path
}

/// Removes the calling thread's scratch folder, and the process's folder when it is empty.
pub fn cleanup() {
    let dir = scratch_dir();
    let _ = std::fs::remove_dir_all(&dir);
    if let Some(parent) = dir.parent() {
        let _ = std::fs::remove_dir(parent);
    }
}

// --- glTF ------------------------------------------------------------------------------------

/// Resources beside a fuzzed glTF: relative URIs resolve in the scratch folder, where these
/// files exist (seeds refer to them), so external buffers and images are read too:
/// `fuzz.bin` (256 bytes: every byte value once, in order) and `fuzz.png` (a 2x2 RGBA PNG).
fn gltf_resources() -> &'static [(&'static str, Vec<u8>)] {
    static RESOURCES: OnceLock<Vec<(&'static str, Vec<u8>)>> = OnceLock::new();
    RESOURCES.get_or_init(|| {
        let bin: Vec<u8> = (0..=255u8).collect();
        let img = image::RgbaImage::from_fn(2, 2, |x, y| {
            image::Rgba([255 * x as u8, 255 * y as u8, 128, 255])
        });
        let mut png = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .expect("encoding a 2x2 PNG in memory");
        vec![("fuzz.bin", bin), ("fuzz.png", png)]
    })
}

/// glTF 2.0 (`.gltf` JSON or `.glb`) through `pa_model`'s loader with the default limits (as
/// `propsalive run` loads the prop), then the animate stage on the result.
pub fn gltf(data: &[u8]) {
    if let Ok(model) = load_gltf(data) {
        exercise_model(&model);
    }
}

/// The loading step of [`gltf`].
pub fn load_gltf(data: &[u8]) -> Result<pa_model::Model, pa_model::ModelError> {
    let dir = scratch_dir();
    for (name, bytes) in gltf_resources() {
        let p = dir.join(name);
        if !p.exists() {
            scratch_file(name, bytes);
        }
    }
    let options = pa_model::LoadOptions::default();
    pa_model::Model::from_slice(data, "fuzz.glb", Some(&dir), &options)
}

fn exercise_model(model: &pa_model::Model) {
    use pa_model::{anim, export, skin};
    let _ = model.vertex_count();
    let _ = model.triangle_count();
    let _ = model.mesh_nodes().count();
    let rest = anim::Pose::rest(model);
    let posed = skin::pose_meshes(model, &rest);
    let _ = skin::bounds(&posed);
    for (a, animation) in model.animations.iter().enumerate().take(4) {
        let d = animation.duration_s;
        if let Some(name) = &animation.name {
            let _ = model.find_animation(name);
        }
        for t in [0.0, 0.37 * d, d, d + 0.5, -0.25] {
            if t.is_finite() {
                let pose = anim::sample(model, a, t);
                let _ = skin::bounds(&skin::pose_meshes(model, &pose));
            }
        }
    }
    let _ = model.find_animation("0");
    let _ = export::obj_bytes(model, &posed);
    let _ = export::stl_bytes(model, &posed);
    if let Ok(glb) = export::glb_bytes(model, &posed) {
        let _ = pa_model::Model::from_slice(&glb, "export.glb", None, &Default::default());
    }
}

// --- shot file -------------------------------------------------------------------------------

/// A shot TOML through `Shot::load`, then what `propsalive run` derives from a loaded shot
/// (`pa_pipeline::shot_config`: the board, and the camera of the fov branch).
pub fn shot(data: &[u8]) {
    use pa_pipeline::shot::Shot;
    use pa_pipeline::shot_config;
    let path = scratch_file("shot.toml", data);
    let Ok(shot) = Shot::load(&path) else {
        return;
    };
    let key = &shot.key_poses[shot.present_key_index()];
    let _ = key.frame as f32 / shot.fps;
    let _ = shot.placement.marker_from_prop();
    let _ = Shot::resolve(&path, &shot.model);
    if let Some(c) = &shot.camera.calibration {
        let _ = Shot::resolve(&path, c);
    }
    if let Ok(fps) = pa_video::Fps::from_f64(shot.fps as f64) {
        let _ = fps.mp4_timebase();
        let _ = fps.as_f64();
    }
    // What `propsalive run` and `preview` derive from it (`pa_pipeline::shot_config`): the
    // board, and the camera without a calibration file (a calibration is its own target).
    if let Ok(board) = shot_config::board_from_shot(&shot, &path) {
        let _ = board.all_object_points();
    }
    if shot.camera.calibration.is_none() {
        if let Ok(camera) = shot_config::camera_for_shot(&shot, &path, 640, 480, "fuzz") {
            exercise_camera(&camera.value);
        }
    }
    let _ = shot.to_toml();
}

// --- calibration -----------------------------------------------------------------------------

/// Calibration text in each format the loader reads (OpenCV YAML, TOML, JSON). Like
/// `load_calibration`, bytes that are not UTF-8 are refused before parsing.
pub fn calibration(data: &[u8]) {
    use pa_camera::calib::{format_calibration, parse_calibration, CalibFormat};
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    for format in [
        CalibFormat::OpencvYaml,
        CalibFormat::Toml,
        CalibFormat::Json,
    ] {
        let Ok(model) = parse_calibration(text, format, "fuzz") else {
            continue;
        };
        exercise_camera(&model);
        if let Ok(text) = format_calibration(&model, format, "fuzz") {
            let _ = parse_calibration(&text, format, "fuzz");
        }
    }
}

fn exercise_camera(model: &pa_camera::CameraModel) {
    let k = &model.intrinsics;
    let _ = k.matrix();
    let _ = k.fov_y_rad();
    let _ = k.clip_from_camera(0.01, 100.0);
    // `fit_intrinsics` of `propsalive track`/`run`: the calibration scaled to the frames.
    let _ = k.scaled_to(
        k.width.saturating_mul(2).max(1),
        k.height.saturating_mul(2).max(1),
    );
    let _ = k.scaled_to(640, 480);
    let (w, h) = (f64::from(k.width), f64::from(k.height));
    for p in [
        glam::DVec2::new(0.0, 0.0),
        glam::DVec2::new(w - 1.0, h - 1.0),
        glam::DVec2::new(k.cx, k.cy),
        glam::DVec2::new(-w, 2.0 * h),
    ] {
        let ray = model.ray_from_pixel(p);
        let _ = model.camera_from_pixel(p, 0.5);
        let _ = model.pixel_from_camera(ray);
    }
    for p in [
        DVec3::new(0.1, -0.2, 1.0),
        DVec3::new(3.0, 2.0, 0.1),
        DVec3::Z,
    ] {
        let _ = model.pixel_from_camera(p);
    }
}

// --- MP4 -------------------------------------------------------------------------------------

/// An MP4/MOV file through `VideoReader::open` (sniffing, our demuxer, the H.264 parameter
/// sets, OpenH264) and up to [`MP4_MAX_FRAMES`] calls of `next_frame`, going on after a
/// damaged frame as `propsalive run` does.
pub fn mp4(data: &[u8]) {
    use pa_video::FrameSource;
    let path = scratch_file("input.mp4", data);
    let Ok(mut reader) = pa_video::VideoReader::open(&path) else {
        return;
    };
    let _ = reader.describe();
    let _ = reader.frame_size();
    for _ in 0..MP4_MAX_FRAMES {
        match reader.next_frame() {
            Ok(Some(frame)) => {
                let _ = frame.pts.as_secs_f64();
                let _ = image::RgbaImage::from_raw(frame.width, frame.height, frame.rgba);
            }
            Ok(None) => break,
            Err(_) => {}
        }
    }
}

// --- stills ----------------------------------------------------------------------------------

/// A still as `propsalive run` (and `track`, `preview`) reads one from a folder of stills:
/// `pa_video::still::still_dimensions` for the take's size, then `pa_video::still::read_still`
/// (regular file, budgets checked from the header, truncated JPEGs refused; default
/// [`pa_video::still::StillBudget`]) and the conversions the frame goes through (`to_rgba8`;
/// `to_rgba16` for `--bit-depth 16`; `to_luma8` in `propsalive track`). The scratch file's
/// extension (`.png`, `.jpg`, `.tif`, the extensions the commands list) follows the bytes'
/// signature.
pub fn still(data: &[u8]) {
    if let Ok(img) = open_still(data) {
        let _ = img.to_rgba8();
        let _ = img.to_rgba16();
        let _ = img.to_luma8();
    }
}

/// The reading step of [`still`].
pub fn open_still(data: &[u8]) -> Result<image::DynamicImage, pa_video::still::StillError> {
    use pa_video::still::{read_still, still_dimensions, StillBudget};
    let ext = match image::guess_format(data) {
        Ok(image::ImageFormat::Jpeg) => "jpg",
        Ok(image::ImageFormat::Tiff) => "tif",
        _ => "png",
    };
    let path = scratch_file(&format!("still.{ext}"), data);
    let budget = StillBudget::default();
    let _ = still_dimensions(&path, &budget);
    read_still(&path, &budget)
}
