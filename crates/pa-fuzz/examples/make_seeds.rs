//! Writes the generated part of the seed corpus (`corpus/<target>/`): the glTF models, the
//! MP4s (our own writer), the stills and the TOML/JSON calibrations. The hand-written seeds
//! (shot files, OpenCV/ROS YAML) are committed as they are. Run once after changing it:
//!
//! ```text
//! cargo run -p pa-fuzz --example make_seeds
//! ```
//!
//! Every seed is small (a few KB at most): mutation and AFL both work best on small inputs.

use std::path::{Path, PathBuf};

use base64::Engine as _;
use serde_json::json;

fn main() {
    let corpus = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("corpus");
    gltf_seeds(&corpus.join("gltf"));
    calibration_seeds(&corpus.join("calibration"));
    mp4_seeds(&corpus.join("mp4"));
    still_seeds(&corpus.join("still"));
    println!("seeds written under {}", corpus.display());
}

fn write(dir: &Path, name: &str, bytes: &[u8]) {
    std::fs::create_dir_all(dir).expect("corpus folder");
    std::fs::write(dir.join(name), bytes).expect("write seed");
    println!("{:>6} bytes  {}", bytes.len(), dir.join(name).display());
}

// --- glTF ------------------------------------------------------------------------------------

/// Little-endian bytes of f32s.
fn f32s(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn pad4(b: &mut Vec<u8>) {
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
}

/// A buffer being filled with views and accessors.
#[derive(Default)]
struct Bin {
    bytes: Vec<u8>,
    views: Vec<serde_json::Value>,
    accessors: Vec<serde_json::Value>,
}

impl Bin {
    fn view(&mut self, data: &[u8], target: Option<u32>) -> usize {
        pad4(&mut self.bytes);
        let mut v = json!({"buffer": 0, "byteOffset": self.bytes.len(), "byteLength": data.len()});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.bytes.extend_from_slice(data);
        self.views.push(v);
        self.views.len() - 1
    }

    fn accessor(&mut self, mut a: serde_json::Value, data: &[u8], target: Option<u32>) -> usize {
        let view = self.view(data, target);
        a["bufferView"] = json!(view);
        self.accessors.push(a);
        self.accessors.len() - 1
    }
}

/// A skinned, animated quad with a morph target, a sparse accessor, an embedded texture and
/// three samplers (LINEAR rotation, STEP translation, CUBICSPLINE scale, LINEAR weights).
fn rich_model() -> (serde_json::Value, Vec<u8>) {
    let mut b = Bin::default();
    let positions = [
        0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0f32,
    ];
    let pos = b.accessor(
        json!({"componentType": 5126, "count": 4, "type": "VEC3",
               "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]}),
        &f32s(&positions),
        Some(34962),
    );
    let nrm = b.accessor(
        json!({"componentType": 5126, "count": 4, "type": "VEC3"}),
        &f32s(&[0.0, 0.0, 1.0].repeat(4)),
        Some(34962),
    );
    let uv = b.accessor(
        json!({"componentType": 5126, "count": 4, "type": "VEC2"}),
        &f32s(&[0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0]),
        Some(34962),
    );
    let joints = b.accessor(
        json!({"componentType": 5121, "count": 4, "type": "VEC4"}),
        &[0, 1, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0],
        Some(34962),
    );
    let weights = b.accessor(
        json!({"componentType": 5126, "count": 4, "type": "VEC4"}),
        &f32s(&[
            1.0, 0.0, 0.0, 0.0, 0.75, 0.25, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.5, 0.5, 0.0, 0.0,
        ]),
        Some(34962),
    );
    let indices = b.accessor(
        json!({"componentType": 5123, "count": 6, "type": "SCALAR"}),
        &[0u16, 1, 2, 0, 2, 3]
            .iter()
            .flat_map(|i| i.to_le_bytes())
            .collect::<Vec<_>>(),
        Some(34963),
    );
    // Morph target: sparse, two of four vertices moved.
    let sparse_idx = b.view(&[1u8, 0, 2, 0], None);
    let sparse_val = b.view(&f32s(&[0.0, 0.0, 0.5, 0.0, 0.0, 0.5]), None);
    b.accessors.push(json!({
        "componentType": 5126, "count": 4, "type": "VEC3",
        "min": [0.0, 0.0, 0.0], "max": [0.0, 0.0, 0.5],
        "sparse": {"count": 2,
                   "indices": {"bufferView": sparse_idx, "componentType": 5123},
                   "values": {"bufferView": sparse_val}}
    }));
    let morph = b.accessors.len() - 1;
    let ibm = b.accessor(
        json!({"componentType": 5126, "count": 2, "type": "MAT4"}),
        &f32s(&[
            1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, //
            1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -0.5, 0.0, 1.0,
        ]),
        None,
    );
    let times = b.accessor(
        json!({"componentType": 5126, "count": 3, "type": "SCALAR", "min": [0.0], "max": [1.0]}),
        &f32s(&[0.0, 0.5, 1.0]),
        None,
    );
    let rot = b.accessor(
        json!({"componentType": 5126, "count": 3, "type": "VEC4"}),
        &f32s(&[
            0.0,
            0.0,
            0.0,
            1.0,
            0.0,
            0.0,
            0.382_683_4,
            0.923_879_5,
            0.0,
            0.0,
            std::f32::consts::FRAC_1_SQRT_2,
            std::f32::consts::FRAC_1_SQRT_2,
        ]),
        None,
    );
    let trans = b.accessor(
        json!({"componentType": 5126, "count": 3, "type": "VEC3"}),
        &f32s(&[0.0, 0.5, 0.0, 0.1, 0.5, 0.0, 0.2, 0.5, 0.0]),
        None,
    );
    // CUBICSPLINE: (in-tangent, value, out-tangent) per key.
    let mut scale = Vec::new();
    for s in [1.0f32, 1.5, 1.0] {
        scale.extend_from_slice(&[0.0, 0.0, 0.0, s, s, s, 0.0, 0.0, 0.0]);
    }
    let scale = b.accessor(
        json!({"componentType": 5126, "count": 9, "type": "VEC3"}),
        &f32s(&scale),
        None,
    );
    let wts = b.accessor(
        json!({"componentType": 5126, "count": 3, "type": "SCALAR"}),
        &f32s(&[0.0, 1.0, 0.25]),
        None,
    );
    let png = png_bytes(&image::RgbaImage::from_fn(4, 4, |x, y| {
        image::Rgba([(x * 60) as u8, (y * 60) as u8, 200, 255])
    }));
    let img_view = b.view(&png, None);
    pad4(&mut b.bytes);
    let doc = json!({
        "asset": {"version": "2.0", "generator": "pa-fuzz make_seeds"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [
            {"name": "quad", "mesh": 0, "skin": 0},
            {"name": "root", "children": [2]},
            {"name": "tip", "translation": [0.0, 0.5, 0.0]}
        ],
        "meshes": [{"name": "quad", "weights": [0.0], "primitives": [{
            "attributes": {"POSITION": pos, "NORMAL": nrm, "TEXCOORD_0": uv,
                           "JOINTS_0": joints, "WEIGHTS_0": weights},
            "indices": indices, "material": 0, "mode": 4,
            "targets": [{"POSITION": morph}]
        }]}],
        "skins": [{"joints": [1, 2], "inverseBindMatrices": ibm, "skeleton": 1}],
        "materials": [{"name": "paint", "doubleSided": true, "pbrMetallicRoughness": {
            "baseColorFactor": [1.0, 0.9, 0.8, 1.0], "baseColorTexture": {"index": 0}}}],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9729, "minFilter": 9987}],
        "images": [{"name": "albedo", "bufferView": img_view, "mimeType": "image/png"}],
        "animations": [{"name": "Animate",
            "samplers": [
                {"input": times, "output": rot, "interpolation": "LINEAR"},
                {"input": times, "output": trans, "interpolation": "STEP"},
                {"input": times, "output": scale, "interpolation": "CUBICSPLINE"},
                {"input": times, "output": wts, "interpolation": "LINEAR"}
            ],
            "channels": [
                {"sampler": 0, "target": {"node": 2, "path": "rotation"}},
                {"sampler": 1, "target": {"node": 2, "path": "translation"}},
                {"sampler": 2, "target": {"node": 1, "path": "scale"}},
                {"sampler": 3, "target": {"node": 0, "path": "weights"}}
            ]}],
        "bufferViews": b.views,
        "accessors": b.accessors,
        "buffers": [{"byteLength": b.bytes.len()}]
    });
    (doc, b.bytes)
}

fn glb(doc: &serde_json::Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(doc).expect("json");
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    pad4(&mut bin);
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

fn gltf_seeds(dir: &Path) {
    let (doc, bin) = rich_model();
    write(dir, "rich.glb", &glb(&doc, &bin));
    let mut embedded = doc.clone();
    embedded["buffers"][0]["uri"] = json!(format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    ));
    write(
        dir,
        "rich-embedded.gltf",
        &serde_json::to_vec_pretty(&embedded).expect("json"),
    );
    // External resources: `fuzz.bin` (bytes 0..=255) and `fuzz.png` exist beside the input
    // (the gltf target writes them). The vertex data read from `fuzz.bin` is tiny finite
    // floats (0x03020100...): meaningless, but loadable.
    let external = json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "rotation": [0.0, 0.0, 0.0, 1.0], "scale": [1.0, 2.0, 1.0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
        "textures": [{"source": 0}],
        "images": [{"uri": "fuzz.png"}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 256}],
        "accessors": [
            {"bufferView": 0, "byteOffset": 0, "componentType": 5126, "count": 3, "type": "VEC3",
             "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 1.0]},
            {"bufferView": 0, "byteOffset": 40, "componentType": 5123, "count": 3, "type": "VEC2", "normalized": true}
        ],
        "buffers": [{"uri": "fuzz.bin", "byteLength": 256}]
    });
    write(
        dir,
        "external.gltf",
        &serde_json::to_vec_pretty(&external).expect("json"),
    );
    // The smallest file the loader accepts: no meshes at all.
    write(dir, "empty.gltf", br#"{"asset":{"version":"2.0"}}"#);
}

// --- calibration -----------------------------------------------------------------------------

fn calibration_seeds(dir: &Path) {
    use pa_camera::calib::{format_calibration, CalibFormat};
    let model = pa_camera::CameraModel {
        intrinsics: pa_camera::Intrinsics {
            fx: 812.5,
            fy: 810.25,
            cx: 639.5,
            cy: 359.5,
            width: 1280,
            height: 720,
        },
        distortion: pa_camera::Distortion {
            k1: -0.12,
            k2: 0.05,
            p1: 0.001,
            p2: -0.0005,
            k3: -0.01,
        },
    };
    for (format, name) in [
        (CalibFormat::Toml, "camera.toml"),
        (CalibFormat::Json, "camera.json"),
        (CalibFormat::OpencvYaml, "written.yaml"),
    ] {
        let text = format_calibration(&model, format, name).expect("format");
        write(dir, name, text.as_bytes());
    }
}

// --- MP4 -------------------------------------------------------------------------------------

fn mp4_seeds(dir: &Path) {
    use pa_video::{Fps, Mp4Writer, Mp4WriterOptions, RateControl};
    let tmp = std::env::temp_dir().join(format!("pa-fuzz-seeds-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).expect("temp folder");
    // (name, width, height, frames, keyframe interval): an even size, and an odd one (padded
    // for coding, cropped back by a clean aperture).
    for (name, w, h, frames, key) in [
        ("16x16-3f.mp4", 16u32, 16u32, 3u32, 2u32),
        ("33x17-2f.mp4", 33, 17, 2, 1),
    ] {
        let path = tmp.join(name);
        let mut opts = Mp4WriterOptions::new(Fps::new(24, 1).expect("fps"));
        opts.rate_control = RateControl::Quality {
            qp_min: 40,
            qp_max: 51,
        };
        opts.keyframe_interval = Some(key);
        opts.overwrite = true;
        let mut writer = Mp4Writer::create(&path, w, h, opts).expect("writer");
        for i in 0..frames {
            let rgba: Vec<u8> = (0..w * h)
                .flat_map(|p| {
                    let (x, y) = (p % w, p / w);
                    [(x * 15 + i * 40) as u8, (y * 15) as u8, 128, 255]
                })
                .collect();
            writer.write_frame(&rgba).expect("frame");
        }
        writer.finish().expect("finish");
        write(dir, name, &std::fs::read(&path).expect("read back"));
    }
    let _ = std::fs::remove_dir_all(&tmp);
}

// --- stills ----------------------------------------------------------------------------------

fn png_bytes(img: &image::RgbaImage) -> Vec<u8> {
    encode(
        &image::DynamicImage::ImageRgba8(img.clone()),
        image::ImageFormat::Png,
    )
}

fn encode(img: &image::DynamicImage, format: image::ImageFormat) -> Vec<u8> {
    let mut out = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut out), format)
        .expect("encode");
    out
}

fn still_seeds(dir: &Path) {
    use image::{DynamicImage, ImageFormat};
    let rgb = image::RgbImage::from_fn(8, 8, |x, y| {
        image::Rgb([(x * 32) as u8, (y * 32) as u8, ((x + y) * 16) as u8])
    });
    let rgba = image::RgbaImage::from_fn(2, 2, |x, y| {
        image::Rgba([255 * x as u8, 255 * y as u8, 128, 200])
    });
    let gray16 = image::ImageBuffer::<image::Luma<u16>, _>::from_fn(3, 2, |x, y| {
        image::Luma([(x * 20000 + y * 7000) as u16])
    });
    let rgb16 = image::ImageBuffer::<image::Rgb<u16>, _>::from_fn(2, 2, |x, y| {
        image::Rgb([(x * 60000) as u16, (y * 60000) as u16, 1234])
    });
    write(dir, "rgba-2x2.png", &png_bytes(&rgba));
    write(
        dir,
        "gray16-3x2.png",
        &encode(&DynamicImage::ImageLuma16(gray16), ImageFormat::Png),
    );
    write(
        dir,
        "rgb-8x8.jpg",
        &encode(&DynamicImage::ImageRgb8(rgb.clone()), ImageFormat::Jpeg),
    );
    write(
        dir,
        "gray-8x8.jpg",
        &encode(
            &DynamicImage::ImageLuma8(DynamicImage::ImageRgb8(rgb.clone()).to_luma8()),
            ImageFormat::Jpeg,
        ),
    );
    write(
        dir,
        "rgb-8x8.tif",
        &encode(&DynamicImage::ImageRgb8(rgb), ImageFormat::Tiff),
    );
    write(
        dir,
        "rgb16-2x2.tif",
        &encode(&DynamicImage::ImageRgb16(rgb16), ImageFormat::Tiff),
    );
}
