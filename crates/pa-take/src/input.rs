//! The input of a take, frame after frame, in index order ([`TakeSource`]): a folder of
//! stills ([`TakeStills`]), a video file ([`TakeVideo`]) or a camera ([`TakeCamera`]) —
//! `pa_video::source`'s sources with the identity the log records (the `input` name and its
//! stamp) and, for a camera, every captured frame saved as `inputs/NNNNNN.png` before it is
//! processed. The run loop only sees [`TakeSource`], so it can be tested with a fake.

use std::collections::BTreeMap;
use std::path::PathBuf;

use pa_video::source::{
    CameraSource, Next as SourceNext, Pixels, Source, SourceFrame, StillsSource, VideoSource,
};
use pa_video::still::StillBudget;

use crate::{file_stamp, frame_name, write_durable, Plan, TakeError};

/// One input frame of a take: the source's frame (`pa_video::source`) with what the log
/// records.
#[derive(Debug)]
pub struct InputFrame {
    pub index: usize,
    /// What the log records as `input`.
    pub name: String,
    /// (bytes, mtime ns) the log records.
    pub stamp: (u64, u64),
    /// A still is read only if the frame is to be processed.
    pub pixels: Pixels,
}

/// What a source gives next.
#[derive(Debug)]
pub enum Next {
    Frame(InputFrame),
    /// No more frames.
    End,
    /// A live source disappeared (the message says so): keep the take, end cleanly.
    Lost(String),
}

/// The input of a take, frame after frame, in index order: a folder of stills, a video file,
/// or a camera (`pa_video::source`'s sources, with the identity the log records). The run
/// loop only sees this, so it can be tested with a fake.
// `len` is "when known" (an `Option`): an `is_empty` would say nothing more.
#[allow(clippy::len_without_is_empty)]
pub trait TakeSource {
    /// Frames the source holds, when known (a camera: `None`).
    fn len(&self) -> Option<usize>;
    /// The identity (`input` name, stamp) of frame `index`, when known without reading it:
    /// the run plans with it (which frames are done).
    fn identity(&self, index: usize) -> Option<(String, (u64, u64))>;
    /// True for a live source (its frames are new ones, appended to the take).
    fn live(&self) -> bool {
        false
    }
    fn next(&mut self) -> Result<Next, TakeError>;
}

/// The source's next frame, with its stamp: `None` at the end or when the source is lost.
fn next_of(source: &mut dyn Source) -> Result<Result<SourceFrame, Next>, TakeError> {
    Ok(match source.next()? {
        SourceNext::Frame(f) => Ok(f),
        SourceNext::End => Err(Next::End),
        SourceNext::Lost(e) => Err(Next::Lost(e.to_string())),
    })
}

/// A folder of stills: each still's file name and stamp is its identity.
pub struct TakeStills {
    source: StillsSource,
    stamps: Vec<(u64, u64)>,
}

impl TakeStills {
    /// The stills, in order, with their stamps read now.
    pub fn new(stills: Vec<PathBuf>) -> Result<Self, TakeError> {
        let stamps = stills
            .iter()
            .map(|p| file_stamp(p))
            .collect::<Result<_, _>>()?;
        Ok(Self {
            source: StillsSource::new(stills),
            stamps,
        })
    }
}

impl TakeSource for TakeStills {
    fn len(&self) -> Option<usize> {
        self.source.frame_count()
    }
    fn identity(&self, index: usize) -> Option<(String, (u64, u64))> {
        Some((self.source.name(index)?, *self.stamps.get(index)?))
    }
    fn next(&mut self) -> Result<Next, TakeError> {
        let f = match next_of(&mut self.source)? {
            Ok(f) => f,
            Err(next) => return Ok(next),
        };
        Ok(Next::Frame(InputFrame {
            index: f.index,
            stamp: self.stamps[f.index],
            name: f.name,
            pixels: f.pixels,
        }))
    }
}

/// A video file: frame `i` of the video (presentation order) is still `i`; the video file's
/// name and stamp are the identity of every frame.
pub struct TakeVideo<S: pa_video::FrameSource> {
    pub source: VideoSource<S>,
    pub stamp: (u64, u64),
}

impl<S: pa_video::FrameSource> TakeSource for TakeVideo<S> {
    fn len(&self) -> Option<usize> {
        self.source.frame_count()
    }
    fn identity(&self, index: usize) -> Option<(String, (u64, u64))> {
        match self.source.frame_count() {
            Some(n) if index < n => Some((self.source.name().to_string(), self.stamp)),
            _ => None,
        }
    }
    fn next(&mut self) -> Result<Next, TakeError> {
        let f = match next_of(&mut self.source)? {
            Ok(f) => f,
            Err(next) => return Ok(next),
        };
        Ok(Next::Frame(InputFrame {
            index: f.index,
            name: f.name,
            stamp: self.stamp,
            pixels: f.pixels,
        }))
    }
}

/// A live camera: every captured frame is saved as `inputs/NNNNNN.png` (atomically, before it
/// is processed) and appended to the take.
pub struct TakeCamera<S: pa_video::FrameSource> {
    pub source: CameraSource<S>,
    pub inputs_dir: PathBuf,
    pub next_index: usize,
}

impl<S: pa_video::FrameSource> TakeSource for TakeCamera<S> {
    fn len(&self) -> Option<usize> {
        None
    }
    fn identity(&self, _index: usize) -> Option<(String, (u64, u64))> {
        None
    }
    fn live(&self) -> bool {
        true
    }
    fn next(&mut self) -> Result<Next, TakeError> {
        let f = match next_of(&mut self.source)? {
            Ok(SourceFrame {
                pixels: Pixels::Frame(f),
                ..
            }) => f,
            Ok(_) => {
                return Err(TakeError::NotCameraFrame {
                    desc: self.source.describe(),
                })
            }
            Err(next) => return Ok(next),
        };
        let index = self.next_index;
        self.next_index += 1;
        let pa_video::Frame {
            index: captured,
            pts,
            width,
            height,
            rgba,
        } = f;
        let img = image::RgbaImage::from_raw(width, height, rgba).ok_or_else(|| {
            TakeError::CameraFrameBytes {
                desc: self.source.describe(),
                width,
                height,
            }
        })?;
        let img = image::DynamicImage::ImageRgba8(img);
        let name = format!("inputs/{}", frame_name(index));
        let path = self.inputs_dir.join(frame_name(index));
        let mut png = Vec::new();
        image::DynamicImage::ImageRgb8(img.to_rgb8())
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
        write_durable(&path, &png)?;
        let f = pa_video::Frame {
            index: captured,
            pts,
            width,
            height,
            rgba: img.into_rgba8().into_raw(),
        };
        let stamp = file_stamp(&path)?;
        Ok(Next::Frame(InputFrame {
            index,
            name,
            stamp,
            pixels: Pixels::Frame(f),
        }))
    }
}

/// A frame's pixels as an image, or why it cannot be used (the error's message is what the
/// log records after `unreadable: `).
pub fn decode_pixels(pixels: Pixels) -> Result<image::DynamicImage, TakeError> {
    match pixels {
        Pixels::Frame(f) => match image::RgbaImage::from_raw(f.width, f.height, f.rgba) {
            Some(img) => Ok(image::DynamicImage::ImageRgba8(img)),
            None => Err(TakeError::FrameBytes {
                width: f.width,
                height: f.height,
            }),
        },
        Pixels::Still(path) => {
            pa_video::still::read_still(&path, &StillBudget::default()).map_err(TakeError::Still)
        }
        Pixels::Unreadable(e) => Err(TakeError::Video(e)),
    }
}

impl crate::Take {
    /// The plan of every frame of `source` known in advance (of the first `limit`), and how
    /// many of them are to be processed (`None` when the source's length is unknown: a camera).
    pub fn plan_known(
        &self,
        source: &dyn TakeSource,
        limit: Option<usize>,
    ) -> (BTreeMap<usize, Plan>, Option<usize>) {
        let mut plans = BTreeMap::new();
        let known = source.len().map(|n| limit.map_or(n, |l| n.min(l)));
        if let Some(n) = known {
            for i in 0..n {
                if let Some((name, stamp)) = source.identity(i) {
                    plans.insert(i, self.plan(i, &name, stamp));
                }
            }
        }
        let todo = known.map(|_| {
            plans
                .values()
                .filter(|p| matches!(p, Plan::Process(_)))
                .count()
        });
        (plans, todo)
    }
}

/// Where the stills of a take come from, resolved (the files found, the video opened, the
/// camera opened); [`InputSource::open`] makes it the take's [`TakeSource`].
pub enum InputSource {
    Stills(Vec<PathBuf>),
    Video {
        reader: pa_video::VideoReader,
        path: PathBuf,
        stamp: (u64, u64),
    },
    Camera(pa_video::Camera),
}

impl InputSource {
    /// True for a camera.
    pub fn live(&self) -> bool {
        matches!(self, InputSource::Camera(_))
    }

    /// The take's source over this input. A camera numbers on after the take's last logged
    /// frame and every saved input ([`crate::camera_start_index`]); when a saved input is past
    /// the log (a capture cut short), the note to say comes back too.
    pub fn open(
        self,
        take: &crate::Take,
    ) -> Result<(Box<dyn TakeSource>, Option<String>), TakeError> {
        Ok(match self {
            InputSource::Stills(stills) => (Box::new(TakeStills::new(stills)?), None),
            InputSource::Video {
                reader,
                path,
                stamp,
            } => {
                let count = reader.info().frame_count.map(|c| c as usize);
                let source = TakeVideo {
                    source: VideoSource::new(reader, &path, count),
                    stamp,
                };
                (Box::new(source), None)
            }
            InputSource::Camera(camera) => {
                let next_index = crate::camera_start_index(take);
                let logged = take.entries.keys().next_back().map_or(0, |i| i + 1);
                let note = (next_index > logged).then(|| {
                    format!(
                        "note: {} holds captured frame(s) up to index {} that the log does not have (a capture cut short?): kept; this capture starts at {next_index}",
                        take.out.join("inputs").display(),
                        next_index - 1
                    )
                });
                let source = TakeCamera {
                    source: CameraSource::new(camera),
                    inputs_dir: take.out.join("inputs"),
                    next_index,
                };
                (Box::new(source), note)
            }
        })
    }
}

/// An input resolved for a take: its source, what one of its frames is called in messages
/// ("still" or "frame"), the input in words (for the summary), the take's size and what set
/// it (the first readable still, the video, the camera device), for messages.
pub struct ResolvedInput {
    pub source: InputSource,
    pub unit: &'static str,
    pub desc: String,
    pub width: u32,
    pub height: u32,
    pub first: String,
}

impl ResolvedInput {
    /// A folder of stills (`stills`, listed from `dir`, in order): the take's size is its
    /// first readable still's; none readable is an error.
    pub fn stills(dir: &std::path::Path, stills: Vec<PathBuf>) -> Result<Self, TakeError> {
        let (first, (width, height)) = first_readable_still(dir, &stills)?;
        Ok(Self {
            unit: "still",
            desc: format!("{} still(s) in {}", stills.len(), dir.display()),
            width,
            height,
            first: first.display().to_string(),
            source: InputSource::Stills(stills),
        })
    }

    /// A video file, opened (pa-video's errors name the file, the codec and the feature),
    /// with its stamp; the note (when its rate is not the shot's `shot_fps`) to say.
    pub fn video(path: PathBuf, shot_fps: f32) -> Result<(Self, Option<String>), TakeError> {
        let reader = pa_video::VideoReader::open(&path)?;
        let info = reader.info();
        let (width, height) = (info.width, info.height);
        let desc = pa_video::FrameSource::describe(&reader);
        let stamp = file_stamp(&path)?;
        let note = info.fps.and_then(|f| {
            ((f.as_f64() - shot_fps as f64).abs() > 1e-3 * f.as_f64()).then(|| {
                format!(
                    "note: {} runs at {f} fps and the shot at {} fps: frame i is still i (animation frame i / exposure), whatever the video's timing",
                    path.display(),
                    shot_fps
                )
            })
        });
        let first = path.display().to_string();
        let input = Self {
            source: InputSource::Video {
                reader,
                path,
                stamp,
            },
            unit: "frame",
            desc,
            width,
            height,
            first,
        };
        Ok((input, note))
    }

    /// A camera, opened, at `device`: the take's size is the format it answered with.
    pub fn camera(camera: pa_video::Camera, device: &std::path::Path) -> Self {
        let f = camera.format();
        Self {
            desc: pa_video::FrameSource::describe(&camera),
            unit: "frame",
            width: f.width,
            height: f.height,
            first: device.display().to_string(),
            source: InputSource::Camera(camera),
        }
    }
}

/// The first readable still of `stills` (those listed in `dir`) and its size; none readable
/// is an error naming the first failure.
fn first_readable_still(
    dir: &std::path::Path,
    stills: &[PathBuf],
) -> Result<(PathBuf, (u32, u32)), TakeError> {
    let mut first_error = None;
    let found = stills.iter().find_map(|p| {
        match pa_video::still::still_dimensions(p, &StillBudget::default()) {
            Ok(d) => Some((p, d)),
            Err(e) => {
                first_error.get_or_insert(e);
                None
            }
        }
    });
    match found {
        Some((first, size)) => Ok((first.clone(), size)),
        None => Err(TakeError::NoReadableStill {
            dir: dir.to_path_buf(),
            tried: stills.len(),
            first_error,
        }),
    }
}
