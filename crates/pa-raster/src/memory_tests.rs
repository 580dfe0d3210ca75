use super::*;
use crate::live::FrameCamera;
use crate::srgb::decode_lut;

fn camera() -> LiveParams {
    LiveParams::new(FrameCamera::test_pinhole())
}

/// A key-depth map at constant 1/z over the whole image (0: empty).
struct Flat(f32);
impl InvDepthMap for Flat {
    fn size(&self) -> (u32, u32) {
        (100, 100)
    }
    fn inv_z_clamped(&self, _: i32, _: i32) -> f32 {
        self.0
    }
}

/// `m.observe` at the identity camera over a flat visibility map at 1/z = `inv_z`.
fn observe_at(
    m: &mut VertexMemory,
    params: &LiveParams,
    inv_z: f32,
    frame: &FrameSampler<'_>,
    (positions, normals): (&[Vec3], &[Vec3]),
    albedo: &MemoryAlbedo<'_>,
) -> ObserveCounts {
    let lut = decode_lut();
    m.observe(
        params,
        &Flat(inv_z),
        frame,
        Mat4::IDENTITY,
        positions,
        normals,
        albedo,
        lut,
    )
}

#[test]
fn weighted_mean_and_variance_are_exact() {
    let mut m = VertexMemory::new(1);
    // Weights 1, 3 on values 0.2, 0.6 (no outlier test before ESTABLISHED_WEIGHT... the
    // second sample arrives at weight 1 < 2): mean 0.5, variance (1*0.09 + 3*0.01)/4 = 0.03.
    assert!(!m.add_sample(0, [0.2; 3], 1.0));
    assert!(!m.add_sample(0, [0.6; 3], 3.0));
    let c = m.colour(0).unwrap();
    assert!((c[0] - 0.5).abs() < 1e-6, "{c:?}");
    assert!(
        (m.variance(0)[1] - 0.03).abs() < 1e-6,
        "{:?}",
        m.variance(0)
    );
    assert_eq!(m.weight(0), 4.0);
    assert_eq!(m.confidence(0), 1.0);
    // Unseen and out of range.
    let e = VertexMemory::new(2);
    assert_eq!(e.colour(1), None);
    assert_eq!(e.confidence(1), 0.0);
    let mut e = e;
    assert!(!e.add_sample(5, [1.0; 3], 1.0));
    assert!(!e.add_sample(0, [f32::NAN, 0.0, 0.0], 1.0));
    assert!(!e.add_sample(0, [1.0; 3], 0.0));
    assert_eq!(e.colour(0), None);
}

#[test]
fn a_hand_crossing_an_established_vertex_barely_moves_it() {
    let mut m = VertexMemory::new(1);
    for k in 0..10 {
        // Grey with a little noise.
        let v = 0.5 + if k % 2 == 0 { 0.01 } else { -0.01 };
        m.add_sample(0, [v; 3], 1.0);
    }
    // Five frames of a skin-coloured hand in front of it, at full weight.
    let mut outliers = 0;
    for _ in 0..5 {
        outliers += m.add_sample(0, [0.8, 0.45, 0.35], 1.0) as usize;
    }
    assert_eq!(outliers, 5);
    let c = m.colour(0).unwrap();
    // Without the test the mean would be 0.6 in red (5 of 15 samples at 0.8).
    assert!((c[0] - 0.5).abs() < 0.01, "{c:?}");
    // A change that is consistent (a new light) is followed once it is the majority: the
    // cap makes old samples fade.
    // Uncapped, 100 samples of 0.52 after a weight of 30 at 0.5 would give 0.5154.
    let mut n = VertexMemory::new(1);
    n.add_sample(0, [0.5; 3], MAX_WEIGHT);
    for _ in 0..100 {
        assert!(!n.add_sample(0, [0.52; 3], 1.0));
    }
    let c = n.colour(0).unwrap()[0];
    assert!(c > 0.519 && c < 0.52 + 1e-6, "{c}");
    assert!(n.weight(0) <= MAX_WEIGHT + 1e-3);
}

#[test]
fn observe_samples_only_visible_front_facing_vertices_at_their_pixels() {
    // A frame whose left half is dark (sRGB 50) and right half bright (sRGB 200).
    let mut rgba = vec![0u8; 100 * 100 * 4];
    for y in 0..100 {
        for x in 0..100 {
            let v = if x < 50 { 50 } else { 200 };
            rgba[(y * 100 + x) * 4..][..4].copy_from_slice(&[v, v, v, 255]);
        }
    }
    let frame = FrameSampler::new(100, 100, &rgba).unwrap();
    let lut = decode_lut();
    // Vertices at z = 1 m: left (pixel 19.5), right (79.5), one facing away, one outside.
    let toward = Vec3::new(0.0, 0.0, -1.0);
    let positions = [
        Vec3::new(-0.3, 0.0, 1.0),
        Vec3::new(0.3, 0.0, 1.0),
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::new(3.0, 0.0, 1.0),
    ];
    let normals = [toward, toward, -toward, toward];
    let mut params = camera();
    params.visibility = true;
    let mut m = VertexMemory::new(4);
    let counts = observe_at(
        &mut m,
        &params,
        1.0,
        &frame,
        (&positions, &normals),
        &MemoryAlbedo::uniform([1.0; 4]),
    );
    assert_eq!(counts.sampled, 2);
    assert!((m.colour(0).unwrap()[0] - lut[50]).abs() < 1e-6);
    assert!((m.colour(1).unwrap()[0] - lut[200]).abs() < 1e-6);
    assert_eq!(m.colour(2), None);
    assert_eq!(m.colour(3), None);
    // At z = 1 m with fx = 100 px: 0.1 px/mm; the ray's cosine 1/sqrt(1.09); a full margin.
    let cos = 1.0 / 1.09f32.sqrt();
    assert!((m.weight(0) - 0.1 * cos).abs() < 1e-6, "{}", m.weight(0));
    // Hidden behind a nearer key-pose surface (at 0.5 m): no sample.
    let mut hidden = VertexMemory::new(4);
    let c = observe_at(
        &mut hidden,
        &params,
        2.0,
        &frame,
        (&positions, &normals),
        &MemoryAlbedo::uniform([1.0; 4]),
    );
    assert_eq!(c.sampled, 0);
    // At a silhouette (no surface around it in the map) the weight drops to a fifth.
    let mut edge = VertexMemory::new(4);
    params.visibility = true;
    observe_at(
        &mut edge,
        &params,
        0.0,
        &frame,
        (&positions, &normals),
        &MemoryAlbedo::uniform([1.0; 4]),
    );
    assert!(
        (edge.weight(0) - 0.02 * cos).abs() < 1e-6,
        "{}",
        edge.weight(0)
    );
    // Wrong lengths: nothing.
    let mut short = VertexMemory::new(3);
    let c = observe_at(
        &mut short,
        &params,
        1.0,
        &frame,
        (&positions, &normals),
        &MemoryAlbedo::uniform([1.0; 4]),
    );
    assert_eq!(c, ObserveCounts::default());
}

#[test]
fn the_attribute_blends_memory_into_the_fallback() {
    let mut m = VertexMemory::new(2);
    m.add_sample(0, [0.8, 0.4, 0.2], FULL_WEIGHT * 0.5);
    let mut attr = Vec::new();
    m.premultiplied(&mut attr);
    assert_eq!(attr.len(), 2);
    assert_eq!(attr[1], [0.0; 4]);
    let lit = [0.1, 0.1, 0.1];
    let white = [1.0; 3];
    // Unseen: the lit fallback; half confident: halfway; interpolated attributes too.
    assert_eq!(remembered_or(attr[1], white, lit), lit);
    let half = remembered_or(attr[0], white, lit);
    assert!((half[0] - 0.45).abs() < 1e-6 && (half[2] - 0.15).abs() < 1e-6);
    m.add_sample(0, [0.8, 0.4, 0.2], FULL_WEIGHT);
    m.premultiplied(&mut attr);
    let full = remembered_or(attr[0], white, lit);
    assert!((full[0] - 0.8).abs() < 1e-6, "{full:?}");
    // The remembered gain falls on the pixel's albedo.
    let dark = remembered_or(attr[0], [0.5, 0.25, 1.0], lit);
    assert!(
        (dark[0] - 0.4).abs() < 1e-6 && (dark[1] - 0.1).abs() < 1e-6,
        "{dark:?}"
    );
}

#[test]
fn texels_per_metre_is_the_uv_scale_of_the_surface() {
    // A 0.5 m square mapped onto the whole of a 256-texel texture: 512 texels per metre along
    // its sides and its diagonal alike.
    let positions = [
        Vec3::ZERO,
        Vec3::new(0.5, 0.0, 0.0),
        Vec3::new(0.5, 0.5, 0.0),
        Vec3::new(0.0, 0.5, 0.0),
        Vec3::new(9.0, 9.0, 9.0),
    ];
    let uvs = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]];
    let d = texels_per_metre(&positions, &uvs, &[0, 1, 2, 0, 2, 3, 0, 1, 99], (256, 256));
    for v in &d[..4] {
        assert!((v - 512.0).abs() < 1e-3, "{d:?}");
    }
    // A vertex no triangle uses, an index out of range, and uvs of the wrong length.
    assert_eq!(d[4], 0.0);
    assert_eq!(
        texels_per_metre(&positions, &uvs[..2], &[0, 1, 2], (256, 256)),
        [0.0; 5]
    );
    // A degenerate edge (both ends at one point) is skipped, not infinite.
    let same = [Vec3::ZERO, Vec3::ZERO, Vec3::X];
    let d = texels_per_metre(&same, &uvs[..3], &[0, 1, 2], (256, 256));
    assert!(d.iter().all(|v| v.is_finite()), "{d:?}");
}

/// A 64x64 texture of one-texel black and white squares: level 0 is 0 or 1 (linear), every
/// coarser level mid grey (0.5 linear).
fn checker() -> CpuMipTexture {
    let mut rgba = Vec::new();
    for y in 0..64 {
        for x in 0..64 {
            let v = if (x + y) % 2 == 0 { 255 } else { 0 };
            rgba.extend_from_slice(&[v, v, v, 255]);
        }
    }
    CpuMipTexture::from_srgb8(64, 64, &rgba).unwrap()
}

#[test]
fn a_sample_is_divided_by_the_albedo_at_its_footprint() {
    // One vertex at z = 1 m facing the camera (fx = 100 px: 100 px/m), over a frame of
    // uniform sRGB 128 (linear 0.216); the model's albedo a fine checker whose mean is 0.5.
    let rgba = [128u8, 128, 128, 255].repeat(100 * 100);
    let frame = FrameSampler::new(100, 100, &rgba).unwrap();
    let lut = decode_lut();
    let positions = [Vec3::new(0.0, 0.0, 1.0)];
    let normals = [Vec3::new(0.0, 0.0, -1.0)];
    let tex = checker();
    // A white texel's centre.
    let uvs = [[0.5 / 64.0, 0.5 / 64.0]];
    let mut params = camera();
    params.visibility = true;
    let gain_at = |texels_per_m: f32, factor: [f32; 4]| {
        let mut m = VertexMemory::new(1);
        let albedo = MemoryAlbedo {
            texture: Some(&tex),
            uvs: &uvs,
            factor,
            texels_per_m: &[texels_per_m],
        };
        let c = observe_at(
            &mut m,
            &params,
            1.0,
            &frame,
            (&positions, &normals),
            &albedo,
        );
        assert_eq!(c.sampled, 1);
        m.colour(0).unwrap()
    };
    let seen = lut[128];
    // 6400 texels/m at 100 px/m: 64 texels a pixel, level 6 + bias, mid grey: the frame's
    // grey is the checker's mean seen from afar, so the gain is seen / 0.5.
    let far = gain_at(6400.0, [1.0; 4]);
    assert!((far[0] - seen / 0.5).abs() < 0.01, "{far:?} {seen}");
    // The base colour factor scales the albedo, per channel.
    let tinted = gain_at(6400.0, [0.5, 1.0, 1.0, 1.0]);
    assert!((tinted[0] - seen / 0.25).abs() < 0.02, "{tinted:?}");
    assert!((tinted[1] - seen / 0.5).abs() < 0.01, "{tinted:?}");
    // At 1 texel a pixel the level is the bias alone (1.5): still mostly grey, never the
    // white texel alone (gain = seen) nor the black one (gain = seen / MIN_ALBEDO).
    let near = gain_at(100.0, [1.0; 4]);
    assert!(near[0] > seen * 1.2 && near[0] < seen * 3.0, "{near:?}");
    // No texture: the factor alone.
    let mut m = VertexMemory::new(1);
    observe_at(
        &mut m,
        &params,
        1.0,
        &frame,
        (&positions, &normals),
        &MemoryAlbedo::uniform([0.5, 0.5, 0.0, 1.0]),
    );
    let g = m.colour(0).unwrap();
    assert!((g[0] - seen / 0.5).abs() < 1e-4, "{g:?}");
    // A black albedo: the gain over MIN_ALBEDO, finite.
    assert!((g[2] - seen / MIN_ALBEDO).abs() < 1e-2, "{g:?}");
}
