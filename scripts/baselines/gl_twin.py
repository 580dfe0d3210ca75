#!/usr/bin/env python3
"""The DIY baseline of the texture stage (issue 15, item 4): the same live-textured twin drawn
with OpenGL (moderngl) on Mesa llvmpipe, timed on the same machine. Not part of CI.

What a practitioner would write for our texture stage, on the same inputs:

- the same mesh: the built-in prop exported by `propsalive export` (OBJ, one primitive) at the
  key pose (animation time 0) and at each frame's in-between time;
- the same camera: the intrinsics of the built-in scene (45 degree vertical field of view,
  principal point at the pixel centre (w-1)/2, (h-1)/2) and each frame's tracked
  `camera_from_marker` from `propsalive demo`'s log; the prop's placement `marker_from_prop`
  (prop +Y up -> marker -Z, prop +Z front -> marker +Y);
- the same live-texturing rule with visibility: pass 1 renders the key pose's depth (the
  visibility map); pass 2 draws the twin at the in-between pose and colours each fragment from
  the camera frame at the projection of its key-pose point (the texture coordinate), when the
  key-pose depth map says that point was seen; otherwise from the model's own texture (the
  fallback; ours also relights it with a fitted irradiance, which this baseline skips);
- the same output: the twin's RGBA and coverage in CPU memory (glReadPixels), as our texture
  stage leaves them for the composite.

Timed per frame (what our texture stage does per frame): uploading the camera frame as a
texture and the two posed vertex buffers, both passes, and the read-back (which waits for the
rasteriser). Posing (skinning) is not timed, as our `animate` stage is not part of `texture`.

Usage (1280x720; after `propsalive demo --size 1280x720 --frames 24 --out DEMO`):

    python3 scripts/baselines/gl_twin.py --demo DEMO --propsalive target/release/propsalive \
        [--repeats 5] [--ours out/bench/bench.json] [--png twin.png]

Needs `pip install moderngl numpy pillow` and Mesa's EGL (llvmpipe): no display is used.
"""

import argparse
import json
import math
import os
import struct
import subprocess
import sys
import tempfile
import time

import numpy as np

try:
    import moderngl
except ImportError:  # pragma: no cover
    sys.exit("gl_twin.py needs moderngl: pip install moderngl")
from PIL import Image

FOV_Y_DEG = 45.0
NEAR_M, FAR_M = 0.05, 5.0

VERTEX_DEPTH = """
#version 330
uniform mat4 camera_from_prop;
uniform vec4 k;        // fx, fy, cx, cy
uniform vec2 size;     // w, h
uniform vec2 near_far;
in vec3 key_pos;
out float cam_z;
vec4 clip(vec3 c) {
    // OpenCV camera (x right, y down, z forward) to GL clip space.
    float n = near_far.x, f = near_far.y;
    float x = (k.x * c.x + (k.z + 0.5) * c.z) / size.x * 2.0 - c.z;
    float y = -((k.y * c.y + (k.w + 0.5) * c.z) / size.y * 2.0 - c.z);
    float z = (c.z * (f + n) - 2.0 * f * n) / (f - n);
    return vec4(x, y, z, c.z);
}
void main() {
    vec3 c = (camera_from_prop * vec4(key_pos, 1.0)).xyz;
    cam_z = c.z;
    gl_Position = clip(c);
}
"""

FRAGMENT_DEPTH = """
#version 330
in float cam_z;
out float depth_m;
void main() { depth_m = cam_z; }
"""

VERTEX_TWIN = """
#version 330
uniform mat4 camera_from_prop;
uniform vec4 k;
uniform vec2 size;
uniform vec2 near_far;
in vec3 pos;       // in-between pose
in vec3 key_pos;   // key pose
in vec2 uv;        // the model's texture coordinate
out vec3 key_cam;
out vec2 model_uv;
vec4 clip(vec3 c) {
    float n = near_far.x, f = near_far.y;
    float x = (k.x * c.x + (k.z + 0.5) * c.z) / size.x * 2.0 - c.z;
    float y = -((k.y * c.y + (k.w + 0.5) * c.z) / size.y * 2.0 - c.z);
    float z = (c.z * (f + n) - 2.0 * f * n) / (f - n);
    return vec4(x, y, z, c.z);
}
void main() {
    key_cam = (camera_from_prop * vec4(key_pos, 1.0)).xyz;
    model_uv = uv;
    gl_Position = clip((camera_from_prop * vec4(pos, 1.0)).xyz);
}
"""

FRAGMENT_TWIN = """
#version 330
uniform sampler2D frame;      // the camera image (rows top first)
uniform sampler2D key_depth;  // camera z of the key pose, metres (0 = none)
uniform sampler2D albedo;
uniform vec4 k;
uniform vec2 size;
in vec3 key_cam;
in vec2 model_uv;
out vec4 colour;
void main() {
    // The texture coordinate: the key-pose point projected into the frame.
    vec2 px = vec2(k.x * key_cam.x / key_cam.z + k.z, k.y * key_cam.y / key_cam.z + k.w);
    vec2 t = (px + 0.5) / size;
    // The depth map was drawn with GL's rows (bottom first), the frame uploaded top first.
    float seen = texture(key_depth, vec2(t.x, 1.0 - t.y)).r;
    bool visible = t.x >= 0.0 && t.x <= 1.0 && t.y >= 0.0 && t.y <= 1.0 && seen > 0.0
        && key_cam.z <= seen * 1.01 + 0.002;
    colour = visible ? vec4(texture(frame, t).rgb, 1.0) : vec4(texture(albedo, model_uv).rgb, 1.0);
}
"""


def read_obj(path):
    """Positions, texture coordinates and triangle indices of a `propsalive export` OBJ (one
    primitive, `f a/a/a` faces)."""
    v, vt, f = [], [], []
    with open(path) as fh:
        for line in fh:
            if line.startswith("v "):
                v.append([float(x) for x in line.split()[1:4]])
            elif line.startswith("vt "):
                vt.append([float(x) for x in line.split()[1:3]])
            elif line.startswith("f "):
                f.append([int(c.split("/")[0]) - 1 for c in line.split()[1:4]])
    return (np.asarray(v, np.float32), np.asarray(vt, np.float32), np.asarray(f, np.int32))


def glb_first_image(path):
    """The first embedded image of a GLB (the prop's base colour), as RGBA8."""
    with open(path, "rb") as fh:
        data = fh.read()
    magic, _version, _length = struct.unpack_from("<III", data, 0)
    if magic != 0x46546C67:
        sys.exit(f"{path}: not a GLB file")
    off = 12
    doc, binary = None, None
    while off < len(data):
        n, kind = struct.unpack_from("<II", data, off)
        chunk = data[off + 8 : off + 8 + n]
        if kind == 0x4E4F534A:
            doc = json.loads(chunk)
        elif kind == 0x004E4942:
            binary = chunk
        off += 8 + n
    view = doc["bufferViews"][doc["images"][0]["bufferView"]]
    start = view.get("byteOffset", 0)
    import io

    img = Image.open(io.BytesIO(binary[start : start + view["byteLength"]])).convert("RGBA")
    return img


def export(propsalive, glb, t, out):
    subprocess.run(
        [propsalive, "export", glb, "--time", f"{t}", "--out", out, "--force"],
        check=True,
        stdout=subprocess.DEVNULL,
    )
    return read_obj(out)


def marker_from_prop():
    # Columns: prop X -> marker X, prop Y -> marker -Z, prop Z -> marker Y.
    return np.array(
        [[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]], dtype=np.float64
    )


def stat(v):
    v = sorted(v)
    med = v[len(v) // 2] if len(v) % 2 else 0.5 * (v[len(v) // 2 - 1] + v[len(v) // 2])
    p95 = v[min(len(v) - 1, math.ceil(0.95 * len(v)) - 1)]
    return med, p95


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--demo", required=True, help="output folder of `propsalive demo`")
    ap.add_argument("--propsalive", required=True, help="the propsalive binary (for export)")
    ap.add_argument("--repeats", type=int, default=5, help="passes over the frames")
    ap.add_argument("--ours", help="a `propsalive bench` JSON to compare the texture stage with")
    ap.add_argument("--png", help="write the last frame's twin here (a check)")
    ap.add_argument("--json", help="write the timings here")
    args = ap.parse_args()

    log = [json.loads(l) for l in open(os.path.join(args.demo, "log.jsonl"))]
    frames = [e for e in log if e["camera_from_marker"] is not None]
    if not frames:
        sys.exit(f"{args.demo}/log.jsonl: no tracked frame")
    first = Image.open(os.path.join(args.demo, "strip", f"frame_{frames[0]['frame']:04}.png"))
    w, h = first.width // 3, first.height
    f = 0.5 * h / math.tan(math.radians(FOV_Y_DEG) * 0.5)
    k = (f, f, (w - 1) * 0.5, (h - 1) * 0.5)
    glb = os.path.join(args.demo, "prop.glb")

    tmp = tempfile.mkdtemp(prefix="gl_twin_")
    key_v, uv, tris = export(args.propsalive, glb, 0.0, os.path.join(tmp, "key.obj"))
    data = []
    for e in frames:
        pos, _, t2 = export(args.propsalive, glb, e["anim_time_s"], os.path.join(tmp, "t.obj"))
        if pos.shape != key_v.shape or not np.array_equal(t2, tris):
            sys.exit("the key pose and the in-between differ in topology")
        strip = np.asarray(
            Image.open(os.path.join(args.demo, "strip", f"frame_{e['frame']:04}.png")).convert("RGBA")
        )
        rgba = np.ascontiguousarray(strip[:, :w])  # the input: the left third of the strip
        cfm = np.array(e["camera_from_marker"], dtype=np.float64).reshape(4, 4).T  # column-major
        data.append((rgba, pos, cfm @ marker_from_prop()))

    ctx = moderngl.create_standalone_context(backend="egl")
    renderer = ctx.info["GL_RENDERER"]
    depth_prog = ctx.program(vertex_shader=VERTEX_DEPTH, fragment_shader=FRAGMENT_DEPTH)
    twin_prog = ctx.program(vertex_shader=VERTEX_TWIN, fragment_shader=FRAGMENT_TWIN)
    for p in (depth_prog, twin_prog):
        p["k"].value = k
        p["size"].value = (w, h)
        p["near_far"].value = (NEAR_M, FAR_M)
    ibo = ctx.buffer(tris.astype(np.uint32).tobytes())
    key_vbo = ctx.buffer(reserve=key_v.nbytes)
    pos_vbo = ctx.buffer(reserve=key_v.nbytes)
    uv_vbo = ctx.buffer(uv.tobytes())
    albedo_img = glb_first_image(glb)
    albedo = ctx.texture(albedo_img.size, 4, albedo_img.tobytes())
    albedo.build_mipmaps()
    frame_tex = ctx.texture((w, h), 4)
    key_depth = ctx.texture((w, h), 1, dtype="f4")
    key_depth.filter = (moderngl.NEAREST, moderngl.NEAREST)
    depth_fbo = ctx.framebuffer([key_depth], ctx.depth_renderbuffer((w, h)))
    twin_col = ctx.renderbuffer((w, h), 4)
    twin_fbo = ctx.framebuffer([twin_col], ctx.depth_renderbuffer((w, h)))
    depth_vao = ctx.vertex_array(depth_prog, [(key_vbo, "3f", "key_pos")], ibo)
    twin_vao = ctx.vertex_array(
        twin_prog,
        [(pos_vbo, "3f", "pos"), (key_vbo, "3f", "key_pos"), (uv_vbo, "2f", "uv")],
        ibo,
    )
    twin_prog["frame"].value = 0
    twin_prog["key_depth"].value = 1
    twin_prog["albedo"].value = 2
    ctx.enable(moderngl.DEPTH_TEST)

    def draw(rgba, pos, camera_from_prop, timed):
        t0 = time.perf_counter()
        frame_tex.write(rgba.tobytes())
        key_vbo.write(key_v.tobytes())
        pos_vbo.write(pos.tobytes())
        m = tuple(camera_from_prop.astype(np.float32).T.flatten())  # column-major
        depth_prog["camera_from_prop"].value = m
        twin_prog["camera_from_prop"].value = m
        t1 = time.perf_counter()
        depth_fbo.use()
        depth_fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        depth_vao.render(moderngl.TRIANGLES)
        twin_fbo.use()
        twin_fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        frame_tex.use(0)
        key_depth.use(1)
        albedo.use(2)
        twin_vao.render(moderngl.TRIANGLES)
        out = twin_fbo.read(components=4)  # waits for the rasteriser
        t2 = time.perf_counter()
        if timed is not None:
            timed.append(((t2 - t0) * 1e3, (t2 - t1) * 1e3))
        return out

    for d in data[:2]:  # warm-up (shader compilation, first allocation)
        draw(*d, None)
    timed = []
    for _ in range(args.repeats):
        for d in data:
            out = draw(*d, timed)
    total = stat([t[0] for t in timed])
    passes = stat([t[1] for t in timed])
    covered = np.frombuffer(out, np.uint8).reshape(h, w, 4)[:, :, 3] > 0
    print(f"renderer: {renderer}")
    print(f"{w}x{h}, {len(key_v)} vertices, {len(tris)} triangles, {len(data)} frames x {args.repeats}")
    print(f"GL texture stage (upload + 2 passes + read-back): {total[0]:.2f} ms median, {total[1]:.2f} ms p95")
    print(f"  of which passes + read-back:                    {passes[0]:.2f} ms median, {passes[1]:.2f} ms p95")
    print(f"  twin pixels in the last frame: {int(covered.sum())}")
    result = {
        "renderer": renderer,
        "width": w,
        "height": h,
        "vertices": int(len(key_v)),
        "frames": len(data),
        "repeats": args.repeats,
        "gl_texture_ms": {"median": total[0], "p95": total[1]},
        "gl_passes_readback_ms": {"median": passes[0], "p95": passes[1]},
        "load_average": os.getloadavg()[0],
    }
    if args.ours:
        bench = json.load(open(args.ours))
        rows = [
            c for c in bench["configs"]
            if (c["width"], c["height"], c["props"], c["render_path"]) == (w, h, 1, "cpu")
        ]
        if rows:
            ours = rows[0]["stages_ms"]["texture"]["median"]
            print(f"ours (propsalive bench, cpu path, texture median): {ours:.2f} ms; "
                  f"GL / ours = {total[0] / ours:.2f}x")
            result["ours_texture_ms"] = ours
            result["gl_over_ours"] = total[0] / ours
        else:
            print(f"{args.ours}: no cpu row at {w}x{h} with 1 prop")
    if args.png:
        img = np.frombuffer(out, np.uint8).reshape(h, w, 4)[::-1]  # GL rows bottom first
        Image.fromarray(np.ascontiguousarray(img)).save(args.png)
    if args.json:
        with open(args.json + ".tmp", "w") as fh:
            json.dump(result, fh, indent=2)
        os.replace(args.json + ".tmp", args.json)


if __name__ == "__main__":
    main()
