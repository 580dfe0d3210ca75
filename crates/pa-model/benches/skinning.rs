//! Criterion benches of the animate stage's CPU code: linear blend skinning of every vertex
//! (`skin::pose_meshes`, the reference path behind `export` and the tests; the pipeline skins
//! on the GPU) for skinned meshes of 2k to 128k vertices, and the per-frame work the pipeline
//! does on the CPU (animation sampling, node transforms, joint matrices).
//!
//! The mesh is synthetic (no file, no GPU): a closed cylinder the size of the built-in prop,
//! bound to a chain of four joints with two influences per vertex, and a one-second clip
//! turning the three upper joints.
//!
//! `cargo bench -p pa-model` (add `-- --quick` for a rough figure in seconds).

use std::path::PathBuf;
use std::time::Duration;

use criterion::{black_box, BenchmarkId, Criterion, Throughput};
use glam::{Mat4, Quat, Vec3};
use pa_model::{
    anim, skin, Animation, Channel, Interpolation, LocalTransform, Mesh, Model, Node, Primitive,
    Property, Sampler, Skin, Trs,
};

const HEIGHT_M: f32 = 0.2;
const JOINTS: usize = 4;

/// A skinned cylinder with about `vertices` vertices.
fn skinned_model(vertices: usize) -> Model {
    let side = (vertices as f32).sqrt().round().max(4.0) as usize;
    let (rings, segments) = (side, side);
    let seg_len = HEIGHT_M / (JOINTS - 1) as f32;
    let mut prim = Primitive::default();
    for r in 0..rings {
        let v = r as f32 / (rings - 1) as f32;
        let y = v * HEIGHT_M;
        // Two influences: the joints below and above this height.
        let s = (y / seg_len).min((JOINTS - 1) as f32 - 1e-4);
        let j0 = s.floor() as usize;
        let t = s - j0 as f32;
        for k in 0..segments {
            let a = k as f32 / segments as f32 * std::f32::consts::TAU;
            let n = Vec3::new(a.cos(), 0.0, a.sin());
            prim.positions.push(Vec3::new(0.05 * n.x, y, 0.05 * n.z));
            prim.normals.push(n);
            prim.uvs.push([k as f32 / segments as f32, v]);
            let mut joints = [0u16; 8];
            let mut weights = [0f32; 8];
            joints[0] = j0 as u16;
            joints[1] = (j0 + 1) as u16;
            weights[0] = 1.0 - t;
            weights[1] = t;
            prim.joints.push(joints);
            prim.weights.push(weights);
        }
    }
    for r in 0..rings - 1 {
        for k in 0..segments {
            let a = (r * segments + k) as u32;
            let b = (r * segments + (k + 1) % segments) as u32;
            let (c, d) = (a + segments as u32, b + segments as u32);
            prim.indices.extend_from_slice(&[a, c, b, b, c, d]);
        }
    }
    // Joint chain 0..JOINTS along +Y; node JOINTS carries the mesh.
    let mut nodes: Vec<Node> = (0..JOINTS)
        .map(|j| Node {
            name: Some(format!("joint{j}")),
            parent: j.checked_sub(1),
            children: if j + 1 < JOINTS { vec![j + 1] } else { vec![] },
            local: LocalTransform::Trs(Trs {
                translation: Vec3::new(0.0, if j == 0 { 0.0 } else { seg_len }, 0.0),
                ..Trs::default()
            }),
            mesh: None,
            skin: None,
            morph_weights: vec![],
        })
        .collect();
    nodes.push(Node {
        name: Some("body".into()),
        parent: None,
        children: vec![],
        local: LocalTransform::Trs(Trs::default()),
        mesh: Some(0),
        skin: Some(0),
        morph_weights: vec![],
    });
    let inverse_bind_matrices = (0..JOINTS)
        .map(|j| Mat4::from_translation(Vec3::new(0.0, -(j as f32) * seg_len, 0.0)))
        .collect();
    let channels = (1..JOINTS)
        .map(|j| {
            let q = Quat::from_rotation_z(0.3) * Quat::from_rotation_y(0.4);
            Channel {
                node: j,
                property: Property::Rotation,
                sampler: Sampler {
                    interpolation: Interpolation::Linear,
                    times_s: vec![0.0, 1.0],
                    values: vec![0.0, 0.0, 0.0, 1.0, q.x, q.y, q.z, q.w],
                    components: 4,
                },
            }
        })
        .collect();
    Model {
        path: PathBuf::from("synthetic.glb"),
        nodes,
        roots: vec![0, JOINTS],
        meshes: vec![Mesh {
            name: None,
            primitives: vec![prim],
        }],
        skins: vec![Skin {
            name: None,
            joints: (0..JOINTS).collect(),
            inverse_bind_matrices,
        }],
        materials: vec![],
        images: vec![],
        animations: vec![Animation {
            name: Some("Bend".into()),
            channels,
            duration_s: 1.0,
        }],
        warnings: vec![],
    }
}

fn criterion() -> Criterion {
    Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .configure_from_args()
}

fn main() {
    let mut c = criterion();
    let mut g = c.benchmark_group("skin_cpu_pose_meshes");
    for n in [2_000usize, 8_000, 32_000, 128_000] {
        let model = skinned_model(n);
        let pose = anim::sample(&model, 0, 0.5);
        let count = model.vertex_count();
        g.throughput(Throughput::Elements(count as u64));
        g.bench_with_input(BenchmarkId::from_parameter(count), &model, |b, m| {
            b.iter(|| skin::pose_meshes(m, black_box(&pose)))
        });
    }
    g.finish();

    // What the pipeline's animate stage does on the CPU per pose (skinning itself runs in the
    // vertex stage): sample the clip, resolve world transforms, build the joint matrices.
    let model = skinned_model(8_000);
    c.bench_function("animate_sample_and_joint_matrices", |b| {
        b.iter(|| {
            let pose = anim::sample(&model, 0, black_box(0.37));
            let world = pose.world_from_node(&model);
            skin::joint_matrices(&model, 0, &world)
        })
    });
    c.final_summary();
}
