//! [`VideoReader`]: container/codec sniffing and decoding to RGBA8 frames.

use std::collections::VecDeque;
use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};

use openh264::decoder::{Decoder, DecoderConfig};
use openh264::formats::YUVSource;
use openh264::OpenH264API;

use crate::color::{i420_to_rgba, I420Planes, YuvColor};
use crate::h264::{self, AvcConfig, Sps};
use crate::mp4::{self, fourcc_str, CleanAperture, Sample, VideoTrack};
use crate::{Fps, Frame, FrameSource, Timestamp, VideoError};

/// Which decoder a [`VideoReader`] uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Backend {
    /// Built in: our MP4/MOV demuxer and OpenH264 (H.264 without B-frames).
    OpenH264,
    /// FFmpeg's libavformat/libavcodec (the `ffmpeg` feature): everything FFmpeg reads.
    Ffmpeg,
}

/// What a [`VideoReader`] found when it opened the file.
#[derive(Debug, Clone, PartialEq)]
pub struct VideoInfo {
    /// The file.
    pub path: PathBuf,
    /// Width of the frames in pixels.
    pub width: u32,
    /// Height of the frames in pixels.
    pub height: u32,
    /// Number of frames, when the container says.
    pub frame_count: Option<u64>,
    /// Nominal frame rate, when known (exact for constant-rate files).
    pub fps: Option<Fps>,
    /// Duration in seconds, when known.
    pub duration_s: Option<f64>,
    /// Container, e.g. `"MP4 (isom)"` or `"QuickTime MOV"`.
    pub container: String,
    /// Codec and profile, e.g. `"H.264 Constrained Baseline profile (profile_idc 66, level 3.0)"`.
    pub codec: String,
    /// The decoder in use.
    pub backend: Backend,
}

/// Decodes a video file into RGBA8 [`Frame`]s in presentation order.
///
/// ```no_run
/// # fn main() -> Result<(), pa_video::VideoError> {
/// let mut video = pa_video::VideoReader::open("take.mp4")?;
/// println!("{}x{} {:?}", video.info().width, video.info().height, video.info().fps);
/// while let Some(frame) = video.next_frame()? {
///     println!("frame {} at {:.3} s", frame.index, frame.pts.as_secs_f64());
/// }
/// # Ok(()) }
/// ```
///
/// After an error from [`next_frame`](VideoReader::next_frame) the reader may be called again:
/// it moves on to the next sample (a damaged frame is skipped, and the decoder picks up at
/// the next keyframe).
pub struct VideoReader {
    info: VideoInfo,
    inner: Inner,
}

impl std::fmt::Debug for VideoReader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VideoReader")
            .field("info", &self.info)
            .finish_non_exhaustive()
    }
}

enum Inner {
    Native(Box<NativeDecoder>),
    #[cfg(feature = "ffmpeg")]
    Ffmpeg(Box<crate::ffmpeg::FfmpegDecoder>),
}

/// The container kinds the sniffer tells apart.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Container {
    IsoBmff,
    Matroska,
    Avi,
    MpegTs,
    MpegPs,
    Flv,
    Ogg,
    Asf,
    AnnexB,
    Image(&'static str),
    Unknown,
}

impl Container {
    fn describe(self) -> &'static str {
        match self {
            Container::IsoBmff => "MP4/MOV",
            Container::Matroska => "Matroska/WebM",
            Container::Avi => "AVI",
            Container::MpegTs => "MPEG transport stream",
            Container::MpegPs => "MPEG program stream",
            Container::Flv => "Flash video (FLV)",
            Container::Ogg => "Ogg",
            Container::Asf => "ASF/WMV",
            Container::AnnexB => "a raw H.264/HEVC elementary stream",
            Container::Image(kind) => kind,
            Container::Unknown => "an unrecognised format",
        }
    }
}

fn sniff(head: &[u8]) -> Container {
    let at = |i: usize, s: &[u8]| head.get(i..i + s.len()) == Some(s);
    if head.len() >= 8 {
        const BOXES: [&[u8; 4]; 10] = [
            b"ftyp", b"moov", b"mdat", b"free", b"skip", b"wide", b"pnot", b"uuid", b"styp",
            b"sidx",
        ];
        if BOXES.iter().any(|b| &head[4..8] == *b) {
            return Container::IsoBmff;
        }
    }
    if at(0, &[0x1a, 0x45, 0xdf, 0xa3]) {
        Container::Matroska
    } else if at(0, b"RIFF") && at(8, b"AVI ") {
        Container::Avi
    } else if head.first() == Some(&0x47) && (head.len() < 189 || head[188] == 0x47) {
        Container::MpegTs
    } else if at(0, &[0, 0, 1, 0xba]) {
        Container::MpegPs
    } else if at(0, b"FLV") {
        Container::Flv
    } else if at(0, b"OggS") {
        Container::Ogg
    } else if at(0, &[0x30, 0x26, 0xb2, 0x75]) {
        Container::Asf
    } else if at(0, &[0, 0, 0, 1]) || at(0, &[0, 0, 1]) {
        Container::AnnexB
    } else if at(0, &[0x89, b'P', b'N', b'G']) {
        Container::Image("a PNG image")
    } else if at(0, &[0xff, 0xd8, 0xff]) {
        Container::Image("a JPEG image")
    } else if at(0, b"GIF8") {
        Container::Image("a GIF image")
    } else if at(0, b"II*\0") || at(0, b"MM\0*") {
        Container::Image("a TIFF image")
    } else {
        Container::Unknown
    }
}

/// A human name for an MP4 sample entry's codec.
fn codec_name(fourcc: &mp4::FourCc) -> String {
    let name = match fourcc {
        b"avc1" | b"avc2" | b"avc3" | b"avc4" => "H.264",
        b"hvc1" | b"hev1" => "HEVC/H.265",
        b"dvh1" | b"dvhe" => "Dolby Vision (HEVC)",
        b"av01" => "AV1",
        b"vp08" => "VP8",
        b"vp09" => "VP9",
        b"mp4v" => "MPEG-4 Part 2",
        b"jpeg" | b"mjpa" | b"mjpb" | b"mjp2" => "Motion JPEG",
        b"apch" | b"apcn" | b"apcs" | b"apco" | b"ap4h" | b"ap4x" => "Apple ProRes",
        b"s263" | b"h263" => "H.263",
        b"encv" => "encrypted video",
        _ => "an unknown codec",
    };
    format!("{name} ('{}')", fourcc_str(fourcc))
}

/// Most macroblocks a frame may have for the built-in decoder (H.264 level 5.2).
const MAX_NATIVE_MBS: u64 = 36_864;

impl VideoReader {
    /// Opens `path`, choosing the decoder automatically: the built-in one when it can decode
    /// the stream, FFmpeg otherwise (with the `ffmpeg` feature).
    pub fn open(path: impl AsRef<Path>) -> Result<VideoReader, VideoError> {
        Self::open_with(path, None)
    }

    /// Opens `path` with a given decoder (`None` = automatic). Asking for
    /// [`Backend::Ffmpeg`] in a build without the `ffmpeg` feature returns
    /// [`VideoError::FeatureDisabled`].
    pub fn open_with(
        path: impl AsRef<Path>,
        backend: Option<Backend>,
    ) -> Result<VideoReader, VideoError> {
        let path = path.as_ref();
        // Regular files only: a FIFO or a device would block or never end.
        let mut file = pa_io::open_regular(path)
            .map_err(|e| VideoError::io(path, "open", std::io::Error::from(e)))?;
        let len = file
            .metadata()
            .map_err(|e| VideoError::io(path, "read", e))?
            .len();
        if len == 0 {
            return Err(VideoError::corrupt(path, "the file is empty"));
        }
        if backend == Some(Backend::Ffmpeg) {
            drop(file);
            return open_ffmpeg(path);
        }
        let mut head = vec![0u8; len.min(256) as usize];
        file.read_exact(&mut head)
            .map_err(|e| VideoError::io(path, "read", e))?;
        let container = sniff(&head);
        let native = match container {
            Container::IsoBmff => open_native(file, len, path),
            Container::Image(_) => {
                return Err(VideoError::UnsupportedContainer {
                    path: path.to_path_buf(),
                    container: container.describe().to_string(),
                    hint: "; a still is read as part of a folder of stills, not as a video".into(),
                })
            }
            _ => Err(VideoError::UnsupportedContainer {
                path: path.to_path_buf(),
                container: container.describe().to_string(),
                hint: if cfg!(feature = "ffmpeg") {
                    "; open it with the FFmpeg backend".into()
                } else {
                    "; rebuild with `--features ffmpeg` to read it through FFmpeg".into()
                },
            }),
        };
        match native {
            Ok(reader) => Ok(reader),
            Err(
                e @ (VideoError::NeedsFeature { .. } | VideoError::UnsupportedContainer { .. }),
            ) if backend.is_none() && cfg!(feature = "ffmpeg") => {
                log::info!(
                    "{}: built-in decoder cannot read it ({e}); using FFmpeg",
                    path.display()
                );
                open_ffmpeg(path)
            }
            Err(e) => Err(e),
        }
    }

    /// What was found when opening.
    pub fn info(&self) -> &VideoInfo {
        &self.info
    }

    /// The next frame in presentation order, `Ok(None)` at the end.
    pub fn next_frame(&mut self) -> Result<Option<Frame>, VideoError> {
        match &mut self.inner {
            Inner::Native(d) => d.next_frame(),
            #[cfg(feature = "ffmpeg")]
            Inner::Ffmpeg(d) => d.next_frame(),
        }
    }
}

impl Iterator for VideoReader {
    type Item = Result<Frame, VideoError>;
    fn next(&mut self) -> Option<Self::Item> {
        self.next_frame().transpose()
    }
}

impl FrameSource for VideoReader {
    fn next_frame(&mut self) -> Result<Option<Frame>, VideoError> {
        VideoReader::next_frame(self)
    }
    fn frame_size(&self) -> (u32, u32) {
        (self.info.width, self.info.height)
    }
    fn fps(&self) -> Option<Fps> {
        self.info.fps
    }
    fn describe(&self) -> String {
        let i = &self.info;
        format!(
            "{}: {}x{} {}, {} in {}{}",
            i.path.display(),
            i.width,
            i.height,
            i.fps
                .map(|f| format!("{f} fps"))
                .unwrap_or_else(|| "unknown fps".into()),
            i.codec,
            i.container,
            match i.backend {
                Backend::OpenH264 => "",
                Backend::Ffmpeg => " (FFmpeg)",
            }
        )
    }
}

#[cfg(feature = "ffmpeg")]
fn open_ffmpeg(path: &Path) -> Result<VideoReader, VideoError> {
    let (decoder, info) = crate::ffmpeg::FfmpegDecoder::open(path)?;
    Ok(VideoReader {
        info,
        inner: Inner::Ffmpeg(Box::new(decoder)),
    })
}

#[cfg(not(feature = "ffmpeg"))]
fn open_ffmpeg(path: &Path) -> Result<VideoReader, VideoError> {
    Err(VideoError::FeatureDisabled {
        what: format!("decoding {} through FFmpeg", path.display()),
        feature: "ffmpeg",
    })
}

/// Frame rate of a track from its presentation times: exact when every frame lasts the same.
fn track_fps(track: &VideoTrack) -> (Option<Fps>, Option<f64>) {
    let n = track.samples.len();
    if n < 2 {
        return (None, None);
    }
    let mut pts: Vec<i64> = track.samples.iter().map(|s| s.pts).collect();
    pts.sort_unstable();
    let d0 = pts[1] - pts[0];
    let constant = d0 > 0 && pts.windows(2).all(|w| w[1] - w[0] == d0);
    let span = (pts[n - 1] - pts[0]) as f64 / f64::from(track.timescale);
    let avg = span / (n - 1) as f64;
    let duration = Some(span + avg);
    if constant {
        if let Ok(d) = u32::try_from(d0) {
            let g = crate::gcd(track.timescale, d);
            if let Ok(f) = Fps::new(track.timescale / g, d / g) {
                return (Some(f), duration);
            }
        }
    }
    let fps = if avg > 0.0 {
        Fps::from_f64(1.0 / avg).ok()
    } else {
        None
    };
    (fps, duration)
}

fn open_native(mut file: File, len: u64, path: &Path) -> Result<VideoReader, VideoError> {
    let movie = mp4::read_movie(&mut file, len, path)?;
    let container = match movie.major_brand {
        Some(b) if &b == b"qt  " => "QuickTime MOV".to_string(),
        Some(b) => format!("MP4 ({})", fourcc_str(&b)),
        None => "MP4/MOV".to_string(),
    };
    let Some(track) = movie.video else {
        return Err(VideoError::Unsupported {
            path: path.to_path_buf(),
            detail: format!("the {container} file has no video track"),
        });
    };
    let needs = |codec: String, reason: &str| VideoError::NeedsFeature {
        path: path.to_path_buf(),
        codec,
        reason: reason.to_string(),
        feature: "ffmpeg",
    };
    let fourcc = track.entry.fourcc;
    if movie.fragmented {
        return Err(needs(
            codec_name(&fourcc),
            "fragmented MP4: frames are stored in movie fragments",
        ));
    }
    if !matches!(&fourcc, b"avc1" | b"avc3") {
        let mut codec = codec_name(&fourcc);
        if let Some(orig) = track.entry.original_format {
            codec = format!("{codec} of {}", codec_name(&orig));
        }
        return Err(needs(codec, "the built-in decoder handles H.264 only"));
    }
    if track.samples.is_empty() {
        return Err(VideoError::corrupt(path, "the video track has no frames"));
    }
    if track.multiple_entries {
        return Err(needs(
            codec_name(&fourcc),
            "the track switches between several stream configurations",
        ));
    }
    let avcc = track.entry.avcc.as_deref().ok_or_else(|| {
        VideoError::corrupt(path, "the H.264 sample entry has no 'avcC' configuration")
    })?;
    let config = AvcConfig::parse(avcc).map_err(|d| VideoError::corrupt(path, d.to_string()))?;
    let mut prefix = Vec::new();
    for set in config.sps.iter().chain(&config.pps) {
        prefix.extend_from_slice(&[0, 0, 0, 1]);
        prefix.extend_from_slice(set);
    }
    // avc3 may carry its parameter sets in the samples only: look in the first one.
    let sps_nal = match config.sps.first() {
        Some(s) => s.clone(),
        None => {
            let mut buf = Vec::new();
            mp4::read_sample(&mut file, &track.samples[0], &mut buf, path)?;
            let found = h264::split_length_prefixed(&buf, config.length_size)
                .filter_map(Result::ok)
                .find(|n| h264::nal_type(n) == Some(h264::NAL_SPS))
                .map(<[u8]>::to_vec);
            found.ok_or_else(|| {
                VideoError::corrupt(
                    path,
                    "no sequence parameter set in 'avcC' or the first frame",
                )
            })?
        }
    };
    let sps: Sps =
        h264::parse_sps(&sps_nal).map_err(|d| VideoError::corrupt(path, d.to_string()))?;
    let codec = sps.profile_name();
    if let Some(reason) = sps.native_limitation() {
        return Err(needs(codec, &reason));
    }
    if track.reordered {
        return Err(needs(
            codec,
            "B-frames: frames are stored out of presentation order ('ctts')",
        ));
    }
    let mbs = u64::from(sps.coded_width / 16) * u64::from(sps.coded_height / 16);
    if mbs > MAX_NATIVE_MBS {
        return Err(VideoError::TooLarge {
            path: path.to_path_buf(),
            width: u64::from(sps.width),
            height: u64::from(sps.height),
            limit: format!("{MAX_NATIVE_MBS} macroblocks (4096x2304) for the built-in decoder"),
        });
    }
    let clap = track.entry.clap;
    let (width, height) = clap
        .and_then(|c| c.crop(sps.width, sps.height))
        .map(|(_, _, w, h)| (w, h))
        .unwrap_or((sps.width, sps.height));
    let color = match sps.vui {
        Some(v) => YuvColor::from_vui(v.matrix, v.full_range, sps.height),
        None => YuvColor::unspecified_default(sps.height),
    };
    let (fps, duration_s) = track_fps(&track);
    let decoder = Decoder::with_api_config(OpenH264API::from_source(), DecoderConfig::new())
        .map_err(|e| VideoError::Decode {
            path: path.to_path_buf(),
            frame: 0,
            detail: e.to_string(),
        })?;
    let info = VideoInfo {
        path: path.to_path_buf(),
        width,
        height,
        frame_count: Some(track.samples.len() as u64),
        fps,
        duration_s,
        container,
        codec,
        backend: Backend::OpenH264,
    };
    let native = NativeDecoder {
        path: path.to_path_buf(),
        file,
        samples: track.samples,
        timescale: track.timescale,
        next_sample: 0,
        decoder,
        length_size: config.length_size,
        prefix,
        clap,
        color,
        sample_buf: Vec::new(),
        annex_b: Vec::new(),
        pending_pts: VecDeque::new(),
        out_index: 0,
        flushed: false,
        flushed_frames: VecDeque::new(),
    };
    Ok(VideoReader {
        info,
        inner: Inner::Native(Box::new(native)),
    })
}

/// The built-in path: our demuxer + OpenH264.
struct NativeDecoder {
    path: PathBuf,
    file: File,
    samples: Vec<Sample>,
    timescale: u32,
    next_sample: usize,
    decoder: Decoder,
    length_size: usize,
    /// SPS + PPS from `avcC`, Annex B, sent before every keyframe.
    prefix: Vec<u8>,
    clap: Option<CleanAperture>,
    color: YuvColor,
    sample_buf: Vec<u8>,
    annex_b: Vec<u8>,
    pending_pts: VecDeque<i64>,
    out_index: u64,
    flushed: bool,
    flushed_frames: VecDeque<Frame>,
}

/// A converted picture: width, height, RGBA8 pixels.
type Rgba = (u32, u32, Vec<u8>);

/// A decoded picture whose planes do not match its size.
#[derive(Debug, thiserror::Error)]
#[error("the decoder returned an inconsistent {width}x{height} picture")]
struct InconsistentPicture {
    width: usize,
    height: usize,
}

/// Converts a decoded picture to RGBA8, cropped to the clean aperture; `Err` names the size
/// of an inconsistent picture.
fn yuv_to_rgba(
    yuv: &impl YUVSource,
    clap: Option<CleanAperture>,
    color: YuvColor,
) -> Result<Rgba, InconsistentPicture> {
    let (w, h) = yuv.dimensions();
    let (ys, us, _) = yuv.strides();
    let planes = I420Planes {
        y: yuv.y(),
        u: yuv.u(),
        v: yuv.v(),
        y_stride: ys,
        uv_stride: us,
        width: w,
        height: h,
    };
    let crop = clap
        .and_then(|c| c.crop(w as u32, h as u32))
        .map(|(l, t, cw, ch)| (l as usize, t as usize, cw as usize, ch as usize))
        .unwrap_or((0, 0, w, h));
    let mut rgba = Vec::new();
    if !i420_to_rgba(&planes, crop, color, &mut rgba) {
        return Err(InconsistentPicture {
            width: w,
            height: h,
        });
    }
    Ok((crop.2 as u32, crop.3 as u32, rgba))
}

impl NativeDecoder {
    fn make_frame(&mut self, pts: i64, (width, height, rgba): Rgba) -> Frame {
        let index = self.out_index;
        self.out_index += 1;
        Frame {
            index,
            pts: Timestamp {
                ticks: pts,
                timescale: self.timescale,
            },
            width,
            height,
            rgba,
        }
    }

    fn next_frame(&mut self) -> Result<Option<Frame>, VideoError> {
        while self.next_sample < self.samples.len() {
            let i = self.next_sample;
            self.next_sample += 1;
            let sample = self.samples[i];
            mp4::read_sample(&mut self.file, &sample, &mut self.sample_buf, &self.path)?;
            self.annex_b.clear();
            if sample.sync {
                self.annex_b.extend_from_slice(&self.prefix);
            }
            for nal in h264::split_length_prefixed(&self.sample_buf, self.length_size) {
                let nal =
                    nal.map_err(|d| VideoError::corrupt(&self.path, format!("frame {i}: {d}")))?;
                if nal.is_empty() {
                    continue;
                }
                match h264::slice_type(nal) {
                    Some(1) => {
                        return Err(VideoError::NeedsFeature {
                            path: self.path.clone(),
                            codec: "H.264".into(),
                            reason: format!("B-frames (frame {i} is a B-frame)"),
                            feature: "ffmpeg",
                        })
                    }
                    Some(3) | Some(4) => {
                        return Err(VideoError::NeedsFeature {
                            path: self.path.clone(),
                            codec: "H.264 Extended profile".into(),
                            reason: format!("switching slices (SP/SI) in frame {i}"),
                            feature: "ffmpeg",
                        })
                    }
                    _ => {}
                }
                if h264::nal_type(nal) == Some(h264::NAL_SPS) {
                    if let Ok(sps) = h264::parse_sps(nal) {
                        if let Some(reason) = sps.native_limitation() {
                            return Err(VideoError::NeedsFeature {
                                path: self.path.clone(),
                                codec: sps.profile_name(),
                                reason,
                                feature: "ffmpeg",
                            });
                        }
                    }
                }
                self.annex_b.extend_from_slice(&[0, 0, 0, 1]);
                self.annex_b.extend_from_slice(nal);
            }
            self.pending_pts.push_back(sample.pts);
            let decoded = self.decoder.decode(&self.annex_b);
            match decoded {
                Err(e) => {
                    self.pending_pts.pop_back();
                    return Err(VideoError::Decode {
                        path: self.path.clone(),
                        frame: i as u64,
                        detail: e.to_string(),
                    });
                }
                Ok(None) => continue,
                Ok(Some(yuv)) => {
                    let converted = yuv_to_rgba(&yuv, self.clap, self.color);
                    let pts = self.pending_pts.pop_front().unwrap_or(sample.pts);
                    let converted = converted.map_err(|e| VideoError::Decode {
                        path: self.path.clone(),
                        frame: i as u64,
                        detail: e.to_string(),
                    })?;
                    return Ok(Some(self.make_frame(pts, converted)));
                }
            }
        }
        if !self.flushed {
            self.flushed = true;
            let (clap, color) = (self.clap, self.color);
            let converted: Vec<Result<Rgba, InconsistentPicture>> =
                match self.decoder.flush_remaining() {
                    Ok(frames) => frames
                        .iter()
                        .map(|yuv| yuv_to_rgba(yuv, clap, color))
                        .collect(),
                    Err(e) => {
                        return Err(VideoError::Decode {
                            path: self.path.clone(),
                            frame: self.samples.len() as u64,
                            detail: format!("flushing the decoder: {e}"),
                        })
                    }
                };
            for c in converted {
                let Some(pts) = self.pending_pts.pop_front() else {
                    break;
                };
                let c = c.map_err(|e| VideoError::Decode {
                    path: self.path.clone(),
                    frame: self.samples.len() as u64,
                    detail: e.to_string(),
                })?;
                let f = self.make_frame(pts, c);
                self.flushed_frames.push_back(f);
            }
        }
        Ok(self.flushed_frames.pop_front())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sniffing() {
        assert_eq!(sniff(b"\0\0\0\x18ftypisom\0\0\0\0"), Container::IsoBmff);
        assert_eq!(sniff(&[0x1a, 0x45, 0xdf, 0xa3, 1, 2]), Container::Matroska);
        assert_eq!(sniff(b"RIFF\0\0\0\0AVI LIST"), Container::Avi);
        assert_eq!(sniff(b"\x89PNG\r\n\x1a\n"), Container::Image("a PNG image"));
        assert_eq!(sniff(b"hello world"), Container::Unknown);
        assert_eq!(sniff(b""), Container::Unknown);
    }
}
