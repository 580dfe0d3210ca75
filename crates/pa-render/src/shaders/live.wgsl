// Live-texturing pipeline of pa-render (`Renderer::render_live`); `skinning.wgsl` is
// prepended by the Rust side. See `src/live.rs` for the math; keep `LiveUniforms` in sync with
// the Rust struct of the same name.
//
// Draws without live texturing (live.flags.x == 0) shade exactly like `render.wgsl`.

@group(2) @binding(0) var base_color_texture: texture_2d<f32>;
@group(2) @binding(1) var base_color_sampler: sampler;

// Per-draw live-texturing uniforms (448 bytes).
struct LiveUniforms {
    key_world_from_mesh: mat4x4<f32>,
    // The camera that took the frame (OpenCV axes).
    frame_camera_from_world: mat4x4<f32>,
    // Visibility-map camera from frame camera (identity when they are the same camera).
    visibility_from_frame_camera: mat4x4<f32>,
    // fx, fy, cx, cy of the frame camera, rescaled to the frame texture size.
    frame_intrinsics: vec4<f32>,
    // x, y: frame texture width and height in pixels.
    frame_size: vec4<f32>,
    // k1, k2, p1, p2.
    distortion: vec4<f32>,
    // x: k3, y: min facing cosine, z: relative depth tolerance, w: absolute depth tolerance (m).
    distortion_k3_tolerances: vec4<f32>,
    // fx, fy, cx, cy of the visibility-map camera, rescaled to the map size.
    visibility_intrinsics: vec4<f32>,
    // x, y: visibility map width and height in pixels.
    visibility_size: vec4<f32>,
    // Irradiance on the model's own albedo where no live sample is valid: per linear RGB
    // channel, (constant, n.x, n.y, n.z) of the animated surface's world-space normal.
    fallback_irradiance: array<vec4<f32>, 3>,
    // x: max stretch (animated / key-pose facing cosine; 0 = no test), y: 1 = relight live
    // samples, z: 1 = feathered seams (pa_raster::look).
    stretch: vec4<f32>,
    // x: key joint base, y: key joint count, z: key morph base, w: key morph count.
    key_counts: vec4<u32>,
    // x: 1 = live-textured draw, y: 1 = a visibility map is bound, z: 1 = texture memory,
    // w: 1 = the sun (pa_raster::sun) relights and shades the fallback instead of
    // fallback_irradiance.
    flags: vec4<u32>,
    // The sun: xyz unit direction towards it (world), and ambient and direct linear RGB.
    sun_toward_light: vec4<f32>,
    sun_ambient: vec4<f32>,
    sun_direct: vec4<f32>,
    // rgb: light reflected at grazing angles (pa_raster::look, "Grazing reflection"), applied
    // with relighting; zero for none.
    grazing: vec4<f32>,
}

@group(3) @binding(0) var<uniform> live: LiveUniforms;
@group(3) @binding(1) var frame_texture: texture_2d<f32>;
@group(3) @binding(2) var frame_sampler: sampler;
// Camera-space z (f32 bits, 0 = empty) of the key pose seen by the visibility camera.
@group(3) @binding(3) var visibility_z: texture_2d<u32>;
// Texture memory per vertex: remembered linear RGB times confidence, and the confidence
// (pa_raster::memory; one zero entry when live.flags.z == 0).
@group(3) @binding(4) var<storage, read> live_memory: array<vec4<f32>>;
// Fraction of the sun each vertex receives, (key pose, animated pose) (pa_raster::sun; one
// entry when live.flags.w == 0).
@group(3) @binding(5) var<storage, read> live_sun_lit: array<vec2<f32>>;

// Codes of the validity target (`LiveSample` on the Rust side).
const LIVE_NONE: u32 = 0u;
const LIVE_OUTSIDE: u32 = 1u;
const LIVE_BACK_FACING: u32 = 2u;
const LIVE_OCCLUDED: u32 = 3u;
const LIVE_STRETCHED: u32 = 4u;
const LIVE_VALID: u32 = 255u;

struct LiveVsOut {
    @builtin(position) clip_position: vec4<f32>,
    @location(0) normal_world: vec3<f32>,
    @location(1) uv: vec2<f32>,
    @location(2) camera_z: f32,
    // Key-pose position and normal in the frame camera's coordinates. Default (perspective-
    // correct) interpolation: the fragment gets the key-pose point with the same barycentric
    // coordinates on the key-pose triangle as the fragment has on the animated triangle.
    @location(3) key_camera: vec3<f32>,
    @location(4) key_normal_camera: vec3<f32>,
    // The animated surface's position and normal in the frame camera's coordinates.
    @location(5) anim_camera: vec3<f32>,
    @location(6) anim_normal_camera: vec3<f32>,
    // Texture memory (premultiplied RGB, confidence), interpolated like any attribute.
    @location(7) memory: vec4<f32>,
    // The key-pose normal in the world (relighting).
    @location(8) key_normal_world: vec3<f32>,
    // Fraction of the sun received (key pose, animated pose), interpolated.
    @location(9) sun_lit: vec2<f32>,
    // The relighting ratio E(n_anim) / E(n_key) at the vertex (its unflipped normals),
    // interpolated: the ratio of a triangle's front side (pa_raster's relight_at_vertices).
    @location(10) relight_ratio: vec3<f32>,
}

@vertex
fn vs_live(@builtin(vertex_index) vid: u32) -> LiveVsOut {
    let skinned = skin_vertex(vid);
    let v = vertices[vid];
    let world = vec4<f32>(skinned.position_world, 1.0);
    var out: LiveVsOut;
    out.clip_position = draw.clip_from_world * world;
    out.normal_world = skinned.normal_world;
    out.uv = vec2<f32>(v.position_u.w, v.normal_v.w);
    out.camera_z = (draw.camera_from_world * world).z;
    out.key_camera = vec3<f32>(0.0);
    out.key_normal_camera = vec3<f32>(0.0, 0.0, -1.0);
    out.anim_camera = vec3<f32>(0.0);
    out.anim_normal_camera = vec3<f32>(0.0, 0.0, -1.0);
    out.memory = vec4<f32>(0.0);
    if (live.flags.z == 1u && vid < arrayLength(&live_memory)) {
        out.memory = live_memory[vid];
    }
    out.sun_lit = vec2<f32>(1.0);
    if (live.flags.w == 1u && vid < arrayLength(&live_sun_lit)) {
        out.sun_lit = live_sun_lit[vid];
    }
    out.key_normal_world = vec3<f32>(0.0);
    if (live.flags.x == 1u) {
        let key = skin_vertex_pose(
            vid,
            live.key_counts.x,
            live.key_counts.y,
            live.key_counts.z,
            live.key_counts.w,
            live.key_world_from_mesh,
        );
        let c = live.frame_camera_from_world;
        out.key_normal_world = key.normal_world;
        out.key_camera = (c * vec4<f32>(key.position_world, 1.0)).xyz;
        out.key_normal_camera = transform_normal(
            mat3x3<f32>(c[0].xyz, c[1].xyz, c[2].xyz),
            key.normal_world,
        );
        out.anim_camera = (c * world).xyz;
        out.anim_normal_camera = transform_normal(
            mat3x3<f32>(c[0].xyz, c[1].xyz, c[2].xyz),
            skinned.normal_world,
        );
    }
    out.relight_ratio = vec3<f32>(1.0);
    if (live.flags.x == 1u && live.stretch.y == 1.0) {
        out.relight_ratio = relight_ratio(
            unit_or_zero(skinned.normal_world),
            unit_or_zero(out.key_normal_world),
            out.sun_lit,
        );
    }
    return out;
}

// OpenCV radial-tangential distortion of a normalised image point (pa_camera::Distortion).
fn distort(n: vec2<f32>) -> vec2<f32> {
    let k1 = live.distortion.x;
    let k2 = live.distortion.y;
    let p1 = live.distortion.z;
    let p2 = live.distortion.w;
    let k3 = live.distortion_k3_tolerances.x;
    let x = n.x;
    let y = n.y;
    let r2 = x * x + y * y;
    let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
    let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
    return vec2<f32>(xd, yd);
}

// d/dr [r (1 + k1 r^2 + k2 r^4 + k3 r^6)] > 0: beyond the first radius where the radial
// polynomial folds back, points far outside the view would land inside the image.
fn radial_monotonic(r2: f32) -> bool {
    let k1 = live.distortion.x;
    let k2 = live.distortion.y;
    let k3 = live.distortion_k3_tolerances.x;
    return 1.0 + r2 * (3.0 * k1 + r2 * (5.0 * k2 + r2 * 7.0 * k3)) > 0.0;
}

// 1/z of the visibility map at integer texel (x, y) (clamped to the map), 0 where empty.
fn visibility_inv_z(x: i32, y: i32) -> f32 {
    let size = vec2<i32>(live.visibility_size.xy);
    let t = clamp(vec2<i32>(x, y), vec2<i32>(0), size - vec2<i32>(1));
    let z = bitcast<f32>(textureLoad(visibility_z, t, 0).x);
    return select(0.0, 1.0 / z, z > 0.0);
}

// Validity of the key-pose point `pc` (frame camera coordinates) with normal `nc`, and the
// frame pixel (OpenCV convention) it projects to.
struct LiveLookup {
    code: u32,
    pixel: vec2<f32>,
    // The live sample's weight (pa_raster::look): 0 unless LIVE_VALID, 1 without feathering.
    weight: f32,
}

// Feathered seams (pa_raster::look's constants).
const EDGE_FEATHER_PX: f32 = 6.0;
const FACING_FEATHER_COS: f32 = 0.25;
const STRETCH_FEATHER: f32 = 0.5;
const FULL_WEIGHT_MIN: f32 = 0.998046875; // 1 - 1/512
// Relighting ratio clamp and irradiance floor.
const RELIGHT_MIN: f32 = 0.7;
const RELIGHT_MAX: f32 = 2.0;
const MIN_IRRADIANCE: f32 = 0.02;
// The sun's relighting ratio clamp (pa_raster::sun).
const SUN_RELIGHT_MIN: f32 = 0.25;
const SUN_RELIGHT_MAX: f32 = 2.5;

// Smooth ramp from 0 at x <= 0 to 1 at x >= width (a step at 0 when width <= 0).
fn ramp(x: f32, width: f32) -> f32 {
    if (width > 0.0) {
        let t = clamp(x / width, 0.0, 1.0);
        return t * t * (3.0 - 2.0 * t);
    }
    return select(0.0, 1.0, x > 0.0);
}

// v / |v|, or zero for a zero vector (a model without normals: the irradiance's constant).
fn unit_or_zero(v: vec3<f32>) -> vec3<f32> {
    let len2 = dot(v, v);
    return select(vec3<f32>(0.0), v * inverseSqrt(len2), len2 > 0.0);
}

// The fallback irradiance at a world-space normal, floored.
fn irradiance(n: vec3<f32>) -> vec3<f32> {
    let sh = vec4<f32>(1.0, n);
    let e = vec3<f32>(
        dot(live.fallback_irradiance[0], sh),
        dot(live.fallback_irradiance[1], sh),
        dot(live.fallback_irradiance[2], sh),
    );
    return max(e, vec3<f32>(MIN_IRRADIANCE));
}

// The sun's irradiance at a world-space normal (zero: half the direct light) receiving the
// fraction `lit` of it, floored (pa_raster::sun::SunLight::irradiance).
fn sun_irradiance(n: vec3<f32>, lit: f32) -> vec3<f32> {
    let cos = select(max(dot(n, live.sun_toward_light.xyz), 0.0), 0.5, dot(n, n) == 0.0);
    let e = live.sun_ambient.rgb + live.sun_direct.rgb * (clamp(lit, 0.0, 1.0) * cos);
    return max(e, vec3<f32>(MIN_IRRADIANCE));
}

// The relighting ratio E(n_anim) / E(n_key), clamped, of unit world-space normals (zero: none),
// with the fractions of the sun received (key pose, animated pose) when the sun is on
// (pa_raster::sun::SunLight::relight_factor, pa_raster::look::relight_factor).
fn relight_ratio(n_anim: vec3<f32>, n_key: vec3<f32>, sun_lit: vec2<f32>) -> vec3<f32> {
    if (live.flags.w == 1u) {
        return clamp(
            sun_irradiance(n_anim, sun_lit.y) / sun_irradiance(n_key, sun_lit.x),
            vec3<f32>(SUN_RELIGHT_MIN),
            vec3<f32>(SUN_RELIGHT_MAX),
        );
    }
    return clamp(
        irradiance(n_anim) / irradiance(n_key),
        vec3<f32>(RELIGHT_MIN),
        vec3<f32>(RELIGHT_MAX),
    );
}

// Cosine between a normal and the direction from the point to the camera (at the origin).
fn facing_cos(p: vec3<f32>, n: vec3<f32>) -> f32 {
    let len2 = dot(n, n) * dot(p, p);
    return select(-1.0, -dot(n, p) * inverseSqrt(len2), len2 > 0.0);
}

// Schlick's grazing factor (1 - cos)^5 of the facing cosine, clamped to [0, 1]
// (pa_raster::look::grazing).
fn schlick(p: vec3<f32>, n: vec3<f32>) -> f32 {
    let len2 = dot(n, n) * dot(p, p);
    let cos = select(0.0, -dot(n, p) / sqrt(len2), len2 > 0.0);
    let t = 1.0 - clamp(cos, 0.0, 1.0);
    let t2 = t * t;
    return t2 * t2 * t;
}

fn live_lookup(pc: vec3<f32>, nc: vec3<f32>, pa: vec3<f32>, na: vec3<f32>) -> LiveLookup {
    var out: LiveLookup;
    out.code = LIVE_OUTSIDE;
    out.pixel = vec2<f32>(0.0);
    out.weight = 0.0;
    let feather = live.stretch.z == 1.0;
    // 1. In front of the frame camera, inside the valid distortion range and the image.
    if (!(pc.z > 1e-6)) {
        return out;
    }
    let n = pc.xy / pc.z;
    if (!radial_monotonic(dot(n, n))) {
        return out;
    }
    let d = distort(n);
    let k = live.frame_intrinsics;
    let pixel = vec2<f32>(k.x * d.x + k.z, k.y * d.y + k.w);
    out.pixel = pixel;
    let size = live.frame_size.xy;
    if (any(pixel < vec2<f32>(-0.5)) || any(pixel > size - vec2<f32>(0.5))) {
        return out;
    }
    // 2. Facing the frame camera: n . (point - eye) / |point - eye| < -min_facing_cos.
    let min_facing_cos = live.distortion_k3_tolerances.y;
    let cos_key = facing_cos(pc, nc);
    if (!(cos_key > min_facing_cos)) {
        out.code = LIVE_BACK_FACING;
        return out;
    }
    var weight = 1.0;
    if (feather) {
        let edge = min(min(pixel.x + 0.5, pixel.y + 0.5), min(size.x - 0.5 - pixel.x, size.y - 0.5 - pixel.y));
        weight = ramp(edge, EDGE_FEATHER_PX) * ramp(cos_key - min_facing_cos, FACING_FEATHER_COS);
    }
    // 2b. Not stretched: the animated surface does not face the camera far more squarely.
    let max_stretch = live.stretch.x;
    if (max_stretch > 0.0) {
        let limit = max_stretch * max(cos_key, 0.0);
        let cos_anim = facing_cos(pa, na);
        if (cos_anim > limit) {
            out.code = LIVE_STRETCHED;
            return out;
        }
        if (feather) {
            weight *= ramp(limit - cos_anim, STRETCH_FEATHER * limit);
        }
    }
    // 3. Not occluded: compare with the visibility map (pinhole projection, since the map is
    // rasterised without distortion), against the farthest surface of the 4 nearest texels.
    if (live.flags.y == 1u) {
        let pv = (live.visibility_from_frame_camera * vec4<f32>(pc, 1.0)).xyz;
        if (!(pv.z > 1e-6)) {
            return out;
        }
        let kv = live.visibility_intrinsics;
        let q = vec2<f32>(kv.x * pv.x / pv.z + kv.z, kv.y * pv.y / pv.z + kv.w);
        let vsize = live.visibility_size.xy;
        if (any(q < vec2<f32>(-0.5)) || any(q > vsize - vec2<f32>(0.5))) {
            return out;
        }
        let q0 = floor(q);
        let x0 = i32(q0.x);
        let y0 = i32(q0.y);
        // Smallest non-zero 1/z (the farthest surface); 0 when all four are empty.
        var inv_z = 0.0;
        for (var k = 0; k < 4; k++) {
            let v = visibility_inv_z(x0 + (k & 1), y0 + (k >> 1u));
            if (v > 0.0 && (inv_z == 0.0 || v < inv_z)) {
                inv_z = v;
            }
        }
        // Visible when z <= z_map (1 + rel) + abs, i.e. z / z_map <= 1 + rel + abs / z_map;
        // an empty neighbourhood (inv_z = 0) never occludes.
        let rel = live.distortion_k3_tolerances.z;
        let abs_m = live.distortion_k3_tolerances.w;
        let tolerance = rel + abs_m * inv_z;
        if (pv.z * inv_z > 1.0 + tolerance) {
            out.code = LIVE_OCCLUDED;
            return out;
        }
        if (feather && inv_z > 0.0) {
            weight *= ramp(1.0 + tolerance - pv.z * inv_z, tolerance);
        }
    }
    out.code = LIVE_VALID;
    out.weight = select(weight, 1.0, weight >= FULL_WEIGHT_MIN);
    return out;
}

struct LiveFsOut {
    // Linear colour; the Rgba8UnormSrgb target encodes it to sRGB.
    @location(0) color: vec4<f32>,
    // Camera-space z in metres, as f32 bits (as in `render.wgsl`).
    @location(1) camera_z_bits: vec4<u32>,
    // LIVE_* code (R8Uint target).
    @location(2) live_code: vec4<u32>,
}

@fragment
fn fs_live(in: LiveVsOut, @builtin(front_facing) front_facing: bool) -> LiveFsOut {
    // Sampled in uniform control flow (implicit derivatives for the mip level).
    let albedo = draw.base_color_factor
        * textureSample(base_color_texture, base_color_sampler, in.uv);
    var rgb = albedo.rgb;
    var code = LIVE_NONE;
    if (live.flags.x == 1u) {
        // A live sample already carries the real lighting; the fallback is the albedo under
        // the caller's irradiance estimate, at the animated surface's normal.
        let lookup = live_lookup(
            in.key_camera,
            in.key_normal_camera,
            in.anim_camera,
            in.anim_normal_camera,
        );
        code = lookup.code;
        var n = unit_or_zero(in.normal_world);
        // The triangle's back side: its normal flipped, its ratio not the vertices'.
        let flipped = front_facing == (draw.flags.x == 1u);
        if (flipped) {
            n = -n;
        }
        // The remembered colour first, the lit model texture where the memory is unsure.
        let sun = live.flags.w == 1u;
        var e_anim = irradiance(n);
        if (sun) {
            e_anim = sun_irradiance(n, in.sun_lit.y);
        }
        let lit = albedo.rgb * e_anim;
        // Relit at the animated normal: E(n_anim) / E(n_key), clamped; for what was seen in
        // the key pose (the live sample, the remembered colour).
        let relight = live.stretch.y == 1.0;
        var ratio = vec3<f32>(1.0);
        if (relight) {
            if (flipped) {
                ratio = relight_ratio(n, unit_or_zero(in.key_normal_world), in.sun_lit);
            } else {
                ratio = in.relight_ratio;
            }
        }
        // The remembered gain over the model's albedo (pa_raster::memory::remembered_or).
        var memory_rgb = in.memory.rgb * albedo.rgb;
        if (relight && in.memory.a > 0.0) {
            memory_rgb *= ratio;
        }
        // The reflection at grazing angles: the key pose's out, the in-between's in.
        let s = live.grazing.rgb;
        let grazing = relight && any(s != vec3<f32>(0.0));
        var g_key = 0.0;
        var g_anim = 0.0;
        if (grazing) {
            g_key = schlick(in.key_camera, in.key_normal_camera);
            g_anim = schlick(in.anim_camera, in.anim_normal_camera);
        }
        let fallback = memory_rgb + clamp(1.0 - in.memory.a, 0.0, 1.0) * lit + s * g_anim;
        if (code == LIVE_VALID) {
            let uv = (lookup.pixel + vec2<f32>(0.5)) / live.frame_size.xy;
            var c = textureSampleLevel(frame_texture, frame_sampler, uv, 0.0).rgb;
            if (grazing) {
                c = max(c - s * g_key, vec3<f32>(0.0)) * ratio + s * g_anim;
            } else if (relight) {
                c *= ratio;
            }
            rgb = select(mix(fallback, c, lookup.weight), c, lookup.weight >= 1.0);
        } else {
            rgb = fallback;
        }
    } else if (draw.counts.w == 1u) {
        var n = normalize(in.normal_world);
        // Double-sided lighting: the back side of a triangle uses the flipped normal.
        if (front_facing == (draw.flags.x == 1u)) {
            n = -n;
        }
        let n_dot_l = max(dot(n, draw.toward_light_world.xyz), 0.0);
        rgb = albedo.rgb * (draw.ambient_rgb.rgb + n_dot_l * draw.light_rgb.rgb);
    }
    var out: LiveFsOut;
    out.color = vec4<f32>(rgb, albedo.a);
    out.camera_z_bits = vec4<u32>(bitcast<u32>(in.camera_z), 0u, 0u, 1u);
    out.live_code = vec4<u32>(code, 0u, 0u, 1u);
    return out;
}
