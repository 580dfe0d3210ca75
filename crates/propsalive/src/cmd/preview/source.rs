//! Where the preview's camera frames come from: the built-in scene, a folder of stills, a
//! video file or a live camera. The last three are adapters over `pa_video::source`'s
//! sources (stills in natural order, the video's damaged-frame policy, the camera's loss);
//! the scene stays here because it renders. A source hands out its *newest* frame when asked
//! and keeps no queue of its own, so the preview never shows a stale frame. Each frame says
//! whether it starts a new sequence, and the preview resets the tracker before one (the
//! policy of `pa_video::source`: before each still; kept across video and camera frames).

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use pa_render::Renderer;
use pa_scene::Scene;
use pa_video::source::{self as vs, Next, Pixels, Source};

use super::draw::{fit_text, Image, WHITE};
use super::hud::text_scale;

/// What the preview will show with the next frame (a generated source renders the key prop
/// that is in front of its camera; stills follow the animation frame).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Want {
    pub anim_frame: u32,
    /// The animation frame of the key prop in front of the camera.
    pub key_frame: u32,
}

/// One camera frame.
pub struct SourceFrame {
    /// sRGB RGBA8, `width * height * 4` bytes.
    pub rgba8: Vec<u8>,
    pub width: u32,
    pub height: u32,
    /// When the frame was acquired: camera-to-screen latency starts here.
    pub acquired: Instant,
    /// Capture time, seconds (the tracker's filter uses it).
    pub time_s: f64,
    /// A short label for the log: the scene camera's frame, or the still's file name.
    pub label: String,
    /// True when the frame starts a new sequence: the tracker is reset before it (every
    /// still; the first frame of a video, a camera or the scene's path).
    pub starts_sequence: bool,
}

/// A source of camera frames.
pub trait FrameSource {
    /// One line saying what the source is.
    fn describe(&self) -> String;
    /// The newest frame.
    fn next_frame(&mut self, renderer: &mut Renderer, want: &Want) -> Result<SourceFrame>;
}

/// The built-in scene, generated on the fly: its handheld camera goes back and forth along
/// its path, one path frame per preview frame, filming the key prop in front of it.
pub struct SceneSource {
    pub scene: Scene,
    tick: u64,
}

impl SceneSource {
    pub fn new(scene: Scene) -> Self {
        Self { scene, tick: 0 }
    }
}

/// The path frame at a tick: 0, 1, .., n-1, n-2, .., 1, 0, 1, .. (no jump at the loop).
pub fn ping_pong(tick: u64, n: u32) -> u32 {
    if n <= 1 {
        return 0;
    }
    let period = 2 * (n as u64 - 1);
    let t = tick % period;
    if t < n as u64 {
        t as u32
    } else {
        (period - t) as u32
    }
}

impl FrameSource for SceneSource {
    fn describe(&self) -> String {
        let s = &self.scene.spec;
        format!(
            "built-in scene, {}x{}, handheld camera ({} path frames, back and forth), key poses at frames {:?}",
            s.width, s.height, s.frames, s.key_frames
        )
    }

    fn next_frame(&mut self, renderer: &mut Renderer, want: &Want) -> Result<SourceFrame> {
        let i = ping_pong(self.tick, self.scene.spec.frames);
        let fps = self.scene.spec.fps;
        let time_s = self.tick as f64 / fps as f64;
        self.tick += 1;
        let view = self.scene.camera_from_marker(i);
        let key_time_s = want.key_frame as f32 / fps;
        let f = self
            .scene
            .render_view(renderer, view, Some(key_time_s))
            .context("rendering the built-in scene")?;
        Ok(SourceFrame {
            width: f.width,
            height: f.height,
            rgba8: f.rgba8,
            acquired: Instant::now(),
            time_s,
            label: format!("scene camera {i}"),
            starts_sequence: self.tick == 1,
        })
    }
}

/// A folder of stills (a stop-motion take): animation frame `i` shows still `i` (the last
/// still past the end), as `propsalive run` pairs them.
pub struct StillsSource {
    stills: vs::StillsSource,
    width: u32,
    height: u32,
    fps: f32,
    /// The last still decoded (index, RGBA8).
    cache: Option<(usize, Vec<u8>)>,
    /// Stills already warned about.
    warned: HashSet<usize>,
}

impl StillsSource {
    /// `stills` in order; every still must be `width x height`.
    pub fn new(stills: Vec<PathBuf>, width: u32, height: u32, fps: f32) -> Result<Self> {
        if stills.is_empty() {
            bail!("no stills");
        }
        Ok(Self {
            stills: vs::StillsSource::new(stills),
            width,
            height,
            fps,
            cache: None,
            warned: HashSet::new(),
        })
    }

    /// The still shown with animation frame `anim_frame`.
    pub fn index_for(&self, anim_frame: u32) -> usize {
        (anim_frame as usize).min(self.stills.paths().len() - 1)
    }
}

impl FrameSource for StillsSource {
    fn describe(&self) -> String {
        format!(
            "{} still(s), {}x{}, still i = animation frame i",
            self.stills.paths().len(),
            self.width,
            self.height
        )
    }

    fn next_frame(&mut self, _renderer: &mut Renderer, want: &Want) -> Result<SourceFrame> {
        let i = self.index_for(want.anim_frame);
        let Some(frame) = self.stills.frame(i) else {
            bail!("no still {i}");
        };
        let Pixels::Still(path) = &frame.pixels else {
            bail!("still {i} is not a still");
        };
        let label = frame.name.clone();
        let rgba8 = match self.cache.take() {
            Some((k, data)) if k == i => data,
            _ => match load_still(path, self.width, self.height) {
                Ok(data) => data,
                Err(e) => {
                    // A bad still is shown as a grey frame saying why (and said once on
                    // stderr): the take goes on, as `propsalive run` skips it.
                    let msg = format!("{e:#}");
                    if self.warned.insert(i) {
                        errln!("warning: {msg}");
                    }
                    placeholder(self.width, self.height, &msg)
                }
            },
        };
        self.cache = Some((i, rgba8.clone()));
        Ok(SourceFrame {
            rgba8,
            width: self.width,
            height: self.height,
            acquired: Instant::now(),
            time_s: i as f64 / self.fps as f64,
            label,
            starts_sequence: frame.starts_sequence,
        })
    }
}

/// A video file (a take filmed as a video): animation frame `i` shows frame `i` of the video
/// (the last frame past the end), as `propsalive run` pairs them, through
/// [`vs::SeekableVideo`] (forward one frame a step; back re-reads from the start). A frame
/// the decoder rejects is a grey frame saying why.
pub struct VideoSource {
    video: vs::SeekableVideo,
    width: u32,
    height: u32,
    fps: f32,
    /// Frames already warned about.
    warned: HashSet<usize>,
}

impl VideoSource {
    /// Opens `path` (`pa-video`'s errors name the file, the codec and the feature).
    pub fn open(path: &Path, fps: f32) -> Result<Self> {
        let video = vs::SeekableVideo::open(path)?;
        let (width, height) = (video.info().width, video.info().height);
        Ok(Self {
            video,
            width,
            height,
            fps,
            warned: HashSet::new(),
        })
    }

    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
}

impl FrameSource for VideoSource {
    fn describe(&self) -> String {
        format!(
            "{}, frame i = animation frame i",
            self.video.video().describe()
        )
    }

    fn next_frame(&mut self, _renderer: &mut Renderer, want: &Want) -> Result<SourceFrame> {
        let i = self.video.clamp(want.anim_frame as usize);
        let vs::SeekFrame {
            index: i,
            starts_sequence,
            rgba: decoded,
        } = self.video.seek(i)?;
        let rgba8 = match decoded {
            Ok(data) if data.len() == self.width as usize * self.height as usize * 4 => data,
            Ok(_) => placeholder(self.width, self.height, "a frame of another size"),
            Err(e) => {
                let msg = e.message;
                if self.warned.insert(i) {
                    errln!("warning: {msg}");
                }
                placeholder(self.width, self.height, &msg)
            }
        };
        Ok(SourceFrame {
            rgba8,
            width: self.width,
            height: self.height,
            acquired: Instant::now(),
            time_s: i as f64 / self.fps as f64,
            label: format!("{} frame {i}", self.video.video().name()),
            starts_sequence,
        })
    }
}

/// A live camera (`pa-video`, the `v4l` feature): the frame the camera delivers next. When
/// the camera disappears the preview goes on showing a grey frame that says so (captures,
/// recordings and the keys still work; Q quits).
pub struct CameraSource {
    camera: vs::CameraSource,
    width: u32,
    height: u32,
    /// Why the camera is gone, once it is.
    lost: Option<String>,
    /// The last frame's capture time, seconds.
    last_time_s: f64,
}

impl CameraSource {
    pub fn new(camera: pa_video::Camera) -> Self {
        let f = camera.format();
        Self {
            camera: vs::CameraSource::new(camera),
            width: f.width,
            height: f.height,
            lost: None,
            last_time_s: 0.0,
        }
    }

    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
}

impl FrameSource for CameraSource {
    fn describe(&self) -> String {
        format!(
            "{}, live (the animation advances one frame per camera frame while playing)",
            self.camera.describe()
        )
    }

    fn next_frame(&mut self, _renderer: &mut Renderer, _want: &Want) -> Result<SourceFrame> {
        if self.lost.is_none() {
            match self.camera.next()? {
                Next::Frame(vs::SourceFrame {
                    pixels: Pixels::Frame(f),
                    starts_sequence,
                    ..
                }) if (f.width, f.height) == (self.width, self.height) => {
                    self.last_time_s = f.pts.as_secs_f64();
                    return Ok(SourceFrame {
                        rgba8: f.rgba,
                        width: f.width,
                        height: f.height,
                        acquired: Instant::now(),
                        time_s: f.pts.as_secs_f64(),
                        label: format!("camera frame {}", f.index),
                        starts_sequence,
                    });
                }
                Next::Frame(vs::SourceFrame {
                    pixels: Pixels::Frame(f),
                    ..
                }) => bail!(
                    "camera {}: a {}x{} frame, the stream is {}x{}",
                    self.camera.camera().device().display(),
                    f.width,
                    f.height,
                    self.width,
                    self.height
                ),
                Next::Frame(_) => bail!(
                    "camera {}: not a camera frame",
                    self.camera.camera().device().display()
                ),
                Next::End => {
                    self.lost = Some(format!(
                        "camera {} stopped delivering frames",
                        self.camera.camera().device().display()
                    ))
                }
                Next::Lost(e) => self.lost = Some(e.to_string()),
            }
            if let Some(msg) = &self.lost {
                errln!("warning: {msg}");
            }
        }
        let msg = self.lost.clone().unwrap_or_default();
        // Time goes on (the tracker's filter sees a frame without the marker).
        self.last_time_s += 1.0 / 30.0;
        Ok(SourceFrame {
            rgba8: placeholder(self.width, self.height, &msg),
            width: self.width,
            height: self.height,
            acquired: Instant::now(),
            time_s: self.last_time_s,
            label: "camera lost".into(),
            starts_sequence: false,
        })
    }
}

/// Reads a still as RGBA8, checking its size.
fn load_still(path: &Path, width: u32, height: u32) -> Result<Vec<u8>> {
    let img = pa_video::still::read_still(path, &Default::default())
        .with_context(|| format!("reading still {}", path.display()))?
        .to_rgba8();
    if img.dimensions() != (width, height) {
        bail!(
            "still {} is {}x{}, the take is {}x{}",
            path.display(),
            img.width(),
            img.height(),
            width,
            height
        );
    }
    Ok(img.into_raw())
}

/// A grey frame with a message on it.
fn placeholder(width: u32, height: u32, msg: &str) -> Vec<u8> {
    let mut img = Image::filled(width, height, [48, 48, 52]);
    let scale = text_scale(width);
    let max = width.saturating_sub(16 * scale);
    img.text(
        (8 * scale) as i64,
        (height / 2) as i64,
        fit_text(msg, max, scale),
        scale,
        WHITE,
    );
    img.rgba8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ping_pong_goes_back_and_forth() {
        let seq: Vec<u32> = (0..10).map(|t| ping_pong(t, 4)).collect();
        assert_eq!(seq, [0, 1, 2, 3, 2, 1, 0, 1, 2, 3]);
        assert_eq!(ping_pong(7, 1), 0);
        assert_eq!(ping_pong(7, 0), 0);
        assert!(ping_pong(u64::MAX, 49) < 49);
    }

    #[test]
    fn stills_follow_the_animation_frame() {
        let s = StillsSource::new(
            vec!["a.png".into(), "b.png".into(), "c.png".into()],
            4,
            4,
            24.0,
        )
        .unwrap();
        assert_eq!(s.index_for(0), 0);
        assert_eq!(s.index_for(2), 2);
        assert_eq!(s.index_for(40), 2);
        assert!(StillsSource::new(vec![], 4, 4, 24.0).is_err());
    }

    #[test]
    fn a_video_source_has_the_video_size() {
        // The seeking itself is `pa_video::source::SeekableVideo`'s (tested there).
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("take.mp4");
        let fps = pa_video::Fps::new(24, 1).unwrap();
        let mut w =
            pa_video::Mp4Writer::create(&path, 64, 48, pa_video::Mp4WriterOptions::new(fps))
                .unwrap();
        w.write_frame(&[40, 40, 40, 255].repeat(64 * 48)).unwrap();
        w.finish().unwrap();
        let s = VideoSource::open(&path, 24.0).unwrap();
        assert_eq!(s.size(), (64, 48));
        assert!(s.describe().ends_with(", frame i = animation frame i"));
        let err = VideoSource::open(&dir.path().join("missing.mp4"), 24.0)
            .err()
            .unwrap()
            .to_string();
        assert!(err.contains("missing.mp4"), "{err}");
    }

    #[test]
    fn a_bad_still_is_a_grey_frame_saying_why() {
        let dir = tempfile::tempdir().unwrap();
        let good = dir.path().join("s1.png");
        image::RgbaImage::from_pixel(64, 32, image::Rgba([200, 10, 10, 255]))
            .save(&good)
            .unwrap();
        let bad = dir.path().join("s2.png");
        std::fs::write(&bad, b"not a png").unwrap();
        let small = dir.path().join("s3.png");
        image::RgbaImage::from_pixel(8, 8, image::Rgba([0, 0, 0, 255]))
            .save(&small)
            .unwrap();
        let mut s = StillsSource::new(vec![good, bad, small], 64, 32, 24.0).unwrap();
        assert_eq!(
            &load_still(&s.stills.paths()[0], 64, 32).unwrap()[..4],
            &[200, 10, 10, 255]
        );
        let err = load_still(&s.stills.paths()[2], 64, 32)
            .unwrap_err()
            .to_string();
        assert!(err.contains("is 8x8, the take is 64x32"), "{err}");
        assert!(load_still(&s.stills.paths()[1], 64, 32).is_err());
        let grey = placeholder(64, 32, "oops");
        assert_eq!(grey.len(), 64 * 32 * 4);
        assert_eq!(&grey[..4], &[48, 48, 52, 255]);
        assert!(grey.chunks_exact(4).any(|p| p[..3] == WHITE));
        assert_eq!(s.index_for(1), 1);
        assert!(s.warned.insert(1));
        // The tracker policy: every still starts a new sequence.
        assert!((0..3).all(|i| s.stills.frame(i).unwrap().starts_sequence));
    }
}
