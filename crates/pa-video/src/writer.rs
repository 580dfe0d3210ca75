//! [`Mp4Writer`]: RGBA8 frames -> H.264 (OpenH264) -> MP4, written atomically.

use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use openh264::encoder::{
    BitRate, Encoder, EncoderConfig, FrameRate, IntraFramePeriod, QpRange, RateControlMode,
    UsageType, VuiConfig,
};
use openh264::formats::YUVSource;
use openh264::{OpenH264API, Timestamp as H264Timestamp};

use crate::color::{rgba_to_i420, YuvColor, I420};
use crate::h264::{self, AvcConfig};
use crate::mp4::{build_moov, TrackLayout};
use crate::{Fps, VideoError};

/// How the encoder spends bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RateControl {
    /// Aim at an average bitrate (bits per second); quality varies with the content.
    Bitrate {
        /// Target bits per second.
        bps: u32,
    },
    /// Quality first: the quantiser stays within `qp_min..=qp_max` (0..=51; lower is better
    /// and larger) and the file is as large as the content needs.
    Quality {
        /// Lowest quantiser (best quality the encoder may use).
        qp_min: u8,
        /// Highest quantiser (worst quality it may fall to).
        qp_max: u8,
    },
}

impl Default for RateControl {
    /// `Quality { qp_min: 16, qp_max: 24 }`: visually transparent for rendered frames
    /// (see the crate README for measured PSNR and sizes).
    fn default() -> Self {
        RateControl::Quality {
            qp_min: 16,
            qp_max: 24,
        }
    }
}

/// Settings of an [`Mp4Writer`].
#[derive(Debug, Clone, PartialEq)]
pub struct Mp4WriterOptions {
    /// Frame rate; frame `i` is presented at `i / fps` seconds.
    pub fps: Fps,
    /// Bitrate or quality.
    pub rate_control: RateControl,
    /// Frames between keyframes (IDR); `None` = one a second. Short intervals make seeking and
    /// scrubbing in editors fast at a small cost in size.
    pub keyframe_interval: Option<u32>,
    /// Replace an existing file at the path (otherwise [`VideoError::AlreadyExists`]).
    pub overwrite: bool,
}

impl Mp4WriterOptions {
    /// Defaults at the given frame rate: [`RateControl::default`], a keyframe a second, no
    /// overwriting.
    pub fn new(fps: Fps) -> Self {
        Mp4WriterOptions {
            fps,
            rate_control: RateControl::default(),
            keyframe_interval: None,
            overwrite: false,
        }
    }
}

/// What [`Mp4Writer::finish`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct Mp4Summary {
    /// The final path.
    pub path: PathBuf,
    /// Frames written.
    pub frames: u64,
    /// File size in bytes.
    pub bytes: u64,
    /// Duration in seconds.
    pub duration_s: f64,
}

/// Largest picture OpenH264 encodes (either orientation).
const MAX_LONG_SIDE: u32 = 3840;
const MAX_SHORT_SIDE: u32 = 2160;
/// The smallest side OpenH264 encodes (it fails inside the library below this).
pub const MIN_SIDE: u32 = 16;

static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes RGBA8 frames as an H.264 MP4.
///
/// The file is written under a temporary name in the destination folder
/// (`.NAME.<pid>.<n>.partial`) and moved to its final name by [`finish`](Mp4Writer::finish)
/// after an `fsync`: the final name never holds a half-written file. A writer dropped without
/// `finish` deletes its temporary file. Without [`Mp4WriterOptions::overwrite`], an existing
/// file is refused at [`create`](Mp4Writer::create), and if one appears while writing,
/// `finish` keeps the finished video under its temporary name and says so.
///
/// ```no_run
/// use pa_video::{Fps, Mp4Writer, Mp4WriterOptions};
/// # fn main() -> Result<(), pa_video::VideoError> {
/// let mut w = Mp4Writer::create("take.mp4", 1280, 720, Mp4WriterOptions::new(Fps::new(24, 1)?))?;
/// let frame = vec![128u8; 1280 * 720 * 4];
/// w.write_frame(&frame)?;
/// let summary = w.finish()?;
/// println!("{} frames, {} bytes", summary.frames, summary.bytes);
/// # Ok(()) }
/// ```
pub struct Mp4Writer {
    path: PathBuf,
    temp_path: PathBuf,
    file: Option<BufWriter<File>>,
    encoder: Encoder,
    options: Mp4WriterOptions,
    width: u32,
    height: u32,
    coded: (u32, u32),
    timescale: u32,
    frame_ticks: u32,
    yuv: I420,
    bitstream: Vec<u8>,
    sample: Vec<u8>,
    sps: Option<Vec<u8>>,
    pps: Option<Vec<u8>>,
    sizes: Vec<u32>,
    offsets: Vec<u64>,
    sync: Vec<u32>,
    durations: Vec<(u32, u32)>,
    mdat_start: u64,
    pos: u64,
    frames_in: u64,
    done: bool,
}

impl std::fmt::Debug for Mp4Writer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Mp4Writer")
            .field("path", &self.path)
            .field("temp_path", &self.temp_path)
            .field("size", &(self.width, self.height))
            .field("options", &self.options)
            .field("frames", &self.frames_in)
            .finish_non_exhaustive()
    }
}

struct YuvView<'a>(&'a I420);

impl YUVSource for YuvView<'_> {
    fn dimensions(&self) -> (usize, usize) {
        (self.0.width, self.0.height)
    }
    fn strides(&self) -> (usize, usize, usize) {
        (self.0.width, self.0.width / 2, self.0.width / 2)
    }
    fn y(&self) -> &[u8] {
        &self.0.y
    }
    fn u(&self) -> &[u8] {
        &self.0.u
    }
    fn v(&self) -> &[u8] {
        &self.0.v
    }
}

fn temp_path_for(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    path.with_file_name(format!(".{name}.{}.{n}.partial", std::process::id()))
}

impl Mp4Writer {
    /// Whether H.264 output of `width` x `height` can be written: between
    /// [`MIN_SIDE`]x[`MIN_SIDE`] (OpenH264 rejects smaller frames) and the level's maximum.
    /// Callers check this before a long take, not after it.
    pub fn check_frame_size(width: u32, height: u32) -> Result<(), VideoError> {
        let coded = (width + (width & 1), height + (height & 1));
        if width < MIN_SIDE
            || height < MIN_SIDE
            || coded.0.max(coded.1) > MAX_LONG_SIDE
            || coded.0.min(coded.1) > MAX_SHORT_SIDE
        {
            return Err(VideoError::InvalidSetting {
                name: "frame size",
                value: format!("{width}x{height}"),
                reason: format!(
                    "H.264 output must be between {MIN_SIDE}x{MIN_SIDE} and \
                     {MAX_LONG_SIDE}x{MAX_SHORT_SIDE} (either orientation)"
                ),
            });
        }
        Ok(())
    }

    /// Creates the temporary file and the encoder for `width x height` frames (16x16 to
    /// 3840x2160 in either orientation; odd sizes are padded to even for coding and cropped
    /// back on display, see the crate docs).
    pub fn create(
        path: impl AsRef<Path>,
        width: u32,
        height: u32,
        options: Mp4WriterOptions,
    ) -> Result<Mp4Writer, VideoError> {
        let path = path.as_ref().to_path_buf();
        Self::check_frame_size(width, height)?;
        let coded = (width + (width & 1), height + (height & 1));
        if let RateControl::Quality { qp_min, qp_max } = options.rate_control {
            if qp_min > qp_max || qp_max > 51 {
                return Err(VideoError::InvalidSetting {
                    name: "quality",
                    value: format!("qp {qp_min}..={qp_max}"),
                    reason: "need qp_min <= qp_max <= 51".into(),
                });
            }
        }
        if let RateControl::Bitrate { bps } = options.rate_control {
            if !(10_000..=i32::MAX as u32).contains(&bps) {
                return Err(VideoError::InvalidSetting {
                    name: "bitrate",
                    value: bps.to_string(),
                    reason: "must be at least 10,000 bits per second".into(),
                });
            }
        }
        if options.keyframe_interval == Some(0) {
            return Err(VideoError::InvalidSetting {
                name: "keyframe interval",
                value: "0".into(),
                reason: "must be at least 1 frame".into(),
            });
        }
        if !options.overwrite && path.exists() {
            return Err(VideoError::AlreadyExists {
                path,
                kept: String::new(),
            });
        }
        if path.file_name().is_none() {
            return Err(VideoError::InvalidSetting {
                name: "output path",
                value: path.display().to_string(),
                reason: "needs a file name".into(),
            });
        }

        let fps = options.fps;
        let (timescale, frame_ticks) = fps.mp4_timebase();
        let keyframes = options
            .keyframe_interval
            .unwrap_or_else(|| (fps.as_f64().round() as u32).max(1));
        let mut config = EncoderConfig::new()
            .max_frame_rate(FrameRate::from_hz(fps.as_f64() as f32))
            .skip_frames(false)
            .usage_type(UsageType::CameraVideoRealTime)
            .intra_frame_period(IntraFramePeriod::from_num_frames(keyframes))
            .num_threads(1)
            .vui(VuiConfig::bt709());
        config = match options.rate_control {
            RateControl::Bitrate { bps } => config
                .rate_control_mode(RateControlMode::Bitrate)
                .bitrate(BitRate::from_bps(bps)),
            RateControl::Quality { qp_min, qp_max } => {
                // A generous budget (2 bits per pixel) so that the quantiser, not the budget,
                // sets the quality.
                let budget = (f64::from(coded.0) * f64::from(coded.1) * fps.as_f64() * 2.0)
                    .clamp(100_000.0, f64::from(i32::MAX as u32))
                    as u32;
                config
                    .rate_control_mode(RateControlMode::Quality)
                    .bitrate(BitRate::from_bps(budget))
                    .qp(QpRange::new(qp_min, qp_max))
            }
        };
        let mut encoder =
            Encoder::with_api_config(OpenH264API::from_source(), config).map_err(|e| {
                VideoError::Encode {
                    path: path.clone(),
                    frame: 0,
                    detail: e.to_string(),
                }
            })?;

        // OpenH264 prints a warning to stderr while initialising (frame skipping is off on
        // purpose: every frame of a take is kept); the wrapper lowers the trace level only after
        // initialising, so lower it before the first frame.
        let mut level = openh264_sys2::WELS_LOG_QUIET as u32;
        // SAFETY: the trace level is one of the options OpenH264 accepts before initialisation;
        // the pointer is to a live u32 for the duration of the call, which does not keep it.
        #[allow(unsafe_code)] // FFI: OpenH264's option setter has no safe wrapper.
        unsafe {
            encoder.raw_api().set_option(
                openh264_sys2::ENCODER_OPTION_TRACE_LEVEL,
                (&raw mut level).cast(),
            );
        }
        let temp_path = temp_path_for(&path);
        let file = OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&temp_path)
            .map_err(|e| VideoError::io(&temp_path, "create", e))?;
        let mut writer = Mp4Writer {
            path,
            temp_path,
            file: Some(BufWriter::with_capacity(1 << 20, file)),
            encoder,
            options,
            width,
            height,
            coded,
            timescale,
            frame_ticks,
            yuv: I420::default(),
            bitstream: Vec::new(),
            sample: Vec::new(),
            sps: None,
            pps: None,
            sizes: Vec::new(),
            offsets: Vec::new(),
            sync: Vec::new(),
            durations: Vec::new(),
            mdat_start: 0,
            pos: 0,
            frames_in: 0,
            done: false,
        };
        // ftyp, then mdat with a 64-bit size patched by finish().
        let mut head = Vec::with_capacity(48);
        head.extend_from_slice(&32u32.to_be_bytes());
        head.extend_from_slice(b"ftypisom");
        head.extend_from_slice(&0x200u32.to_be_bytes());
        head.extend_from_slice(b"isomiso2avc1mp41");
        writer.mdat_start = head.len() as u64;
        head.extend_from_slice(&1u32.to_be_bytes());
        head.extend_from_slice(b"mdat");
        head.extend_from_slice(&0u64.to_be_bytes());
        writer.write_bytes(&head)?;
        Ok(writer)
    }

    /// The final path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Frames written so far.
    pub fn frames(&self) -> u64 {
        self.frames_in
    }

    /// The frame size `(width, height)` this writer takes.
    pub fn frame_size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    fn write_bytes(&mut self, bytes: &[u8]) -> Result<(), VideoError> {
        let Some(file) = self.file.as_mut() else {
            return Err(VideoError::io(
                &self.temp_path,
                "write",
                std::io::Error::other("the writer is already finished"),
            ));
        };
        file.write_all(bytes)
            .map_err(|e| VideoError::io(&self.temp_path, "write", e))?;
        self.pos += bytes.len() as u64;
        Ok(())
    }

    fn push_duration(&mut self, ticks: u32) {
        match self.durations.last_mut() {
            Some((n, d)) if *d == ticks => *n += 1,
            _ => self.durations.push((1, ticks)),
        }
    }

    /// Encodes one RGBA8 frame (`width * height * 4` bytes, the size given to
    /// [`create`](Mp4Writer::create)).
    ///
    /// A wrong-sized frame is refused before anything is written, and the writer stays usable.
    /// After an encoder or disk error the file is incomplete: drop the writer (which deletes
    /// its temporary file).
    pub fn write_frame(&mut self, rgba: &[u8]) -> Result<(), VideoError> {
        let index = self.frames_in;
        let expected = self.width as usize * self.height as usize * 4;
        if rgba.len() != expected {
            return Err(VideoError::FrameSize {
                path: self.path.clone(),
                frame: index,
                width: self.width,
                height: self.height,
                expected,
                actual: rgba.len(),
            });
        }
        let encode_err = |path: &Path, detail: String| VideoError::Encode {
            path: path.to_path_buf(),
            frame: index,
            detail,
        };
        rgba_to_i420(
            rgba,
            self.width as usize,
            self.height as usize,
            YuvColor::BT709_LIMITED,
            &mut self.yuv,
        );
        let ms = (u128::from(index) * 1000 * u128::from(self.options.fps.den())
            / u128::from(self.options.fps.num())) as u64;
        self.bitstream.clear();
        {
            let encoded = self
                .encoder
                .encode_at(&YuvView(&self.yuv), H264Timestamp::from_millis(ms))
                .map_err(|e| encode_err(&self.path, e.to_string()))?;
            encoded.write_vec(&mut self.bitstream);
        }
        self.sample.clear();
        let mut sync = false;
        for nal in h264::split_annex_b(&self.bitstream) {
            match h264::nal_type(nal) {
                Some(h264::NAL_SPS) => match &self.sps {
                    None => self.sps = Some(nal.to_vec()),
                    Some(s) if s == nal => {}
                    Some(_) => {
                        return Err(encode_err(
                            &self.path,
                            "the encoder changed its sequence parameters mid-stream".into(),
                        ))
                    }
                },
                Some(h264::NAL_PPS) => match &self.pps {
                    None => self.pps = Some(nal.to_vec()),
                    Some(p) if p == nal => {}
                    Some(_) => {
                        return Err(encode_err(
                            &self.path,
                            "the encoder changed its picture parameters mid-stream".into(),
                        ))
                    }
                },
                // Access unit delimiters and filler data are not stored in MP4.
                Some(9) | Some(12) => {}
                Some(t) => {
                    if t == h264::NAL_IDR {
                        sync = true;
                    }
                    self.sample
                        .extend_from_slice(&(nal.len() as u32).to_be_bytes());
                    self.sample.extend_from_slice(nal);
                }
                None => {}
            }
        }
        self.frames_in += 1;
        if self.sample.is_empty() {
            // The encoder skipped the frame (rate control): the previous frame stays on screen
            // for its time. Frame skipping is disabled, so this is a safety net.
            let Some(&(n, d)) = self.durations.last() else {
                return Err(encode_err(
                    &self.path,
                    "the encoder produced no first frame".into(),
                ));
            };
            let longer = d + self.frame_ticks;
            if n == 1 {
                self.durations.pop();
            } else if let Some(last) = self.durations.last_mut() {
                last.0 -= 1;
            }
            self.durations.push((1, longer));
            return Ok(());
        }
        if self.sizes.is_empty() && !sync {
            return Err(encode_err(
                &self.path,
                "the first frame is not a keyframe".into(),
            ));
        }
        let offset = self.pos;
        let sample = std::mem::take(&mut self.sample);
        let written = self.write_bytes(&sample);
        self.sample = sample;
        written?;
        self.sizes.push(self.sample.len() as u32);
        self.offsets.push(offset);
        if sync {
            self.sync.push(self.sizes.len() as u32);
        }
        self.push_duration(self.frame_ticks);
        Ok(())
    }

    /// Writes the index (`moov`), syncs the file to disk and moves it to its final name.
    pub fn finish(mut self) -> Result<Mp4Summary, VideoError> {
        let (Some(sps), Some(pps)) = (self.sps.clone(), self.pps.clone()) else {
            return Err(VideoError::Encode {
                path: self.path.clone(),
                frame: self.frames_in,
                detail: "no frames were written; an empty video is not created".into(),
            });
        };
        let avcc =
            AvcConfig::from_parameter_sets(&sps, &pps).map_err(|detail| VideoError::Encode {
                path: self.path.clone(),
                frame: 0,
                detail: format!("the encoder's parameter sets are unusable: {detail}"),
            })?;
        let moov = build_moov(&TrackLayout {
            timescale: self.timescale,
            durations: &self.durations,
            sizes: &self.sizes,
            offsets: &self.offsets,
            sync: &self.sync,
            coded: self.coded,
            display: (self.width, self.height),
            avcc: &avcc,
        })
        .map_err(|e| VideoError::Encode {
            path: self.path.clone(),
            frame: self.frames_in,
            detail: e.to_string(),
        })?;
        let mdat_size = self.pos - self.mdat_start;
        self.write_bytes(&moov)?;
        let temp = self.temp_path.clone();
        let Some(buffered) = self.file.take() else {
            return Err(VideoError::io(
                &temp,
                "write",
                std::io::Error::other("already finished"),
            ));
        };
        let mut file = buffered
            .into_inner()
            .map_err(|e| VideoError::io(&temp, "write", e.into_error()))?;
        file.seek(SeekFrom::Start(self.mdat_start + 8))
            .and_then(|_| file.write_all(&mdat_size.to_be_bytes()))
            .and_then(|_| file.sync_all())
            .map_err(|e| VideoError::io(&temp, "write", e))?;
        drop(file);

        if self.options.overwrite {
            // Never swap a regular file in for a FIFO, a device node or a link.
            if let Err(e) = pa_io::check_replaceable(&self.path) {
                self.done = true; // keep the temporary file: it holds the take
                return Err(VideoError::io(
                    &self.path,
                    "replace",
                    std::io::Error::other(format!(
                        "{e} - the finished video was kept as {}",
                        temp.display()
                    )),
                ));
            }
            std::fs::rename(&temp, &self.path)
                .map_err(|e| VideoError::io(&self.path, "rename into place", e))?;
        } else {
            // A hard link refuses to replace an existing file atomically; filesystems without
            // hard links fall back to check-then-rename.
            match std::fs::hard_link(&temp, &self.path) {
                Ok(()) => {
                    let _ = std::fs::remove_file(&temp);
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    self.done = true; // keep the temporary file: it holds the take
                    return Err(VideoError::AlreadyExists {
                        path: self.path.clone(),
                        kept: format!(" - the finished video was kept as {}", temp.display()),
                    });
                }
                Err(_) => {
                    if self.path.exists() {
                        self.done = true;
                        return Err(VideoError::AlreadyExists {
                            path: self.path.clone(),
                            kept: format!(" - the finished video was kept as {}", temp.display()),
                        });
                    }
                    std::fs::rename(&temp, &self.path)
                        .map_err(|e| VideoError::io(&self.path, "rename into place", e))?;
                }
            }
        }
        self.done = true;
        if let Some(dir) = self.path.parent() {
            let dir = if dir.as_os_str().is_empty() {
                Path::new(".")
            } else {
                dir
            };
            if let Ok(d) = File::open(dir) {
                let _ = d.sync_all();
            }
        }
        let ticks: u64 = self
            .durations
            .iter()
            .map(|&(n, d)| u64::from(n) * u64::from(d))
            .sum();
        Ok(Mp4Summary {
            path: self.path.clone(),
            frames: self.frames_in,
            bytes: self.pos,
            duration_s: ticks as f64 / f64::from(self.timescale),
        })
    }
}

impl Drop for Mp4Writer {
    fn drop(&mut self) {
        if !self.done {
            self.file = None;
            let _ = std::fs::remove_file(&self.temp_path);
        }
    }
}
