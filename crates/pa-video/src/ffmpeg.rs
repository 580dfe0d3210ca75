//! The `ffmpeg` feature: decoding through FFmpeg's libavformat/libavcodec (system libraries),
//! for everything the built-in decoder refuses: H.264 with B-frames, HEVC, other codecs and
//! containers. Frames come out in presentation order; 8-bit 4:2:0 pictures are converted to
//! RGBA8 by [`crate::color`] with the stream's signalled matrix and range (so both decoders
//! agree), other pixel formats (10-bit, 4:2:2, NV12...) are first converted to 8-bit 4:2:0 by
//! libswscale.

use std::path::{Path, PathBuf};

use ff::format::Pixel;
use ff::software::scaling;
use ff::util::color::{Range, Space};
use ffmpeg_next as ff;

use crate::color::{i420_to_rgba, I420Planes, YuvColor, YuvMatrix, YuvRange};
use crate::reader::{Backend, VideoInfo};
use crate::{Fps, Frame, Timestamp, VideoError};

/// Largest frame the FFmpeg path accepts.
const MAX_SIDE: u32 = 8192;

pub(crate) struct FfmpegDecoder {
    path: PathBuf,
    input: ff::format::context::Input,
    decoder: ff::decoder::Video,
    stream_index: usize,
    time_base: (i64, u32),
    start: i64,
    scaler: Option<(Pixel, u32, u32, Scaler)>,
    frame: ff::frame::Video,
    converted: ff::frame::Video,
    eof_sent: bool,
    out_index: u64,
    packets_sent: u64,
}

/// A libswscale context that may move to another thread with its reader.
struct Scaler(scaling::Context);

// SAFETY: an SwsContext holds no thread-local state and is only ever used through `&mut`
// by the one decoder that owns it, so moving it between threads is sound (FFmpeg documents
// contexts as usable from any thread, one at a time).
#[allow(unsafe_code)] // FFI: the ffmpeg-next context type is not `Send` by itself.
unsafe impl Send for Scaler {}

fn rational_fps(r: ff::Rational) -> Option<Fps> {
    let (n, d) = (r.numerator(), r.denominator());
    if n <= 0 || d <= 0 {
        return None;
    }
    Fps::new(u32::try_from(n).ok()?, u32::try_from(d).ok()?)
        .ok()
        .or_else(|| Fps::from_f64(f64::from(n) / f64::from(d)).ok())
}

impl FfmpegDecoder {
    pub(crate) fn open(path: &Path) -> Result<(FfmpegDecoder, VideoInfo), VideoError> {
        let fail = |detail: String| VideoError::Decode {
            path: path.to_path_buf(),
            frame: 0,
            detail,
        };
        ff::init().map_err(|e| fail(format!("FFmpeg failed to initialise: {e}")))?;
        // FFmpeg's own console chatter (probing warnings) stays quiet: its errors reach the
        // caller as typed errors.
        ff::util::log::set_level(ff::util::log::Level::Fatal);
        let input = ff::format::input(path).map_err(|e| VideoError::UnsupportedContainer {
            path: path.to_path_buf(),
            container: "a format FFmpeg cannot read".into(),
            hint: format!(" ({e})"),
        })?;
        let container = input.format().description().to_string();
        let stream = input
            .streams()
            .best(ff::media::Type::Video)
            .ok_or_else(|| VideoError::Unsupported {
                path: path.to_path_buf(),
                detail: format!("the {container} file has no video stream"),
            })?;
        let stream_index = stream.index();
        let tb = stream.time_base();
        let time_base = (
            i64::from(tb.numerator().max(1)),
            u32::try_from(tb.denominator()).unwrap_or(1).max(1),
        );
        let start = match stream.start_time() {
            i64::MIN => 0,
            s => s,
        };
        let fps = rational_fps(stream.avg_frame_rate()).or_else(|| rational_fps(stream.rate()));
        let frame_count = u64::try_from(stream.frames()).ok().filter(|&n| n > 0);
        let duration_s = match stream.duration() {
            d if d > 0 => Some(d as f64 * time_base.0 as f64 / f64::from(time_base.1)),
            _ => None,
        };
        let context = ff::codec::context::Context::from_parameters(stream.parameters())
            .map_err(|e| fail(format!("cannot set up the decoder: {e}")))?;
        let codec_id = context.id();
        let decoder = context
            .decoder()
            .video()
            .map_err(|e| VideoError::Unsupported {
                path: path.to_path_buf(),
                detail: format!("this FFmpeg has no decoder for {codec_id:?}: {e}"),
            })?;
        let (width, height) = (decoder.width(), decoder.height());
        if width > MAX_SIDE || height > MAX_SIDE {
            return Err(VideoError::TooLarge {
                path: path.to_path_buf(),
                width: u64::from(width),
                height: u64::from(height),
                limit: format!("{MAX_SIDE}x{MAX_SIDE}"),
            });
        }
        let codec = match decoder.codec() {
            Some(c) => format!("{} ({:?})", c.description(), decoder.profile()),
            None => format!("{codec_id:?}"),
        };
        let info = VideoInfo {
            path: path.to_path_buf(),
            width,
            height,
            frame_count,
            fps,
            duration_s,
            container,
            codec,
            backend: Backend::Ffmpeg,
        };
        Ok((
            FfmpegDecoder {
                path: path.to_path_buf(),
                input,
                decoder,
                stream_index,
                time_base,
                start,
                scaler: None,
                frame: ff::frame::Video::empty(),
                converted: ff::frame::Video::empty(),
                eof_sent: false,
                out_index: 0,
                packets_sent: 0,
            },
            info,
        ))
    }

    fn decode_error(&self, detail: String) -> VideoError {
        VideoError::Decode {
            path: self.path.clone(),
            frame: self.packets_sent,
            detail,
        }
    }

    pub(crate) fn next_frame(&mut self) -> Result<Option<Frame>, VideoError> {
        loop {
            match self.decoder.receive_frame(&mut self.frame) {
                Ok(()) => return self.convert().map(Some),
                Err(ff::Error::Eof) => return Ok(None),
                Err(ff::Error::Other { errno }) if errno == ff::util::error::EAGAIN => {}
                Err(e) => return Err(self.decode_error(e.to_string())),
            }
            if self.eof_sent {
                return Ok(None);
            }
            // Feed packets until one of our stream is accepted (or the file ends).
            loop {
                let mut packet = ff::Packet::empty();
                match packet.read(&mut self.input) {
                    Ok(()) => {
                        if packet.stream() != self.stream_index {
                            continue;
                        }
                        self.packets_sent += 1;
                        if let Err(e) = self.decoder.send_packet(&packet) {
                            return Err(self.decode_error(e.to_string()));
                        }
                        break;
                    }
                    Err(ff::Error::Eof) => {
                        self.eof_sent = true;
                        if let Err(e) = self.decoder.send_eof() {
                            return Err(self.decode_error(e.to_string()));
                        }
                        break;
                    }
                    Err(e) => return Err(self.decode_error(format!("reading the file: {e}"))),
                }
            }
        }
    }

    fn convert(&mut self) -> Result<Frame, VideoError> {
        let (w, h) = (self.frame.width(), self.frame.height());
        if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
            return Err(VideoError::TooLarge {
                path: self.path.clone(),
                width: u64::from(w),
                height: u64::from(h),
                limit: format!("{MAX_SIDE}x{MAX_SIDE}"),
            });
        }
        let format = self.frame.format();
        let mut range = match (self.frame.color_range(), format) {
            (Range::JPEG, _) | (_, Pixel::YUVJ420P) => YuvRange::Full,
            _ => YuvRange::Limited,
        };
        let matrix = match self.frame.color_space() {
            Space::BT709 => YuvMatrix::Bt709,
            Space::BT470BG | Space::SMPTE170M => YuvMatrix::Bt601,
            Space::Unspecified | Space::Reserved => YuvColor::unspecified_default(h).matrix,
            _ => YuvMatrix::Bt709,
        };
        let src = if matches!(format, Pixel::YUV420P | Pixel::YUVJ420P) {
            &self.frame
        } else {
            let rebuild = !matches!(&self.scaler, Some((f, sw, sh, _)) if *f == format && *sw == w && *sh == h);
            if rebuild {
                let ctx = scaling::Context::get(
                    format,
                    w,
                    h,
                    Pixel::YUV420P,
                    w,
                    h,
                    scaling::Flags::BILINEAR,
                )
                .map_err(|e| {
                    self.decode_error(format!("cannot convert {format:?} pictures: {e}"))
                })?;
                self.scaler = Some((format, w, h, Scaler(ctx)));
            }
            let Some((_, _, _, ctx)) = self.scaler.as_mut() else {
                return Err(self.decode_error("no pixel format converter".into()));
            };
            ctx.0
                .run(&self.frame, &mut self.converted)
                .map_err(|e| VideoError::Decode {
                    path: self.path.clone(),
                    frame: self.packets_sent,
                    detail: e.to_string(),
                })?;
            if format == Pixel::YUVJ422P || format == Pixel::YUVJ444P {
                range = YuvRange::Full;
            }
            &self.converted
        };
        let planes = I420Planes {
            y: src.data(0),
            u: src.data(1),
            v: src.data(2),
            y_stride: src.stride(0),
            uv_stride: src.stride(1),
            width: w as usize,
            height: h as usize,
        };
        let mut rgba = Vec::new();
        if !i420_to_rgba(
            &planes,
            (0, 0, w as usize, h as usize),
            YuvColor { matrix, range },
            &mut rgba,
        ) {
            return Err(
                self.decode_error(format!("FFmpeg returned an inconsistent {w}x{h} picture"))
            );
        }
        let pts = self.frame.timestamp().or(self.frame.pts()).unwrap_or(0);
        let ticks = (pts.saturating_sub(self.start)).saturating_mul(self.time_base.0);
        let index = self.out_index;
        self.out_index += 1;
        Ok(Frame {
            index,
            pts: Timestamp {
                ticks,
                timescale: self.time_base.1,
            },
            width: w,
            height: h,
            rgba,
        })
    }
}
