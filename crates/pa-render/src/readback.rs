//! Offscreen targets and GPU -> CPU readback (wgpu's 256-byte row alignment handled here).

use crate::error::RenderError;
use crate::pipeline::{CAMERA_Z_FORMAT, COLOR_FORMAT, DEPTH_FORMAT, LIVE_CODE_FORMAT};

/// Bytes per row of a `width`-texel row of 4-byte texels, padded to
/// `COPY_BYTES_PER_ROW_ALIGNMENT`.
pub(crate) fn padded_bytes_per_row(width: u32) -> u32 {
    padded_bytes_per_row_of(width, 4)
}

/// Bytes per row of a `width`-texel row of `texel_bytes`-byte texels, padded to
/// `COPY_BYTES_PER_ROW_ALIGNMENT`.
pub(crate) fn padded_bytes_per_row_of(width: u32, texel_bytes: u32) -> u32 {
    let unpadded = width * texel_bytes;
    let align = wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    unpadded.div_ceil(align) * align
}

/// Removes row padding: `padded` holds `height` rows of `padded_row` bytes, of which the first
/// `row` bytes are kept.
pub(crate) fn unpad_rows(padded: &[u8], row: usize, padded_row: usize, height: usize) -> Vec<u8> {
    let mut out = Vec::with_capacity(row * height);
    for chunk in padded.chunks(padded_row).take(height) {
        out.extend_from_slice(&chunk[..row.min(chunk.len())]);
    }
    out
}

/// A rectangle of a render target's pixels: columns `x..x + width`, rows `y..y + height`
/// (from the top-left). Reading back only the region a draw covers instead of the whole
/// target is what keeps the GPU -> CPU transfer small on a discrete GPU.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PixelRegion {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
}

impl PixelRegion {
    /// The whole of a `width` x `height` target.
    pub fn full(width: u32, height: u32) -> Self {
        Self {
            x: 0,
            y: 0,
            width,
            height,
        }
    }

    /// Number of pixels.
    pub fn area(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// An error unless the region is non-empty and inside a `width` x `height` target.
    pub(crate) fn check(&self, width: u32, height: u32) -> Result<(), RenderError> {
        let inside = |start: u32, len: u32, side: u32| {
            len > 0 && start.checked_add(len).is_some_and(|end| end <= side)
        };
        if inside(self.x, self.width, width) && inside(self.y, self.height, height) {
            Ok(())
        } else {
            Err(RenderError::RegionOutsideTarget {
                region: *self,
                width,
                height,
            })
        }
    }

    /// The copy's origin in the target.
    fn origin(&self) -> wgpu::Origin3d {
        wgpu::Origin3d {
            x: self.x,
            y: self.y,
            z: 0,
        }
    }

    /// The copy's extent.
    fn extent(&self) -> wgpu::Extent3d {
        wgpu::Extent3d {
            width: self.width,
            height: self.height,
            depth_or_array_layers: 1,
        }
    }
}

/// Records the copy of `region` of `texture` (of `texel_bytes`-byte texels) into the start of
/// `buffer`, rows padded to [`wgpu::COPY_BYTES_PER_ROW_ALIGNMENT`].
pub(crate) fn record_region_copy(
    encoder: &mut wgpu::CommandEncoder,
    texture: &wgpu::Texture,
    buffer: &wgpu::Buffer,
    texel_bytes: u32,
    region: PixelRegion,
) {
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: region.origin(),
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded_bytes_per_row_of(region.width, texel_bytes)),
                rows_per_image: Some(region.height),
            },
        },
        region.extent(),
    );
}

/// Colour, camera-z and depth targets plus their readback buffers, for one size. Kept by the
/// renderer and reused while the size does not change.
pub(crate) struct Targets {
    pub width: u32,
    pub height: u32,
    pub color: wgpu::Texture,
    pub color_view: wgpu::TextureView,
    pub camera_z: wgpu::Texture,
    pub camera_z_view: wgpu::TextureView,
    pub depth_view: wgpu::TextureView,
    pub color_readback: wgpu::Buffer,
    pub camera_z_readback: wgpu::Buffer,
}

impl Targets {
    pub fn new(device: &wgpu::Device, width: u32, height: u32) -> Self {
        let size = wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        };
        let make = |label, format, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let target_usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
        let color = make("pa-render colour target", COLOR_FORMAT, target_usage);
        let camera_z = make("pa-render camera-z target", CAMERA_Z_FORMAT, target_usage);
        let depth = make(
            "pa-render depth buffer",
            DEPTH_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let buffer_size = u64::from(padded_bytes_per_row(width)) * u64::from(height);
        let readback = |label| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: buffer_size,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            })
        };
        Self {
            width,
            height,
            color_view: color.create_view(&Default::default()),
            camera_z_view: camera_z.create_view(&Default::default()),
            depth_view: depth.create_view(&Default::default()),
            color,
            camera_z,
            color_readback: readback("pa-render colour readback"),
            camera_z_readback: readback("pa-render camera-z readback"),
        }
    }

    /// Records the copies of `region` of both colour targets into their readback buffers.
    pub fn record_copies(&self, encoder: &mut wgpu::CommandEncoder, region: PixelRegion) {
        record_region_copy(encoder, &self.color, &self.color_readback, 4, region);
        record_region_copy(encoder, &self.camera_z, &self.camera_z_readback, 4, region);
    }
}

/// The targets of a live-textured frame: [`Targets`] plus the R8Uint live-code target and its
/// readback buffer.
pub(crate) struct LiveTargets {
    pub base: Targets,
    pub code: wgpu::Texture,
    pub code_view: wgpu::TextureView,
    pub code_readback: wgpu::Buffer,
}

impl LiveTargets {
    pub fn new(device: &wgpu::Device, width: u32, height: u32) -> Self {
        let base = Targets::new(device, width, height);
        let code = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("pa-render live code target"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: LIVE_CODE_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let code_readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("pa-render live code readback"),
            size: u64::from(padded_bytes_per_row_of(width, 1)) * u64::from(height),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        Self {
            base,
            code_view: code.create_view(&Default::default()),
            code,
            code_readback,
        }
    }

    /// Records the copies of `region` of all three colour targets into their readback buffers.
    pub fn record_copies(&self, encoder: &mut wgpu::CommandEncoder, region: PixelRegion) {
        self.base.record_copies(encoder, region);
        record_region_copy(encoder, &self.code, &self.code_readback, 1, region);
    }
}

/// Cumulative readback timings of a [`crate::Renderer`] ([`crate::Renderer::readback_times`]);
/// subtract two snapshots ([`ReadbackTimes::since`]) to time a piece of work.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ReadbackTimes {
    /// Milliseconds spent waiting for submitted GPU work to finish before its results could be
    /// mapped. On a software rasteriser (lavapipe, llvmpipe) this is mostly the rendering
    /// itself, not the transfer.
    pub wait_ms: f64,
    /// Milliseconds spent copying mapped readback buffers to CPU memory, removing the row
    /// padding and decoding depth: the CPU side of the GPU -> CPU readback.
    pub copy_ms: f64,
    /// Number of readbacks (one per `read_buffers` call).
    pub count: u64,
}

impl ReadbackTimes {
    /// The time spent between the snapshot `earlier` and `self`.
    pub fn since(&self, earlier: &ReadbackTimes) -> ReadbackTimes {
        ReadbackTimes {
            wait_ms: self.wait_ms - earlier.wait_ms,
            copy_ms: self.copy_ms - earlier.copy_ms,
            count: self.count.saturating_sub(earlier.count),
        }
    }
}

/// Milliseconds since `t`.
pub(crate) fn ms_since(t: std::time::Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Bytes of a readback buffer that a copy of `region` (of `texel_bytes`-byte texels) fills.
pub(crate) fn region_bytes(region: PixelRegion, texel_bytes: u32) -> u64 {
    u64::from(padded_bytes_per_row_of(region.width, texel_bytes)) * u64::from(region.height)
}

/// Maps the first `bytes` of each given buffer for reading (after the copies were submitted),
/// waits, and returns those bytes; adds the wait and the copy to `times`. Only what a copy
/// filled is mapped and copied, not the whole buffer.
pub(crate) fn read_buffers(
    device: &wgpu::Device,
    buffers: &[(&wgpu::Buffer, u64)],
    times: &mut ReadbackTimes,
) -> Result<Vec<Vec<u8>>, RenderError> {
    let t_wait = std::time::Instant::now();
    let (sender, receiver) = std::sync::mpsc::channel();
    for (i, &(buffer, bytes)) in buffers.iter().enumerate() {
        let sender = sender.clone();
        buffer.map_async(wgpu::MapMode::Read, ..bytes, move |result| {
            // The receiver outlives the poll below; a send error cannot happen then.
            let _ = sender.send((i, result));
        });
    }
    drop(sender);
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| RenderError::Readback(e.to_string()))?;
    for _ in buffers {
        let (i, result) = receiver
            .recv()
            .map_err(|_| RenderError::Readback("map callback was not called".to_owned()))?;
        result.map_err(|e| RenderError::Readback(format!("buffer {i}: {e}")))?;
    }
    times.wait_ms += ms_since(t_wait);
    times.count += 1;
    let t_copy = std::time::Instant::now();
    let mut out = Vec::with_capacity(buffers.len());
    for &(buffer, bytes) in buffers {
        let data = {
            let view = buffer
                .get_mapped_range(..bytes)
                .map_err(|e| RenderError::Readback(e.to_string()))?;
            view.to_vec()
        };
        buffer.unmap();
        out.push(data);
    }
    times.copy_ms += ms_since(t_copy);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn row_padding() {
        assert_eq!(padded_bytes_per_row(64), 256);
        assert_eq!(padded_bytes_per_row(65), 512);
        assert_eq!(padded_bytes_per_row(1), 256);
        let padded: Vec<u8> = (0..2 * 256).map(|i| (i % 256) as u8).collect();
        let rows = unpad_rows(&padded, 4, 256, 2);
        assert_eq!(rows, vec![0, 1, 2, 3, 0, 1, 2, 3]);
    }
}
