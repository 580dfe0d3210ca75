//! Bind group layouts, shader modules and pipelines.
//!
//! Groups (shared by the render and the compute pipeline, so that `skinning.wgsl` is one
//! source for both):
//!
//! | group | binding | content                                   | used by            |
//! |-------|---------|-------------------------------------------|--------------------|
//! | 0     | 0       | mesh vertices (storage, `GpuVertex`)      | vertex, compute    |
//! | 0     | 1       | morph deltas (storage)                    | vertex, compute    |
//! | 1     | 0       | `DrawUniforms` (uniform)                  | all                |
//! | 1     | 1       | joint matrices (storage)                  | vertex, compute    |
//! | 1     | 2       | morph weights (storage)                   | vertex, compute    |
//! | 2     | 0, 1    | base colour texture + sampler             | fragment           |
//! | 2     | 0       | skinned output (storage, read-write)      | compute            |
//! | 3     | 0       | `LiveUniforms` (uniform)                  | live vertex + frag |
//! | 3     | 1, 2    | camera frame + clamp/linear sampler       | live fragment      |
//! | 3     | 3       | visibility map (R32Uint camera-z bits)    | live fragment      |
//! | 3     | 4       | texture memory per vertex (storage)       | live vertex        |
//! | 3     | 5       | fraction of the sun per vertex (storage)  | live vertex        |
//!
//! Live draws append their key-pose joint matrices and morph weights to the draw's own in
//! group 1 (bases and counts in `LiveUniforms::key_counts`), so the vertex stage binds no more
//! storage buffers than the plain render pipeline.

use bytemuck::{Pod, Zeroable};

/// Colour target format (sRGB encoding on store).
pub(crate) const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
/// Camera-space z target format: the f32 bits as u32 (R32Float is not renderable on GLES).
pub(crate) const CAMERA_Z_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;
/// Depth-test buffer format.
pub(crate) const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Live-texturing validity target format (one `LiveSample` code per pixel).
pub(crate) const LIVE_CODE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R8Uint;
/// Workgroup size of `cs_skin`.
pub(crate) const SKIN_WORKGROUP_SIZE: u32 = 64;

const SKINNING_WGSL: &str = include_str!("shaders/skinning.wgsl");
const RENDER_WGSL: &str = include_str!("shaders/render.wgsl");
const SKIN_COMPUTE_WGSL: &str = include_str!("shaders/skin_compute.wgsl");
const LIVE_WGSL: &str = include_str!("shaders/live.wgsl");

/// Per-draw uniforms (`DrawUniforms` in `skinning.wgsl`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct DrawUniforms {
    pub clip_from_world: [[f32; 4]; 4],
    pub camera_from_world: [[f32; 4]; 4],
    pub world_from_mesh: [[f32; 4]; 4],
    pub base_color_factor: [f32; 4],
    pub toward_light_world: [f32; 4],
    pub light_rgb: [f32; 4],
    pub ambient_rgb: [f32; 4],
    pub counts: [u32; 4],
    pub flags: [u32; 4],
}

/// Per-draw live-texturing uniforms (`LiveUniforms` in `live.wgsl`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct LiveUniforms {
    pub key_world_from_mesh: [[f32; 4]; 4],
    pub frame_camera_from_world: [[f32; 4]; 4],
    pub visibility_from_frame_camera: [[f32; 4]; 4],
    pub frame_intrinsics: [f32; 4],
    pub frame_size: [f32; 4],
    pub distortion: [f32; 4],
    pub distortion_k3_tolerances: [f32; 4],
    pub visibility_intrinsics: [f32; 4],
    pub visibility_size: [f32; 4],
    pub fallback_irradiance: [[f32; 4]; 3],
    pub stretch: [f32; 4],
    pub key_counts: [u32; 4],
    pub flags: [u32; 4],
    pub sun_toward_light: [f32; 4],
    pub sun_ambient: [f32; 4],
    pub sun_direct: [f32; 4],
    pub grazing: [f32; 4],
}

/// Everything created once per renderer.
pub(crate) struct Pipelines {
    pub mesh_layout: wgpu::BindGroupLayout,
    pub draw_layout: wgpu::BindGroupLayout,
    pub texture_layout: wgpu::BindGroupLayout,
    pub skin_output_layout: wgpu::BindGroupLayout,
    pub live_layout: wgpu::BindGroupLayout,
    pub render: wgpu::RenderPipeline,
    /// `vs_main` + `fs_visibility`: camera-z bits only (visibility maps).
    pub visibility: wgpu::RenderPipeline,
    /// `vs_live` + `fs_live`: colour, camera-z bits and live codes.
    pub live: wgpu::RenderPipeline,
    pub skin: wgpu::ComputePipeline,
    pub sampler: wgpu::Sampler,
    /// Camera frames: bilinear, no mips, clamp to edge.
    pub frame_sampler: wgpu::Sampler,
}

fn storage_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    read_only: bool,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

impl Pipelines {
    pub fn new(device: &wgpu::Device) -> Self {
        let vc = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::COMPUTE;
        let mesh_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("pa-render mesh layout"),
            entries: &[storage_entry(0, vc, true), storage_entry(1, vc, true)],
        });
        let draw_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("pa-render draw layout"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: vc | wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: wgpu::BufferSize::new(
                            std::mem::size_of::<DrawUniforms>() as u64,
                        ),
                    },
                    count: None,
                },
                storage_entry(1, vc, true),
                storage_entry(2, vc, true),
            ],
        });
        let texture_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("pa-render texture layout"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
            ],
        });
        let skin_output_layout =
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("pa-render skin output layout"),
                entries: &[storage_entry(0, wgpu::ShaderStages::COMPUTE, false)],
            });

        let live_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("pa-render live layout"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: wgpu::BufferSize::new(
                            std::mem::size_of::<LiveUniforms>() as u64,
                        ),
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 3,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Uint,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 4,
                    visibility: wgpu::ShaderStages::VERTEX,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: true },
                        has_dynamic_offset: false,
                        min_binding_size: wgpu::BufferSize::new(16),
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 5,
                    visibility: wgpu::ShaderStages::VERTEX,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: true },
                        has_dynamic_offset: false,
                        min_binding_size: wgpu::BufferSize::new(8),
                    },
                    count: None,
                },
            ],
        });

        let render_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("pa-render render.wgsl"),
            source: wgpu::ShaderSource::Wgsl(format!("{SKINNING_WGSL}\n{RENDER_WGSL}").into()),
        });
        let skin_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("pa-render skin_compute.wgsl"),
            source: wgpu::ShaderSource::Wgsl(
                format!("{SKINNING_WGSL}\n{SKIN_COMPUTE_WGSL}").into(),
            ),
        });

        let render_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("pa-render render pipeline layout"),
            bind_group_layouts: &[
                Some(&mesh_layout),
                Some(&draw_layout),
                Some(&texture_layout),
            ],
            immediate_size: 0,
        });
        let render = triangle_pipeline(
            device,
            "pa-render render pipeline",
            &render_layout,
            &render_module,
            ("vs_main", "fs_main"),
            &[COLOR_FORMAT, CAMERA_Z_FORMAT],
        );

        let visibility = triangle_pipeline(
            device,
            "pa-render visibility pipeline",
            &render_layout,
            &render_module,
            ("vs_main", "fs_visibility"),
            &[CAMERA_Z_FORMAT],
        );

        let live_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("pa-render live.wgsl"),
            source: wgpu::ShaderSource::Wgsl(format!("{SKINNING_WGSL}\n{LIVE_WGSL}").into()),
        });
        let live_pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("pa-render live pipeline layout"),
            bind_group_layouts: &[
                Some(&mesh_layout),
                Some(&draw_layout),
                Some(&texture_layout),
                Some(&live_layout),
            ],
            immediate_size: 0,
        });
        let live = triangle_pipeline(
            device,
            "pa-render live pipeline",
            &live_pipeline_layout,
            &live_module,
            ("vs_live", "fs_live"),
            &[COLOR_FORMAT, CAMERA_Z_FORMAT, LIVE_CODE_FORMAT],
        );

        let skin_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("pa-render skin pipeline layout"),
            bind_group_layouts: &[
                Some(&mesh_layout),
                Some(&draw_layout),
                Some(&skin_output_layout),
            ],
            immediate_size: 0,
        });
        let skin = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("pa-render skin pipeline"),
            layout: Some(&skin_layout),
            module: &skin_module,
            entry_point: Some("cs_skin"),
            compilation_options: Default::default(),
            cache: None,
        });

        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("pa-render base colour sampler"),
            address_mode_u: wgpu::AddressMode::Repeat,
            address_mode_v: wgpu::AddressMode::Repeat,
            address_mode_w: wgpu::AddressMode::Repeat,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            mipmap_filter: wgpu::MipmapFilterMode::Linear,
            ..Default::default()
        });

        let frame_sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("pa-render camera frame sampler"),
            address_mode_u: wgpu::AddressMode::ClampToEdge,
            address_mode_v: wgpu::AddressMode::ClampToEdge,
            address_mode_w: wgpu::AddressMode::ClampToEdge,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            mipmap_filter: wgpu::MipmapFilterMode::Nearest,
            ..Default::default()
        });

        Self {
            mesh_layout,
            draw_layout,
            texture_layout,
            skin_output_layout,
            live_layout,
            render,
            visibility,
            live,
            skin,
            sampler,
            frame_sampler,
        }
    }
}

/// A triangle-list pipeline with the state every Props Alive draw shares: no culling (glTF
/// models are often double-sided), depth test `Less` with writes into [`DEPTH_FORMAT`], no
/// blending, one colour target per format in `formats`.
fn triangle_pipeline(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    (vertex_entry, fragment_entry): (&str, &str),
    formats: &[wgpu::TextureFormat],
) -> wgpu::RenderPipeline {
    let targets: Vec<Option<wgpu::ColorTargetState>> = formats
        .iter()
        .map(|&format| {
            Some(wgpu::ColorTargetState {
                format,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })
        })
        .collect();
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some(vertex_entry),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            front_face: wgpu::FrontFace::Ccw,
            cull_mode: None,
            ..Default::default()
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some(fragment_entry),
            compilation_options: Default::default(),
            targets: &targets,
        }),
        multiview_mask: None,
        cache: None,
    })
}
