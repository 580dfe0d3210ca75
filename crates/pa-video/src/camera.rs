//! Live capture from a Video4Linux2 camera (the `v4l` feature, Linux).
//!
//! [`Camera::open`] negotiates a format: among the device's YUYV (4:2:2) and MJPEG formats it
//! takes the one that gives the requested size and frame rate, preferring YUYV (no
//! compression artefacts) when both do, and MJPEG when only it reaches the rate (USB 2
//! cameras deliver 720p30 only as MJPEG). The driver's answer is what [`Camera::format`]
//! reports; the request is not an error when the driver picks a nearby size or rate.
//!
//! Frames are converted to RGBA8 (YUYV with the colour the driver reports, BT.601 limited
//! range when it reports none, as UVC cameras do; MJPEG through `zune-jpeg`, which also fills
//! in the Huffman tables that webcams leave out). Timestamps are the driver's capture times,
//! relative to the first frame of the take, in microseconds.
//!
//! Errors: a missing device is [`VideoError::DeviceNotFound`]; one used by another program
//! is [`VideoError::DeviceBusy`]; a camera unplugged mid-take yields
//! [`VideoError::DeviceLost`] once and then `Ok(None)`: the frames captured before are good,
//! so keep the take and end cleanly. A stream that delivers nothing for 5 s is an error
//! naming the device.
//!
//! Without the feature (or off Linux) [`Camera::open`] returns
//! [`VideoError::FeatureDisabled`] naming the feature, so callers need no `cfg`.

use std::path::{Path, PathBuf};

use crate::{Fps, Frame, FrameSource, VideoError};

/// The pixel format the camera delivers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CameraPixelFormat {
    /// Packed 4:2:2 Y'CbCr (`YUYV`).
    Yuyv,
    /// Motion JPEG (`MJPG`).
    Mjpeg,
}

impl std::fmt::Display for CameraPixelFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            CameraPixelFormat::Yuyv => "YUYV 4:2:2",
            CameraPixelFormat::Mjpeg => "MJPEG",
        })
    }
}

/// What the camera and driver agreed on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CameraFormat {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixel format on the wire.
    pub pixel_format: CameraPixelFormat,
    /// Frame rate the driver set, when it reports one.
    pub fps: Option<Fps>,
    /// Bytes per row of YUYV frames.
    pub stride: u32,
}

/// A live camera. See the [module docs](self).
pub struct Camera {
    inner: imp::CameraImpl,
}

impl std::fmt::Debug for Camera {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Camera")
            .field("device", &self.device())
            .field("format", &self.format())
            .finish()
    }
}

impl Camera {
    /// Opens `device` (e.g. `/dev/video0`) asking for `width x height` at `fps`.
    pub fn open(
        device: impl AsRef<Path>,
        width: u32,
        height: u32,
        fps: u32,
    ) -> Result<Camera, VideoError> {
        let device = device.as_ref();
        if width == 0 || height == 0 || fps == 0 || width > 8192 || height > 8192 || fps > 1000 {
            return Err(VideoError::InvalidSetting {
                name: "camera request",
                value: format!("{width}x{height} at {fps} fps"),
                reason: "need 1x1 to 8192x8192 at 1 to 1000 fps".into(),
            });
        }
        imp::CameraImpl::open(device, width, height, fps).map(|inner| Camera { inner })
    }

    /// The device path.
    pub fn device(&self) -> &Path {
        self.inner.device()
    }

    /// The negotiated format.
    pub fn format(&self) -> CameraFormat {
        self.inner.format()
    }

    /// The next frame (blocks until the camera delivers one). After the camera is lost:
    /// [`VideoError::DeviceLost`] once, then `Ok(None)`.
    pub fn next_frame(&mut self) -> Result<Option<Frame>, VideoError> {
        self.inner.next_frame()
    }
}

impl FrameSource for Camera {
    fn next_frame(&mut self) -> Result<Option<Frame>, VideoError> {
        Camera::next_frame(self)
    }
    fn frame_size(&self) -> (u32, u32) {
        let f = self.format();
        (f.width, f.height)
    }
    fn fps(&self) -> Option<Fps> {
        self.format().fps
    }
    fn describe(&self) -> String {
        let f = self.format();
        format!(
            "camera {}: {}x{} {}{}",
            self.device().display(),
            f.width,
            f.height,
            f.pixel_format,
            f.fps.map(|r| format!(" at {r} fps")).unwrap_or_default()
        )
    }
}

#[cfg(not(all(feature = "v4l", target_os = "linux")))]
mod imp {
    use super::*;

    /// Uninhabited: no camera can exist without the feature.
    pub(super) enum CameraImpl {}

    impl CameraImpl {
        pub(super) fn open(
            device: &Path,
            _w: u32,
            _h: u32,
            _fps: u32,
        ) -> Result<CameraImpl, VideoError> {
            Err(VideoError::FeatureDisabled {
                what: format!("camera capture ({})", device.display()),
                feature: if cfg!(target_os = "linux") {
                    "v4l"
                } else {
                    "v4l (Linux only)"
                },
            })
        }
        pub(super) fn device(&self) -> &Path {
            match *self {}
        }
        pub(super) fn format(&self) -> CameraFormat {
            match *self {}
        }
        pub(super) fn next_frame(&mut self) -> Result<Option<Frame>, VideoError> {
            match *self {}
        }
    }

    #[allow(dead_code)]
    fn _uses(_: PathBuf, _: Fps) {}
}

#[cfg(all(feature = "v4l", target_os = "linux"))]
mod imp {
    use super::*;
    use crate::color::{yuyv_to_rgba, YuvColor, YuvMatrix, YuvRange};
    use crate::Timestamp;
    use std::io;
    use std::time::{Duration, Instant};
    use v4l::buffer::{Flags as BufferFlags, Type};
    use v4l::capability::Flags as CapFlags;
    use v4l::format::{Colorspace, Quantization};
    use v4l::io::mmap::Stream;
    use v4l::io::traits::{CaptureStream, Stream as _};
    use v4l::video::capture::Parameters;
    use v4l::video::Capture;
    use v4l::{Device, Format, FourCC};

    const ENOENT: i32 = 2;
    const ENXIO: i32 = 6;
    const EBUSY: i32 = 16;
    const ENODEV: i32 = 19;

    /// How long a frame may take before the stream counts as stalled.
    const FRAME_TIMEOUT: Duration = Duration::from_secs(5);
    /// Corrupt buffers tolerated in a row before giving up.
    const MAX_BAD_FRAMES: u32 = 30;

    pub(super) struct CameraImpl {
        // Field order: the stream (buffers, mappings) goes before the device.
        stream: Option<Stream<'static>>,
        _dev: Device,
        device: PathBuf,
        format: CameraFormat,
        color: YuvColor,
        first_us: Option<i64>,
        started: Option<Instant>,
        frames: u64,
        lost: bool,
    }

    fn open_error(device: &Path, action: &'static str, e: io::Error) -> VideoError {
        match e.raw_os_error() {
            Some(ENOENT) | Some(ENXIO) | Some(ENODEV) => VideoError::DeviceNotFound {
                device: device.to_path_buf(),
            },
            Some(EBUSY) => VideoError::DeviceBusy {
                device: device.to_path_buf(),
            },
            _ => VideoError::Device {
                device: device.to_path_buf(),
                action,
                source: e,
            },
        }
    }

    fn fps_of(p: &Parameters) -> Option<Fps> {
        // interval is seconds per frame.
        let (n, d) = (p.interval.numerator, p.interval.denominator);
        if n == 0 || d == 0 {
            return None;
        }
        Fps::new(d, n).ok()
    }

    impl CameraImpl {
        pub(super) fn open(
            device: &Path,
            width: u32,
            height: u32,
            fps: u32,
        ) -> Result<CameraImpl, VideoError> {
            let dev = Device::with_path(device).map_err(|e| open_error(device, "open", e))?;
            let caps = dev.query_caps().map_err(|e| match e.raw_os_error() {
                Some(25) => VideoError::DeviceFormat {
                    device: device.to_path_buf(),
                    detail: "not a Video4Linux device".into(),
                },
                _ => open_error(device, "query its capabilities", e),
            })?;
            if !caps.capabilities.contains(CapFlags::VIDEO_CAPTURE)
                || !caps.capabilities.contains(CapFlags::STREAMING)
            {
                return Err(VideoError::DeviceFormat {
                    device: device.to_path_buf(),
                    detail: format!(
                        "'{}' ({}) is not a streaming capture device (UVC cameras also create \
                         a metadata node: try the other /dev/video number)",
                        caps.card, caps.driver
                    ),
                });
            }
            let offered: Vec<FourCC> = dev
                .enum_formats()
                .map_err(|e| open_error(device, "list its formats", e))?
                .into_iter()
                .map(|d| d.fourcc)
                .collect();
            let yuyv = FourCC::new(b"YUYV");
            let mjpg = FourCC::new(b"MJPG");
            let candidates: Vec<FourCC> = [yuyv, mjpg]
                .into_iter()
                .filter(|c| offered.contains(c))
                .collect();
            if candidates.is_empty() {
                let names: Vec<String> = offered.iter().map(|f| f.to_string()).collect();
                return Err(VideoError::DeviceFormat {
                    device: device.to_path_buf(),
                    detail: format!(
                        "offers only {} (this program reads YUYV and MJPEG)",
                        if names.is_empty() {
                            "no formats".to_string()
                        } else {
                            names.join(", ")
                        }
                    ),
                });
            }
            // Try each; score (exact size, reaches the rate, YUYV preferred).
            let mut best: Option<((bool, bool, bool), Format)> = None;
            for &fourcc in &candidates {
                let got = dev
                    .set_format(&Format::new(width, height, fourcc))
                    .map_err(|e| open_error(device, "set its format", e))?;
                if got.fourcc != fourcc {
                    continue;
                }
                let rate = dev
                    .set_params(&Parameters::with_fps(fps))
                    .ok()
                    .as_ref()
                    .and_then(fps_of);
                let reaches = rate.is_none_or(|r| r.as_f64() >= f64::from(fps) * 0.99);
                let score = (
                    got.width == width && got.height == height,
                    reaches,
                    fourcc == yuyv,
                );
                if best.as_ref().is_none_or(|(s, _)| score > *s) {
                    best = Some((score, got));
                }
            }
            let Some((_, chosen)) = best else {
                return Err(VideoError::DeviceFormat {
                    device: device.to_path_buf(),
                    detail: "the driver refused both YUYV and MJPEG".into(),
                });
            };
            let got = dev
                .set_format(&Format::new(width, height, chosen.fourcc))
                .map_err(|e| open_error(device, "set its format", e))?;
            let rate = dev
                .set_params(&Parameters::with_fps(fps))
                .ok()
                .as_ref()
                .and_then(fps_of);
            let pixel_format = if got.fourcc == yuyv {
                CameraPixelFormat::Yuyv
            } else if got.fourcc == mjpg {
                CameraPixelFormat::Mjpeg
            } else {
                return Err(VideoError::DeviceFormat {
                    device: device.to_path_buf(),
                    detail: format!("the driver switched to {} after negotiation", got.fourcc),
                });
            };
            if got.width == 0 || got.height == 0 || got.width > 8192 || got.height > 8192 {
                return Err(VideoError::DeviceFormat {
                    device: device.to_path_buf(),
                    detail: format!(
                        "the driver reports an unusable size {}x{}",
                        got.width, got.height
                    ),
                });
            }
            let color = YuvColor {
                matrix: match got.colorspace {
                    Colorspace::Rec709 => YuvMatrix::Bt709,
                    _ => YuvMatrix::Bt601,
                },
                range: match (got.quantization, got.colorspace) {
                    (Quantization::FullRange, _) | (Quantization::Default, Colorspace::JPEG) => {
                        YuvRange::Full
                    }
                    _ => YuvRange::Limited,
                },
            };
            let mut stream = Stream::with_buffers(&dev, Type::VideoCapture, 4)
                .map_err(|e| open_error(device, "allocate capture buffers", e))?;
            stream.set_timeout(FRAME_TIMEOUT);
            stream
                .start()
                .map_err(|e| open_error(device, "start streaming", e))?;
            let format = CameraFormat {
                width: got.width,
                height: got.height,
                pixel_format,
                fps: rate,
                stride: got.stride.max(got.width * 2),
            };
            log::info!(
                "camera {}: asked {width}x{height} at {fps} fps, got {}x{} {} at {}",
                device.display(),
                format.width,
                format.height,
                format.pixel_format,
                rate.map(|r| r.to_string())
                    .unwrap_or_else(|| "an unreported rate".into())
            );
            Ok(CameraImpl {
                stream: Some(stream),
                _dev: dev,
                device: device.to_path_buf(),
                format,
                color,
                first_us: None,
                started: None,
                frames: 0,
                lost: false,
            })
        }

        pub(super) fn device(&self) -> &Path {
            &self.device
        }

        pub(super) fn format(&self) -> CameraFormat {
            self.format
        }

        fn lose(&mut self) -> VideoError {
            self.lost = true;
            self.shutdown();
            VideoError::DeviceLost {
                device: self.device.clone(),
                frames: self.frames,
            }
        }

        /// Stops streaming; if the driver refuses in a way `v4l`'s destructor would panic on,
        /// the stream is leaked instead (a few mapped buffers) so that no panic escapes.
        fn shutdown(&mut self) {
            if let Some(mut stream) = self.stream.take() {
                match stream.stop() {
                    Ok(()) => drop(stream),
                    Err(e) if e.raw_os_error() == Some(ENODEV) => drop(stream),
                    Err(_) => std::mem::forget(stream),
                }
            }
        }

        pub(super) fn next_frame(&mut self) -> Result<Option<Frame>, VideoError> {
            if self.lost {
                return Ok(None);
            }
            let mut bad = 0;
            loop {
                let Some(stream) = self.stream.as_mut() else {
                    return Ok(None);
                };
                let (data, meta) = match CaptureStream::next(stream) {
                    Ok((data, meta)) => (data, *meta),
                    Err(e) => {
                        return Err(match e.raw_os_error() {
                            Some(ENODEV) | Some(ENXIO) => self.lose(),
                            _ if e.kind() == io::ErrorKind::TimedOut => VideoError::Device {
                                device: self.device.clone(),
                                action: "receive a frame within 5 s",
                                source: e,
                            },
                            _ => VideoError::Device {
                                device: self.device.clone(),
                                action: "receive a frame",
                                source: e,
                            },
                        })
                    }
                };
                let used = (meta.bytesused as usize).min(data.len());
                let payload = &data[..used];
                let mut rgba = Vec::new();
                let f = self.format;
                let ok = !meta.flags.contains(BufferFlags::ERROR)
                    && match f.pixel_format {
                        CameraPixelFormat::Yuyv => yuyv_to_rgba(
                            payload,
                            f.width as usize,
                            f.height as usize,
                            f.stride as usize,
                            self.color,
                            &mut rgba,
                        ),
                        CameraPixelFormat::Mjpeg => {
                            decode_mjpeg(payload, f.width, f.height, &mut rgba)
                        }
                    };
                if !ok {
                    bad += 1;
                    if bad >= MAX_BAD_FRAMES {
                        return Err(VideoError::DeviceFormat {
                            device: self.device.clone(),
                            detail: format!("{bad} corrupt frames in a row"),
                        });
                    }
                    continue;
                }
                // `time_t` is i32 on 32-bit targets, i64 here.
                #[allow(clippy::useless_conversion)]
                let driver_us =
                    i64::from(meta.timestamp.sec) * 1_000_000 + i64::from(meta.timestamp.usec);
                // Drivers that leave the timestamp empty get the time of arrival instead.
                let us = if driver_us > 0 {
                    driver_us
                } else {
                    let start = *self.started.get_or_insert_with(Instant::now);
                    i64::try_from(start.elapsed().as_micros()).unwrap_or(i64::MAX)
                };
                let first = *self.first_us.get_or_insert(us);
                let index = self.frames;
                self.frames += 1;
                return Ok(Some(Frame {
                    index,
                    pts: Timestamp {
                        ticks: us - first,
                        timescale: 1_000_000,
                    },
                    width: f.width,
                    height: f.height,
                    rgba,
                }));
            }
        }
    }

    impl Drop for CameraImpl {
        fn drop(&mut self) {
            self.shutdown();
        }
    }

    /// Decodes one MJPEG frame of the negotiated size into RGBA8; `false` when it is damaged.
    fn decode_mjpeg(jpeg: &[u8], width: u32, height: u32, out: &mut Vec<u8>) -> bool {
        use zune_jpeg::zune_core::bytestream::ZCursor;
        use zune_jpeg::zune_core::colorspace::ColorSpace;
        use zune_jpeg::zune_core::options::DecoderOptions;
        let options = DecoderOptions::default()
            .jpeg_set_out_colorspace(ColorSpace::RGBA)
            .set_max_width(8192)
            .set_max_height(8192);
        let mut decoder = zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(jpeg), options);
        match decoder.decode() {
            Ok(pixels) if pixels.len() == width as usize * height as usize * 4 => {
                *out = pixels;
                true
            }
            _ => false,
        }
    }
}
