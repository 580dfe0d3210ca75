//! Writes a few generated frames (input | ground truth) and the clean plate to a folder:
//! `cargo run --release -p pa-scene --example scene_preview -- OUT_DIR`.
fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::path::PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "out/scene".into()),
    );
    std::fs::create_dir_all(&out)?;
    let mut renderer = pa_render::Renderer::new()?;
    let scene = pa_scene::Scene::new(pa_scene::SceneSpec::default(), &mut renderer)?;
    for i in [0u32, 12, 24, 36] {
        let f = scene.frame(&mut renderer, i)?;
        for (name, img) in [("input", &f.input), ("truth", &f.ground_truth)] {
            image::RgbaImage::from_raw(img.width, img.height, img.rgba8.clone())
                .ok_or("size")?
                .save(out.join(format!("{name}_{i:02}.png")))?;
        }
    }
    let (plate, _) = scene.clean_plate(&mut renderer)?;
    image::RgbaImage::from_raw(plate.width, plate.height, plate.rgba8)
        .ok_or("size")?
        .save(out.join("plate.png"))?;
    Ok(())
}
