//! Canonical marker images.

use pa_track::{family_layout, marker_cells, marker_image, Detector, DetectorConfig, TagFamily};

#[test]
fn marker_image_is_detectable_and_sized() {
    let l = family_layout(TagFamily::Tag36h11).expect("layout");
    assert_eq!((l.total_cells, l.border_cells, l.id_count), (10, 8, 587));
    let img = marker_image(TagFamily::Tag36h11, 42, 200).expect("image");
    assert_eq!((img.width, img.height), (200, 200));
    let padded = img.upscale_pad(1, 30, 255);
    let mut det = Detector::new(DetectorConfig::default()).expect("detector");
    let d = det.detect(&padded).expect("detect");
    assert_eq!(d.len(), 1);
    assert_eq!(d[0].id, 42);
    assert!(marker_image(TagFamily::Tag36h11, 587, 100).is_err());
    assert!(marker_image(TagFamily::Tag36h11, 0, 5).is_err());
    // Other families render and decode too.
    for fam in [
        TagFamily::Tag25h9,
        TagFamily::Tag16h5,
        TagFamily::TagStandard41h12,
    ] {
        let cells = marker_cells(fam, 3).expect("cells");
        let img = cells.upscale_pad(20, 40, 255);
        let mut det = Detector::new(DetectorConfig {
            families: vec![fam],
            ..Default::default()
        })
        .expect("detector");
        let d = det.detect(&img).expect("detect");
        assert!(
            d.iter().any(|d| d.id == 3 && d.family == fam),
            "{fam}: {d:?}"
        );
    }
    assert_eq!(
        "tag36h11".parse::<TagFamily>().expect("name"),
        TagFamily::Tag36h11
    );
    assert_eq!(
        "tagStandard41h12".parse::<TagFamily>().expect("name"),
        TagFamily::TagStandard41h12
    );
    assert!("tag99".parse::<TagFamily>().is_err());
}
