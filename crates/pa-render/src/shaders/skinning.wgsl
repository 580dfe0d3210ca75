// Shared skinning and morph-target code of pa-render.
//
// This file is prepended to `render.wgsl` and `live.wgsl` (vertex stage) and to
// `skin_compute.wgsl` (compute entry point used by `Renderer::skin_gpu`), so that all of them
// evaluate exactly the same function `skin_vertex`. Keep the Rust-side layouts in `pipeline.rs`
// / `mesh.rs` in sync.

// One mesh vertex, as packed by `mesh.rs` (80 bytes).
struct GpuVertex {
    // xyz: position in mesh space (metres), w: texture coordinate u.
    position_u: vec4<f32>,
    // xyz: normal in mesh space, w: texture coordinate v.
    normal_v: vec4<f32>,
    // Eight u16 joint indices, two per u32, influence 2i in the low half of joints[i].
    joints: vec4<u32>,
    // Weights of influences 0..4 and 4..8.
    weights0: vec4<f32>,
    weights1: vec4<f32>,
}

// Per-draw uniforms (288 bytes), see `DrawUniforms` in `pipeline.rs`.
struct DrawUniforms {
    clip_from_world: mat4x4<f32>,
    camera_from_world: mat4x4<f32>,
    world_from_mesh: mat4x4<f32>,
    base_color_factor: vec4<f32>,
    // xyz: unit vector from the surface toward the light, world space.
    toward_light_world: vec4<f32>,
    light_rgb: vec4<f32>,
    ambient_rgb: vec4<f32>,
    // x: joint count (0 = rigid), y: morph target count, z: vertex count, w: 1 = lit, 0 = unlit.
    counts: vec4<u32>,
    // x: 1 when the vertex transform mirrors (negative determinant), y: unused,
    // z: invocations per dispatch row (compute only), w: unused.
    flags: vec4<u32>,
}

@group(0) @binding(0) var<storage, read> vertices: array<GpuVertex>;
// Morph deltas, laid out [target][vertex][position delta, normal delta] as vec4 (w unused).
@group(0) @binding(1) var<storage, read> morph_deltas: array<vec4<f32>>;

@group(1) @binding(0) var<uniform> draw: DrawUniforms;
// joint_matrices[j] = world_from_joint[j] * inverse_bind_matrix[j].
@group(1) @binding(1) var<storage, read> joint_matrices: array<mat4x4<f32>>;
@group(1) @binding(2) var<storage, read> morph_weights: array<f32>;

struct SkinnedVertex {
    position_world: vec3<f32>,
    normal_world: vec3<f32>,
}

// Joint index of influence k (0..8) of a vertex.
fn joint_index(joints: vec4<u32>, k: u32) -> u32 {
    return (joints[k >> 1u] >> ((k & 1u) * 16u)) & 0xffffu;
}

// Morph targets (base + sum_k w_k delta_k), then linear blend skinning
// (sum_i w_i M_i p, no renormalisation of the weights) or the rigid world_from_mesh.
// Normals use the cofactor matrix (the inverse transpose up to a positive scale) and are
// normalised. This is the draw's own pose (`draw` uniforms, joints and weights from index 0).
fn skin_vertex(vid: u32) -> SkinnedVertex {
    return skin_vertex_pose(vid, 0u, draw.counts.x, 0u, draw.counts.y, draw.world_from_mesh);
}

// The same deformation for an arbitrary pose of the same mesh: joint matrices
// `joint_matrices[joint_base .. joint_base + joint_count]` (0 joints: rigid with `m`), morph
// weights `morph_weights[morph_base .. morph_base + morph_count]` (one per target, or none).
// Live texturing evaluates the key pose with it (key joints appended after the draw's own).
fn skin_vertex_pose(
    vid: u32,
    joint_base: u32,
    joint_count: u32,
    morph_base: u32,
    morph_count: u32,
    m: mat4x4<f32>,
) -> SkinnedVertex {
    let v = vertices[vid];
    var p = v.position_u.xyz;
    var n = v.normal_v.xyz;

    let vertex_count = draw.counts.z;
    for (var k = 0u; k < morph_count; k++) {
        let w = morph_weights[morph_base + k];
        if (w != 0.0) {
            let base = (k * vertex_count + vid) * 2u;
            p += w * morph_deltas[base].xyz;
            n += w * morph_deltas[base + 1u].xyz;
        }
    }

    if (joint_count > 0u) {
        let last = joint_count - 1u;
        var acc_p = vec3<f32>(0.0);
        var acc_m = mat3x3<f32>(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
        for (var i = 0u; i < 4u; i++) {
            let wa = v.weights0[i];
            if (wa != 0.0) {
                let ma = joint_matrices[joint_base + min(joint_index(v.joints, i), last)];
                acc_p += wa * (ma * vec4<f32>(p, 1.0)).xyz;
                acc_m += mat3x3<f32>(wa * ma[0].xyz, wa * ma[1].xyz, wa * ma[2].xyz);
            }
            let wb = v.weights1[i];
            if (wb != 0.0) {
                let mb = joint_matrices[joint_base + min(joint_index(v.joints, i + 4u), last)];
                acc_p += wb * (mb * vec4<f32>(p, 1.0)).xyz;
                acc_m += mat3x3<f32>(wb * mb[0].xyz, wb * mb[1].xyz, wb * mb[2].xyz);
            }
        }
        return SkinnedVertex(acc_p, transform_normal(acc_m, n));
    }
    let linear = mat3x3<f32>(m[0].xyz, m[1].xyz, m[2].xyz);
    return SkinnedVertex((m * vec4<f32>(p, 1.0)).xyz, transform_normal(linear, n));
}

// Normal transform by the cofactor matrix of `m` (columns b x c, c x a, a x b), which equals
// det(m) * inverse_transpose(m); the sign of det keeps the orientation, then normalise.
fn transform_normal(m: mat3x3<f32>, n: vec3<f32>) -> vec3<f32> {
    let cof = mat3x3<f32>(cross(m[1], m[2]), cross(m[2], m[0]), cross(m[0], m[1]));
    let det = dot(m[0], cof[0]);
    let t = select(1.0, -1.0, det < 0.0) * (cof * n);
    let len2 = dot(t, t);
    if (len2 > 1e-30) {
        return t * inverseSqrt(len2);
    }
    return vec3<f32>(0.0, 0.0, 1.0);
}
