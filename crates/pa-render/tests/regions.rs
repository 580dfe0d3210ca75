//! Region read-back and region upload (`Renderer::render_live_region`,
//! `Renderer::read_visibility_region`, `Renderer::update_frame_region`): the wgpu path moves
//! only the pixels a prop can reach. Each must give exactly the pixels of the full-frame call
//! inside the region (same draws, same GPU), and refuse a region outside the target.

mod common;

use glam::{Mat4, Vec3};
use pa_render::{
    CpuCamera, CpuTexture, Draw, LiveCamera, LiveTexturing, PixelRegion, RenderError, Renderer,
};

const W: u32 = 320;
const H: u32 = 240;

fn camera() -> CpuCamera {
    CpuCamera {
        intrinsics: common::test_intrinsics().scaled_to(W, H),
        camera_from_world: common::look_at(
            Vec3::new(0.22, -0.05, 0.75),
            Vec3::new(0.18, 0.03, 0.0),
            Vec3::Y,
        ),
        near_m: 0.05,
        far_m: 20.0,
    }
}

/// Rows `region` of a row-major `width`-wide buffer of `texel`-sized items.
fn crop<T: Copy>(full: &[T], width: u32, texel: usize, region: PixelRegion) -> Vec<T> {
    let mut out = Vec::with_capacity(region.area() * texel);
    for y in region.y..region.y + region.height {
        let start = (y * width + region.x) as usize * texel;
        out.extend_from_slice(&full[start..start + region.width as usize * texel]);
    }
    out
}

/// A camera frame of the bent cylinder (the live samples' source) and the renderer.
fn setup(test: &str) -> Option<(Renderer, pa_render::GpuMesh, CpuTexture)> {
    let mut renderer = common::renderer_or_skip(test)?;
    let mesh = renderer
        .upload_mesh(&common::bent_cylinder_mesh())
        .expect("mesh");
    let texture = renderer
        .upload_texture(&common::checker_texture())
        .expect("texture");
    let joints = common::cylinder_joint_matrices(20f32.to_radians());
    let draw = Draw {
        joint_matrices: &joints,
        texture: Some(&texture),
        ..Draw::new(&mesh, Mat4::IDENTITY)
    };
    let direct = renderer
        .render(&camera(), None, &[draw], [0.1, 0.2, 0.3, 1.0], W, H)
        .expect("frame");
    let frame = CpuTexture {
        width: W,
        height: H,
        rgba8: direct.rgba8,
    };
    Some((renderer, mesh, frame))
}

#[test]
fn region_readback_equals_the_full_frame_inside_the_region() {
    let Some((mut renderer, mesh, frame)) =
        setup("region_readback_equals_the_full_frame_inside_the_region")
    else {
        return;
    };
    let camera = camera();
    let gpu_frame = renderer.upload_frame(&frame).expect("upload");
    let key = common::cylinder_joint_matrices(20f32.to_radians());
    let anim = common::cylinder_joint_matrices(45f32.to_radians());
    let key_draw = Draw {
        joint_matrices: &key,
        ..Draw::new(&mesh, Mat4::IDENTITY)
    };
    let mut visibility = renderer
        .render_visibility(&camera, &[key_draw], W, H)
        .expect("visibility");
    let regions = [
        PixelRegion::full(W, H),
        PixelRegion {
            x: 37,
            y: 21,
            width: 131,
            height: 97,
        },
        PixelRegion {
            x: W - 1,
            y: H - 1,
            width: 1,
            height: 1,
        },
    ];
    let bad_regions = [
        PixelRegion {
            x: W - 10,
            y: 0,
            width: 11,
            height: 5,
        },
        PixelRegion {
            x: 0,
            y: 0,
            width: 0,
            height: 5,
        },
        PixelRegion {
            x: u32::MAX,
            y: 0,
            width: 2,
            height: 2,
        },
    ];
    // The key pose's depth: a region of it is that region of the whole map.
    let key_full = renderer.read_visibility(&mut visibility).expect("key");
    let region = regions[1];
    let key_region = renderer
        .read_visibility_region(&mut visibility, region)
        .expect("key region");
    assert_eq!(key_region, crop(&key_full, W, 1, region));
    assert!(key_region.iter().any(|z| z.is_finite()));
    for bad in bad_regions {
        let e = renderer.read_visibility_region(&mut visibility, bad);
        assert!(
            matches!(e, Err(RenderError::RegionOutsideTarget { .. })),
            "{bad:?}"
        );
    }
    let live = LiveTexturing::new(
        &gpu_frame,
        LiveCamera::from_render_camera(&camera, Default::default()),
        Mat4::IDENTITY,
    )
    .with_key_pose(&key, &[])
    .with_visibility(&visibility);
    let draw = Draw {
        joint_matrices: &anim,
        ..Draw::new(&mesh, Mat4::IDENTITY)
    }
    .with_live(live);
    let full = renderer
        .render_live(&camera, None, &[draw], [0.0; 4], W, H)
        .expect("full");
    for region in regions {
        let r = renderer
            .render_live_region(&camera, None, &[draw], [0.0; 4], W, H, region)
            .expect("region");
        assert_eq!((r.region, r.target_size), (region, (W, H)));
        assert_eq!(r.rgba8, crop(&full.frame.rgba8, W, 4, region), "{region:?}");
        let depth_bits = |d: &[f32]| d.iter().map(|z| z.to_bits()).collect::<Vec<_>>();
        assert_eq!(
            depth_bits(&r.depth_m),
            depth_bits(&crop(&full.frame.depth_m, W, 1, region)),
            "{region:?}"
        );
        assert_eq!(
            r.live_valid,
            crop(&full.live_valid, W, 1, region),
            "{region:?}"
        );
    }
    let covered = full.live_valid.iter().filter(|&&c| c != 0).count();
    assert!(covered > 1000, "the twin covers {covered} px");

    for bad in bad_regions {
        let e = renderer.render_live_region(&camera, None, &[draw], [0.0; 4], W, H, bad);
        assert!(
            matches!(e, Err(RenderError::RegionOutsideTarget { .. })),
            "{bad:?}: {e:?}"
        );
    }
}

#[test]
fn region_upload_changes_the_region_only() {
    let Some((mut renderer, mesh, frame)) = setup("region_upload_changes_the_region_only") else {
        return;
    };
    let camera = camera();
    // A frame texture of the real frame, then a grey frame written into one region of it.
    let gpu_frame = renderer.upload_frame(&frame).expect("upload");
    let grey = vec![128u8; frame.rgba8.len()];
    let region = PixelRegion {
        x: 150,
        y: 0,
        width: W - 150,
        height: H,
    };
    renderer
        .update_frame_region(&gpu_frame, &grey, W, H, region)
        .expect("region update");
    // What the live twin samples at the identity pose shows the texture: the real frame left
    // of x = 150, grey right of it (away from the boundary's bilinear taps).
    let key = common::cylinder_joint_matrices(20f32.to_radians());
    let draw = Draw {
        joint_matrices: &key,
        ..Draw::new(&mesh, Mat4::IDENTITY)
    };
    let live = LiveTexturing::new(
        &gpu_frame,
        LiveCamera::from_render_camera(&camera, Default::default()),
        Mat4::IDENTITY,
    )
    .with_key_pose(&key, &[]);
    let out = renderer
        .render_live(&camera, None, &[draw.with_live(live)], [0.0; 4], W, H)
        .expect("live");
    let (mut left, mut right) = ((0usize, 0usize), (0usize, 0usize));
    for y in 0..H as usize {
        for x in 0..W as usize {
            let i = y * W as usize + x;
            if out.live_valid[i] != 255 || (146..=153).contains(&x) {
                continue;
            }
            let px = &out.frame.rgba8[i * 4..i * 4 + 3];
            let near = |want: &[u8]| px.iter().zip(want).all(|(a, b)| a.abs_diff(*b) <= 3);
            if x < 150 {
                left.0 += 1;
                left.1 += usize::from(near(&frame.rgba8[i * 4..i * 4 + 3]));
            } else {
                right.0 += 1;
                right.1 += usize::from(near(&[128, 128, 128]));
            }
        }
    }
    println!("left {left:?}, right {right:?} (live px, of them as expected)");
    assert!(left.0 > 300 && right.0 > 300, "{left:?} {right:?}");
    assert!(left.1 as f64 >= 0.99 * left.0 as f64, "{left:?}");
    assert_eq!(right.1, right.0);

    let bad = renderer.update_frame_region(&gpu_frame, &grey[4..], W, H, region);
    assert!(matches!(bad, Err(RenderError::TextureDataLength { .. })));
    let outside = PixelRegion {
        x: 0,
        y: H,
        width: 1,
        height: 1,
    };
    let bad = renderer.update_frame_region(&gpu_frame, &grey, W, H, outside);
    assert!(matches!(bad, Err(RenderError::RegionOutsideTarget { .. })));
}
