"""Render an external set for `propsalive eval --set` with Blender's Cycles (CPU, headless).

    propsalive eval --write-kit KIT [--kit-model PATH.gltf --kit-height-m 0.16]
    blender -b -P scripts/blender/render_set.py -- --kit KIT --out SET [--samples 64]

Reads KIT/kit.json (written by `propsalive eval --write-kit`: model, board sheet, placement,
key pose, the camera path) and builds our set in Blender: the printed board sheet at true
size on a procedural wood table, a sun with a soft cast shadow plus sky light, the model
imported from glTF and placed with the kit's `marker_from_prop`. For every frame of the path
it renders, into SET:

    input/NNNN.png       the key prop (the model at the key pose) on the board
    truth/NNNN.png       the same view with the model at the frame's in-between time
    plate/NNNN.png       the same view without the prop (clean plate)
    mask_key/NNNN.png    the key prop's pixels in the input (object index pass)
    mask_truth/NNNN.png  the in-between's pixels in the truth
    manifest.json        format propsalive-set/1 (see README.md), rewritten after every frame

The cameras in the manifest are read back from Blender's camera objects (not copied from the
kit), so a convention error shows up as a tracking error in `propsalive eval --set`.
Frames already rendered are skipped: a stopped render resumes.

Conventions: Blender world = the marker frame turned 180 degrees about X (blender = (x, -y,
-z) of marker: Blender's +Z is up, the marker's -Z). A Blender camera looks down its -Z with
+Y up; OpenCV's looks down +Z with +Y down: camera_from_marker = F inv(world_from_camera) B
with F = diag(1, -1, -1), B = blender_from_marker = diag(1, -1, -1).
"""

import argparse
import glob
import json
import math
import os
import sys

import bpy
from mathutils import Matrix, Vector

B = Matrix(((1, 0, 0, 0), (0, -1, 0, 0), (0, 0, -1, 0), (0, 0, 0, 1)))
F = B.copy()
# The glTF importer turns glTF's +Y up into Blender's +Z up: blender = (x, -z, y).
BLENDER_FROM_GLTF = Matrix(((1, 0, 0, 0), (0, 0, -1, 0), (0, 1, 0, 0), (0, 0, 0, 1)))
PROP_INDEX = 1
TABLE_M = 1.6


def args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="render_set.py")
    p.add_argument("--kit", required=True, help="folder with kit.json")
    p.add_argument("--out", required=True, help="set folder to write")
    p.add_argument("--samples", type=int, default=64)
    p.add_argument("--frames", default="", help="first:last (inclusive) frame range")
    p.add_argument("--threads", type=int, default=0, help="0 = all cores")
    p.add_argument("--sun-angle-deg", type=float, default=3.0, help="sun disc: shadow softness")
    p.add_argument("--no-plate", action="store_true", help="plate for frame 0 only")
    return p.parse_args(argv)


def matrix(rows):
    return Matrix([list(map(float, r)) for r in rows])


def rows(m):
    return [[float(m[i][j]) for j in range(4)] for i in range(4)]


def wood_material():
    """A procedural wood: wave rings warped by noise, fine streaks, a colour ramp."""
    mat = bpy.data.materials.new("wood")
    mat.use_nodes = True
    nt = mat.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    coord = nt.nodes.new("ShaderNodeTexCoord")
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (1.0, 6.0, 1.0)
    wave = nt.nodes.new("ShaderNodeTexWave")
    wave.wave_type = "RINGS"
    wave.inputs["Scale"].default_value = 3.0
    wave.inputs["Distortion"].default_value = 6.0
    wave.inputs["Detail"].default_value = 3.0
    wave.inputs["Detail Scale"].default_value = 1.5
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 250.0
    noise.inputs["Detail"].default_value = 2.0
    mapping2 = nt.nodes.new("ShaderNodeMapping")
    mapping2.inputs["Scale"].default_value = (1.0, 25.0, 1.0)
    mix = nt.nodes.new("ShaderNodeMixRGB")
    mix.blend_type = "MULTIPLY"
    mix.inputs["Fac"].default_value = 0.35
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (0.16, 0.075, 0.03, 1)
    ramp.color_ramp.elements[1].color = (0.42, 0.22, 0.1, 1)
    nt.links.new(coord.outputs["Object"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], wave.inputs["Vector"])
    nt.links.new(coord.outputs["Object"], mapping2.inputs["Vector"])
    nt.links.new(mapping2.outputs["Vector"], noise.inputs["Vector"])
    nt.links.new(wave.outputs["Fac"], ramp.inputs["Fac"])
    nt.links.new(ramp.outputs["Color"], mix.inputs["Color1"])
    nt.links.new(noise.outputs["Color"], mix.inputs["Color2"])
    nt.links.new(mix.outputs["Color"], bsdf.inputs["Base Color"])
    bsdf.inputs["Roughness"].default_value = 0.45
    bsdf.inputs["Specular"].default_value = 0.35
    return mat


def board_material(png):
    mat = bpy.data.materials.new("board")
    mat.use_nodes = True
    nt = mat.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = bpy.data.images.load(png)
    tex.interpolation = "Cubic"
    nt.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    bsdf.inputs["Roughness"].default_value = 0.7
    bsdf.inputs["Specular"].default_value = 0.25
    return mat


def plane(name, size, z, mat):
    bpy.ops.mesh.primitive_plane_add(size=size, location=(0, 0, z))
    ob = bpy.context.active_object
    ob.name = name
    ob.data.materials.append(mat)
    return ob


def build_set(kit, kit_dir, o):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.fps = int(kit.get("fps", 24))
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.samples = o.samples
    sc.cycles.use_adaptive_sampling = True
    sc.cycles.adaptive_threshold = 0.01
    sc.cycles.max_bounces = 6
    import _cycles

    sc.cycles.use_denoising = bool(getattr(_cycles, "with_openimagedenoise", False))
    if sc.cycles.use_denoising:
        sc.cycles.denoiser = "OPENIMAGEDENOISE"
    if o.threads > 0:
        sc.render.threads_mode = "FIXED"
        sc.render.threads = o.threads
    sc.render.resolution_x = kit["width"]
    sc.render.resolution_y = kit["height"]
    sc.render.resolution_percentage = 100
    sc.render.pixel_aspect_x = sc.render.pixel_aspect_y = 1
    sc.render.image_settings.file_format = "PNG"
    sc.render.image_settings.color_mode = "RGB"
    sc.render.image_settings.color_depth = "8"
    sc.view_settings.view_transform = "Standard"
    sc.view_settings.look = "None"
    sc.render.use_compositing = True

    world = bpy.data.worlds.new("sky")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.52, 0.57, 0.68, 1)
    bg.inputs["Strength"].default_value = 0.45
    sc.world = world

    plane("table", TABLE_M, -0.0005, wood_material())
    sheet = kit.get("board_sheet_m", 0.26)
    plane("board", sheet, 0.0, board_material(os.path.join(kit_dir, kit["board_png"])))

    sun_data = bpy.data.lights.new("sun", "SUN")
    sun_data.energy = 2.4
    sun_data.angle = math.radians(o.sun_angle_deg)
    sun = bpy.data.objects.new("sun", sun_data)
    sc.collection.objects.link(sun)
    # Toward the light, marker frame (-0.5, 0.6, -1) as in the generator: Blender (-0.5, -0.6, 1).
    toward = B.to_3x3() @ Vector((-0.5, 0.6, -1.0))
    sun.rotation_euler = toward.to_track_quat("Z", "Y").to_euler()

    # The model.
    model = kit["model"]
    path = os.path.join(kit_dir, model["glb"]) if "glb" in model else model["path"]
    before = set(bpy.data.objects)
    import numpy

    # Blender 3.4's glTF importer uses `np.bool`, which NumPy 1.24 (Debian 12) removed.
    if "bool" not in numpy.__dict__:
        numpy.bool = bool
    bpy.ops.import_scene.gltf(filepath=path)
    imported = [ob for ob in bpy.data.objects if ob not in before]
    root = bpy.data.objects.new("prop_root", None)
    sc.collection.objects.link(root)
    root.matrix_world = B @ matrix(kit["marker_from_prop"]) @ BLENDER_FROM_GLTF.inverted()
    for ob in imported:
        if ob.parent is None:
            ob.parent = root
        if ob.type == "MESH":
            ob.pass_index = PROP_INDEX
    meshes = [ob for ob in imported if ob.type == "MESH"]

    cam_data = bpy.data.cameras.new("camera")
    cam = bpy.data.objects.new("camera", cam_data)
    sc.collection.objects.link(cam)
    sc.camera = cam
    k = kit["intrinsics"]
    w, h = kit["width"], kit["height"]
    cam_data.sensor_fit = "HORIZONTAL"
    cam_data.sensor_width = 36.0
    cam_data.lens = k["fx"] * 36.0 / w
    cam_data.shift_x = ((w - 1) / 2 - k["cx"]) / w
    cam_data.shift_y = (k["cy"] - (h - 1) / 2) / w
    cam_data.clip_start = 0.02
    cam_data.clip_end = 10.0

    # Compositor: the image, and the object-index mask of the prop to a file.
    vl = sc.view_layers[0]
    vl.use_pass_object_index = True
    sc.use_nodes = True
    nt = sc.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    rl = nt.nodes.new("CompositorNodeRLayers")
    comp = nt.nodes.new("CompositorNodeComposite")
    nt.links.new(rl.outputs["Image"], comp.inputs["Image"])
    idm = nt.nodes.new("CompositorNodeIDMask")
    idm.index = PROP_INDEX
    idm.use_antialiasing = False
    fo = nt.nodes.new("CompositorNodeOutputFile")
    fo.format.file_format = "PNG"
    fo.format.color_mode = "BW"
    fo.base_path = os.path.join(o.out, "_mask")
    fo.file_slots[0].path = "mask"
    nt.links.new(rl.outputs["IndexOB"], idm.inputs["ID value"])
    nt.links.new(idm.outputs["Alpha"], fo.inputs[0])
    return cam, meshes, fo


def set_time(t, fps):
    f = t * fps
    bpy.context.scene.frame_set(int(math.floor(f)), subframe=f - math.floor(f))


def render(path, mask_to, fo):
    """Renders the current state to `path`; the prop mask to `mask_to` (None: no mask)."""
    sc = bpy.context.scene
    fo.mute = mask_to is None
    for old in glob.glob(os.path.join(fo.base_path, "mask*.png")):
        os.remove(old)
    tmp = path + ".tmp.png"
    sc.render.filepath = tmp
    bpy.ops.render.render(write_still=True)
    os.replace(tmp, path)
    if mask_to is not None:
        written = glob.glob(os.path.join(fo.base_path, "mask*.png"))
        if len(written) != 1:
            raise RuntimeError(f"expected one mask file, found {written}")
        os.replace(written[0], mask_to)


def camera_back(cam):
    """camera_from_marker (OpenCV axes) and intrinsics, read back from Blender's camera."""
    sc = bpy.context.scene
    bpy.context.view_layer.update()
    m = F @ cam.matrix_world.inverted() @ B
    d = cam.data
    w, h = sc.render.resolution_x, sc.render.resolution_y
    fx = d.lens * w / d.sensor_width
    k = {"fx": fx, "fy": fx, "cx": (w - 1) / 2 - d.shift_x * w, "cy": (h - 1) / 2 + d.shift_y * w}
    return m, k


def main():
    o = args()
    with open(os.path.join(o.kit, "kit.json")) as f:
        kit = json.load(f)
    for sub in ["input", "truth", "plate", "mask_key", "mask_truth", "_mask"]:
        os.makedirs(os.path.join(o.out, sub), exist_ok=True)
    cam, meshes, fo = build_set(kit, o.kit, o)
    fps = bpy.context.scene.render.fps
    frames = kit["frames"]
    lo, hi = 0, len(frames) - 1
    if o.frames:
        a, b = o.frames.split(":")
        lo, hi = int(a), min(int(b), hi)
    model = {k: v for k, v in kit["model"].items() if k != "glb"}
    manifest_path = os.path.join(o.out, "manifest.json")
    done = []
    if os.path.exists(manifest_path):
        with open(manifest_path) as f:
            done = json.load(f).get("frames", [])
    by_index = {f["index"]: f for f in done}
    plate = None
    if os.path.exists(manifest_path):
        with open(manifest_path) as f:
            plate = json.load(f).get("plate")
    for fr in frames[lo:hi + 1]:
        i = fr["index"]
        name = f"{i:04d}.png"
        paths = {s: os.path.join(s, name) for s in ["input", "truth", "plate", "mask_key", "mask_truth"]}
        if i in by_index and all(os.path.exists(os.path.join(o.out, p)) for k, p in paths.items() if k != "plate"):
            continue
        c = matrix(fr["camera_from_marker"])
        cam.matrix_world = B @ c.inverted() @ F
        out = lambda k: os.path.join(o.out, paths[k])
        for ob in meshes:
            ob.hide_render = False
        set_time(fr["key_time_s"], fps)
        render(out("input"), out("mask_key"), fo)
        set_time(fr["time_s"], fps)
        render(out("truth"), out("mask_truth"), fo)
        want_plate = not o.no_plate or plate is None
        if want_plate:
            for ob in meshes:
                ob.hide_render = True
            render(out("plate"), None, fo)
            for ob in meshes:
                ob.hide_render = False
        m, k = camera_back(cam)
        entry = {
            "index": i, "time_s": fr["time_s"], "key_time_s": fr["key_time_s"],
            "camera_from_marker": rows(m), "input": paths["input"], "truth": paths["truth"],
            "key_mask": paths["mask_key"], "truth_mask": paths["mask_truth"],
            "plate": paths["plate"] if want_plate else None,
        }
        if plate is None:
            plate = {"image": paths["plate"], "camera_from_marker": rows(m)}
        by_index[i] = entry
        manifest = {
            "format": "propsalive-set/1",
            "renderer": f"Blender {bpy.app.version_string} Cycles CPU, {o.samples} spp, "
                        f"denoise {'OIDN' if bpy.context.scene.cycles.use_denoising else 'off'}, "
                        f"sun angle {o.sun_angle_deg} deg",
            "width": kit["width"], "height": kit["height"], "intrinsics": k,
            "model": model, "animation": kit.get("animation", 0),
            "marker_from_prop": kit["marker_from_prop"], "board": kit["board"],
            "plate": plate, "table_m": TABLE_M,
            "frames": [by_index[j] for j in sorted(by_index)],
        }
        with open(manifest_path + ".tmp", "w") as f:
            json.dump(manifest, f, indent=1)
        os.replace(manifest_path + ".tmp", manifest_path)
        print(f"render_set: frame {i} done", flush=True)


main()
