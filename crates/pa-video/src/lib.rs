//! Video in and out for Props Alive: read frames from a video file or a live camera, write
//! the composited frames as an MP4 (H.264).
//!
//! # What is where
//! * [`Mp4Writer`]: RGBA8 frames -> H.264 (OpenH264, built from source) -> MP4, written to a
//!   temporary file and moved into place by [`Mp4Writer::finish`].
//! * [`VideoReader`]: opens a file, sniffs container and codec, and yields decoded
//!   [`Frame`]s in presentation order. The default build decodes MP4/MOV with H.264 that has
//!   no B-frames (what [`Mp4Writer`] and most screen recorders and webcams write) through
//!   OpenH264. Anything else (HEVC, H.264 with B-frames as phones record it, Matroska, AVI,
//!   ...) is recognised and refused with [`VideoError::NeedsFeature`] /
//!   [`VideoError::UnsupportedContainer`], whose message names the file and the codec and says
//!   to rebuild with `--features ffmpeg`. With the `ffmpeg` feature those files are decoded
//!   through FFmpeg (system libraries).
//! * [`Camera`]: Video4Linux capture with the `v4l` feature (Linux): format negotiation,
//!   conversion to RGBA8, timestamps, and a distinct [`VideoError::DeviceLost`] when the
//!   camera disappears mid-take. Without the feature, [`Camera::open`] returns
//!   [`VideoError::FeatureDisabled`].
//! * [`FrameSource`]: the common "next frame" interface of files and cameras.
//! * [`source`]: the inputs of the commands: parsing an input (folder of stills, video file,
//!   camera), stills in natural order, and the stills, video and camera sources with one
//!   frame type that says whether a frame starts a new sequence (the tracker policy).
//!
//! # Conventions
//! * Frames are RGBA8, sRGB-encoded, row-major, `width * 4` bytes a row, no padding; alpha is
//!   255 on output and ignored on input.
//! * Y'CbCr conversion ([`color`]): the writer encodes **BT.709, limited range** and signals
//!   it in the H.264 VUI (colour primaries, transfer and matrix 1, `video_full_range_flag` 0),
//!   which is what players assume for HD and what phones record. The reader converts with
//!   whatever the stream signals (BT.601 or BT.709, limited or full range); a stream that
//!   signals nothing is taken as BT.709 from 720 lines up and BT.601 below, limited range.
//!   sRGB values are carried as they are (no transfer conversion), as every SDR pipeline does.
//! * Timestamps ([`Timestamp`]) are exact ticks of the stream's timescale: the writer's frame
//!   `i` is presented at `i * fps.den / fps.num` seconds.
//! * Odd frame sizes: H.264 4:2:0 can only code even sizes. The writer pads the right column
//!   and bottom row (by repetition), records the real size in `tkhd` and a `clap` (clean
//!   aperture) box, and the reader crops back, so a 321x241 video reads back as 321x241.
//! * Limits: the writer accepts up to 3840x2160 (OpenH264's limit, either orientation); the
//!   built-in decoder up to level 5.2's 36,864 macroblocks (4096x2304); FFmpeg up to
//!   8192x8192. See [`mp4`] for the demuxer's limits on hostile files.

pub mod camera;
pub mod color;
mod error;
#[cfg(feature = "ffmpeg")]
mod ffmpeg;
pub mod h264;
pub mod mp4;
mod reader;
pub mod source;
pub mod still;
mod writer;

pub use camera::{Camera, CameraFormat, CameraPixelFormat};
pub use error::VideoError;
pub use reader::{Backend, VideoInfo, VideoReader};
pub use writer::{Mp4Summary, Mp4Writer, Mp4WriterOptions, RateControl};

/// A frame rate as an exact fraction `num / den` frames per second (e.g. 24/1, 30000/1001).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Fps {
    num: u32,
    den: u32,
}

impl Fps {
    /// `num / den` frames per second, reduced. Allowed: 0.01 to 1000 fps, numerator and
    /// denominator up to 1,000,000.
    pub fn new(num: u32, den: u32) -> Result<Fps, VideoError> {
        let bad = |reason: &str| VideoError::InvalidSetting {
            name: "fps",
            value: format!("{num}/{den}"),
            reason: reason.to_string(),
        };
        if num == 0 || den == 0 {
            return Err(bad("numerator and denominator must be positive"));
        }
        if num > 1_000_000 || den > 1_000_000 {
            return Err(bad("numerator and denominator must be at most 1,000,000"));
        }
        let f = f64::from(num) / f64::from(den);
        if !(0.01..=1000.0).contains(&f) {
            return Err(bad("must be between 0.01 and 1000 frames per second"));
        }
        let g = gcd(num, den);
        Ok(Fps {
            num: num / g,
            den: den / g,
        })
    }

    /// From a decimal rate: integers exactly, NTSC rates (23.976, 29.97, 59.94...) as
    /// `n*1000/1001`, anything else to the nearest 1/1000 fps.
    pub fn from_f64(fps: f64) -> Result<Fps, VideoError> {
        if !fps.is_finite() || !(0.01..=1000.0).contains(&fps) {
            return Err(VideoError::InvalidSetting {
                name: "fps",
                value: fps.to_string(),
                reason: "must be between 0.01 and 1000 frames per second".into(),
            });
        }
        if (fps - fps.round()).abs() < 1e-6 {
            return Fps::new(fps.round() as u32, 1);
        }
        let ntsc = fps * 1.001;
        if (ntsc - ntsc.round()).abs() < 2e-3 {
            return Fps::new(ntsc.round() as u32 * 1000, 1001);
        }
        Fps::new((fps * 1000.0).round() as u32, 1000)
    }

    /// Numerator (frames).
    pub fn num(&self) -> u32 {
        self.num
    }

    /// Denominator (seconds).
    pub fn den(&self) -> u32 {
        self.den
    }

    /// As a float.
    pub fn as_f64(&self) -> f64 {
        f64::from(self.num) / f64::from(self.den)
    }

    /// The MP4 track timescale and per-frame duration the writer uses: `num * m` and
    /// `den * m`, with `m = 1000` for rates with a small numerator (24 fps -> 24000 / 1000) so
    /// that the timescale is fine enough for editors.
    pub fn mp4_timebase(&self) -> (u32, u32) {
        let m = if self.num < 1000 { 1000 } else { 1 };
        (self.num * m, self.den * m)
    }
}

impl std::fmt::Display for Fps {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.den == 1 {
            write!(f, "{}", self.num)
        } else {
            write!(f, "{}/{} ({:.3})", self.num, self.den, self.as_f64())
        }
    }
}

fn gcd(mut a: u32, mut b: u32) -> u32 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a.max(1)
}

/// A presentation time: `ticks / timescale` seconds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Timestamp {
    /// Ticks of the timescale (may be negative before an edit list's start).
    pub ticks: i64,
    /// Ticks per second (> 0).
    pub timescale: u32,
}

impl Timestamp {
    /// Seconds.
    pub fn as_secs_f64(&self) -> f64 {
        self.ticks as f64 / f64::from(self.timescale.max(1))
    }
}

/// One decoded or captured frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// 0-based index in presentation order (for a camera: frames delivered so far).
    pub index: u64,
    /// Presentation time (for a camera: since the first frame of the take).
    pub pts: Timestamp,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// RGBA8 pixels, sRGB, row-major, `width * height * 4` bytes.
    pub rgba: Vec<u8>,
}

/// A source of frames: a video file ([`VideoReader`]) or a camera ([`Camera`]).
pub trait FrameSource {
    /// The next frame; `Ok(None)` at the end of a file.
    ///
    /// A camera that disappears returns [`VideoError::DeviceLost`] once (check
    /// [`VideoError::is_source_lost`]: keep what was captured and end cleanly) and `Ok(None)`
    /// afterwards.
    fn next_frame(&mut self) -> Result<Option<Frame>, VideoError>;

    /// The frame size `(width, height)` frames will have.
    fn frame_size(&self) -> (u32, u32);

    /// The nominal frame rate, when known.
    fn fps(&self) -> Option<Fps>;

    /// A one-line description for logs: path or device, size, codec or pixel format.
    fn describe(&self) -> String;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn handles_can_move_to_another_thread() {
        fn send<T: Send>() {}
        send::<Mp4Writer>();
        send::<VideoReader>();
        send::<Frame>();
        send::<Camera>();
    }

    #[test]
    fn fps_parsing() {
        assert_eq!(
            Fps::from_f64(24.0).map(|f| (f.num(), f.den())).ok(),
            Some((24, 1))
        );
        assert_eq!(
            Fps::from_f64(29.97).map(|f| (f.num(), f.den())).ok(),
            Some((30000, 1001))
        );
        assert_eq!(
            Fps::from_f64(23.976).map(|f| (f.num(), f.den())).ok(),
            Some((24000, 1001))
        );
        assert_eq!(
            Fps::from_f64(12.5).map(|f| (f.num(), f.den())).ok(),
            Some((25, 2))
        );
        assert_eq!(
            Fps::new(48, 2).map(|f| (f.num(), f.den())).ok(),
            Some((24, 1))
        );
        assert!(Fps::new(0, 1).is_err());
        assert!(Fps::from_f64(f64::NAN).is_err());
        assert!(Fps::from_f64(5000.0).is_err());
        assert_eq!(
            Fps::new(24, 1).map(|f| f.mp4_timebase()).ok(),
            Some((24000, 1000))
        );
        assert_eq!(
            Fps::new(30000, 1001).map(|f| f.mp4_timebase()).ok(),
            Some((30000, 1001))
        );
    }
}
