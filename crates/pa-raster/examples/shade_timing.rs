//! Times the CPU texture stage's two renders on a synthetic twin, with the pipeline's default
//! look (visibility, relighting with a sun, feathered seams, texture memory): a UV sphere of
//! about 8k vertices, 0.14 m across at 0.9 m from a 1280x720 camera (about 60k covered
//! pixels, the generated scene's bust), its in-between turned 25 degrees from the key pose,
//! and a noise frame. Prints the median of each render over N frames.
//!
//! `cargo run --release -p pa-raster --example shade_timing [N] [WIDTHxHEIGHT]`

use std::time::Instant;

use glam::{Mat4, Quat, Vec3};
use pa_raster::sun::SunLight;
use pa_raster::{
    CpuDepthMesh, CpuLiveMesh, CpuPosedMesh, CpuRenderer, FrameCamera, FrameSampler, LiveParams,
    RasterCamera, Shading,
};

fn uv_sphere(rows: usize, cols: usize, radius: f32) -> (Vec<Vec3>, Vec<Vec3>, Vec<u32>) {
    let mut p = Vec::new();
    let mut n = Vec::new();
    for r in 0..=rows {
        let theta = std::f32::consts::PI * r as f32 / rows as f32;
        for c in 0..=cols {
            let phi = std::f32::consts::TAU * c as f32 / cols as f32;
            let d = Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            );
            p.push(d * radius);
            n.push(d);
        }
    }
    let mut idx = Vec::new();
    for r in 0..rows as u32 {
        for c in 0..cols as u32 {
            let a = r * (cols as u32 + 1) + c;
            let b = a + cols as u32 + 1;
            idx.extend_from_slice(&[a, a + 1, b, a + 1, b + 1, b]);
        }
    }
    (p, n, idx)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let mut args = std::env::args().skip(1);
    let frames: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(60);
    let (w, h) = args
        .next()
        .and_then(|s| {
            let (a, b) = s.split_once('x')?;
            Some((a.parse().ok()?, b.parse().ok()?))
        })
        .unwrap_or((1280u32, 720u32));
    let scale = w as f64 / 1280.0;
    let k = pa_camera::Intrinsics {
        fx: 1000.0 * scale,
        fy: 1000.0 * scale,
        cx: w as f64 / 2.0 - 0.5,
        cy: h as f64 / 2.0 - 0.5,
        width: w,
        height: h,
    };
    let camera = RasterCamera::new(&k, 0.01, 50.0);
    let model = pa_camera::CameraModel::pinhole(k);
    let (key_p, key_n, indices) = uv_sphere(63, 127, 0.14);
    let turn = Quat::from_rotation_y(25f32.to_radians());
    let anim_p: Vec<Vec3> = key_p.iter().map(|&p| turn * p).collect();
    let anim_n: Vec<Vec3> = key_n.iter().map(|&n| turn * n).collect();
    let uvs: Vec<[f32; 2]> = (0..key_p.len())
        .map(|i| [(i % 128) as f32 / 128.0, (i / 128) as f32 / 64.0])
        .collect();
    let sun_lit: Vec<[f32; 2]> = (0..key_p.len())
        .map(|i| [((i * 7) % 11) as f32 / 10.0, ((i * 5) % 11) as f32 / 10.0])
        .collect();
    let memory: Vec<[f32; 4]> = (0..key_p.len())
        .map(|i| {
            let c = (i % 3) as f32 / 4.0;
            [0.3 * c, 0.2 * c, 0.1 * c, c]
        })
        .collect();
    let mut seed = 12345u32;
    let frame_rgba: Vec<u8> = (0..w * h * 4)
        .map(|_| {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            (seed >> 24) as u8
        })
        .collect();
    let camera_from_world = Mat4::from_translation(Vec3::new(0.0, 0.0, 0.9));
    let mesh = CpuPosedMesh {
        positions_world: &anim_p,
        normals_world: &anim_n,
        uvs: &uvs,
        indices: &indices,
        albedo: None,
        base_color_factor: [0.8, 0.7, 0.6, 1.0],
        mirrored: false,
        cull_back_faces: true,
    };
    let live = [CpuLiveMesh {
        mesh,
        key_positions_world: &key_p,
        key_normals_world: &key_n,
        memory: &memory,
        sun_lit: &sun_lit,
    }];
    let depth = [CpuDepthMesh {
        positions_world: &key_p,
        indices: &indices,
        mirrored: false,
        cull_back_faces: true,
    }];
    let frame = FrameSampler::new(w, h, &frame_rgba).expect("frame");
    let mut params = LiveParams::new(FrameCamera::new(&model));
    params.visibility = true;
    params.min_facing_cos = -0.2;
    params.max_stretch = 3.0;
    params.relight = true;
    params.feather = true;
    params.fallback_irradiance = [[0.8, 0.1, 0.2, 0.1]; 3];
    params.sun = Some(SunLight {
        toward_light: Vec3::new(0.3, 0.8, -0.5).normalize(),
        ambient_rgb: [0.3; 3],
        direct_rgb: [0.7; 3],
    });
    let shading = Shading::Live { frame, params };
    let mut r = CpuRenderer::new();
    let (mut key_ms, mut twin_ms) = (Vec::new(), Vec::new());
    let mut checksum = 0u64;
    for _ in 0..frames {
        let t = Instant::now();
        r.render_key_depth(&camera, camera_from_world, &depth);
        key_ms.push(t.elapsed().as_secs_f64() * 1e3);
        let t = Instant::now();
        let image = r.render_twin(&camera, camera_from_world, &live, &shading);
        twin_ms.push(t.elapsed().as_secs_f64() * 1e3);
        checksum = image
            .rgba8
            .iter()
            .fold(checksum, |s, &v| s.wrapping_mul(31).wrapping_add(v as u64));
    }
    let (valid, fallback) = r.twin_image().counts();
    println!(
        "{w}x{h}, {} vertices, {} triangles, {valid} live + {fallback} fallback pixels",
        key_p.len(),
        indices.len() / 3
    );
    println!("key depth  {:7.3} ms median", median(key_ms));
    println!("twin       {:7.3} ms median", median(twin_ms));
    println!("checksum   {checksum:016x}");
}
