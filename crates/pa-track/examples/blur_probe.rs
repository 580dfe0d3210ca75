//! Recall of the detection modes on large, blurred, rotated tags (diagnostic):
//! `cargo run --release -p pa-track --example blur_probe`.

use pa_track::{marker_cells, Detector, DetectorConfig, GrayImage, TagFamily};

fn blur(img: &GrayImage, sigma: f64) -> GrayImage {
    if sigma <= 0.0 {
        return img.clone();
    }
    let r = (3.0 * sigma).ceil() as i64;
    let k: Vec<f64> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let s: f64 = k.iter().sum();
    let (w, h) = (img.width as i64, img.height as i64);
    let mut tmp = vec![0.0f64; (w * h) as usize];
    for y in 0..h {
        for x in 0..w {
            let mut a = 0.0;
            for (j, kv) in k.iter().enumerate() {
                let xx = (x + j as i64 - r).clamp(0, w - 1);
                a += kv * img.data[(y * w + xx) as usize] as f64;
            }
            tmp[(y * w + x) as usize] = a / s;
        }
    }
    let mut out = img.clone();
    for y in 0..h {
        for x in 0..w {
            let mut a = 0.0;
            for (j, kv) in k.iter().enumerate() {
                let yy = (y + j as i64 - r).clamp(0, h - 1);
                a += kv * tmp[(yy * w + x) as usize];
            }
            out.data[(y * w + x) as usize] = (a / s).round().clamp(0.0, 255.0) as u8;
        }
    }
    out
}

/// The tag (10 cells of `cell` px, rotated by `angle`) centred in a `w x h` grey frame.
fn scene(w: u32, h: u32, cell: f64, angle: f64) -> GrayImage {
    let cells = marker_cells(TagFamily::Tag36h11, 3).expect("tag");
    let mut img = GrayImage::filled(w, h, 128);
    let (c, s) = (angle.cos(), angle.sin());
    for y in 0..h {
        for x in 0..w {
            let mut acc = 0.0;
            for (sx, sy) in [(-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25)] {
                let dx = x as f64 + sx - w as f64 / 2.0;
                let dy = y as f64 + sy - h as f64 / 2.0;
                let u = (c * dx + s * dy) / cell + 5.0;
                let v = (-s * dx + c * dy) / cell + 5.0;
                acc += if (0.0..10.0).contains(&u) && (0.0..10.0).contains(&v) {
                    cells.data[v as usize * 10 + u as usize] as f64 * 0.8 + 20.0
                } else if (-1.0..11.0).contains(&u) && (-1.0..11.0).contains(&v) {
                    224.0
                } else {
                    128.0
                };
            }
            img.data[(y * w + x) as usize] = (acc / 4.0) as u8;
        }
    }
    img
}

fn main() {
    let (w, h) = (1280, 720);
    println!("tag px (black square) / blur sigma: found by [dec1 only, default, dec 2 only]");
    for tag_px in [60.0, 150.0, 300.0, 600.0] {
        for sigma in [0.0, 1.0, 2.0, 4.0, 8.0] {
            let mut row = Vec::new();
            for angle in [0.0f64, 0.3, 0.785] {
                let img = blur(&scene(w, h, tag_px / 8.0, angle), sigma);
                let mut r = String::new();
                for cfg in [
                    DetectorConfig {
                        second_pass_decimate: None,
                        fallback_decimate: None,
                        ..Default::default()
                    },
                    DetectorConfig::default(),
                    DetectorConfig {
                        decimate: 2,
                        second_pass_decimate: None,
                        fallback_decimate: None,
                        ..Default::default()
                    },
                ] {
                    let mut det = Detector::new(cfg).expect("detector");
                    let n = det
                        .detect(&img)
                        .expect("detect")
                        .iter()
                        .filter(|d| d.id == 3)
                        .count();
                    r.push(if n > 0 { 'Y' } else { '.' });
                }
                row.push(r);
            }
            println!("{tag_px:5} px, sigma {sigma}: {row:?}");
        }
    }
}
