//! `propsalive render` with a given camera puts the model at the right pixels: the rendered
//! silhouette's bounding box matches the CPU projection of the posed vertices (pa-model
//! skinning + pa-camera projection) within 1.5 px, at three animation times. Also: existing
//! frames are never replaced without --force.

use std::process::Command;

use glam::{DVec2, Vec3};
use pa_camera::{camera_from_world_look_at, CameraModel, Intrinsics};
use pa_model::{anim, skin, Model};

const TOL_PX: f64 = 1.5;

#[test]
fn rendered_silhouette_lands_where_the_camera_model_projects_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let glb = dir.path().join("prop.glb");
    std::fs::write(
        &glb,
        pa_scene::prop_glb(&pa_scene::PropSpec::default()).expect("prop"),
    )
    .expect("write");
    let out = dir.path().join("frames");
    let run = Command::new(env!("CARGO_BIN_EXE_propsalive"))
        .arg("render")
        .arg(&glb)
        .args([
            "--fps",
            "1",
            "--size",
            "320x240",
            "--intrinsics",
            "420,410,150.5,125.5",
        ])
        .args([
            "--eye",
            "0.1,0.2,0.6",
            "--target",
            "0,0.1,0",
            "--unlit",
            "--out",
        ])
        .arg(&out)
        .output()
        .expect("run");
    let stderr = String::from_utf8_lossy(&run.stderr);
    if stderr.contains("no wgpu adapter") || stderr.contains("No wgpu adapter") {
        println!("skipped: no wgpu adapter ({stderr})");
        return;
    }
    assert!(run.status.success(), "{stderr}");

    let model = Model::load(&glb).expect("model");
    let k = Intrinsics {
        fx: 420.0,
        fy: 410.0,
        cx: 150.5,
        cy: 125.5,
        width: 320,
        height: 240,
    };
    let cam = CameraModel::pinhole(k);
    let camera_from_world =
        camera_from_world_look_at(Vec3::new(0.1, 0.2, 0.6), Vec3::new(0.0, 0.1, 0.0), Vec3::Y)
            .expect("camera");
    for frame in 0..3u32 {
        let pose = anim::sample(&model, 0, frame as f32);
        let posed = skin::pose_meshes(&model, &pose);
        let (mut lo, mut hi) = (DVec2::splat(f64::MAX), DVec2::splat(f64::MIN));
        for p in posed.iter().flat_map(|p| &p.positions) {
            let pc = camera_from_world.transform_point3(*p).as_dvec3();
            let px = cam.pixel_from_camera(pc).expect("in front");
            lo = lo.min(px);
            hi = hi.max(px);
        }
        let img = image::open(out.join(format!("frame_{frame:04}.png")))
            .expect("frame")
            .to_rgba8();
        let bg = *img.get_pixel(0, 0);
        let (mut rlo, mut rhi) = (DVec2::splat(f64::MAX), DVec2::splat(f64::MIN));
        for (x, y, p) in img.enumerate_pixels() {
            if *p != bg {
                rlo = rlo.min(DVec2::new(x as f64, y as f64));
                rhi = rhi.max(DVec2::new(x as f64, y as f64));
            }
        }
        // A pixel is covered when its centre is inside; the projected extreme lies within
        // half a pixel of the first/last covered centre.
        for (r, e, what) in [(rlo, lo, "min"), (rhi, hi, "max")] {
            let d = (r - e).abs();
            assert!(
                d.x <= TOL_PX && d.y <= TOL_PX,
                "frame {frame}: rendered {what} {r} vs projected {e}"
            );
        }
    }

    // A second run without --force refuses and leaves the frames as they were.
    let before = std::fs::read(out.join("frame_0000.png")).expect("frame");
    let again = Command::new(env!("CARGO_BIN_EXE_propsalive"))
        .arg("render")
        .arg(&glb)
        .args(["--fps", "1", "--size", "64x48", "--out"])
        .arg(&out)
        .output()
        .expect("run");
    assert!(!again.status.success());
    assert!(String::from_utf8_lossy(&again.stderr).contains("--force"));
    assert_eq!(
        std::fs::read(out.join("frame_0000.png")).expect("frame"),
        before
    );
}
