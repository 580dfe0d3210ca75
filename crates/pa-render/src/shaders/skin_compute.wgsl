// Compute entry point of pa-render; `skinning.wgsl` is prepended by the Rust side.
// Writes the skinned world position and normal of every vertex, two vec4 per vertex.

@group(2) @binding(0) var<storage, read_write> skinned_out: array<vec4<f32>>;

@compute @workgroup_size(64)
fn cs_skin(@builtin(global_invocation_id) gid: vec3<u32>) {
    let vid = gid.x + gid.y * draw.flags.z;
    if (vid >= draw.counts.z) {
        return;
    }
    let skinned = skin_vertex(vid);
    skinned_out[vid * 2u] = vec4<f32>(skinned.position_world, 1.0);
    skinned_out[vid * 2u + 1u] = vec4<f32>(skinned.normal_world, 0.0);
}
