// Render pipeline of pa-render; `skinning.wgsl` is prepended by the Rust side.
// Vertex pulling: no vertex buffers, the vertex stage reads `vertices` by vertex_index.

@group(2) @binding(0) var base_color_texture: texture_2d<f32>;
@group(2) @binding(1) var base_color_sampler: sampler;

struct VsOut {
    @builtin(position) clip_position: vec4<f32>,
    @location(0) normal_world: vec3<f32>,
    @location(1) uv: vec2<f32>,
    @location(2) camera_z: f32,
}

@vertex
fn vs_main(@builtin(vertex_index) vid: u32) -> VsOut {
    let skinned = skin_vertex(vid);
    let v = vertices[vid];
    let world = vec4<f32>(skinned.position_world, 1.0);
    var out: VsOut;
    out.clip_position = draw.clip_from_world * world;
    out.normal_world = skinned.normal_world;
    out.uv = vec2<f32>(v.position_u.w, v.normal_v.w);
    out.camera_z = (draw.camera_from_world * world).z;
    return out;
}

struct FsOut {
    // Linear colour; the Rgba8UnormSrgb target encodes it to sRGB.
    @location(0) color: vec4<f32>,
    // Camera-space z in metres, as f32 bits (R32Uint target; R32Float is not renderable on
    // GLES).
    @location(1) camera_z_bits: vec4<u32>,
}

@fragment
fn fs_main(in: VsOut, @builtin(front_facing) front_facing: bool) -> FsOut {
    let albedo = draw.base_color_factor * textureSample(base_color_texture, base_color_sampler, in.uv);
    var rgb = albedo.rgb;
    if (draw.counts.w == 1u) {
        var n = normalize(in.normal_world);
        // Double-sided lighting: the back side of a triangle uses the flipped normal.
        if (front_facing == (draw.flags.x == 1u)) {
            n = -n;
        }
        let n_dot_l = max(dot(n, draw.toward_light_world.xyz), 0.0);
        rgb = albedo.rgb * (draw.ambient_rgb.rgb + n_dot_l * draw.light_rgb.rgb);
    }
    var out: FsOut;
    out.color = vec4<f32>(rgb, albedo.a);
    out.camera_z_bits = vec4<u32>(bitcast<u32>(in.camera_z), 0u, 0u, 1u);
    return out;
}

// Visibility pass (`Renderer::render_visibility`): only the camera-space z, as f32 bits, into
// the single R32Uint target that live texturing reads back with `textureLoad`.
@fragment
fn fs_visibility(in: VsOut) -> @location(0) vec4<u32> {
    return vec4<u32>(bitcast<u32>(in.camera_z), 0u, 0u, 1u);
}
