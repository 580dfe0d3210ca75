//! CPU textures (sRGB RGBA8) and their upload with a CPU-built mip chain.

use crate::error::RenderError;

/// An sRGB-encoded RGBA8 image, row-major from the top-left, no row padding (alpha is linear,
/// straight). Sampled as sRGB with linear (trilinear) filtering and repeat wrapping.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct CpuTexture {
    pub width: u32,
    pub height: u32,
    pub rgba8: Vec<u8>,
}

/// A texture uploaded by [`crate::Renderer::upload_texture`] (with mips) or
/// [`crate::Renderer::upload_frame`] (without). Cheap to clone (clones share the GPU texture,
/// so [`crate::Renderer::update_texture`] changes what every clone sees).
#[derive(Debug, Clone)]
pub struct GpuTexture {
    pub(crate) renderer_id: u64,
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) texture: wgpu::Texture,
    /// View of all mip levels.
    pub(crate) view: wgpu::TextureView,
    /// Group 2 of the render pipeline: texture view and sampler.
    pub(crate) bind_group: wgpu::BindGroup,
}

impl GpuTexture {
    /// Size of mip level 0.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Number of mip levels (1 for camera frames).
    pub fn mip_level_count(&self) -> u32 {
        self.texture.mip_level_count()
    }
}

impl CpuTexture {
    /// A single-colour texture.
    pub fn solid(width: u32, height: u32, rgba8: [u8; 4]) -> Self {
        Self {
            width,
            height,
            rgba8: rgba8.repeat(width as usize * height as usize),
        }
    }

    /// Checks size and data length against a maximum side length.
    pub fn validate(&self, max_side: u32) -> Result<(), RenderError> {
        if self.width == 0 || self.height == 0 || self.width > max_side || self.height > max_side {
            return Err(RenderError::InvalidTextureSize {
                width: self.width,
                height: self.height,
                max: max_side,
            });
        }
        let expected = self.width as usize * self.height as usize * 4;
        if self.rgba8.len() != expected {
            return Err(RenderError::TextureDataLength {
                width: self.width,
                height: self.height,
                expected,
                actual: self.rgba8.len(),
            });
        }
        Ok(())
    }
}

// The mip chain is the CPU path's (`pa_raster::texture::downsample_srgb8`), so that both
// renderers sample the same texels.
use pa_raster::texture::downsample_srgb8;

/// Writes `texture` into mip level 0 of `gpu` and, when `gpu` has more levels, the CPU-built
/// mip chain (2x2 box filter in linear light) into the others.
pub(crate) fn write_levels(queue: &wgpu::Queue, gpu: &wgpu::Texture, texture: &CpuTexture) {
    let mip_level_count = gpu.mip_level_count();
    let (mut w, mut h) = (texture.width, texture.height);
    let mut level_data = std::borrow::Cow::Borrowed(texture.rgba8.as_slice());
    for level in 0..mip_level_count {
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: gpu,
                mip_level: level,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            &level_data,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(4 * w),
                rows_per_image: Some(h),
            },
            wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
        if level + 1 < mip_level_count {
            let (w2, h2, data) = downsample_srgb8(w, h, &level_data);
            (w, h) = (w2, h2);
            level_data = std::borrow::Cow::Owned(data);
        }
    }
}

/// Uploads `texture` as sRGB RGBA8, with a full CPU-built mip chain when `mips`, else a single
/// level (camera frames: sampled at level 0 only).
#[allow(clippy::too_many_arguments)]
pub(crate) fn upload(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    max_side: u32,
    layout: &wgpu::BindGroupLayout,
    sampler: &wgpu::Sampler,
    renderer_id: u64,
    texture: &CpuTexture,
    mips: bool,
) -> Result<GpuTexture, RenderError> {
    texture.validate(max_side)?;
    let mip_level_count = if mips {
        32 - texture.width.max(texture.height).leading_zeros()
    } else {
        1
    };
    let gpu = device.create_texture(&wgpu::TextureDescriptor {
        label: Some(if mips {
            "pa-render base colour texture"
        } else {
            "pa-render camera frame texture"
        }),
        size: wgpu::Extent3d {
            width: texture.width,
            height: texture.height,
            depth_or_array_layers: 1,
        },
        mip_level_count,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8UnormSrgb,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    write_levels(queue, &gpu, texture);
    let view = gpu.create_view(&wgpu::TextureViewDescriptor::default());
    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("pa-render texture bind group"),
        layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(&view),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::Sampler(sampler),
            },
        ],
    });
    Ok(GpuTexture {
        renderer_id,
        width: texture.width,
        height: texture.height,
        texture: gpu,
        view,
        bind_group,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downsample_is_linear_light_average() {
        // Black and white average to linear 0.5, i.e. sRGB 188.
        let data = [
            0, 0, 0, 255, 255, 255, 255, 255, 0, 0, 0, 255, 255, 255, 255, 255,
        ];
        let (w, h, out) = downsample_srgb8(2, 2, &data);
        assert_eq!((w, h), (1, 1));
        assert_eq!(out, vec![188, 188, 188, 255]);
    }
}
