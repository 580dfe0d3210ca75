use super::*;

const SHOT: &str = r#"
model = "prop.glb"
[[key_poses]]
name = "A"
frame = 0
[camera]
fov_y_deg = 45.0
[marker]
[[marker.tags]]
id = 0
center_m = [0.0, 0.0]
size_m = 0.05
"#;

fn write(extra: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("shot.toml");
    std::fs::write(&p, format!("{SHOT}{extra}")).expect("write");
    std::fs::write(dir.path().join("plate.png"), b"not checked here").expect("write");
    (dir, p)
}

fn config(extra: &str, flags: &DiminishOverrides) -> Result<DiminishConfig, ShotError> {
    let (_d, p) = write(extra);
    let shot = Shot::load(&p)?;
    resolve(&shot.diminish, flags, &p)
}

#[test]
fn without_the_table_the_defaults_are_todays() {
    let (_d, p) = write("");
    let shot = Shot::load(&p).expect("valid");
    assert!(shot.diminish.is_empty());
    // The TOML of a shot without [diminish] has none.
    assert!(!shot.to_toml().expect("toml").contains("diminish"));
    let c = resolve(&shot.diminish, &DiminishOverrides::default(), &p).expect("config");
    assert_eq!(c, DiminishConfig::default());
    assert_eq!(
        (c.fill.to_fill(), c.dilation_px, c.shadows),
        (Some(crate::ar::Fill::Rays), 4, false)
    );
    assert_eq!(
        c.fill.to_fill(),
        Some(crate::ar::ArSettings::ours().fill),
        "the default is our method's"
    );
    assert_eq!(c.dilation_px, crate::ar::ArSettings::ours().dilate_px);
}

#[test]
fn the_table_is_read_and_round_trips() {
    let extra =
        "[diminish]\nfill = \"rectangle\"\ndilation_px = 7\nshadows = true\nalign_plate = false\n";
    let (_d, p) = write(extra);
    let shot = Shot::load(&p).expect("valid");
    let again: Shot = toml::from_str(&shot.to_toml().expect("toml")).expect("parse");
    assert_eq!(again, shot);
    let c = resolve(&shot.diminish, &DiminishOverrides::default(), &p).expect("config");
    assert_eq!(c.fill, FillName::Rectangle);
    assert_eq!((c.dilation_px, c.shadows, &c.plate), (7, true, &None));
    assert!(!c.align_plate);
    assert_eq!(
        c.describe(),
        "fill=rectangle plate=none dilation_px=7 shadows=true align_plate=false"
    );
    // Without the key the plate is aligned; a flag overrides the shot.
    let flags = DiminishOverrides {
        align_plate: Some(true),
        ..DiminishOverrides::default()
    };
    assert!(
        resolve(&shot.diminish, &flags, &p)
            .expect("config")
            .align_plate
    );
    assert!(DiminishConfig::default().align_plate);
}

#[test]
fn a_plate_selects_the_plate_fill_and_resolves_against_the_shot() {
    let (d, p) = write("[diminish]\nclean_plate = \"plate.png\"\n");
    let shot = Shot::load(&p).expect("valid");
    let c = resolve(&shot.diminish, &DiminishOverrides::default(), &p).expect("config");
    assert_eq!(c.fill, FillName::Plate);
    assert_eq!(
        c.plate,
        Some(PlateSource::Still(d.path().join("plate.png")))
    );
    let c = config(
        "[diminish]\nplate_frames = 3\nfill = \"rays\"\n",
        &DiminishOverrides::default(),
    )
    .expect("config");
    assert_eq!(
        (c.fill, c.plate),
        (FillName::Rays, Some(PlateSource::FirstFrames(3)))
    );
}

#[test]
fn flags_override_the_shot() {
    let flags = DiminishOverrides {
        fill: Some("none".into()),
        dilation_px: Some(0),
        shadows: Some(false),
        plate_frames: Some(2),
        ..Default::default()
    };
    let c = config(
        "[diminish]\nfill = \"plate\"\nclean_plate = \"plate.png\"\ndilation_px = 9\nshadows = true\n",
        &flags,
    )
    .expect("config");
    assert_eq!(
        c,
        DiminishConfig {
            fill: FillName::None,
            plate: Some(PlateSource::FirstFrames(2)),
            dilation_px: 0,
            shadows: false,
            align_plate: true,
        }
    );
}

#[test]
fn refusals_name_the_shot_and_the_problem() {
    let none = DiminishOverrides::default();
    for (extra, needle) in [
        (
            "[diminish]\nfill = \"smudge\"\n",
            "[diminish] fill: fill \"smudge\": expected one of rays, plate, patch, rectangle, none",
        ),
        (
            "[diminish]\ndilation_px = -2\n",
            "[diminish] dilation_px must be 0..=64 pixels, got -2",
        ),
        ("[diminish]\ndilation_px = 65\n", "got 65"),
        (
            "[diminish]\nclean_plate = \"missing.png\"\n",
            "clean plate ",
        ),
        ("[diminish]\nclean_plate = \".\"\n", "is not a regular file"),
        ("[diminish]\nfill = \"plate\"\n", "needs a clean plate"),
        (
            "[diminish]\nplate_frames = 0\n",
            "plate_frames must be 1..=10000, got 0",
        ),
        (
            "[diminish]\nclean_plate = \"plate.png\"\nplate_frames = 2\n",
            "not both",
        ),
        ("[diminish]\nshadows = \"yes\"\n", "not a valid shot"),
    ] {
        let e = config(extra, &none).expect_err(needle).to_string();
        assert!(
            e.contains(needle) && e.contains("shot.toml"),
            "{needle}: {e}"
        );
    }
    let e = config(
        "",
        &DiminishOverrides {
            fill: Some("Rays".into()),
            ..Default::default()
        },
    )
    .expect_err("case")
    .to_string();
    assert!(e.contains("--fill: fill \"Rays\""), "{e}");
    let e = config(
        "",
        &DiminishOverrides {
            dilation_px: Some(-1),
            ..Default::default()
        },
    )
    .expect_err("negative")
    .to_string();
    assert!(e.contains("--dilation must be 0..=64"), "{e}");
}

#[test]
fn fill_names_round_trip() {
    for f in FillName::ALL {
        assert_eq!(f.name().parse::<FillName>(), Ok(f));
    }
    assert_eq!(
        FillName::Patch.to_fill(),
        Some(Fill::Patch { plate: false })
    );
    // The patch fill prefers the clean plate when the shot has one.
    let mut c = DiminishConfig {
        fill: FillName::Patch,
        ..DiminishConfig::default()
    };
    assert_eq!(c.fill(), Some(Fill::Patch { plate: false }));
    c.plate = Some(PlateSource::FirstFrames(2));
    assert_eq!(c.fill(), Some(Fill::Patch { plate: true }));
    c.fill = FillName::Rays;
    assert_eq!(c.fill(), Some(Fill::Rays));
}
