//! GPU skinning and morphing (`Renderer::skin_gpu`, the same WGSL function the vertex stage
//! runs) against a CPU reference written out here with glam:
//! p' = sum_i w_i * M[j_i] * (p + sum_k m_k * delta_k).
//!
//! Tolerances: positions within 1e-5 m (max abs component error; coordinates are O(1 m));
//! normals within 1e-4 (unit vectors, reference normalise(inverse_transpose(sum_i w_i M_i) n)).

mod common;

use glam::{Mat3, Mat4, Quat, Vec3, Vec4Swizzles};
use pa_render::CpuMesh;

const POSITION_TOL_M: f32 = 1e-5;
const NORMAL_TOL: f32 = 1e-4;

/// xorshift64*: deterministic "random" numbers for the test mesh.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    /// Uniform in [lo, hi).
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        let unit = (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        lo + (hi - lo) * unit
    }
    fn vec3(&mut self, lo: f32, hi: f32) -> Vec3 {
        Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }
}

const JOINTS: usize = 12;
const VERTICES: usize = 300;
const MORPHS: usize = 3;

fn random_mesh(rng: &mut Rng) -> CpuMesh {
    let mut mesh = CpuMesh::default();
    for v in 0..VERTICES {
        mesh.positions.push(rng.vec3(-1.0, 1.0).to_array());
        let n = rng.vec3(-1.0, 1.0).try_normalize().unwrap_or(Vec3::Z);
        mesh.normals.push(n.to_array());
        mesh.uvs.push([rng.range(0.0, 1.0), rng.range(0.0, 1.0)]);
        let mut joints = [0u16; 8];
        let mut weights = [0f32; 8];
        for k in 0..8 {
            joints[k] = (rng.next_u64() % JOINTS as u64) as u16;
            weights[k] = rng.range(0.0, 1.0);
        }
        // Some vertices use fewer influences (zero weights with arbitrary joint indices).
        if v % 5 == 0 {
            weights[3..].fill(0.0);
        }
        let sum: f32 = weights.iter().sum();
        for w in &mut weights {
            *w /= sum;
        }
        mesh.joints.push(joints);
        mesh.weights.push(weights);
    }
    for t in 0..(VERTICES as u32 - 2) {
        mesh.indices.extend_from_slice(&[t, t + 1, t + 2]);
    }
    for k in 0..MORPHS {
        mesh.morph_position_deltas.push(
            (0..VERTICES)
                .map(|_| rng.vec3(-0.1, 0.1).to_array())
                .collect(),
        );
        // Target 1 has no normal deltas.
        mesh.morph_normal_deltas.push(if k == 1 {
            Vec::new()
        } else {
            (0..VERTICES)
                .map(|_| rng.vec3(-0.2, 0.2).to_array())
                .collect()
        });
    }
    mesh
}

fn random_joint_matrices(rng: &mut Rng) -> Vec<Mat4> {
    (0..JOINTS)
        .map(|_| {
            let axis = rng.vec3(-1.0, 1.0).try_normalize().unwrap_or(Vec3::X);
            let rotation = Quat::from_axis_angle(axis, rng.range(-3.0, 3.0));
            let scale = rng.vec3(0.5, 1.5);
            Mat4::from_scale_rotation_translation(scale, rotation, rng.vec3(-1.0, 1.0))
        })
        .collect()
}

fn morphed(mesh: &CpuMesh, v: usize, morph_weights: &[f32]) -> (Vec3, Vec3) {
    let mut p = Vec3::from(mesh.positions[v]);
    let mut n = Vec3::from(mesh.normals[v]);
    for (k, &w) in morph_weights.iter().enumerate() {
        p += w * Vec3::from(mesh.morph_position_deltas[k][v]);
        if let Some(d) = mesh.morph_normal_deltas[k].get(v) {
            n += w * Vec3::from(*d);
        }
    }
    (p, n)
}

/// CPU reference: sum_i w_i M_{j_i} p, normals by the inverse transpose of sum_i w_i M_{j_i}.
fn cpu_skin(mesh: &CpuMesh, joints: &[Mat4], morph_weights: &[f32]) -> Vec<(Vec3, Vec3)> {
    (0..mesh.positions.len())
        .map(|v| {
            let (p, n) = morphed(mesh, v, morph_weights);
            let mut position = Vec3::ZERO;
            let mut blended = Mat3::ZERO;
            for k in 0..8 {
                let w = mesh.weights[v][k];
                let m = joints[mesh.joints[v][k] as usize];
                position += w * (m * p.extend(1.0)).xyz();
                blended += Mat3::from_mat4(m) * w;
            }
            let normal = (blended.inverse().transpose() * n).normalize();
            (position, normal)
        })
        .collect()
}

fn max_abs_error(a: [f32; 3], b: Vec3) -> f32 {
    (Vec3::from(a) - b).abs().max_element()
}

#[test]
fn gpu_skinning_matches_cpu_reference_with_8_influences_and_morphs() {
    let Some(mut renderer) = common::renderer_or_skip("gpu_skinning") else {
        return;
    };
    let mut rng = Rng(0x5eed_1234_abcd_0001);
    let mesh = random_mesh(&mut rng);
    let gpu_mesh = renderer.upload_mesh(&mesh).expect("upload");
    let morph_weights = [0.3, -0.5, 1.2];

    for pose in 0..3 {
        let joints = random_joint_matrices(&mut rng);
        let gpu = renderer
            .skin_gpu(&gpu_mesh, &joints, &morph_weights)
            .expect("skin on GPU");
        assert_eq!(gpu.positions.len(), VERTICES);
        let cpu = cpu_skin(&mesh, &joints, &morph_weights);
        let mut worst_p = 0f32;
        let mut worst_n = 0f32;
        for (v, (cp, cn)) in cpu.iter().enumerate() {
            let ep = max_abs_error(gpu.positions[v], *cp);
            let en = max_abs_error(gpu.normals[v], *cn);
            assert!(
                ep <= POSITION_TOL_M,
                "pose {pose} vertex {v}: GPU {:?} vs CPU {cp} (error {ep} m)",
                gpu.positions[v]
            );
            assert!(
                en <= NORMAL_TOL,
                "pose {pose} vertex {v}: GPU normal {:?} vs CPU {cn} (error {en})",
                gpu.normals[v]
            );
            worst_p = worst_p.max(ep);
            worst_n = worst_n.max(en);
        }
        eprintln!("pose {pose}: max position error {worst_p:e} m, max normal error {worst_n:e}");
        // skin_positions_gpu is the positions of skin_gpu.
        let positions = renderer
            .skin_positions_gpu(&gpu_mesh, &joints, &morph_weights)
            .expect("skin positions");
        assert_eq!(positions, gpu.positions);
    }
}

#[test]
fn rigid_morph_only_and_no_morph_weights() {
    let Some(mut renderer) = common::renderer_or_skip("rigid_morph") else {
        return;
    };
    let mut rng = Rng(77);
    let mut mesh = random_mesh(&mut rng);
    mesh.joints.clear();
    mesh.weights.clear();
    let gpu_mesh = renderer.upload_mesh(&mesh).expect("upload");
    let weights = [1.0, 0.25, -2.0];
    let got = renderer
        .skin_positions_gpu(&gpu_mesh, &[], &weights)
        .expect("morph only");
    for (v, p) in got.iter().enumerate() {
        let (want, _) = morphed(&mesh, v, &weights);
        assert!(
            max_abs_error(*p, want) <= POSITION_TOL_M,
            "vertex {v}: {p:?} vs {want}"
        );
    }
    // Empty morph weights = all zero: the base mesh.
    let base = renderer
        .skin_positions_gpu(&gpu_mesh, &[], &[])
        .expect("base");
    assert_eq!(base, mesh.positions);
}

#[test]
fn bent_cylinder_skinning_is_a_rotation_beyond_the_blend_zone() {
    let Some(mut renderer) = common::renderer_or_skip("bent_cylinder_skinning") else {
        return;
    };
    let mesh = common::bent_cylinder_mesh();
    let gpu_mesh = renderer.upload_mesh(&mesh).expect("upload");
    let angle = 50f32.to_radians();
    let got = renderer
        .skin_gpu(&gpu_mesh, &common::cylinder_joint_matrices(angle), &[])
        .expect("skin");
    let pivot = Vec3::new(common::CYLINDER_JOINT_X, 0.0, 0.0);
    let rotation = Mat3::from_rotation_z(angle);
    for (v, p) in mesh.positions.iter().enumerate() {
        let p = Vec3::from(*p);
        let n = Vec3::from(mesh.normals[v]);
        let (want_p, want_n) = if p.x >= 0.25 {
            (pivot + rotation * (p - pivot), rotation * n)
        } else if p.x <= 0.15 {
            (p, n)
        } else {
            continue;
        };
        assert!(max_abs_error(got.positions[v], want_p) <= POSITION_TOL_M);
        assert!(max_abs_error(got.normals[v], want_n) <= NORMAL_TOL);
    }
}
