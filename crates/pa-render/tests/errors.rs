//! Bad input gives typed errors whose messages name the problem; nothing panics.

mod common;

use glam::Mat4;
use pa_render::{CpuCamera, CpuMesh, CpuTexture, Draw, RenderError};

fn assert_message(err: &RenderError, parts: &[&str]) {
    let msg = err.to_string();
    for part in parts {
        assert!(
            msg.contains(part),
            "message {msg:?} should mention {part:?}"
        );
    }
}

fn skinned_triangle() -> CpuMesh {
    CpuMesh {
        positions: vec![[0.0, 0.0, 1.0], [0.1, 0.0, 1.0], [0.0, 0.1, 1.0]],
        joints: vec![
            [0, 0, 0, 0, 0, 0, 0, 0],
            [1, 0, 0, 0, 0, 0, 0, 0],
            [3, 7, 0, 0, 0, 0, 0, 0],
        ],
        // Vertex 2 uses joint 3 with weight 1 and joint 7 with weight 0 (ignored).
        weights: vec![[1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]; 3],
        indices: vec![0, 1, 2],
        morph_position_deltas: vec![vec![[0.0; 3]; 3]; 2],
        ..Default::default()
    }
}

#[test]
fn mesh_validation_errors_need_no_gpu() {
    let good = common::quad_mesh(1.0, 1.0);
    assert!(good.validate().is_ok());

    let mut m = good.clone();
    m.normals.pop();
    let e = m.validate().unwrap_err();
    assert!(matches!(
        e,
        RenderError::AttributeLength {
            expected: 4,
            actual: 3,
            ..
        }
    ));
    assert_message(&e, &["normals", "3", "4"]);

    let mut m = good.clone();
    m.uvs.push([0.0, 0.0]);
    assert_message(&m.validate().unwrap_err(), &["uvs", "5", "4"]);

    let mut m = skinned_triangle();
    m.weights.pop();
    assert_message(&m.validate().unwrap_err(), &["weights", "2", "3"]);

    let mut m = skinned_triangle();
    m.morph_position_deltas[1].pop();
    assert_message(&m.validate().unwrap_err(), &["morph_position_deltas[1]"]);

    let mut m = good.clone();
    m.indices[4] = 99;
    let e = m.validate().unwrap_err();
    assert!(matches!(
        e,
        RenderError::IndexOutOfRange {
            position: 4,
            index: 99,
            vertex_count: 4
        }
    ));
    assert_message(&e, &["index #4 = 99", "out of range", "4 vertices"]);

    let mut m = good.clone();
    m.indices.pop();
    assert_message(&m.validate().unwrap_err(), &["not a multiple of 3"]);

    assert_message(&CpuMesh::default().validate().unwrap_err(), &["empty"]);

    let mut m = good.clone();
    m.positions[2][1] = f32::NAN;
    assert_message(
        &m.validate().unwrap_err(),
        &["positions", "vertex 2", "not finite"],
    );

    let mut m = good;
    m.morph_position_deltas = vec![vec![[0.0; 3]; 4]; pa_render::MAX_MORPH_TARGETS + 1];
    assert_message(&m.validate().unwrap_err(), &["257 morph targets", "256"]);
}

#[test]
fn draw_and_render_errors() {
    let Some(mut renderer) = common::renderer_or_skip("draw_errors") else {
        return;
    };
    let camera = common::camera(Mat4::IDENTITY);

    // Upload rejects invalid meshes and textures.
    let mut bad = common::quad_mesh(1.0, 1.0);
    bad.indices[0] = 4;
    assert_message(&renderer.upload_mesh(&bad).unwrap_err(), &["index #0 = 4"]);
    let tex = CpuTexture {
        width: 4,
        height: 4,
        rgba8: vec![0; 10],
    };
    assert_message(
        &renderer.upload_texture(&tex).unwrap_err(),
        &["10 bytes", "needs 64"],
    );
    let tex = CpuTexture {
        width: 0,
        height: 4,
        rgba8: vec![],
    };
    assert_message(
        &renderer.upload_texture(&tex).unwrap_err(),
        &["texture size 0x4"],
    );

    let mesh = renderer.upload_mesh(&skinned_triangle()).expect("upload");
    let render = |renderer: &mut pa_render::Renderer, draw: Draw<'_>| {
        renderer
            .render(&camera, None, &[draw], [0.0; 4], 160, 120)
            .unwrap_err()
    };

    // Joint index >= joint_matrices.len() (joint 3 with weight 1; joint 7 has weight 0).
    let three = [Mat4::IDENTITY; 3];
    let e = render(
        &mut renderer,
        Draw {
            joint_matrices: &three,
            ..Draw::new(&mesh, Mat4::IDENTITY)
        },
    );
    assert!(matches!(
        e,
        RenderError::JointIndexOutOfRange {
            draw: 0,
            vertex: 2,
            joint: 3,
            joint_count: 3
        }
    ));
    assert_message(&e, &["vertex 2", "joint 3", "3 joint matrices"]);
    let e = renderer.skin_positions_gpu(&mesh, &three, &[]).unwrap_err();
    assert_message(&e, &["joint 3"]);
    // Four joints are enough.
    let four = [Mat4::IDENTITY; 4];
    assert!(renderer.skin_positions_gpu(&mesh, &four, &[]).is_ok());

    let many = vec![Mat4::IDENTITY; pa_render::MAX_JOINTS + 1];
    let e = render(
        &mut renderer,
        Draw {
            joint_matrices: &many,
            ..Draw::new(&mesh, Mat4::IDENTITY)
        },
    );
    assert_message(&e, &["4097 joint matrices", "at most 4096"]);

    let e = render(
        &mut renderer,
        Draw {
            morph_weights: &[1.0],
            ..Draw::new(&mesh, Mat4::IDENTITY)
        },
    );
    assert_message(&e, &["1 morph weights", "2 morph targets"]);

    let nan = Mat4::from_cols_array(&[f32::NAN; 16]);
    let e = render(&mut renderer, Draw::new(&mesh, nan));
    assert_message(&e, &["world_from_mesh", "not finite"]);

    let rigid = renderer
        .upload_mesh(&common::quad_mesh(1.0, 1.0))
        .expect("upload");
    let e = render(
        &mut renderer,
        Draw {
            joint_matrices: &four,
            ..Draw::new(&rigid, Mat4::IDENTITY)
        },
    );
    assert_message(&e, &["no joints/weights"]);

    // Render size: zero and absurd.
    for (w, h) in [(0, 120), (160, 0), (100_000, 10), (10, u32::MAX)] {
        let e = renderer
            .render(
                &camera,
                None,
                &[Draw::new(&rigid, Mat4::IDENTITY)],
                [0.0; 4],
                w,
                h,
            )
            .unwrap_err();
        assert!(matches!(e, RenderError::InvalidRenderSize { .. }), "{e}");
        assert_message(&e, &[&format!("render size {w}x{h}")]);
    }

    // Camera.
    let bad_camera = CpuCamera {
        near_m: 0.0,
        ..camera
    };
    let e = renderer
        .render(&bad_camera, None, &[], [0.0; 4], 160, 120)
        .unwrap_err();
    assert_message(&e, &["invalid camera", "near_m = 0"]);
    let mut bad_camera = camera;
    bad_camera.intrinsics.fx = -1.0;
    let e = renderer
        .render(&bad_camera, None, &[], [0.0; 4], 160, 120)
        .unwrap_err();
    assert_message(&e, &["invalid camera", "fx"]);

    // A mesh from another renderer (another device).
    if let Ok(mut other) = pa_render::Renderer::new() {
        let foreign = other
            .upload_mesh(&common::quad_mesh(1.0, 1.0))
            .expect("upload");
        let e = render(&mut renderer, Draw::new(&foreign, Mat4::IDENTITY));
        assert_message(&e, &["different Renderer"]);
    }

    // After all these errors the renderer still works.
    let frame = renderer
        .render(
            &camera,
            None,
            &[Draw::new(&rigid, Mat4::from_translation(glam::Vec3::Z))],
            [0.0; 4],
            160,
            120,
        )
        .expect("renderer still usable");
    assert!(frame.depth_m.iter().any(|z| z.is_finite()));
}

#[test]
fn no_adapter_error_says_what_to_install() {
    let e = RenderError::NoAdapter {
        backends: "VULKAN".to_owned(),
    };
    assert_message(
        &e,
        &["mesa-vulkan-drivers", "libegl-mesa0", "WGPU_BACKEND=gl"],
    );
}
