//! Helpers shared by the end-to-end tests of `propsalive run` (`run_cli.rs`, `run_video.rs`):
//! a fresh folder under the target's temporary directory, the built-in prop with a shot file
//! that matches the generated scene, the binary's `run` command, and reading a take back.

#![allow(dead_code)]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::Mutex;
use std::time::Duration;

use pa_scene::prop::PropSpec;
use pa_scene::scene::{marker_from_prop, set_board};
use pa_scene::SceneSpec;

pub fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_propsalive")
}

/// Tests of one file run one at a time (each runs the renderer; the kill tests need the
/// machine).
pub fn lock() -> std::sync::MutexGuard<'static, ()> {
    static L: Mutex<()> = Mutex::new(());
    L.lock().unwrap_or_else(|e| e.into_inner())
}

/// A fresh, empty `<prefix><pid>` folder under the target's temporary directory; folders of
/// earlier test runs with that prefix older than an hour are removed.
pub fn fresh_root(prefix: &str) -> PathBuf {
    let tmp = Path::new(env!("CARGO_TARGET_TMPDIR"));
    for e in std::fs::read_dir(tmp).into_iter().flatten().flatten() {
        let old = e
            .metadata()
            .and_then(|m| m.modified())
            .ok()
            .and_then(|t| t.elapsed().ok())
            .is_some_and(|age| age > Duration::from_secs(3600));
        if old && e.file_name().to_string_lossy().starts_with(prefix) {
            let _ = std::fs::remove_dir_all(e.path());
        }
    }
    let root = tmp.join(format!("{prefix}{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    std::fs::create_dir_all(&root).expect("mkdir");
    root
}

/// Writes `root/prop.glb` (the built-in bust) and `root/shot.toml` matching a scene of `spec`:
/// the board's tags, the upright placement, the scene's field of view and fps, key pose A at
/// frame 0. Returns the shot's path.
pub fn write_prop_and_shot(root: &Path, spec: &SceneSpec) -> PathBuf {
    let glb = pa_scene::prop_glb(&PropSpec::default()).expect("glb");
    std::fs::write(root.join("prop.glb"), glb).expect("write glb");
    let m = marker_from_prop();
    assert!((m.transform_vector3(glam::Vec3::Y) - glam::Vec3::NEG_Z).length() < 1e-6);
    let mut shot = format!(
        "model = \"prop.glb\"\nanimation = \"Animate\"\nfps = {}\npresent_key = \"A\"\n\n\
         [[key_poses]]\nname = \"A\"\nframe = 0\n\n[camera]\nfov_y_deg = {}\n\n\
         [placement]\nupright = true\nyaw_deg = 0.0\n\n[marker]\nfamily = \"tag36h11\"\n",
        spec.fps, spec.fov_y_deg
    );
    for t in set_board().tags {
        shot.push_str(&format!(
            "[[marker.tags]]\nid = {}\ncenter_m = [{}, {}]\nsize_m = {}\n",
            t.id, t.center_m.x, t.center_m.y, t.size_m
        ));
    }
    let shot_path = root.join("shot.toml");
    std::fs::write(&shot_path, shot).expect("write shot");
    shot_path
}

/// `propsalive run SHOT --input INPUT --out OUT EXTRA...`, not started.
pub fn command(shot: &Path, input: &Path, out: &Path, extra: &[&str]) -> Command {
    let mut c = Command::new(bin());
    c.arg("run")
        .arg(shot)
        .arg("--input")
        .arg(input)
        .arg("--out")
        .arg(out)
        .args(extra);
    c
}

/// Runs [`command`] to the end.
pub fn run(shot: &Path, input: &Path, out: &Path, extra: &[&str]) -> Output {
    command(shot, input, out, extra).output().expect("runs")
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The files of a take's sub-folder: name -> bytes (hidden temporary files included, to catch
/// leftovers). While a run is going, a temporary file can be renamed between the listing and
/// the read: a file that vanished is left out (regression: the kill test once failed on CI
/// with NotFound).
pub fn files(dir: &Path, sub: &str) -> BTreeMap<String, Vec<u8>> {
    let mut m = BTreeMap::new();
    if let Ok(rd) = std::fs::read_dir(dir.join(sub)) {
        for e in rd.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            match std::fs::read(e.path()) {
                Ok(bytes) => {
                    m.insert(name, bytes);
                }
                Err(err) if err.kind() == std::io::ErrorKind::NotFound => {}
                Err(err) => panic!("read {name}: {err}"),
            }
        }
    }
    m
}

/// The log's lines, parsed; panics on a duplicate index or an unparsable line.
pub fn log(dir: &Path) -> BTreeMap<u64, serde_json::Value> {
    let text = std::fs::read_to_string(dir.join("log.jsonl")).expect("log");
    let mut m = BTreeMap::new();
    for line in text.lines() {
        let v: serde_json::Value = serde_json::from_str(line).expect("json line");
        let i = v["index"].as_u64().expect("index");
        assert!(m.insert(i, v).is_none(), "duplicate log line for index {i}");
    }
    m
}

/// A generated take of `stills` PNG stills (`s1.png` .. `sN.png`, so natural order matters) of
/// `width` x `height` in `<prefix><pid>/stills`, the prop and shot file, and the reference output
/// of an uninterrupted run in `reference/`. None (with a "skipped" line) without a renderer.
pub struct GeneratedTake {
    pub root: PathBuf,
    pub stills: PathBuf,
    pub shot: PathBuf,
    pub reference: PathBuf,
}

/// The renderer, or None with a "skipped" line (a machine without any adapter).
pub fn renderer_or_skip() -> Option<pa_render::Renderer> {
    match pa_render::Renderer::new() {
        Ok(r) => Some(r),
        Err(e) => {
            println!("skipped: no renderer ({e})");
            None
        }
    }
}

/// The built-in scene of `stills` frames at `width` x `height`, its input stills written as
/// `s1.png` .. `sN.png` (so natural order matters) into `root/stills`: the scene, its spec and
/// the stills' folder.
pub fn scene_stills(
    renderer: &mut pa_render::Renderer,
    root: &Path,
    stills: u32,
    width: u32,
    height: u32,
) -> (pa_scene::Scene, SceneSpec, PathBuf) {
    let dir = root.join("stills");
    std::fs::create_dir_all(&dir).expect("mkdir");
    let spec = SceneSpec {
        width,
        height,
        frames: stills,
        ..SceneSpec::default()
    };
    let scene = pa_scene::Scene::new(spec.clone(), renderer).expect("scene");
    for i in 0..stills {
        let f = scene.frame(renderer, i).expect("frame");
        let img = image::RgbaImage::from_raw(width, height, f.input.rgba8).expect("size");
        img.save(dir.join(format!("s{}.png", i + 1))).expect("save");
    }
    (scene, spec, dir)
}

pub fn generate_take(prefix: &str, stills: u32, width: u32, height: u32) -> Option<GeneratedTake> {
    let mut renderer = renderer_or_skip()?;
    let root = fresh_root(prefix);
    let (_, spec, dir) = scene_stills(&mut renderer, &root, stills, width, height);
    let shot = write_prop_and_shot(&root, &spec);
    drop(renderer);
    let reference = root.join("reference");
    let o = run(&shot, &dir, &reference, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    Some(GeneratedTake {
        root,
        stills: dir,
        shot,
        reference,
    })
}

/// (translation difference mm, rotation difference degrees) of two camera_from_marker.
pub fn pose_delta(a: &glam::DMat4, b: &glam::DMat4) -> (f64, f64) {
    let t = (a.w_axis.truncate() - b.w_axis.truncate()).length() * 1e3;
    // The angle of the rotation between them: |Ra - Rb|_F = 2 sqrt(2) sin(angle / 2) (well
    // conditioned for small angles, unlike the trace's acos).
    let d = glam::DMat3::from_mat4(*a) - glam::DMat3::from_mat4(*b);
    let f =
        (d.x_axis.length_squared() + d.y_axis.length_squared() + d.z_axis.length_squared()).sqrt();
    let angle = 2.0 * (f / (2.0 * 2f64.sqrt())).clamp(0.0, 1.0).asin();
    (t, angle.to_degrees())
}
