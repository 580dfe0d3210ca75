//! Where a key prop touches the table: its key pose posed on the CPU, placed on the marker
//! (`marker_from_prop`: the marker's -Z is up, the table is `z = 0`), its lowest points (the
//! vertices within [`CONTACT_BAND_M`] of the lowest one) and their outline on the table.
//!
//! `propsalive new` uses it to stand the prop on the sheet ([`rest_on_table`]: the lift that
//! puts the lowest point on the table and the shift that centres the contact on the marker
//! origin); `propsalive marker --shot` prints the outline and the prop's front direction, so
//! that the animator stands the print where the shot says.

use glam::{DVec2, Mat4, Vec3};
use pa_model::{anim, skin, Model};

use crate::shot::Placement;

/// How far above the lowest vertex a vertex still counts as touching the table (2 mm).
pub const CONTACT_BAND_M: f64 = 0.002;

/// The key pose's contact with the table, in the marker frame (metres).
#[derive(Debug, Clone, PartialEq)]
pub struct Footprint {
    /// Convex hull of the contact points on the table plane, counter-clockwise in (x, y)
    /// (at least one point; two for a contact along a line).
    pub outline_m: Vec<DVec2>,
    /// Area centroid of the outline (the mean of its points when it has no area).
    pub centre_m: DVec2,
    /// Marker `z` of the lowest vertex (0 when the prop rests on the table; negative above).
    pub lowest_z_m: f64,
    /// The prop's front (+Z of the model) projected on the table, unit length; zero when the
    /// front points straight up or down.
    pub front: DVec2,
    /// Number of vertices in the contact band.
    pub contact_vertices: usize,
}

/// The posed vertices of `model` at `time_s` of `animation` (the rest pose when `None`), in
/// the marker frame through `marker_from_prop`.
pub fn posed_points(
    model: &Model,
    animation: Option<usize>,
    time_s: f32,
    marker_from_prop: Mat4,
) -> Vec<Vec3> {
    let pose = match animation {
        Some(a) => anim::sample(model, a, time_s),
        None => anim::Pose::rest(model),
    };
    skin::pose_meshes(model, &pose)
        .iter()
        .flat_map(|p| p.positions.iter())
        .map(|p| marker_from_prop.transform_point3(*p))
        .filter(|p| p.is_finite())
        .collect()
}

/// The footprint of marker-frame points (the table is `z = 0`, up is -Z) placed by
/// `marker_from_prop` (for the front direction); `None` without a point.
pub fn footprint(points: &[Vec3], marker_from_prop: Mat4, band_m: f64) -> Option<Footprint> {
    let lowest = points
        .iter()
        .map(|p| f64::from(p.z))
        .fold(f64::NEG_INFINITY, f64::max);
    if !lowest.is_finite() {
        return None;
    }
    let contact: Vec<DVec2> = points
        .iter()
        .filter(|p| f64::from(p.z) >= lowest - band_m)
        .map(|p| DVec2::new(f64::from(p.x), f64::from(p.y)))
        .collect();
    let outline = convex_hull(&contact);
    let centre = centroid(&outline);
    let f = marker_from_prop.transform_vector3(Vec3::Z).as_dvec3();
    Some(Footprint {
        centre_m: centre,
        lowest_z_m: lowest,
        front: DVec2::new(f.x, f.y).try_normalize().unwrap_or(DVec2::ZERO),
        contact_vertices: contact.len(),
        outline_m: outline,
    })
}

/// `placement` with its translation chosen so that the key pose (`time_s` of `animation`)
/// rests on the table, its contact centred on the marker origin: its orientation and scale
/// are kept. `None` when the model has no vertex.
pub fn rest_on_table(
    model: &Model,
    animation: Option<usize>,
    time_s: f32,
    placement: &Placement,
) -> Option<(Placement, Footprint)> {
    let unplaced = Placement {
        translation_m: [0.0; 3],
        ..placement.clone()
    };
    let m = unplaced.marker_from_prop();
    let points = posed_points(model, animation, time_s, m);
    let fp = footprint(&points, m, CONTACT_BAND_M)?;
    let placed = Placement {
        translation_m: [
            -fp.centre_m.x as f32,
            -fp.centre_m.y as f32,
            -fp.lowest_z_m as f32,
        ],
        ..unplaced
    };
    let m = placed.marker_from_prop();
    let fp = footprint(
        &posed_points(model, animation, time_s, m),
        m,
        CONTACT_BAND_M,
    )?;
    Some((placed, fp))
}

/// Convex hull (Andrew's monotone chain), counter-clockwise, without collinear points; one or
/// two points for degenerate input.
pub fn convex_hull(points: &[DVec2]) -> Vec<DVec2> {
    let mut p: Vec<DVec2> = points.iter().copied().filter(|q| q.is_finite()).collect();
    p.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let cross = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    let mut hull: Vec<DVec2> = Vec::with_capacity(2 * p.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &DVec2>> = if pass == 0 {
            Box::new(p.iter())
        } else {
            Box::new(p.iter().rev())
        };
        for &q in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0
            {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
    }
    if hull.len() < 3 {
        // Every point on a line: its two ends.
        return vec![p[0], p[p.len() - 1]];
    }
    hull
}

/// Area centroid of a polygon; the mean of its points when the area vanishes.
pub fn centroid(poly: &[DVec2]) -> DVec2 {
    if poly.is_empty() {
        return DVec2::ZERO;
    }
    let (mut a2, mut c) = (0.0, DVec2::ZERO);
    for (i, p) in poly.iter().enumerate() {
        let q = poly[(i + 1) % poly.len()];
        let w = p.perp_dot(q);
        a2 += w;
        c += (*p + q) * w;
    }
    let mean = poly.iter().copied().sum::<DVec2>() / poly.len() as f64;
    if a2.abs() < 1e-18 {
        mean
    } else {
        c / (3.0 * a2)
    }
}

/// Area of a polygon (absolute).
pub fn area(poly: &[DVec2]) -> f64 {
    let mut a2 = 0.0;
    for (i, p) in poly.iter().enumerate() {
        a2 += p.perp_dot(poly[(i + 1) % poly.len()]);
    }
    (a2 * 0.5).abs()
}

/// The ids of `board`'s tags whose black square overlaps the footprint (the outline's
/// bounding box, in the marker frame): tags the key prop stands on.
pub fn covered_tags(footprint: &Footprint, board: &pa_track::Board) -> Vec<u32> {
    let o = &footprint.outline_m;
    let (lo, hi) = o.iter().fold(
        (
            glam::DVec2::splat(f64::INFINITY),
            glam::DVec2::splat(f64::NEG_INFINITY),
        ),
        |(l, h), p| (l.min(*p), h.max(*p)),
    );
    board
        .tags
        .iter()
        .filter(|t| {
            let r = t.size_m / 2.0;
            t.center_m.x + r > lo.x
                && t.center_m.x - r < hi.x
                && t.center_m.y + r > lo.y
                && t.center_m.y - r < hi.y
        })
        .map(|t| t.id)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hull_of_a_square_with_inner_and_collinear_points() {
        let mut pts = vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(2.0, 0.0),
            DVec2::new(2.0, 2.0),
            DVec2::new(0.0, 2.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(1.0, 1.0),
            DVec2::new(0.5, 1.5),
        ];
        pts.extend(pts.clone());
        let h = convex_hull(&pts);
        assert_eq!(h.len(), 4, "{h:?}");
        assert!((area(&h) - 4.0).abs() < 1e-12);
        assert!((centroid(&h) - DVec2::ONE).length() < 1e-12);
        // Counter-clockwise: positive signed area.
        let signed: f64 = (0..h.len())
            .map(|i| h[i].perp_dot(h[(i + 1) % h.len()]))
            .sum();
        assert!(signed > 0.0);
        // Degenerate input.
        assert_eq!(convex_hull(&[DVec2::X]), vec![DVec2::X]);
        let line = convex_hull(&[DVec2::ZERO, DVec2::X, DVec2::X * 3.0]);
        assert_eq!(line, vec![DVec2::ZERO, DVec2::X * 3.0]);
        assert!((centroid(&line) - DVec2::X * 1.5).length() < 1e-12);
    }

    /// A box 40 x 30 mm wide (model x, z), 50 mm tall (model y), base at model y = 0.01,
    /// offset (5, 0, -3) mm: upright with a yaw of 90 degrees and scale 2, its contact is the
    /// rotated 80 x 60 mm rectangle; `rest_on_table`'s translation puts it on the table,
    /// centred on the origin.
    #[test]
    fn a_box_rests_on_the_table_centred() {
        let (lo, hi) = (
            Vec3::new(-0.015, 0.01, -0.018),
            Vec3::new(0.025, 0.06, 0.012),
        );
        let corners: Vec<Vec3> = (0..8)
            .map(|i| {
                Vec3::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                )
            })
            .collect();
        let placement = Placement {
            yaw_deg: 90.0,
            scale: 2.0,
            ..Placement::default()
        };
        let m = placement.marker_from_prop();
        let pts: Vec<Vec3> = corners.iter().map(|p| m.transform_point3(*p)).collect();
        let fp = footprint(&pts, m, CONTACT_BAND_M).expect("footprint");
        assert_eq!(fp.contact_vertices, 4);
        // Lowest = model y = 0.01 (scaled 0.02) at marker z = -0.02.
        assert!((fp.lowest_z_m + 0.02).abs() < 1e-6, "{}", fp.lowest_z_m);
        assert!((area(&fp.outline_m) - 0.08 * 0.06).abs() < 1e-8);
        // Yaw 90 about up: model +Z (front) -> model +X before upright -> marker +X.
        assert!((fp.front - DVec2::X).length() < 1e-6, "{}", fp.front);
        // The box's centre (5, _, -3) mm, scaled, yawed (x, z) -> (z, -x), upright (x, z) ->
        // (x, y) on the marker: (2 * -3, 2 * -5) mm.
        assert!(
            (fp.centre_m - DVec2::new(-0.006, -0.010)).length() < 1e-6,
            "{}",
            fp.centre_m
        );

        // `rest_on_table` on a model made of that box (through the same code as a model's).
        let model = box_model(lo, hi);
        let (placed, fp) = rest_on_table(&model, None, 0.0, &placement).expect("placed");
        assert!(fp.lowest_z_m.abs() < 1e-6, "{}", fp.lowest_z_m);
        assert!(fp.centre_m.length() < 1e-6, "{}", fp.centre_m);
        let t = placed.translation_m;
        assert!(
            (t[0] - 0.006).abs() < 1e-6 && (t[1] - 0.010).abs() < 1e-6,
            "{t:?}"
        );
        assert!((t[2] - 0.02).abs() < 1e-6, "{t:?}");
        assert_eq!(
            (placed.yaw_deg, placed.scale, placed.upright),
            (90.0, 2.0, true)
        );
        // The contact, 60 mm along x and 80 mm along y (yawed), on a 3x3 board of 45 mm tags
        // 56.25 mm apart reaches the middle column's top and bottom tags (their inner edges at
        // +-33.75 mm), not the side columns.
        let board = pa_track::Board::grid(pa_track::TagFamily::Tag36h11, 3, 3, 0.045, 0.01125, 0)
            .expect("grid");
        assert_eq!(covered_tags(&fp, &board), vec![1, 4, 7]);
    }

    /// A model of one box (12 triangles), through glTF JSON.
    fn box_model(lo: Vec3, hi: Vec3) -> Model {
        use base64::Engine as _;
        let mut bin = Vec::new();
        for i in 0..8 {
            let p = Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            );
            for c in p.to_array() {
                bin.extend(c.to_le_bytes());
            }
        }
        let idx: [u16; 36] = [
            0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4,
            6, 1, 3, 5, 3, 7, 5,
        ];
        for i in idx {
            bin.extend(i.to_le_bytes());
        }
        let uri = format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&bin)
        );
        let doc = serde_json::json!({
            "asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
            "buffers": [{"byteLength": bin.len(), "uri": uri}],
            "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 96},
                            {"buffer": 0, "byteOffset": 96, "byteLength": 72}],
            "accessors": [
                {"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
                 "min": lo.to_array(), "max": hi.to_array()},
                {"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"}]
        });
        let bytes = serde_json::to_vec(&doc).expect("json");
        Model::from_slice(&bytes, "box.gltf", None, &Default::default()).expect("box model")
    }
}
