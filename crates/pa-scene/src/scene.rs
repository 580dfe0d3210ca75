//! The synthetic set: the built-in prop standing on an AprilTag board on a textured table, lit
//! by a directional light plus ambient (Lambertian), seen by a moving handheld-like camera with
//! known intrinsics. For every camera frame it renders:
//!
//! - the **input**: the physical key prop (the model at its key pose) on the board;
//! - the **ground truth**: the same view with the prop at the in-between pose, as if that pose
//!   had been printed and shot (what the paper's authors wanted and never had);
//! - the **clean plate** (once): the set without the prop, from a reference view.
//!
//! [`SceneSpec::set`] adds what real sets have (soft cast and contact shadows, the prop across
//! the sheet's edge or on a tag, a fill light; [`crate::variant`]), and [`Background::Cloth`] a
//! woven table; by default the set is exactly the original one.
//!
//! World space is the marker (board) frame of `pa-track`: origin at the board centre, +X right,
//! +Y down the printed page, +Z into the table, metres. The prop stands at the origin with
//! `marker_from_prop` (prop +Y up -> marker -Z, prop front +Z -> marker +Y).

use glam::{DVec2, Mat3, Mat4, Vec3};
use pa_camera::{camera_from_world_look_at, Intrinsics};
use pa_model::{anim, Model};
use pa_pipeline::GpuTwin;
use pa_render::{
    CpuCamera, CpuMesh, CpuTexture, DirectionalLight, Draw, GpuMesh, GpuTexture, Lighting,
    RenderError, RenderedFrame, Renderer,
};
use pa_track::board::BoardTag;
use pa_track::{Board, GrayImage, ImageTarget, TagFamily, TrackTarget};

use crate::hide::TruthSheet;
use crate::prop::{prop_model, value_noise, PropSpec};
use crate::shadow::PlaneShadows;
use crate::variant::{fill_light, shadow_lights, PlaneLighting, SetOptions, CONTACT};
use crate::SceneError;

/// Table surface texture.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Background {
    /// Wood grain with knots: a textured background where boundary-average fills fail.
    Wood,
    /// A nearly uniform grey cloth: the paper's "solid colours" case.
    Plain,
    /// A woven cloth: a plain weave of 4.7 mm threads with coloured bands (a tablecloth),
    /// structure the fill must continue across the hole.
    Cloth,
}

/// How the camera moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CameraPath {
    /// A slow arc with handheld jitter.
    Handheld,
    /// A tripod: the same view every frame.
    Static,
}

/// What to generate.
#[derive(Debug, Clone)]
pub struct SceneSpec {
    pub seed: u64,
    pub width: u32,
    pub height: u32,
    pub fov_y_deg: f64,
    /// Camera frames to generate.
    pub frames: u32,
    /// Animation frames per second (camera frame i shows animation frame i).
    pub fps: f32,
    /// Animation frames that exist as physical key props (at least one).
    pub key_frames: Vec<u32>,
    pub background: Background,
    pub camera_path: CameraPath,
    pub prop: PropSpec,
    /// Samples per pixel side of the camera and ground-truth images (`s x s` samples box-
    /// filtered in linear light, as a sensor integrates over its pixel area; 1 = aliased).
    pub supersample: u32,
    /// What a real set adds (shadows, placement, fill light); all off by default.
    pub set: SetOptions,
    /// What the ground truth shows where the board's sheet is (the board by default; the
    /// truth of the pipeline's hiding of it, [`crate::hide`]).
    pub truth_sheet: TruthSheet,
    /// Copies of the prop on the set (1..=[`PROP_SPOTS`]`.len()`), each at its own spot
    /// ([`PROP_SPOTS`], the first at the placement); the input, the ground truth and the
    /// prop masks show all of them, the clean plate none.
    pub props: u32,
}

impl Default for SceneSpec {
    fn default() -> Self {
        Self {
            seed: 1,
            width: 960,
            height: 540,
            fov_y_deg: 45.0,
            frames: 49,
            fps: 24.0,
            key_frames: vec![0],
            background: Background::Wood,
            camera_path: CameraPath::Handheld,
            prop: PropSpec::default(),
            supersample: 2,
            set: SetOptions::default(),
            truth_sheet: TruthSheet::Board,
            props: 1,
        }
    }
}

/// Where the copies of the prop stand (marker plane, metres, added to the placement's
/// offset): the first at the board's centre, two beside the board's left and right columns
/// of tags, then three rows behind the board (5, 6 and 2 props, 0.1 m apart: the pedestals,
/// 0.048 m in radius, do not touch). None stands in front of the board or on a tag, so the
/// tags stay in view; on the default handheld path every spot's bounding box (0.1 m wide,
/// 0.2 m tall) stays at least 17 px inside a 1280x720 frame in every frame.
pub const PROP_SPOTS: [[f32; 2]; 16] = [
    [0.0, 0.0],
    [-0.19, 0.0],
    [0.17, 0.0],
    [-0.2, -0.17],
    [-0.1, -0.17],
    [0.0, -0.17],
    [0.1, -0.17],
    [0.2, -0.17],
    [-0.25, -0.27],
    [-0.15, -0.27],
    [-0.05, -0.27],
    [0.05, -0.27],
    [0.15, -0.27],
    [0.25, -0.27],
    [-0.05, -0.37],
    [0.05, -0.37],
];

/// The board of the set: eight 45 mm tag36h11 tags (ids 0..8) in a ring around the prop.
pub fn set_board() -> Board {
    let pitch = 0.085;
    let mut tags = Vec::new();
    let mut id = 0;
    for r in -1..=1 {
        for c in -1..=1 {
            if r == 0 && c == 0 {
                continue;
            }
            tags.push(BoardTag {
                id,
                center_m: DVec2::new(c as f64 * pitch, r as f64 * pitch),
                size_m: 0.045,
                rotation_rad: 0.0,
            });
            id += 1;
        }
    }
    Board {
        family: TagFamily::Tag36h11,
        tags,
    }
}

/// Side of the printed board sheet, metres.
pub const BOARD_SHEET_M: f32 = 0.26;

/// Side of the picture marker's picture, pixels ([`marker_picture`]).
pub const MARKER_PICTURE_PX: u32 = 512;

/// Printed side of the picture marker, metres: a small poster or rug (the picture must fill
/// enough of the frame at the set's grazing 56-62 degree view for its features to be found).
pub const MARKER_PICTURE_M: f32 = 0.4;

/// The picture printed on the sheet of a picture-marker set ([`SetOptions::picture_marker`]):
/// the image-target tests' procedural picture (blobs, edges and texture at several scales),
/// square, printed [`MARKER_PICTURE_M`] wide, centred where the board would be. The tracker gets the same
/// pixels the sheet shows: a user's own file.
pub fn marker_picture() -> GrayImage {
    pa_track::image_target::synth::natural_picture(MARKER_PICTURE_PX, MARKER_PICTURE_PX, 11)
}

/// [`marker_picture`] printed on the sheet's paper: grey levels scaled to the paper's white
/// (245) as ink on paper.
fn marker_picture_texture() -> CpuTexture {
    let pic = marker_picture();
    let rgba8 = pic
        .data
        .iter()
        .flat_map(|&v| {
            let g = (v as u32 * 245 / 255) as u8;
            [g, g, g, 255]
        })
        .collect();
    CpuTexture {
        width: pic.width,
        height: pic.height,
        rgba8,
    }
}

/// The prop's placement on the marker: prop +Y (up) -> marker -Z, prop +Z (front) -> marker +Y.
pub fn marker_from_prop() -> Mat4 {
    Mat4::from_mat3(Mat3::from_cols(Vec3::X, Vec3::NEG_Z, Vec3::Y))
}

/// The key light and ambient of the set (world = marker frame; -Z is up).
pub fn set_lighting() -> Lighting {
    Lighting {
        ambient_rgb: [0.38, 0.38, 0.4],
        directional: Some(DirectionalLight {
            toward_light_world: Vec3::new(-0.5, 0.6, -1.0),
            radiance_rgb: [0.72, 0.7, 0.66],
        }),
    }
}

/// Deterministic pseudo-random numbers (SplitMix64).
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed ^ 0x9e37_79b9_7f4a_7c15)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// The table texture (sRGB RGBA8), `px` square, covering `TABLE_M` metres.
pub fn table_texture(background: Background, px: u32, seed: u32) -> CpuTexture {
    let mut rgba8 = Vec::with_capacity((px * px * 4) as usize);
    for y in 0..px {
        for x in 0..px {
            let u = x as f32 / px as f32;
            let v = y as f32 / px as f32;
            let c = match background {
                Background::Wood => {
                    let warp = value_noise(u * 6.0, v * 1.5, seed) * 3.0;
                    let rings = (v * 90.0 + warp * 6.0 + value_noise(u * 30.0, v * 4.0, seed + 1))
                        .sin()
                        * 0.5
                        + 0.5;
                    let fine = value_noise(u * 400.0, v * 20.0, seed + 2);
                    let t = 0.55 + 0.3 * rings + 0.15 * fine;
                    Vec3::new(0.55, 0.36, 0.2) * t
                }
                Background::Plain => {
                    Vec3::splat(0.55 + 0.03 * value_noise(u * 50.0, v * 50.0, seed))
                }
                Background::Cloth => cloth(x, y, u, v, seed),
            };
            let to8 = |x: f32| (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
            rgba8.extend_from_slice(&[to8(c.x), to8(c.y), to8(c.z), 255]);
        }
    }
    CpuTexture {
        width: px,
        height: px,
        rgba8,
    }
}

/// One texel of the woven cloth: a plain weave (warp over weft on alternate cells) of threads
/// 6 texels wide, each thread rounded across its width, cream with red warp bands and blue
/// weft bands every 12 threads.
fn cloth(x: u32, y: u32, u: f32, v: f32, seed: u32) -> Vec3 {
    const PITCH: u32 = 6;
    let (i, j) = (x / PITCH, y / PITCH);
    let (fx, fy) = (
        ((x % PITCH) as f32 + 0.5) / PITCH as f32,
        ((y % PITCH) as f32 + 0.5) / PITCH as f32,
    );
    let cream = Vec3::new(0.78, 0.72, 0.6);
    let thread = |k: u32, band: Vec3, s: u32| {
        let c = if k % 12 < 3 { band } else { cream };
        c * (0.9 + 0.2 * value_noise(k as f32 * 0.7, 0.5, seed + s))
    };
    let warp_on_top = (i + j) % 2 == 0;
    let (c, across) = if warp_on_top {
        (thread(i, Vec3::new(0.62, 0.16, 0.12), 3), fx)
    } else {
        (thread(j, Vec3::new(0.16, 0.22, 0.5), 4), fy)
    };
    let round = (std::f32::consts::PI * across).sin().sqrt();
    let fuzz = value_noise(u * 700.0, v * 700.0, seed + 5);
    c * (0.62 + 0.3 * round + 0.08 * fuzz)
}

/// Side of the table quad, metres.
pub const TABLE_M: f32 = 1.6;

/// The printed board sheet: white paper with the board's tags, `px` square over
/// [`BOARD_SHEET_M`].
pub fn board_texture(board: &Board, px: u32) -> Result<CpuTexture, SceneError> {
    let mut cells = Vec::new();
    for t in &board.tags {
        let c = pa_track::marker_cells(board.family, t.id)?;
        cells.push(c);
    }
    let layout = pa_track::family_layout(board.family)?;
    let scale = layout.total_cells as f64 / layout.border_cells as f64;
    let mut rgba8 = Vec::with_capacity((px * px * 4) as usize);
    for y in 0..px {
        for x in 0..px {
            let mx = ((x as f64 + 0.5) / px as f64 - 0.5) * BOARD_SHEET_M as f64;
            let my = ((y as f64 + 0.5) / px as f64 - 0.5) * BOARD_SHEET_M as f64;
            let mut v = 245u8;
            for (t, c) in board.tags.iter().zip(&cells) {
                let half = t.size_m * scale * 0.5;
                let (dx, dy) = (mx - t.center_m.x + half, my - t.center_m.y + half);
                if dx >= 0.0 && dy >= 0.0 && dx < 2.0 * half && dy < 2.0 * half {
                    let n = c.width as f64;
                    let cx = ((dx / (2.0 * half)) * n) as usize;
                    let cy = ((dy / (2.0 * half)) * n) as usize;
                    v = if c.data[cy * c.width as usize + cx] > 127 {
                        245
                    } else {
                        18
                    };
                }
            }
            rgba8.extend_from_slice(&[v, v, v, 255]);
        }
    }
    Ok(CpuTexture {
        width: px,
        height: px,
        rgba8,
    })
}

/// A quad in the plane z, normal up (-Z). `lit`: wound so that the camera above sees its
/// front face and the renderer lights it with the directional light; otherwise the original
/// winding, whose front face points into the table, so that the renderer flips the normal
/// and the plane receives the ambient light only (the default set, kept as it was).
fn quad(half_w: f32, half_h: f32, z: f32, lit: bool) -> CpuMesh {
    let indices = if lit {
        vec![0, 2, 1, 0, 3, 2]
    } else {
        vec![0, 1, 2, 0, 2, 3]
    };
    CpuMesh {
        positions: vec![
            [-half_w, -half_h, z],
            [half_w, -half_h, z],
            [half_w, half_h, z],
            [-half_w, half_h, z],
        ],
        normals: vec![[0.0, 0.0, -1.0]; 4],
        uvs: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
        indices,
        ..Default::default()
    }
}

/// One generated camera frame.
pub struct SceneFrame {
    pub index: u32,
    /// Animation time shown by this frame (seconds).
    pub time_s: f32,
    /// The key pose physically present (index into `SceneSpec::key_frames`).
    pub key: usize,
    /// True camera pose.
    pub camera_from_marker: Mat4,
    /// The camera image: the key prop on the set.
    pub input: RenderedFrame,
    /// The in-between pose as if printed and shot.
    pub ground_truth: RenderedFrame,
}

/// The generator, holding uploaded set pieces and the prop.
pub struct Scene {
    pub spec: SceneSpec,
    pub model: Model,
    pub intrinsics: Intrinsics,
    pub board: Board,
    twin: GpuTwin,
    table: (GpuMesh, GpuTexture),
    sheet: (GpuMesh, GpuTexture),
    path: Vec<Mat4>,
    /// The cover of [`TruthSheet::Cover`], uploaded.
    truth_cover: Option<CoverSheet>,
}

/// Clip planes of the set's cameras.
pub const NEAR_M: f32 = 0.05;
pub const FAR_M: f32 = 5.0;

impl Scene {
    /// Builds the set and uploads it to `renderer`.
    pub fn new(spec: SceneSpec, renderer: &mut Renderer) -> Result<Self, SceneError> {
        if spec.key_frames.is_empty() {
            return Err(SceneError::NoKeyPose);
        }
        if !(1..=PROP_SPOTS.len()).contains(&(spec.props as usize)) {
            return Err(SceneError::PropCount {
                props: spec.props,
                max: PROP_SPOTS.len(),
            });
        }
        let model = prop_model(&spec.prop)?;
        let intrinsics =
            Intrinsics::from_fov_y(spec.fov_y_deg.to_radians(), spec.width, spec.height)?;
        // A picture marker has no tags: its board is empty.
        let board = if spec.set.picture_marker {
            Board {
                family: TagFamily::Tag36h11,
                tags: Vec::new(),
            }
        } else {
            set_board()
        };
        let twin = GpuTwin::upload(renderer, &model)?;
        // A set with shadows or a second light lights its table (a shadow needs a light to
        // take away).
        let lit = spec.set.shadows || spec.set.fill_light;
        let table_mesh = renderer.upload_mesh(&quad(TABLE_M * 0.5, TABLE_M * 0.5, 0.0005, lit))?;
        let table_tex =
            renderer.upload_texture(&table_texture(spec.background, 2048, spec.seed as u32))?;
        let half = 0.5 * spec.set.sheet_side_m();
        let sheet_mesh = renderer.upload_mesh(&quad(half, half, 0.0, lit))?;
        let sheet_tex = if spec.set.picture_marker {
            renderer.upload_texture(&marker_picture_texture())?
        } else {
            renderer.upload_texture(&board_texture(&board, 2080)?)?
        };
        let path = camera_path(&spec);
        let mut scene = Self {
            spec,
            model,
            intrinsics,
            board,
            twin,
            table: (table_mesh, table_tex),
            sheet: (sheet_mesh, sheet_tex),
            path,
            truth_cover: None,
        };
        if let TruthSheet::Cover {
            picture,
            min_m,
            max_m,
        } = &scene.spec.truth_sheet
        {
            scene.truth_cover = Some(scene.cover_sheet(renderer, picture, *min_m, *max_m)?);
        }
        Ok(scene)
    }

    /// What the tracker follows on this set: the board of tags, or for a picture-marker set
    /// ([`SetOptions::picture_marker`]) the printed picture, [`MARKER_PICTURE_M`] wide (prepared
    /// here: keypoints at several scales, tens of milliseconds).
    pub fn track_target(&self) -> Result<TrackTarget, SceneError> {
        if self.spec.set.picture_marker {
            let target = ImageTarget::new(&marker_picture(), f64::from(MARKER_PICTURE_M))?;
            Ok(TrackTarget::Image(Box::new(target)))
        } else {
            Ok(TrackTarget::Board(self.board.clone()))
        }
    }

    /// The animation time of camera frame `i`.
    pub fn time_s(&self, i: u32) -> f32 {
        i as f32 / self.spec.fps
    }

    /// The key pose present for animation frame `i`: the nearest key frame.
    pub fn key_for(&self, i: u32) -> usize {
        self.spec
            .key_frames
            .iter()
            .enumerate()
            .min_by_key(|(_, &k)| (k as i64 - i as i64).abs())
            .map(|(n, _)| n)
            .unwrap_or(0)
    }

    /// The prop's placement on the marker: [`marker_from_prop`] moved to
    /// [`crate::Placement::offset_m`].
    pub fn marker_from_prop(&self) -> Mat4 {
        let offset = self.spec.set.placement.offset_m();
        if offset == glam::Vec2::ZERO {
            marker_from_prop()
        } else {
            Mat4::from_translation(offset.extend(0.0)) * marker_from_prop()
        }
    }

    /// Every copy's placement ([`SceneSpec::props`] of them): [`Scene::marker_from_prop`]
    /// moved to its spot of [`PROP_SPOTS`] (the first is [`Scene::marker_from_prop`] itself).
    pub fn marker_from_props(&self) -> Vec<Mat4> {
        let first = self.marker_from_prop();
        PROP_SPOTS
            .iter()
            .take(self.spec.props as usize)
            .map(|&[x, y]| {
                if x == 0.0 && y == 0.0 {
                    first
                } else {
                    Mat4::from_translation(Vec3::new(x, y, 0.0)) * first
                }
            })
            .collect()
    }

    /// The posed props' triangles in the marker frame at animation time `time_s` (the shadow
    /// casters; every copy).
    pub fn prop_triangles(&self, time_s: f32) -> Vec<[Vec3; 3]> {
        let pose = anim::sample(&self.model, 0, time_s);
        let mut tris = Vec::new();
        let posed_meshes = pa_model::skin::pose_meshes(&self.model, &pose);
        for (marker_from_prop, posed) in self
            .marker_from_props()
            .into_iter()
            .flat_map(|m| posed_meshes.iter().map(move |p| (m, p)))
        {
            let prim = &self.model.meshes[posed.mesh].primitives[posed.primitive];
            let p: Vec<Vec3> = posed
                .positions
                .iter()
                .map(|&v| marker_from_prop.transform_point3(v))
                .collect();
            let sequential: Vec<u32>;
            let indices = if prim.indices.is_empty() {
                sequential = (0..p.len() as u32).collect();
                &sequential
            } else {
                &prim.indices
            };
            for t in indices.chunks_exact(3) {
                let at = |k: u32| p.get(k as usize).copied();
                if let (Some(a), Some(b), Some(c)) = (at(t[0]), at(t[1]), at(t[2])) {
                    tris.push([a, b, c]);
                }
            }
        }
        tris
    }

    /// True `camera_from_marker` of frame `i`.
    pub fn camera_from_marker(&self, i: u32) -> Mat4 {
        self.path[(i as usize).min(self.path.len().saturating_sub(1))]
    }

    fn render(
        &self,
        renderer: &mut Renderer,
        camera_from_marker: Mat4,
        prop_time_s: Option<f32>,
    ) -> Result<RenderedFrame, RenderError> {
        self.render_with_sheet(renderer, camera_from_marker, prop_time_s, SheetLook::Board)
    }

    /// The set with its board sheet as `sheet` says (the truth of the pipeline's hiding of
    /// the marker), the prop at `prop_time_s` if any, from `camera_from_marker`.
    pub fn render_with_sheet(
        &self,
        renderer: &mut Renderer,
        camera_from_marker: Mat4,
        prop_time_s: Option<f32>,
        sheet_look: SheetLook<'_>,
    ) -> Result<RenderedFrame, RenderError> {
        let s = self.spec.supersample.clamp(1, 4);
        let (w, h) = (self.spec.width * s, self.spec.height * s);
        let camera = CpuCamera {
            intrinsics: self.intrinsics.scaled_to(w, h),
            camera_from_world: camera_from_marker,
            near_m: NEAR_M,
            far_m: FAR_M,
        };
        let mut table = Draw::new(&self.table.0, Mat4::IDENTITY);
        table.texture = Some(&self.table.1);
        let mut draws = vec![table];
        let sheet_draw = match sheet_look {
            SheetLook::Board => Some((&self.sheet.0, &self.sheet.1, Mat4::IDENTITY)),
            SheetLook::Bare => None,
            SheetLook::Cover(c) => Some((&c.mesh, &c.texture, c.marker_from_sheet)),
        };
        if let Some((mesh, texture, m)) = sheet_draw {
            let mut sheet = Draw::new(mesh, m);
            sheet.texture = Some(texture);
            draws.push(sheet);
        }
        let frames: Vec<_> = match prop_time_s {
            Some(t) => {
                let pose = anim::sample(&self.model, 0, t);
                self.marker_from_props()
                    .into_iter()
                    .map(|m| self.twin.frame(&self.model, &pose, m))
                    .collect()
            }
            None => Vec::new(),
        };
        for frame in &frames {
            draws.extend(self.twin.draws(frame));
        }
        let lighting = set_lighting();
        let mut full = renderer.render(
            &camera,
            Some(&lighting),
            &draws,
            [0.1, 0.1, 0.12, 1.0],
            w,
            h,
        )?;
        let set = self.spec.set;
        if set.shadows || set.fill_light {
            // The fill light's own pass (no ambient), added in linear light.
            let fill = set.fill_light.then(fill_light);
            let fill_frame = match &fill {
                Some(f) => Some(renderer.render(
                    &camera,
                    Some(&Lighting {
                        ambient_rgb: [0.0; 3],
                        directional: Some(*f),
                    }),
                    &draws,
                    [0.0, 0.0, 0.0, 1.0],
                    w,
                    h,
                )?),
                None => None,
            };
            let mut lights = Vec::new();
            if let Some(key) = &lighting.directional {
                lights.push(key);
            }
            lights.extend(fill.as_ref());
            let shadows = match (set.shadows, prop_time_s, lighting.directional) {
                (true, Some(t), Some(key)) => Some(PlaneShadows::compute(
                    &self.prop_triangles(t),
                    &shadow_lights(&key, fill.as_ref()),
                    Some(&CONTACT),
                )),
                _ => None,
            };
            crate::variant::relight(
                &mut full,
                fill_frame.as_ref(),
                &PlaneLighting::new(lighting.ambient_rgb, &lights),
                shadows.as_ref(),
                &camera.intrinsics,
                camera_from_marker,
            );
        }
        Ok(downsample(&full, s))
    }

    /// Renders camera frame `i`: input (key prop) and ground truth (in-between).
    pub fn frame(&self, renderer: &mut Renderer, i: u32) -> Result<SceneFrame, RenderError> {
        let key = self.key_for(i);
        let key_time = self.spec.key_frames[key] as f32 / self.spec.fps;
        let time_s = self.time_s(i);
        let camera_from_marker = self.camera_from_marker(i);
        let input = self.render(renderer, camera_from_marker, Some(key_time))?;
        let look = match (&self.spec.truth_sheet, &self.truth_cover) {
            (TruthSheet::Bare, _) => SheetLook::Bare,
            (TruthSheet::Cover { .. }, Some(c)) => SheetLook::Cover(c),
            _ => SheetLook::Board,
        };
        let ground_truth =
            self.render_with_sheet(renderer, camera_from_marker, Some(time_s), look)?;
        Ok(SceneFrame {
            index: i,
            time_s,
            key,
            camera_from_marker,
            input,
            ground_truth,
        })
    }

    /// The clean plate: the set without the prop, from the first frame's view. Returns the
    /// image and its `camera_from_marker`.
    pub fn clean_plate(
        &self,
        renderer: &mut Renderer,
    ) -> Result<(RenderedFrame, Mat4), RenderError> {
        let view = self.camera_from_marker(0);
        Ok((self.render(renderer, view, None)?, view))
    }

    /// Pixels covered by the props alone (every copy) at `prop_time_s`, seen from
    /// `camera_from_marker`.
    pub fn prop_mask(
        &self,
        renderer: &mut Renderer,
        camera_from_marker: Mat4,
        prop_time_s: f32,
    ) -> Result<Vec<bool>, RenderError> {
        let camera = CpuCamera {
            intrinsics: self.intrinsics,
            camera_from_world: camera_from_marker,
            near_m: NEAR_M,
            far_m: FAR_M,
        };
        let pose = anim::sample(&self.model, 0, prop_time_s);
        let frames: Vec<_> = self
            .marker_from_props()
            .into_iter()
            .map(|m| self.twin.frame(&self.model, &pose, m))
            .collect();
        let draws: Vec<Draw> = frames.iter().flat_map(|f| self.twin.draws(f)).collect();
        let r = renderer.render(
            &camera,
            None,
            &draws,
            [0.0; 4],
            self.spec.width,
            self.spec.height,
        )?;
        Ok(r.depth_m.iter().map(|d| d.is_finite()).collect())
    }

    /// The set with the prop at an arbitrary animation time from an arbitrary view (for
    /// tests and the degradation study).
    pub fn render_view(
        &self,
        renderer: &mut Renderer,
        camera_from_marker: Mat4,
        prop_time_s: Option<f32>,
    ) -> Result<RenderedFrame, RenderError> {
        self.render(renderer, camera_from_marker, prop_time_s)
    }
}

/// What lies on the table where the board's sheet is ([`Scene::render_with_sheet`]).
#[derive(Clone, Copy)]
pub enum SheetLook<'a> {
    /// The printed board (every other render of the set).
    Board,
    /// No sheet: the table.
    Bare,
    /// Another picture printed on the same paper ([`Scene::cover_sheet`]).
    Cover(&'a CoverSheet),
}

/// A picture printed on the board's paper, uploaded: a sheet over a rectangle of the marker
/// plane.
pub struct CoverSheet {
    mesh: GpuMesh,
    texture: GpuTexture,
    marker_from_sheet: Mat4,
}

impl Scene {
    /// `picture` printed on the sheet's paper (its white is the paper's, 245/255; each channel
    /// the picture's reflectance times the paper's, in linear light) over the rectangle
    /// `min_m`..`max_m` of the marker plane (+X along the picture's width, +Y down it), lying
    /// on the table like the board, lit like it.
    pub fn cover_sheet(
        &self,
        renderer: &mut Renderer,
        picture: &CpuTexture,
        min_m: glam::Vec2,
        max_m: glam::Vec2,
    ) -> Result<CoverSheet, RenderError> {
        let lit = self.spec.set.shadows || self.spec.set.fill_light;
        let half = (max_m - min_m) * 0.5;
        let centre = (min_m + max_m) * 0.5;
        let mesh = renderer.upload_mesh(&quad(half.x, half.y, 0.0, lit))?;
        let paper = srgb_to_linear(245.0 / 255.0);
        let rgba8 = picture
            .rgba8
            .chunks_exact(4)
            .flat_map(|p| {
                let c = |v: u8| {
                    (linear_to_srgb(srgb_to_linear(v as f32 / 255.0) * paper) * 255.0 + 0.5) as u8
                };
                [c(p[0]), c(p[1]), c(p[2]), 255]
            })
            .collect();
        let texture = renderer.upload_texture(&CpuTexture {
            width: picture.width,
            height: picture.height,
            rgba8,
        })?;
        Ok(CoverSheet {
            mesh,
            texture,
            marker_from_sheet: Mat4::from_translation(centre.extend(0.0)),
        })
    }
}

fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn linear_to_srgb(l: f32) -> f32 {
    let l = l.clamp(0.0, 1.0);
    if l <= 0.003_130_8 {
        12.92 * l
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    }
}

/// Box-filters `s x s` blocks of `frame` in linear light (depth: the nearest surface).
pub fn downsample(frame: &RenderedFrame, s: u32) -> RenderedFrame {
    if s <= 1 {
        return frame.clone();
    }
    let (w, h) = (frame.width / s, frame.height / s);
    let lut: [f32; 256] = std::array::from_fn(|v| {
        let c = v as f32 / 255.0;
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    });
    let encode = |l: f32| -> u8 {
        let l = l.clamp(0.0, 1.0);
        let c = if l <= 0.003_130_8 {
            12.92 * l
        } else {
            1.055 * l.powf(1.0 / 2.4) - 0.055
        };
        (c * 255.0 + 0.5) as u8
    };
    let n = (s * s) as f32;
    let fw = frame.width as usize;
    let mut rgba8 = Vec::with_capacity((w * h * 4) as usize);
    let mut depth_m = Vec::with_capacity((w * h) as usize);
    for y in 0..h as usize {
        for x in 0..w as usize {
            let mut sum = [0f32; 4];
            let mut depth = f32::INFINITY;
            for dy in 0..s as usize {
                for dx in 0..s as usize {
                    let i = (y * s as usize + dy) * fw + x * s as usize + dx;
                    for c in 0..3 {
                        sum[c] += lut[frame.rgba8[i * 4 + c] as usize];
                    }
                    sum[3] += frame.rgba8[i * 4 + 3] as f32;
                    depth = depth.min(frame.depth_m[i]);
                }
            }
            rgba8.extend_from_slice(&[
                encode(sum[0] / n),
                encode(sum[1] / n),
                encode(sum[2] / n),
                (sum[3] / n + 0.5) as u8,
            ]);
            depth_m.push(depth);
        }
    }
    RenderedFrame {
        width: w,
        height: h,
        rgba8,
        depth_m,
    }
}

/// How much higher the camera looks down with [`SetOptions::high_camera`], degrees.
pub const HIGH_CAMERA_RAISE_DEG: f32 = 24.0;

/// The camera path: an arc in front of the prop with handheld jitter (or a fixed view).
fn camera_path(spec: &SceneSpec) -> Vec<Mat4> {
    let mut rng = Rng::new(spec.seed);
    // Smooth jitter: a sum of a few random sinusoids per axis.
    let waves: Vec<(f32, f32, f32)> = (0..9)
        .map(|_| {
            (
                0.3 + rng.f32() * 1.7,
                rng.f32() * std::f32::consts::TAU,
                0.5 + rng.f32(),
            )
        })
        .collect();
    let target = Vec3::new(0.0, 0.0, -0.1);
    // The camera follows the prop (the default prop stands at the origin: nothing added).
    let offset = spec.set.placement.offset_m();
    let shift = |p: Vec3| {
        if offset == glam::Vec2::ZERO {
            p
        } else {
            p + offset.extend(0.0)
        }
    };
    (0..spec.frames.max(1))
        .map(|i| {
            let u = if spec.frames > 1 {
                i as f32 / (spec.frames - 1) as f32
            } else {
                0.0
            };
            let (azimuth_deg, mut elevation_deg, distance_m, jitter) = match spec.camera_path {
                CameraPath::Handheld => (-18.0 + 36.0 * u, 28.0 + 6.0 * u, 0.55 - 0.05 * u, 1.0),
                CameraPath::Static => (0.0, 30.0, 0.55, 0.0),
            };
            if spec.set.high_camera {
                elevation_deg += HIGH_CAMERA_RAISE_DEG;
            }
            let t = i as f32 / 24.0;
            let j = |k: usize| {
                let (f, p, a) = waves[k];
                a * (f * std::f32::consts::TAU * t + p).sin() * jitter
            };
            let az = (azimuth_deg + 1.5 * j(0)).to_radians();
            let el = (elevation_deg + 1.0 * j(1)).to_radians();
            let d = distance_m + 0.01 * j(2);
            // The prop faces +Y (marker); up is -Z.
            let eye = Vec3::new(
                d * el.cos() * az.sin(),
                d * el.cos() * az.cos(),
                -d * el.sin(),
            );
            let look = target + Vec3::new(0.004 * j(3), 0.004 * j(4), 0.004 * j(5));
            let up = Vec3::new(0.03 * j(6), 0.0, -1.0).normalize();
            camera_from_world_look_at(shift(eye), shift(look), up).unwrap_or(Mat4::IDENTITY)
        })
        .collect()
}
