//! The window's wgpu surface and a tiny blit pipeline: each canvas (RGBA8) is uploaded to a
//! texture and drawn letterboxed into the surface, with no frame queue
//! (`desired_maximum_frame_latency = 1`, Mailbox or Immediate where the surface has them,
//! else Fifo).
//!
//! The window has its own wgpu instance and device (pa-render's renderer is headless and
//! keeps its own); the instance is built from the environment as pa-render's is, so
//! `WGPU_BACKEND` and `WGPU_ADAPTER_NAME` work, and carries the window system's display
//! handle, which GL (EGL) needs to present.

use std::sync::{Arc, Mutex};

use anyhow::{anyhow, bail, Context, Result};
use winit::window::Window;

use super::draw::Image;
use super::layout::{letterbox, Rect};

/// The present mode for a surface offering `modes`: one that does not build a queue of frames
/// (Mailbox replaces the waiting frame, Immediate shows it at once), else Fifo (always
/// supported; with a frame latency of 1 it holds at most one frame).
pub fn choose_present_mode(modes: &[wgpu::PresentMode]) -> wgpu::PresentMode {
    [wgpu::PresentMode::Mailbox, wgpu::PresentMode::Immediate]
        .into_iter()
        .find(|m| modes.contains(m))
        .unwrap_or(wgpu::PresentMode::Fifo)
}

/// The surface format: a plain (non-sRGB) 8-bit format where offered, so the canvas's sRGB
/// bytes reach the screen unchanged; else the surface's first format.
pub fn choose_format(formats: &[wgpu::TextureFormat]) -> Option<wgpu::TextureFormat> {
    [
        wgpu::TextureFormat::Bgra8Unorm,
        wgpu::TextureFormat::Rgba8Unorm,
    ]
    .into_iter()
    .find(|f| formats.contains(f))
    .or_else(|| formats.first().copied())
}

/// The canvas texture's format for a surface format: sRGB-ness matches, so that sampling
/// and writing cancel out and the bytes pass through.
pub fn texture_format_for(surface: wgpu::TextureFormat) -> wgpu::TextureFormat {
    if surface.is_srgb() {
        wgpu::TextureFormat::Rgba8UnormSrgb
    } else {
        wgpu::TextureFormat::Rgba8Unorm
    }
}

const BLIT_WGSL: &str = r#"
@group(0) @binding(0) var canvas: texture_2d<f32>;
@group(0) @binding(1) var canvas_sampler: sampler;

struct VsOut {
    @builtin(position) position: vec4<f32>,
    @location(0) uv: vec2<f32>,
};

// One triangle covering the viewport: uv (0,0) top-left .. (1,1) bottom-right.
@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> VsOut {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    var out: VsOut;
    out.position = vec4<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, 0.0, 1.0);
    out.uv = uv;
    return out;
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    return vec4<f32>(textureSample(canvas, canvas_sampler, in.uv).rgb, 1.0);
}
"#;

/// The uploaded canvas.
struct CanvasTexture {
    texture: wgpu::Texture,
    bind_group: wgpu::BindGroup,
    size: (u32, u32),
}

/// What became of a present.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Presented {
    /// On screen, drawn into this rectangle of the window.
    Shown(Rect),
    /// Skipped: the window is minimised, occluded, or the surface timed out.
    Skipped,
}

/// The window's surface, device and blit pipeline.
pub struct Presenter {
    // The surface is dropped before the window it draws into.
    surface: wgpu::Surface<'static>,
    window: Arc<Window>,
    instance: wgpu::Instance,
    adapter: wgpu::Adapter,
    device: wgpu::Device,
    queue: wgpu::Queue,
    config: wgpu::SurfaceConfiguration,
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    sampler: wgpu::Sampler,
    canvas: Option<CanvasTexture>,
    errors: Arc<Mutex<Option<String>>>,
    /// "adapter (backend), format, present mode".
    pub description: String,
}

/// "name (backend, type)".
fn describe(info: &wgpu::AdapterInfo) -> String {
    format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type)
}

impl Presenter {
    /// Creates the surface for `window` and a device that can present to it.
    pub fn new(instance: wgpu::Instance, window: Arc<Window>) -> Result<Self> {
        let surface = instance
            .create_surface(wgpu::SurfaceTarget::from_window_without_display(
                window.clone(),
            ))
            .context("creating the window's wgpu surface")?;
        let backends = wgpu::Backends::from_env().unwrap_or_default();
        let mut adapters = pollster::block_on(instance.enumerate_adapters(backends));
        let all: Vec<String> = adapters.iter().map(|a| describe(&a.get_info())).collect();
        adapters.retain(|a| a.is_surface_supported(&surface));
        if let Ok(wanted) = std::env::var("WGPU_ADAPTER_NAME") {
            let w = wanted.to_lowercase();
            adapters.retain(|a| a.get_info().name.to_lowercase().contains(&w));
        }
        adapters.sort_by_key(|a| pa_render::adapter_rank(&a.get_info()));
        let Some(adapter) = adapters.into_iter().next() else {
            if all.is_empty() {
                bail!(
                    "no graphics adapter for the window (backends {backends:?}); install Mesa \
                     (mesa-vulkan-drivers or libegl-mesa0) or set WGPU_BACKEND"
                );
            }
            bail!(
                "no graphics adapter can present to this window{} (found: {})",
                std::env::var("WGPU_ADAPTER_NAME")
                    .map(|n| format!(" with WGPU_ADAPTER_NAME={n}"))
                    .unwrap_or_default(),
                all.join(", ")
            );
        };
        let info = adapter.get_info();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("preview window device"),
            required_features: wgpu::Features::empty(),
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .with_context(|| format!("opening a device on {}", describe(&info)))?;
        // wgpu's default handler panics; keep the first error and report it instead.
        let errors: Arc<Mutex<Option<String>>> = Arc::new(Mutex::new(None));
        let sink = errors.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            if let Ok(mut slot) = sink.lock() {
                slot.get_or_insert_with(|| e.to_string());
            }
        }));

        let caps = surface.get_capabilities(&adapter);
        let format = choose_format(&caps.formats)
            .ok_or_else(|| anyhow!("the window surface offers no format on {}", describe(&info)))?;
        let present_mode = choose_present_mode(&caps.present_modes);
        let alpha_mode = if caps.alpha_modes.contains(&wgpu::CompositeAlphaMode::Opaque) {
            wgpu::CompositeAlphaMode::Opaque
        } else {
            caps.alpha_modes
                .first()
                .copied()
                .unwrap_or(wgpu::CompositeAlphaMode::Auto)
        };
        let size = window.inner_size();
        let config = wgpu::SurfaceConfiguration {
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            format,
            color_space: wgpu::SurfaceColorSpace::Auto,
            width: size.width.max(1),
            height: size.height.max(1),
            present_mode,
            desired_maximum_frame_latency: 1,
            alpha_mode,
            view_formats: vec![],
        };
        surface.configure(&device, &config);

        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("preview blit"),
            source: wgpu::ShaderSource::Wgsl(BLIT_WGSL.into()),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("preview blit layout"),
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
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("preview blit pipeline layout"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("preview blit pipeline"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("preview blit sampler"),
            address_mode_u: wgpu::AddressMode::ClampToEdge,
            address_mode_v: wgpu::AddressMode::ClampToEdge,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        let description = format!(
            "{}, {:?}, {:?}, frame latency 1",
            describe(&info),
            format,
            present_mode
        );
        let p = Self {
            window,
            instance,
            surface,
            adapter,
            device,
            queue,
            config,
            pipeline,
            layout,
            sampler,
            canvas: None,
            errors,
            description,
        };
        p.check_errors()?;
        Ok(p)
    }

    fn check_errors(&self) -> Result<()> {
        let err = self.errors.lock().ok().and_then(|mut e| e.take());
        match err {
            Some(e) => bail!("the window's graphics device reported: {e}"),
            None => Ok(()),
        }
    }

    /// Follows a window resize (a zero size is kept until the window is shown again).
    pub fn resize(&mut self, width: u32, height: u32) {
        if width == 0 || height == 0 {
            return;
        }
        if (self.config.width, self.config.height) != (width, height) {
            self.config.width = width;
            self.config.height = height;
            self.surface.configure(&self.device, &self.config);
        }
    }

    /// Uploads a canvas (replacing the previous one).
    pub fn upload(&mut self, img: &Image) -> Result<()> {
        let size = (img.width, img.height);
        let max = self.device.limits().max_texture_dimension_2d;
        if size.0 == 0 || size.1 == 0 || size.0 > max || size.1 > max {
            bail!(
                "a {}x{} frame does not fit the window's GPU textures (1..={max})",
                size.0,
                size.1
            );
        }
        if self.canvas.as_ref().map(|c| c.size) != Some(size) {
            let texture = self.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("preview canvas"),
                size: wgpu::Extent3d {
                    width: size.0,
                    height: size.1,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: texture_format_for(self.config.format),
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            });
            let view = texture.create_view(&Default::default());
            let bind_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("preview canvas bind group"),
                layout: &self.layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::TextureView(&view),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::Sampler(&self.sampler),
                    },
                ],
            });
            self.canvas = Some(CanvasTexture {
                texture,
                bind_group,
                size,
            });
        }
        let Some(canvas) = &self.canvas else {
            bail!("no canvas texture");
        };
        self.queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &canvas.texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            &img.rgba8,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(4 * size.0),
                rows_per_image: Some(size.1),
            },
            wgpu::Extent3d {
                width: size.0,
                height: size.1,
                depth_or_array_layers: 1,
            },
        );
        Ok(())
    }

    /// Draws the uploaded canvas letterboxed into the window and presents it; returns when
    /// the present call has returned.
    pub fn present(&mut self) -> Result<Presented> {
        let Some(canvas_size) = self.canvas.as_ref().map(|c| c.size) else {
            return Ok(Presented::Skipped);
        };
        let size = self.window.inner_size();
        if size.width == 0 || size.height == 0 {
            return Ok(Presented::Skipped);
        }
        self.resize(size.width, size.height);
        let Some(rect) = letterbox((self.config.width, self.config.height), canvas_size) else {
            return Ok(Presented::Skipped);
        };
        let mut frame = None;
        for _attempt in 0..2 {
            match self.surface.get_current_texture() {
                wgpu::CurrentSurfaceTexture::Success(t) => {
                    frame = Some((t, false));
                    break;
                }
                wgpu::CurrentSurfaceTexture::Suboptimal(t) => {
                    frame = Some((t, true));
                    break;
                }
                wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => {
                    return Ok(Presented::Skipped);
                }
                wgpu::CurrentSurfaceTexture::Outdated => {
                    self.surface.configure(&self.device, &self.config);
                }
                wgpu::CurrentSurfaceTexture::Lost => {
                    self.surface = self
                        .instance
                        .create_surface(wgpu::SurfaceTarget::from_window_without_display(
                            self.window.clone(),
                        ))
                        .context("recreating the lost window surface")?;
                    if !self.adapter.is_surface_supported(&self.surface) {
                        bail!("the recreated window surface is not supported by the adapter");
                    }
                    self.surface.configure(&self.device, &self.config);
                }
                wgpu::CurrentSurfaceTexture::Validation => {
                    self.check_errors()?;
                    bail!("the window surface reported a validation error");
                }
            }
        }
        let Some((surface_texture, suboptimal)) = frame else {
            return Ok(Presented::Skipped);
        };
        let Some(canvas) = &self.canvas else {
            return Ok(Presented::Skipped);
        };
        let view = surface_texture.texture.create_view(&Default::default());
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("preview blit"),
            });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("preview blit pass"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_viewport(
                rect.x as f32,
                rect.y as f32,
                rect.w as f32,
                rect.h as f32,
                0.0,
                1.0,
            );
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &canvas.bind_group, &[]);
            pass.draw(0..3, 0..1);
        }
        self.queue.submit([encoder.finish()]);
        self.window.pre_present_notify();
        self.queue.present(surface_texture);
        if suboptimal {
            self.surface.configure(&self.device, &self.config);
        }
        self.check_errors()?;
        Ok(Presented::Shown(rect))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wgpu::{PresentMode as P, TextureFormat as F};

    #[test]
    fn present_mode_never_queues_when_it_can_avoid_it() {
        assert_eq!(
            choose_present_mode(&[P::Fifo, P::Mailbox, P::Immediate]),
            P::Mailbox
        );
        assert_eq!(choose_present_mode(&[P::Fifo, P::Immediate]), P::Immediate);
        assert_eq!(choose_present_mode(&[P::Fifo]), P::Fifo);
        assert_eq!(choose_present_mode(&[]), P::Fifo);
    }

    #[test]
    fn formats_pass_srgb_bytes_through() {
        assert_eq!(
            choose_format(&[F::Bgra8UnormSrgb, F::Bgra8Unorm]),
            Some(F::Bgra8Unorm)
        );
        assert_eq!(choose_format(&[F::Rgba8UnormSrgb]), Some(F::Rgba8UnormSrgb));
        assert_eq!(choose_format(&[]), None);
        assert_eq!(texture_format_for(F::Bgra8Unorm), F::Rgba8Unorm);
        assert_eq!(texture_format_for(F::Bgra8UnormSrgb), F::Rgba8UnormSrgb);
        assert_eq!(texture_format_for(F::Rgba8UnormSrgb), F::Rgba8UnormSrgb);
    }
}
