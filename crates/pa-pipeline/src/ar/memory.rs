//! Texture memory ([`pa_raster::memory`]): the key props' appearance per key-pose vertex,
//! accumulated from every tracked frame in which the camera sees it, and read by both render
//! paths as the first fallback colour (remembered colour, then the model's lit texture).
//!
//! The memory belongs to the key props, not to a sequence: the physical key prop stands in
//! its key pose through the whole take, so [`ArPipeline::reset_tracker`] keeps it (a scan
//! pass before the take primes it, [`ArPipeline::remember`]). It is forgotten when what it
//! describes changes: a prop's placement on the marker, its key-pose time, the list of props
//! ([`ArPipeline::forget_memory`] by hand). Off by default ([`ArPipeline::set_texture_memory`]);
//! used only with [`Texturing::Live`] `{ visibility: true }`, whose visibility map says which
//! key-pose points a frame sees.
//!
//! Both paths update it on the CPU from the CPU path's posed key pose and its key-pose depth
//! (the GPU path poses and rasterises the key pose on the CPU for it: a few milliseconds).

use glam::Mat4;
use pa_raster::memory::{texels_per_metre, MemoryAlbedo, ObserveCounts, VertexMemory};

use super::texture::CpuState;
use super::{ArError, ArPipeline, FrameTimes, Texturing};
use crate::cpu_twin::CpuTwin;

/// The memory of one prop.
#[derive(Debug, Clone, Default)]
pub(super) struct PropMemory {
    /// What it was accumulated for: the key-pose time and the placement on the marker.
    key_pose_s: f32,
    marker_from_prop: Mat4,
    /// Per primitive of the prop's twin (both twins' order), one entry per drawn vertex.
    pub(super) primitives: Vec<VertexMemory>,
    /// The render paths' vertex attribute of each primitive
    /// ([`VertexMemory::premultiplied`]), refreshed after each update.
    pub(super) attributes: Vec<Vec<[f32; 4]>>,
    /// Texels of each primitive's albedo per metre of its key pose, per vertex
    /// ([`texels_per_metre`]): made on the first update, kept while the key pose is.
    texels_per_m: Vec<Vec<f32>>,
}

/// The texture memory of all props.
#[derive(Debug, Clone, Default)]
pub(super) struct TextureMemory {
    pub(super) enabled: bool,
    /// One per prop, in [`ArPipeline::props`] order (empty until the first update).
    pub(super) props: Vec<PropMemory>,
    /// Frames that updated the memory since it was last forgotten.
    pub(super) frames: u64,
}

impl TextureMemory {
    /// The memory of each prop, made or forgotten for the twins `twins` (vertex counts of
    /// their primitives), the props' placements and the key-pose time.
    fn prepare(&mut self, twins: &[CpuTwin], placements: &[Mat4], key_pose_s: f32) {
        if self.props.len() != twins.len() {
            self.props = vec![PropMemory::default(); twins.len()];
        }
        for ((m, tw), &placement) in self.props.iter_mut().zip(twins).zip(placements) {
            let counts: Vec<usize> = tw.key.iter().map(|k| k.positions_world.len()).collect();
            let same = m.key_pose_s == key_pose_s
                && m.marker_from_prop == placement
                && m.primitives.len() == counts.len()
                && m.primitives.iter().zip(&counts).all(|(p, &n)| p.len() == n);
            if !same {
                m.key_pose_s = key_pose_s;
                m.marker_from_prop = placement;
                m.primitives = counts.iter().map(|&n| VertexMemory::new(n)).collect();
                m.attributes = counts.iter().map(|&n| vec![[0.0; 4]; n]).collect();
                m.texels_per_m.clear();
            }
        }
    }

    /// The attribute slices of every primitive of every prop, in the order the CPU path
    /// lists its meshes (props, then primitives).
    pub(super) fn attributes(&self) -> impl Iterator<Item = &[[f32; 4]]> {
        self.props
            .iter()
            .flat_map(|p| p.attributes.iter().map(|a| a.as_slice()))
    }

    /// Samples the frame into every prop's memory from the CPU state's posed key pose and
    /// key-pose depth (both already made for this frame and camera).
    pub(super) fn observe(
        &mut self,
        cpu: &CpuState,
        props: &[super::Prop],
        view: &MemoryView<'_>,
    ) -> Result<ObserveCounts, ArError> {
        let placements: Vec<Mat4> = props.iter().map(|p| p.marker_from_prop).collect();
        self.prepare(&cpu.twins, &placements, view.key_pose_s);
        let frame = pa_raster::FrameSampler::new(view.width, view.height, view.rgba8)?;
        let mut params = pa_raster::LiveParams::new(pa_raster::FrameCamera::new(view.camera));
        params.visibility = true;
        let lut = pa_raster::srgb::decode_lut();
        let key_depth = cpu.renderer.key_depth();
        let mut counts = ObserveCounts::default();
        for ((m, tw), prop) in self.props.iter_mut().zip(&cpu.twins).zip(props) {
            let meshes = tw.live_meshes(&prop.model);
            if m.texels_per_m.len() != meshes.len() {
                m.texels_per_m = meshes
                    .iter()
                    .map(|lm| {
                        let me = &lm.mesh;
                        let size = me.albedo.map_or((1, 1), |t| t.size());
                        texels_per_metre(lm.key_positions_world, me.uvs, me.indices, size)
                    })
                    .collect();
            }
            for (((mem, attr), key), (lm, density)) in m
                .primitives
                .iter_mut()
                .zip(m.attributes.iter_mut())
                .zip(&tw.key)
                .zip(meshes.iter().zip(&m.texels_per_m))
            {
                let albedo = MemoryAlbedo {
                    texture: lm.mesh.albedo,
                    uvs: lm.mesh.uvs,
                    factor: lm.mesh.base_color_factor,
                    texels_per_m: density,
                };
                counts += mem.observe(
                    &params,
                    key_depth,
                    &frame,
                    view.camera_from_marker,
                    &key.positions_world,
                    &key.normals_world,
                    &albedo,
                    lut,
                );
                mem.premultiplied(attr);
            }
        }
        self.frames += 1;
        Ok(counts)
    }
}

/// What the texture memory holds at one moment ([`ArPipeline::memory_snapshot`]).
#[derive(Debug, Clone, Default)]
pub struct MemorySnapshot(TextureMemory);

/// One frame as the memory sees it.
pub(super) struct MemoryView<'a> {
    pub(super) rgba8: &'a [u8],
    pub(super) width: u32,
    pub(super) height: u32,
    /// At the frame's size, with distortion.
    pub(super) camera: &'a pa_camera::CameraModel,
    pub(super) camera_from_marker: Mat4,
    pub(super) key_pose_s: f32,
}

impl ArPipeline {
    /// Turns the texture memory on or off (off by default; see [`self::memory`](self)).
    /// Turning it off forgets it.
    pub fn set_texture_memory(&mut self, on: bool) {
        self.memory.enabled = on;
        if !on {
            self.forget_memory();
        }
    }

    /// Whether the texture memory is on.
    pub fn texture_memory(&self) -> bool {
        self.memory.enabled
    }

    /// Frames that updated the texture memory since it was last forgotten.
    pub fn memory_frames(&self) -> u64 {
        self.memory.frames
    }

    /// What the texture memory holds now: `run` keeps the scan's memory and gives it back
    /// before each still ([`ArPipeline::restore_memory`]), so that a frame depends only on its
    /// still, the shot and the scan (a resumed take is identical to an uninterrupted one).
    pub fn memory_snapshot(&self) -> MemorySnapshot {
        MemorySnapshot(self.memory.clone())
    }

    /// Puts back what [`ArPipeline::memory_snapshot`] took (on or off as it was then).
    pub fn restore_memory(&mut self, snapshot: &MemorySnapshot) {
        self.memory.clone_from(&snapshot.0);
    }

    /// Forgets what the texture memory holds (it stays on or off).
    pub fn forget_memory(&mut self) {
        self.memory.props.clear();
        self.memory.frames = 0;
    }

    /// Whether this frame updates the memory and reads it.
    pub(super) fn memory_active(&self) -> bool {
        self.memory.enabled && self.settings.texturing == (Texturing::Live { visibility: true })
    }

    /// The scan pass: tracks the marker in `rgba8` and, when it has a pose, feeds the frame
    /// to the texture memory only (no output frame). Returns whether the frame was used.
    /// Does nothing (Ok(false)) while the memory is off.
    pub fn remember(
        &mut self,
        rgba8: &[u8],
        width: u32,
        height: u32,
        key_pose_s: f32,
        capture_s: f64,
    ) -> Result<bool, ArError> {
        self.check_frame(rgba8, width, height)?;
        let Some(tracker) = &mut self.tracker else {
            return Err(ArError::NoTracker);
        };
        let gray = super::gray_from_rgba(rgba8, width, height)?;
        let out = tracker.update(&gray, capture_s)?;
        match out.pose {
            Some(p) => self.remember_with_pose(rgba8, width, height, key_pose_s, p.to_mat4()),
            None => Ok(false),
        }
    }

    /// [`ArPipeline::remember`] with a known `camera_from_marker` (no tracking).
    pub fn remember_with_pose(
        &mut self,
        rgba8: &[u8],
        width: u32,
        height: u32,
        key_pose_s: f32,
        camera_from_marker: Mat4,
    ) -> Result<bool, ArError> {
        if !self.memory_active() {
            return Ok(false);
        }
        let expected = width as usize * height as usize * 4;
        if rgba8.len() != expected || width == 0 || height == 0 {
            return Err(ArError::BadFrame {
                index: self.frame_index,
                width,
                height,
                expected,
                got: rgba8.len(),
            });
        }
        let intrinsics =
            if (self.camera.intrinsics.width, self.camera.intrinsics.height) == (width, height) {
                self.camera.intrinsics
            } else {
                self.camera.intrinsics.scaled_to(width, height)
            };
        let camera = pa_camera::CameraModel {
            intrinsics,
            distortion: self.camera.distortion,
        };
        let times = FrameTimes {
            animation_s: key_pose_s,
            key_pose_s,
        };
        self.observe_on_cpu(rgba8, width, height, &camera, camera_from_marker, times)?;
        Ok(true)
    }

    /// Poses the key pose and renders its depth with the CPU path's state (made on first
    /// use), then updates the memory: the GPU path's and the scan's update.
    pub(super) fn observe_on_cpu(
        &mut self,
        rgba8: &[u8],
        width: u32,
        height: u32,
        camera: &pa_camera::CameraModel,
        camera_from_marker: Mat4,
        times: FrameTimes,
    ) -> Result<ObserveCounts, ArError> {
        let cpu = match &mut self.cpu {
            Some(c) => c,
            None => self.cpu.insert(Box::new(CpuState::new(&self.props)?)),
        };
        // (The animated pose is posed too; at the key-pose time it costs the same twice.)
        for (twin, p) in cpu.twins.iter_mut().zip(&self.props) {
            let (_, key_pose) = p.poses(times);
            twin.pose(&p.model, &key_pose, &key_pose, p.marker_from_prop);
        }
        let raster_camera = pa_raster::RasterCamera::new(
            &camera.intrinsics,
            super::texture::NEAR_M,
            super::texture::FAR_M,
        );
        let key_meshes: Vec<_> = cpu
            .twins
            .iter()
            .zip(&self.props)
            .flat_map(|(tw, p)| tw.key_depth_meshes(&p.model))
            .collect();
        cpu.renderer
            .render_key_depth(&raster_camera, camera_from_marker, &key_meshes);
        let view = MemoryView {
            rgba8,
            width,
            height,
            camera,
            camera_from_marker,
            key_pose_s: times.key_pose_s,
        };
        let Some(cpu) = self.cpu.as_deref() else {
            return Ok(ObserveCounts::default());
        };
        self.memory.observe(cpu, &self.props, &view)
    }
}
