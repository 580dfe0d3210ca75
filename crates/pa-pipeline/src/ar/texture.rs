//! The texture stage on either renderer: the key pose as the camera sees it (the diminish
//! mask, the visibility map, the light on the prop) and the live-textured twin. `texture_gpu`
//! draws with wgpu, `texture_cpu` with our rasteriser; both give the same [`Textured`].

use std::time::Instant;

use glam::{Mat4, Vec3};
use pa_model::anim;
use pa_model::skin::PosedPrimitive;
use pa_render::{CpuCamera, CpuTexture, Draw, LiveCamera, LiveDraw, LiveTexturing, Renderer};

use super::gpu_region;
use super::sun::{sun_on_primitives, SunPrimitive};
use super::{ms, ArError, ArPipeline, FrameView, StageTimings, Texturing};
use crate::composite::bounding_box;
use crate::cpu_twin::CpuTwin;
use crate::grazing::{grazing_rgb, GrazingSamples, GrazingTrack};
use crate::shading::{
    irradiance_samples, irradiance_samples_from, posed_parts, Irradiance, IrradianceSample,
    KeyDepth, KeyView,
};
use crate::twin::TwinFrame;

/// What the CPU path keeps between frames.
pub(super) struct CpuState {
    /// One per prop, in [`ArPipeline::props`] order.
    pub(super) twins: Vec<CpuTwin>,
    /// Key-pose depth (visibility map) and the animated twin.
    pub(super) renderer: pa_raster::CpuRenderer,
    /// The key pose's unlit colour (the colour gain of the paper's baseline).
    key_colour: pa_raster::CpuRenderer,
    /// Per twin primitive (in [`CpuTwin::live_meshes`] order over the props): the fraction of
    /// the sun each vertex receives, `[key, animated]` (see [`crate::sun_fit`]).
    sun_lit: Vec<Vec<[f32; 2]>>,
}

impl CpuState {
    pub(super) fn new(props: &[super::Prop]) -> Result<Self, ArError> {
        Ok(Self {
            twins: props
                .iter()
                .map(|p| CpuTwin::new(&p.model))
                .collect::<Result<_, _>>()?,
            renderer: pa_raster::CpuRenderer::new(),
            key_colour: pa_raster::CpuRenderer::new(),
            sun_lit: Vec::new(),
        })
    }
}

/// The texture stage's results, whichever renderer made them (full-frame buffers).
pub(super) struct Textured {
    /// Pixels covered by the key pose as the camera sees it.
    pub(super) key_mask: Vec<bool>,
    /// Bounding box of `key_mask` (inclusive), `None` when empty.
    pub(super) key_bbox: Option<Bbox>,
    pub(super) twin_rgba: Vec<u8>,
    pub(super) twin_mask: Vec<bool>,
    pub(super) twin_bbox: Option<Bbox>,
    pub(super) live_counts: (usize, usize),
    pub(super) live_codes: Vec<u8>,
}

/// An inclusive pixel box `(x0, y0, x1, y1)`.
pub(super) type Bbox = (usize, usize, usize, usize);

/// The full-frame mask of a CPU visibility buffer's surfaces, written into `mask` (any
/// buffer: made the frame's size, all false outside the surfaces), and its bounding box; work
/// proportional to the buffer's dirty rectangle, rows in parallel.
pub(super) fn mask_from_vis(v: &pa_raster::VisBuffer, mask: &mut Vec<bool>) -> Option<Bbox> {
    use rayon::prelude::*;
    let w = v.width as usize;
    mask.clear();
    mask.resize(w * v.height as usize, false);
    let r = v.dirty?;
    let (x0, x1, y0) = (r.x0 as usize, r.x1 as usize, r.y0 as usize);
    let rows = y0 * w..(r.y1 as usize + 1) * w;
    // Each row set without branches, then its first and last set column.
    mask[rows.clone()]
        .par_chunks_mut(w)
        .zip(v.inv_z[rows].par_chunks(w))
        .enumerate()
        .filter_map(|(k, (m, iz))| {
            let m = &mut m[x0..=x1];
            for (m, &iz) in m.iter_mut().zip(&iz[x0..=x1]) {
                *m = iz > 0.0;
            }
            let first = m.iter().position(|&c| c)?;
            let last = m.iter().rposition(|&c| c)?;
            Some((x0 + first, y0 + k, x0 + last, y0 + k))
        })
        .reduce_with(|a, b| (a.0.min(b.0), a.1.min(b.1), a.2.max(b.2), a.3.max(b.3)))
}

/// Sets `mask` where `covered` holds for the values of the given rows and returns the bounding
/// box of what it set. A row is `(y, x, range)`: frame row `y` from column `x`, `range` its
/// span in `mask`; `values(range)` gives the values over that span.
pub(super) fn mask_rows<'a, T: 'a>(
    rows: impl Iterator<Item = (usize, usize, std::ops::Range<usize>)>,
    mask: &mut [bool],
    values: impl Fn(std::ops::Range<usize>) -> &'a [T],
    covered: impl Fn(&T) -> bool,
) -> Option<Bbox> {
    let mut b: Option<Bbox> = None;
    for (y, x, row) in rows {
        let (mut first, mut last) = (usize::MAX, 0);
        for (k, (m, v)) in mask[row.clone()].iter_mut().zip(values(row)).enumerate() {
            if covered(v) {
                *m = true;
                first = first.min(k);
                last = k;
            }
        }
        if first != usize::MAX {
            let (x0, x1) = (x + first, x + last);
            b = Some(match b {
                None => (x0, y, x1, y),
                Some((bx0, by0, bx1, _)) => (bx0.min(x0), by0, bx1.max(x1), y),
            });
        }
    }
    b
}

/// Key-pose vertices sampled for the fallback's irradiance fit (at most about this many).
const IRRADIANCE_SAMPLES: usize = 3000;

/// With a visibility map: the smallest facing cosine of a key-pose normal for a live sample
/// (slightly back-facing interpolated normals at a silhouette are still seen).
const VISIBLE_MIN_FACING_COS: f32 = -0.3;
/// With a visibility map: a surface that now faces the camera more than twice as squarely as
/// in the key pose takes the lit fallback (measured on the generated scene with 2, 2.5, 4 and
/// off: 2 was best on frames 20-40 degrees from the key, and equal near it).
const MAX_STRETCH: f32 = 2.0;

/// Clip planes of the AR camera.
pub(super) const NEAR_M: f32 = 0.01;
pub(super) const FAR_M: f32 = 50.0;
impl ArPipeline {
    /// The texture stage on wgpu ([`RenderPath::Gpu`](super::RenderPath::Gpu)).
    pub(super) fn texture_gpu(
        &mut self,
        renderer: &mut Renderer,
        view: &FrameView<'_>,
        timings: &mut StageTimings,
    ) -> Result<Textured, ArError> {
        let FrameView {
            rgba8,
            width,
            height,
            camera_model,
            camera_from_marker,
            times,
        } = *view;
        let n = (width * height) as usize;
        // Texture memory: updated on the CPU (see memory.rs), counted in the texture stage.
        let memory_on = self.memory_active();
        let t = Instant::now();
        if memory_on {
            self.observe_on_cpu(
                rgba8,
                width,
                height,
                &camera_model,
                camera_from_marker,
                times,
            )?;
        }
        let memory_ms = ms(t);
        let t = Instant::now();
        let camera = CpuCamera {
            intrinsics: camera_model.intrinsics,
            camera_from_world: camera_from_marker,
            near_m: NEAR_M,
            far_m: FAR_M,
        };
        let props = &self.props;
        // Per prop: (in-between pose, key pose, in-between frame data, key-pose frame data).
        let frames: Vec<(anim::Pose, anim::Pose, TwinFrame, TwinFrame)> = props
            .iter()
            .map(|p| {
                let (anim_pose, key_pose) = p.poses(times);
                let a = p.twin.frame(&p.model, &anim_pose, p.marker_from_prop);
                let k = p.twin.frame(&p.model, &key_pose, p.marker_from_prop);
                (anim_pose, key_pose, a, k)
            })
            .collect();
        timings.animate_ms = ms(t);

        // Texture: the key pose as the camera sees it gives the diminish mask and the light on
        // the prop (with visibility: the visibility map, read back; without: a plain unlit
        // render, whose colours also give the baseline's colour gain); then the animated twin.
        let t = Instant::now();
        let live = matches!(self.settings.texturing, Texturing::Live { .. });
        // Live texturing: both poses posed on the CPU too, in the world (marker) frame: the
        // irradiance samples', the sun's, and the screen regions that the transfers to and
        // from the GPU are limited to (gpu_region).
        let (posed_keys, posed_anims): (Vec<Vec<PosedPrimitive>>, Vec<Vec<PosedPrimitive>>) =
            if live {
                props
                    .iter()
                    .zip(&frames)
                    .map(|(p, (anim_pose, key_pose, _, _))| {
                        (posed_in_world(p, key_pose), posed_in_world(p, anim_pose))
                    })
                    .unzip()
            } else {
                Default::default()
            };
        let region_of = |posed: &[Vec<PosedPrimitive>]| {
            gpu_region::screen_region(
                posed.iter().flatten().flat_map(|p| &p.positions),
                &camera_model,
                camera_from_marker,
                NEAR_M,
                width,
                height,
            )
        };
        let (key_region, twin_region) = (region_of(&posed_keys), region_of(&posed_anims));
        let key_draws: Vec<Draw<'_>> = props
            .iter()
            .zip(&frames)
            .flat_map(|(p, (_, _, _, k))| p.twin.draws(k))
            .collect();
        let (key_mask, key_bbox, gain) = match self.settings.texturing {
            Texturing::Live { visibility: true } => {
                let map = match self.visibility.as_mut() {
                    Some(v) if v.size() == (width, height) => {
                        renderer.update_visibility(v, &camera, &key_draws)?;
                        v
                    }
                    _ => self
                        .visibility
                        .insert(renderer.render_visibility(&camera, &key_draws, width, height)?),
                };
                let depth = renderer.read_visibility_region(map, key_region)?;
                self.gpu_key_depth.write(width, height, key_region, &depth);
                let (mask, bbox) = self.gpu_key_depth.mask_and_bbox();
                (mask, bbox, None)
            }
            _ => {
                let r = renderer.render(&camera, None, &key_draws, [0.0; 4], width, height)?;
                let mask: Vec<bool> = r.depth_m.iter().map(|d| d.is_finite()).collect();
                let gain = colour_gain(rgba8, &r.rgba8, &mask);
                let bbox = bounding_box(&mask, width as usize, height as usize);
                (mask, bbox, Some(gain))
            }
        };
        let (twin_rgba, twin_mask, twin_bbox, live_counts, live_codes) =
            match self.settings.texturing {
                Texturing::ModelTexture => {
                    let draws: Vec<Draw<'_>> = props
                        .iter()
                        .zip(&frames)
                        .flat_map(|(p, (_, _, a, _))| p.twin.draws(a))
                        .collect();
                    let r = renderer.render(&camera, None, &draws, [0.0; 4], width, height)?;
                    let mask: Vec<bool> = r.depth_m.iter().map(|d| d.is_finite()).collect();
                    let bbox = bounding_box(&mask, width as usize, height as usize);
                    (r.rgba8, mask, bbox, (0, 0), vec![0; n])
                }
                Texturing::Live { visibility } => {
                    // Every live sample lies where the key pose projects: only that part of the
                    // frame travels once the texture exists.
                    let frame_tex = match self.frame_texture.take() {
                        Some(t) if t.size() == (width, height) => {
                            let sample =
                                gpu_region::sample_region(key_region, &camera_model, width, height);
                            renderer.update_frame_region(&t, rgba8, width, height, sample)?;
                            t
                        }
                        _ => renderer.upload_frame(&CpuTexture {
                            width,
                            height,
                            rgba8: rgba8.to_vec(),
                        })?,
                    };
                    // The fallback's shading: the set's light measured on the visible key props
                    // (ours), or one colour gain (the baseline without visibility).
                    // The key frame as the light fits see it (ours: the key depth read back).
                    let key_view = KeyView {
                        camera: &camera_model,
                        camera_from_world: camera_from_marker,
                        frame_rgba8: rgba8,
                        key_depth: KeyDepth::Metres(self.gpu_key_depth.depth()),
                        width,
                        height,
                    };
                    let irradiance = if visibility {
                        key_light(props.iter().zip(&posed_keys), |(p, key), n| {
                            irradiance_samples(&p.model, key, Mat4::IDENTITY, &key_view, n)
                        })
                    } else {
                        (Irradiance::constant(gain.unwrap_or([1.0; 3])), Vec::new())
                    };
                    let (irradiance, samples) = irradiance;
                    let live_camera = LiveCamera::new(camera_model, camera_from_marker);
                    let look = self.settings.look;
                    // The sun (ours), on both poses posed above; its fractions keyed by (prop,
                    // node, primitive).
                    let mut sun_lit = Vec::new();
                    let mut sun_keys: Vec<(usize, usize, usize)> = Vec::new();
                    let sun = if visibility && look.relight && look.sun {
                        let posed = posed_keys.iter().zip(&posed_anims);
                        let mut prims = Vec::new();
                        for (pi, (p, (key, anim))) in props.iter().zip(posed).enumerate() {
                            for (k, a) in key.iter().zip(anim) {
                                sun_keys.push((pi, k.node, k.primitive));
                                prims.push(SunPrimitive {
                                    key_positions: &k.positions,
                                    key_normals: &k.normals,
                                    anim_positions: &a.positions,
                                    anim_normals: &a.normals,
                                    shadow: &p.shadow_meshes[k.mesh][k.primitive],
                                });
                            }
                        }
                        let known = self.sun_direction_from_shadows();
                        let track = &mut self.sun_track;
                        sun_on_primitives(&irradiance, &samples, known, track, &prims, &mut sun_lit)
                    } else {
                        None
                    };
                    let grazing = if visibility && look.relight && look.grazing {
                        let posed = props
                            .iter()
                            .zip(&posed_keys)
                            .map(|(p, key)| (&p.model, posed_parts(key)));
                        let track = &mut self.grazing_track;
                        let sun = sun.as_ref();
                        grazing_light(posed, &key_view, &irradiance, sun, &sun_lit, track)
                    } else {
                        [0.0; 3]
                    };
                    let vis = if visibility {
                        self.visibility.as_ref()
                    } else {
                        None
                    };
                    let mut draws: Vec<LiveDraw<'_>> = Vec::new();
                    let memory = memory_on.then_some(&self.memory.props);
                    for (pi, (p, (_, _, anim_frame, key_frame))) in
                        props.iter().zip(&frames).enumerate()
                    {
                        draws.extend(
                            p.twin
                                .draws(anim_frame)
                                .into_iter()
                                .zip(&p.twin.primitives)
                                .enumerate()
                                .map(|(k, (d, tp))| {
                                    let key_joints: &[Mat4] = if tp.mesh.is_skinned() {
                                        &key_frame.joint_matrices[tp.node]
                                    } else {
                                        &[]
                                    };
                                    let mut live = LiveTexturing::new(
                                        &frame_tex,
                                        live_camera,
                                        key_frame.world_from_node[tp.node],
                                    )
                                    .with_key_pose(key_joints, &key_frame.morph_weights[tp.node])
                                    .with_fallback_irradiance(irradiance.rows);
                                    if let Some(v) = vis {
                                        live = live.with_visibility(v);
                                        // The depth test decides occlusion, so grazing key-pose
                                        // normals may sample; surfaces turned to face the camera
                                        // take the lit fallback instead of a smeared sample.
                                        live.min_facing_cos = VISIBLE_MIN_FACING_COS;
                                        live.max_stretch = MAX_STRETCH;
                                        live.relight = look.relight;
                                        live.feather = look.feather;
                                        live.grazing_rgb = grazing;
                                    }
                                    if let Some(sun) = sun {
                                        let lit = sun_keys
                                            .iter()
                                            .position(|&key| key == (pi, tp.node, tp.primitive))
                                            .and_then(|i| sun_lit.get(i))
                                            .filter(|l| l.len() == d.mesh.vertex_count());
                                        if let Some(lit) = lit {
                                            live = live.with_sun(sun, lit);
                                        }
                                    }
                                    let mem = memory.and_then(|m| m.get(pi)?.attributes.get(k));
                                    if let Some(a) = mem {
                                        live = live.with_memory(a);
                                    }
                                    d.with_live(live)
                                }),
                        );
                    }
                    let r = renderer.render_live_region(
                        &camera,
                        None,
                        &draws,
                        [0.0; 4],
                        width,
                        height,
                        twin_region,
                    )?;
                    drop(draws);
                    self.frame_texture = Some(frame_tex);
                    let (rgba, mask, bbox, codes) = gpu_region::twin_from_region(&r);
                    (rgba, mask, bbox, r.counts(), codes)
                }
            };
        timings.texture_ms = ms(t) + memory_ms;
        Ok(Textured {
            key_mask,
            key_bbox,
            twin_rgba,
            twin_mask,
            twin_bbox,
            live_counts,
            live_codes,
        })
    }

    /// The texture stage on our own rasteriser
    /// ([`RenderPath::Cpu`](super::RenderPath::Cpu)): the same passes as
    /// [`ArPipeline::texture_gpu`], with the models posed on the CPU.
    pub(super) fn texture_cpu(
        &mut self,
        view: &FrameView<'_>,
        timings: &mut StageTimings,
    ) -> Result<Textured, ArError> {
        use rayon::prelude::*;
        let FrameView {
            rgba8,
            width,
            height,
            camera_model,
            camera_from_marker,
            times,
        } = *view;
        let n = (width * height) as usize;
        let t = Instant::now();
        let memory_on = self.memory_active();
        let known_sun = self.sun_direction_from_shadows();
        let props = &self.props;
        let cpu = match &mut self.cpu {
            Some(c) => c,
            None => self.cpu.insert(Box::new(CpuState::new(props)?)),
        };
        // Every prop posed at both times (props in parallel; each poses its two in parallel).
        cpu.twins
            .par_iter_mut()
            .zip(props.par_iter())
            .for_each(|(twin, p)| {
                let (anim_pose, key_pose) = p.poses(times);
                twin.pose(&p.model, &anim_pose, &key_pose, p.marker_from_prop);
            });
        timings.animate_ms = ms(t);

        let t = Instant::now();
        let camera = pa_raster::RasterCamera::new(&camera_model.intrinsics, NEAR_M, FAR_M);
        let frame = pa_raster::FrameSampler::new(width, height, rgba8)?;
        let mut params = pa_raster::LiveParams::new(pa_raster::FrameCamera::new(&camera_model));
        let twins = &cpu.twins;
        let key_vis = match self.settings.texturing {
            Texturing::Live { visibility: false } => {
                // The paper's baseline: the key poses' unlit colours give one colour gain.
                let key_meshes: Vec<_> = twins
                    .iter()
                    .zip(props)
                    .flat_map(|(tw, p)| tw.key_meshes(&p.model))
                    .collect();
                cpu.key_colour.render_twin(
                    &camera,
                    camera_from_marker,
                    &key_meshes,
                    &pa_raster::Shading::Albedo,
                );
                let mut mask = self.spare.take_mask();
                let bbox = mask_from_vis(cpu.key_colour.twin_depth(), &mut mask);
                let gain = colour_gain(rgba8, &cpu.key_colour.twin_image().rgba8, &mask);
                params.fallback_irradiance = Irradiance::constant(gain).rows;
                (mask, bbox)
            }
            _ => {
                let key_meshes: Vec<_> = twins
                    .iter()
                    .zip(props)
                    .flat_map(|(tw, p)| tw.key_depth_meshes(&p.model))
                    .collect();
                cpu.renderer
                    .render_key_depth(&camera, camera_from_marker, &key_meshes);
                let mut mask = self.spare.take_mask();
                let bbox = mask_from_vis(cpu.renderer.key_depth(), &mut mask);
                (mask, bbox)
            }
        };
        let (key_mask, key_bbox) = key_vis;
        if memory_on {
            let view = super::memory::MemoryView {
                rgba8,
                width,
                height,
                camera: &camera_model,
                camera_from_marker,
                key_pose_s: times.key_pose_s,
            };
            self.memory.observe(cpu, props, &view)?;
        }
        let mut meshes: Vec<_> = twins
            .iter()
            .zip(props)
            .flat_map(|(tw, p)| tw.live_meshes(&p.model))
            .collect();
        if memory_on {
            for (m, a) in meshes.iter_mut().zip(self.memory.attributes()) {
                m.memory = a;
            }
        }
        // The set's light (ours) is fitted on the key depth while the twin is rasterised:
        // neither waits for the other.
        let settings = self.settings;
        let light_on_key = matches!(settings.texturing, Texturing::Live { visibility: true });
        let live = matches!(settings.texturing, Texturing::Live { .. });
        let (sun_track, sun_lit) = (&mut self.sun_track, &mut cpu.sun_lit);
        let grazing_track = &mut self.grazing_track;
        let fitted = cpu.renderer.rasterise_twin_beside(
            &camera,
            camera_from_marker,
            &meshes,
            live,
            |key_depth| {
                sun_lit.clear();
                if !light_on_key {
                    return None;
                }
                let key_view = KeyView {
                    camera: &camera_model,
                    camera_from_world: camera_from_marker,
                    frame_rgba8: rgba8,
                    key_depth: KeyDepth::InverseMetres(&key_depth.inv_z),
                    width,
                    height,
                };
                let (light, samples) = key_light(twins.iter().zip(props), |(tw, p), n| {
                    // Posed in the marker frame already: the world is the model's.
                    irradiance_samples_from(&p.model, tw.key_parts(), Mat4::IDENTITY, &key_view, n)
                });
                let sun = if settings.look.relight && settings.look.sun {
                    let prims: Vec<SunPrimitive<'_>> = twins
                        .iter()
                        .zip(props)
                        .flat_map(|(tw, p)| {
                            tw.primitives.iter().zip(tw.key.iter().zip(&tw.anim)).map(
                                |(tp, (k, a))| SunPrimitive {
                                    key_positions: &k.positions_world,
                                    key_normals: &k.normals_world,
                                    anim_positions: &a.positions_world,
                                    anim_normals: &a.normals_world,
                                    shadow: &p.shadow_meshes[tp.mesh][tp.primitive],
                                },
                            )
                        })
                        .collect();
                    sun_on_primitives(&light, &samples, known_sun, sun_track, &prims, sun_lit)
                } else {
                    None
                };
                let grazing = (settings.look.relight && settings.look.grazing).then(|| {
                    let posed = twins
                        .iter()
                        .zip(props)
                        .map(|(tw, p)| (&p.model, tw.key_parts()));
                    grazing_light(
                        posed,
                        &key_view,
                        &light,
                        sun.as_ref(),
                        sun_lit,
                        grazing_track,
                    )
                });
                Some((light, sun, grazing.unwrap_or([0.0; 3])))
            },
        );
        let shading = match settings.texturing {
            Texturing::ModelTexture => pa_raster::Shading::Albedo,
            Texturing::Live { .. } => {
                if let Some((light, sun, grazing)) = fitted {
                    params.grazing_rgb = grazing;
                    params.fallback_irradiance = light.rows;
                    params.visibility = true;
                    params.min_facing_cos = VISIBLE_MIN_FACING_COS;
                    params.max_stretch = MAX_STRETCH;
                    params.relight = settings.look.relight;
                    params.feather = settings.look.feather;
                    params.sun = sun;
                }
                pa_raster::Shading::Live { frame, params }
            }
        };
        for (m, lit) in meshes.iter_mut().zip(&cpu.sun_lit) {
            m.sun_lit = lit;
        }
        let image = cpu.renderer.shade_twin(&meshes, &shading);
        let live_counts = image.counts();
        let live_codes = self.spare.codes_copy(&image.codes);
        // Lent to the composite, given back after it (see render_frame).
        let twin_rgba = cpu.renderer.take_twin_rgba();
        let mut twin_mask = self.spare.take_mask();
        let twin_bbox = mask_from_vis(cpu.renderer.twin_depth(), &mut twin_mask);
        debug_assert_eq!(twin_rgba.len(), n * 4);
        timings.texture_ms = ms(t);
        Ok(Textured {
            key_mask,
            key_bbox,
            twin_rgba,
            twin_mask,
            twin_bbox,
            live_counts,
            live_codes,
        })
    }
}

/// The key props' grazing reflection (`crate::grazing`), smoothed over the take by `track`:
/// `posed` gives each prop's model and posed key-pose primitives (world frame), in the order
/// of `sun_lit`'s primitives (each vertex's fraction of the sun, `[key, in-between]`). None
/// without the sun: measured against the first-order light alone, a matte prop's rim passes
/// for a reflection (generated scene: rim gain up to 0.2, the first-order row 0.24-0.38 dB
/// worse).
fn grazing_light<'a, P>(
    posed: impl Iterator<Item = (&'a pa_model::Model, P)>,
    view: &KeyView<'_>,
    light: &Irradiance,
    sun: Option<&pa_raster::sun::SunLight>,
    sun_lit: &[Vec<[f32; 2]>],
    track: &mut GrazingTrack,
) -> [f32; 3]
where
    P: Iterator<Item = (usize, usize, &'a [Vec3], &'a [Vec3])> + Clone,
{
    let Some(sun) = sun else {
        return [0.0; 3];
    };
    let mean = light.rows.map(|r| r[0]);
    let mut samples = GrazingSamples::default();
    let mut base = 0;
    for (model, prims) in posed {
        let count = prims.clone().count();
        let at = |prim: usize, v: usize, n: Vec3| {
            let lit = sun_lit.get(base + prim).and_then(|l| l.get(v));
            sun.irradiance(n, lit.map_or(1.0, |l| l[0]))
        };
        samples.add(model, prims, Mat4::IDENTITY, view, mean, at);
        base += count;
    }
    grazing_rgb(track.update(samples.kappa()), mean)
}

/// The set's light on the visible key props, fitted over all of them: `samples_of(prop, n)`
/// gives at most about `n` irradiance samples of one prop, [`IRRADIANCE_SAMPLES`] shared
/// evenly between the props (both render paths).
fn key_light<P>(
    props: impl ExactSizeIterator<Item = P>,
    mut samples_of: impl FnMut(P, usize) -> Vec<IrradianceSample>,
) -> (Irradiance, Vec<IrradianceSample>) {
    let per_prop = IRRADIANCE_SAMPLES / props.len();
    let samples: Vec<_> = props.flat_map(|p| samples_of(p, per_prop)).collect();
    (Irradiance::fit_or_mean(&samples), samples)
}

/// The prop's primitives posed as drawn ([`pa_model::skin::pose_drawn_meshes`]) and placed in
/// the world (marker) frame.
fn posed_in_world(prop: &super::Prop, pose: &anim::Pose) -> Vec<PosedPrimitive> {
    let mut posed = pa_model::skin::pose_drawn_meshes(&prop.model, pose);
    let world_from_model = prop.marker_from_prop;
    let rotation = glam::Mat3::from_mat4(world_from_model);
    for p in &mut posed {
        for v in &mut p.positions {
            *v = world_from_model.transform_point3(*v);
        }
        for n in &mut p.normals {
            *n = (rotation * *n).normalize_or_zero();
        }
    }
    posed
}

/// Per-channel gain that maps the model's texture (as rendered, unlit) to the live frame over
/// the key-pose silhouette: the colour match of the fallback. Clamped to [0.25, 4].
pub fn colour_gain(frame: &[u8], model_render: &[u8], mask: &[bool]) -> [f32; 3] {
    let mut sf = [0f64; 3];
    let mut sm = [0f64; 3];
    for (i, &m) in mask.iter().enumerate() {
        if m {
            for c in 0..3 {
                sf[c] += pa_raster::srgb::srgb_to_linear(frame[i * 4 + c]) as f64;
                sm[c] += pa_raster::srgb::srgb_to_linear(model_render[i * 4 + c]) as f64;
            }
        }
    }
    let mut g = [1f32; 3];
    for c in 0..3 {
        if sm[c] > 1e-6 {
            g[c] = ((sf[c] / sm[c]) as f32).clamp(0.25, 4.0);
        }
    }
    g
}
