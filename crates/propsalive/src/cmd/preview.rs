//! `propsalive preview [SHOT.toml --input FOLDER|VIDEO|camera:/dev/videoN]`: the live
//! preview window.
//!
//! Each camera frame goes through the real pipeline (track -> place -> animate -> texture ->
//! diminish -> composite) and is shown at once in a window (winit + a wgpu surface), with
//! keys to step, scrub and play the animation, switch the key prop in front of the camera,
//! toggle diminished reality and the overlays (tracked axes, masks, onion skin, line-up of a
//! captured frame), capture frames and record. A status bar under the frame gives fps, the
//! camera-to-screen latency, the tracking state, the animation frame and key pose, and the
//! stage timings.
//!
//! Sources ([`source::FrameSource`]): with no arguments the built-in scene, generated on the
//! fly (its handheld camera going back and forth); with a shot file and `--input FOLDER` a
//! folder of stills, still `i` showing animation frame `i` as `propsalive run` pairs them;
//! `--input VIDEO` a video file, frame `i` showing animation frame `i` the same way;
//! `--input camera:/dev/videoN` a live camera (the `v4l` feature), tracked as a video
//! (temporal filter), the animation advancing one frame per camera frame while playing. The
//! tracker follows `pa_video::source`'s policy: reset before each still (a still is tracked
//! on its own, as `propsalive run` does), kept across the frames of a video or a camera.
//!
//! Decisions:
//! - **No frame queue.** One thread: take the source's newest frame, run the pipeline, draw,
//!   upload, present, then the next. The surface has `desired_maximum_frame_latency = 1` and
//!   a present mode that holds no queue (Mailbox, else Immediate, else Fifo). Latency is
//!   measured from the moment the frame was acquired to the return of the present call, and
//!   shown in the status bar and logged (`--log`).
//! - **Playing** advances the animation one frame per camera frame (every in-between is seen,
//!   as in `demo`); the camera keeps running while the animation is paused.
//! - **What is saved is the clean composited frame**: captures (`C`/Enter) and recordings
//!   (`R`) hold the pipeline's output without overlays or the status bar; the overlays and
//!   the bar are for the screen only. Captures are `capture_NNNN.png`, numbered on after the
//!   highest in the folder, written atomically and never over an existing file; each
//!   recording is a new `take_NNN/` folder of `NNNNNN.png`.
//! - **Automation hooks** (the screenshot test uses them): `--exit-after-frames N` quits after
//!   N presented frames, keeping the last one on screen for `--hold-ms`; `--dump-presented
//!   DIR` writes every presented canvas (`presented.png`) and where it went on screen
//!   (`presented.json`, with `"final": true` on the last one).

mod keys;
mod output;
mod place;
mod present;
mod setup;
mod source;

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use pa_pipeline::ar::{ArFrame, ArPipeline, Fill};
use pa_pipeline::GpuTwin;
use pa_render::{CpuCamera, Renderer};
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::ModifiersState;
use winit::window::{Window, WindowId};

// The window-free parts (drawing, status bar, state machine, layout) live in pa-overlay; the
// children `source`, `setup`, `present` and `output` reach them as `super::draw` etc.
use pa_overlay::action::{repeats, Action, HELP};
use pa_overlay::{draw, hud, layout, state};

use draw::Image;
use hud::{BarLayout, Status};
use keys::action_for;
use layout::{frame_camera, Rect};
use output::{Captures, JsonLog, Recording};
use pa_overlay::meter::Meter;
use present::{Presented, Presenter};
use source::{FrameSource, Want};
use state::{select_capture, Effect, PreviewState};

#[derive(clap::Args)]
pub struct Args {
    /// Shot file (TOML) of a stop-motion take, with --input. Without it: the built-in scene.
    pub shot: Option<PathBuf>,
    /// Folder of stills (.png, .jpg, .jpeg, .tif, .tiff, natural order): still i shows
    /// animation frame i; or a video file (frame i shows animation frame i); or a live
    /// camera, `camera:/dev/video0` (`camera:N` = /dev/videoN; needs `--features v4l`).
    #[arg(long)]
    pub input: Option<PathBuf>,
    /// Camera input: the frame size to ask for, WIDTHxHEIGHT [default: the shot's
    /// calibration size, else 1280x720].
    #[arg(long, value_name = "WxH")]
    pub camera_size: Option<String>,
    /// Frame size of the built-in scene, WIDTHxHEIGHT [default: 640x360] (stills keep
    /// their own size).
    #[arg(long)]
    pub size: Option<String>,
    /// Where `C`/Enter saves captured frames (capture_NNNN.png; never overwritten).
    #[arg(long, default_value = "out/preview/captures")]
    pub capture_dir: PathBuf,
    /// Where `R` records (a new take_NNN/ folder of numbered PNGs per recording).
    #[arg(long, default_value = "out/preview/recordings")]
    pub record_dir: PathBuf,
    /// JSON Lines log, one line per presented frame (frame, anim_frame, state, stage
    /// timings, latency_ms); replaced if it exists.
    #[arg(long)]
    pub log: Option<PathBuf>,
    /// Start with the animation paused.
    #[arg(long)]
    pub paused: bool,
    /// Start in placement mode (`P`): the key pose's outline and the nudge keys.
    #[arg(long)]
    pub place: bool,
    /// Overlays on at start, comma-separated: axes, masks, onion, lineup, help.
    #[arg(long, value_delimiter = ',')]
    pub overlays: Vec<String>,
    /// Automation: quit after this many presented frames (after --hold-ms).
    #[arg(long)]
    pub exit_after_frames: Option<u64>,
    /// Automation: with --exit-after-frames, keep the last frame on screen this long, ms.
    #[arg(long, default_value_t = 0)]
    pub hold_ms: u64,
    /// Automation: write each presented canvas to DIR/presented.png and where it is on the
    /// screen to DIR/presented.json.
    #[arg(long)]
    pub dump_presented: Option<PathBuf>,
    /// How the real prop is removed at start (overriding the shot's `[diminish]`); `F` cycles
    /// the fills, `S` toggles shadows.
    #[command(flatten)]
    pub diminish: crate::cmd::run::diminish::DiminishArgs,
    /// What replaces the board (overriding the shot's `[marker] hide`; a shot only); `B` shows
    /// the board again and hides it back.
    #[command(flatten)]
    pub hide: crate::cmd::run::hide::HideArgs,
    /// How each frame's tags are found (a shot's input; the built-in scene is tracked with
    /// the full detector).
    #[arg(long, value_enum, default_value_t = crate::cmd::track::Tracking::Full)]
    pub tracking: crate::cmd::track::Tracking,
}

/// The command's long help: what it does and the keys.
pub fn long_about() -> String {
    let mut s = String::from(
        "The live preview window: each camera frame through the whole pipeline, shown at once \
         (no frame queue), with a status bar (fps, camera-to-screen latency, tracking state, \
         animation frame and key pose, stage timings).\n\nWith no arguments it shows the \
         built-in scene; `preview SHOT.toml --input FOLDER` shows a folder of stills, \
         `--input VIDEO` a video file (frame i = animation frame i), `--input \
         camera:/dev/video0` a live camera (with `--features v4l`).\n\nKeys:\n",
    );
    for l in HELP {
        s.push_str("  ");
        s.push_str(l);
        s.push('\n');
    }
    s
}

/// Largest initial window (the frame is letterboxed into any size after that).
const MAX_WINDOW: (u32, u32) = (1280, 800);
/// Consecutive source failures before the preview gives up.
const MAX_SOURCE_FAILURES: u32 = 30;
/// How long a message stays on screen.
const TOAST: Duration = Duration::from_millis(2500);

/// The frame on screen and what is needed to redraw or save it.
struct Shown {
    /// The clean composited frame (what captures and recordings hold).
    composited: Image,
    /// The canvas on screen: the frame with overlays and the status bar.
    canvas: Image,
}

/// The preview while it runs.
struct Preview {
    renderer: Renderer,
    pipeline: ArPipeline,
    source: Box<dyn FrameSource>,
    state: PreviewState,
    fps: f32,
    axes_len_m: f32,
    /// The fill used while diminishing is on when the state's fill has none in this build.
    fill: Fill,
    onion_twin: Option<GpuTwin>,
    captures: Captures,
    capture_sel: Option<usize>,
    lineup: Option<(PathBuf, Image)>,
    record_root: PathBuf,
    recording: Option<Recording>,
    log: Option<JsonLog>,
    dump_dir: Option<PathBuf>,
    meter: Meter,
    shown: Option<Shown>,
    toast: Option<(String, Instant)>,
    frames: u64,
    source_failures: u32,
    last_warning: String,
    placer: place::Placer,
}

impl Preview {
    /// Says `msg` on stdout and for a moment on screen.
    fn toast(&mut self, msg: String) {
        outln!("{msg}");
        self.toast = Some((msg, Instant::now()));
    }

    /// Says an error on stderr and for a moment on screen.
    fn toast_error(&mut self, msg: String) {
        errln!("error: {msg}");
        self.toast = Some((format!("error: {msg}"), Instant::now()));
    }

    /// Carries out one action's effect; false to quit. A capture or recording that cannot be
    /// written is said on screen and on stderr, and the preview goes on.
    fn act(&mut self, action: Action) -> bool {
        let effect = self.state.apply(action);
        match action {
            Action::CycleFill => self.toast(format!("fill: {}", self.state.fill_name())),
            Action::ToggleShadows => {
                let on = if self.state.shadows { "on" } else { "off" };
                self.toast(format!("shadows {on}"));
            }
            Action::ToggleHide => {
                let msg = if !self.pipeline.has_hide() {
                    "no hiding set: the shot's [marker] hide, or --hide cover|plate"
                } else if self.state.hide_board {
                    "board hidden"
                } else {
                    "board shown"
                };
                self.toast(msg.to_string());
            }
            _ => {}
        }
        match effect {
            Effect::None => {}
            Effect::Quit => return false,
            Effect::PrintHelp => print_help(),
            Effect::Capture => {
                let saved = match &self.shown {
                    Some(s) => Some(self.captures.save(&s.composited)),
                    None => None,
                };
                match saved {
                    Some(Ok(path)) => {
                        self.capture_sel = None;
                        self.lineup = None;
                        self.toast(format!("captured {}", path.display()));
                    }
                    Some(Err(e)) => self.toast_error(format!("capture failed: {e:#}")),
                    None => self.toast("nothing to capture yet".into()),
                }
            }
            Effect::StartRecording => match Recording::start(&self.record_root) {
                Ok(rec) => {
                    self.toast(format!("recording to {}", rec.dir.display()));
                    self.recording = Some(rec);
                }
                Err(e) => {
                    self.state.recording = false;
                    self.toast_error(format!("cannot record: {e:#}"));
                }
            },
            Effect::StopRecording => {
                if let Some(rec) = self.recording.take() {
                    self.toast(format!(
                        "recorded {} frame(s) to {}",
                        rec.frames,
                        rec.dir.display()
                    ));
                }
            }
            Effect::LineUpOn => self.select_capture(0),
            Effect::SelectCapture(d) => self.select_capture(d),
            Effect::PlacementChanged => self.place_pipeline(),
            Effect::Register => self.register(),
            Effect::WritePlacement => self.write_placement(),
        }
        true
    }

    /// Moves the line-up's capture by `delta` (0: the one selected, else the latest) and
    /// shows the line-up; says so when there is no capture yet.
    fn select_capture(&mut self, delta: i32) {
        self.capture_sel = select_capture(self.capture_sel, self.captures.files.len(), delta);
        match self.capture_sel {
            Some(i) => {
                self.state.overlays.line_up = true;
                let msg = format!(
                    "line-up with {} ({}/{})",
                    self.captures.files[i].display(),
                    i + 1,
                    self.captures.files.len()
                );
                self.toast(msg);
            }
            None => {
                self.state.overlays.line_up = false;
                let msg = format!(
                    "no captured frame in {} yet: press C to capture one",
                    self.captures.dir.display()
                );
                self.toast(msg);
            }
        }
    }

    /// The line-up image (the selected capture, at the frame's size), loaded once.
    fn lineup_image(&mut self, w: u32, h: u32) -> Option<&Image> {
        let i = select_capture(self.capture_sel, self.captures.files.len(), 0)?;
        let path = self.captures.files[i].clone();
        let stale = match &self.lineup {
            Some((p, img)) => *p != path || (img.width, img.height) != (w, h),
            None => true,
        };
        if stale {
            let loaded =
                pa_video::still::read_still(&path, &Default::default()).map(|d| d.to_rgba8());
            match loaded {
                Ok(mut img) => {
                    if img.dimensions() != (w, h) {
                        img = image::imageops::resize(
                            &img,
                            w,
                            h,
                            image::imageops::FilterType::Triangle,
                        );
                    }
                    self.lineup = Some((
                        path,
                        Image {
                            width: w,
                            height: h,
                            rgba8: img.into_raw(),
                        },
                    ));
                }
                Err(e) => {
                    self.state.overlays.line_up = false;
                    self.toast(format!("line-up: cannot read {}: {e}", path.display()));
                    return None;
                }
            }
        }
        self.lineup.as_ref().map(|(_, img)| img)
    }

    /// Silhouettes of the twin at animation frames `frames`, seen from `camera_from_marker`.
    fn onion_masks(
        &mut self,
        camera_from_marker: glam::Mat4,
        w: u32,
        h: u32,
        frames: &[u32],
    ) -> Result<Vec<Vec<bool>>> {
        let prop = self.pipeline.first_prop();
        if self.onion_twin.is_none() {
            self.onion_twin = Some(GpuTwin::upload(&mut self.renderer, &prop.model)?);
        }
        let Some(twin) = &self.onion_twin else {
            return Ok(Vec::new());
        };
        let camera = CpuCamera {
            intrinsics: frame_camera(&self.pipeline.camera, w, h).intrinsics,
            camera_from_world: camera_from_marker,
            near_m: 0.01,
            far_m: 50.0,
        };
        let mut masks = Vec::new();
        for &f in frames {
            let pose = pa_model::anim::sample(&prop.model, prop.animation, f as f32 / self.fps);
            let tf = twin.frame(&prop.model, &pose, prop.marker_from_prop);
            let r = self
                .renderer
                .render(&camera, None, &twin.draws(&tf), [0.0; 4], w, h)?;
            masks.push(r.depth_m.iter().map(|d| d.is_finite()).collect());
        }
        Ok(masks)
    }

    /// Draws the overlays the state asks for over the composited frame.
    fn overlay(&mut self, out: &ArFrame, img: &mut Image) -> Result<()> {
        let (w, h) = (img.width, img.height);
        if self.state.overlays.line_up {
            if let Some(l) = self.lineup_image(w, h) {
                img.blend_image(l, 0.5);
            }
        }
        if self.state.overlays.masks {
            img.tint(&out.key_mask, draw::MAGENTA, 0.35);
            img.tint(&out.twin_mask, draw::CYAN, 0.35);
        }
        if let (true, Some(pose)) = (self.state.overlays.onion, out.camera_from_marker) {
            let f = self.state.anim_frame;
            let mut frames = Vec::new();
            let mut colours = Vec::new();
            if f > 0 {
                frames.push(f - 1);
                colours.push(draw::RED);
            }
            if f < self.state.last_frame {
                frames.push(f + 1);
                colours.push(draw::GREEN);
            }
            let masks = self.onion_masks(pose, w, h, &frames)?;
            for (m, c) in masks.iter().zip(colours) {
                img.outline(m, c);
            }
        }
        if let (true, Some(pose)) = (self.state.overlays.axes, out.camera_from_marker) {
            let cam = frame_camera(&self.pipeline.camera, w, h);
            hud::draw_axes(img, &cam, pose, self.axes_len_m);
        }
        if let (true, Some(pose), Some(p)) = (
            self.state.placing,
            out.camera_from_marker,
            self.state.placement,
        ) {
            let cam = frame_camera(&self.pipeline.camera, w, h);
            let prop = self.pipeline.first_prop();
            let key_frame = self.state.key_pose().frame;
            let key_s = key_frame as f32 / self.fps;
            let px = self.placer.outline(
                &prop.model,
                || pa_model::anim::sample(&prop.model, prop.animation, key_s),
                key_frame,
                &cam,
                pose,
                &p,
                (w, h),
            );
            hud::draw_placement(img, &px, &p, self.state.placement_edited);
        }
        if self.state.overlays.help {
            hud::draw_help(img);
        } else if let Some((msg, at)) = &self.toast {
            if at.elapsed() < TOAST {
                let msg = msg.clone();
                hud::draw_panel(img, &[&msg], draw::YELLOW);
            }
        }
        Ok(())
    }

    fn status(&self, out: &ArFrame) -> Status {
        let key = self.state.key_pose();
        Status {
            fps: self.meter.fps,
            latency_ms: self.meter.latency_ms,
            state: format!("{:?}", out.state),
            anim_frame: self.state.anim_frame,
            last_frame: self.state.last_frame,
            playing: self.state.playing,
            key_name: key.name.clone(),
            key_frame: key.frame,
            timings: hud::StageTimings {
                track_ms: out.timings.track_ms,
                animate_ms: out.timings.animate_ms,
                texture_ms: out.timings.texture_ms,
                diminish_ms: out.timings.diminish_ms,
                composite_ms: out.timings.composite_ms,
            },
            flags: self.state.flags(),
            recorded: self.recording.as_ref().map(|r| r.frames),
        }
    }

    /// One camera frame: acquire the newest, process, draw, present, log; false when the
    /// source could not give one (skipped with a warning). `last`: the final frame of
    /// --exit-after-frames.
    fn tick(&mut self, presenter: &mut Presenter, window: &Window, last: bool) -> Result<bool> {
        let want = Want {
            anim_frame: self.state.anim_frame,
            key_frame: self.state.key_pose().frame,
        };
        let t0 = Instant::now();
        let frame = match self.source.next_frame(&mut self.renderer, &want) {
            Ok(f) => {
                self.source_failures = 0;
                f
            }
            Err(e) => {
                self.source_failures += 1;
                if self.source_failures >= MAX_SOURCE_FAILURES {
                    return Err(e.context(format!(
                        "{MAX_SOURCE_FAILURES} camera frames in a row failed"
                    )));
                }
                let msg = format!("warning: {e:#}");
                if msg != self.last_warning {
                    errln!("{msg}");
                    self.last_warning = msg;
                }
                return Ok(false);
            }
        };
        let acquire_ms = t0.elapsed().as_secs_f64() * 1e3;
        self.pipeline.settings.fill = if self.state.diminish {
            setup::fill_named(self.state.fill_name()).unwrap_or(self.fill)
        } else {
            Fill::None
        };
        self.pipeline.set_shadows(self.state.shadows);
        self.pipeline.set_hide_enabled(self.state.hide_board);
        let anim_time_s = self.state.anim_frame as f32 / self.fps;
        let key_time_s = want.key_frame as f32 / self.fps;
        // The tracker policy (`pa_video::source`): reset before each still, kept across video
        // and camera frames.
        if frame.starts_sequence {
            self.pipeline.reset_tracker();
        }
        let mut out = self.pipeline.process(
            &mut self.renderer,
            &frame.rgba8,
            frame.width,
            frame.height,
            pa_pipeline::ar::FrameTimes {
                animation_s: anim_time_s,
                key_pose_s: key_time_s,
            },
            frame.time_s,
        )?;
        if let Some(pose) = out.camera_from_marker {
            let cam = frame_camera(&self.pipeline.camera, frame.width, frame.height);
            let size = (frame.width, frame.height);
            self.placer
                .remember(&frame.label, &frame.rgba8, size, cam, pose);
        }
        let t_overlay = Instant::now();
        let composited = Image {
            width: frame.width,
            height: frame.height,
            rgba8: std::mem::take(&mut out.rgba8),
        };
        let mut view = composited.clone();
        self.overlay(&out, &mut view)?;
        let bar = BarLayout::for_width(frame.width);
        let mut canvas = Image::filled(frame.width, frame.height + bar.height, draw::BAR);
        canvas.paste_rows(&view, 0);
        let status = self.status(&out);
        let key_frames: Vec<u32> = self.state.key_poses.iter().map(|k| k.frame).collect();
        hud::draw_bar(&mut canvas, frame.height, &status, &key_frames);
        let overlay_ms = t_overlay.elapsed().as_secs_f64() * 1e3;

        let t_present = Instant::now();
        presenter.upload(&canvas)?;
        let presented = presenter.present()?;
        let now = Instant::now();
        let present_ms = now.duration_since(t_present).as_secs_f64() * 1e3;
        let latency_ms = now.duration_since(frame.acquired).as_secs_f64() * 1e3;
        self.meter.presented(now, latency_ms);

        let mut record_ms = 0.0;
        if let Some(rec) = &mut self.recording {
            let t = Instant::now();
            let pushed = rec.push(&composited);
            record_ms = t.elapsed().as_secs_f64() * 1e3;
            if let Err(e) = pushed {
                let n = rec.frames;
                self.recording = None;
                self.state.recording = false;
                self.toast_error(format!("recording stopped after {n} frame(s): {e:#}"));
            }
        }
        let index = self.frames;
        self.frames += 1;
        let key = self.state.key_pose();
        if let Some(log) = &mut self.log {
            let t = &out.timings;
            log.line(&serde_json::json!({
                "frame": index,
                "source": frame.label,
                "anim_frame": self.state.anim_frame,
                "key_pose": key.name,
                "key_frame": key.frame,
                "state": format!("{:?}", out.state),
                "diminish": self.state.diminish,
                "overlays": self.state.flags(),
                "timings_ms": {
                    "acquire": acquire_ms, "track": t.track_ms, "animate": t.animate_ms,
                    "texture": t.texture_ms, "diminish": t.diminish_ms,
                    "composite": t.composite_ms, "overlay": overlay_ms, "present": present_ms,
                    "record": record_ms,
                },
                "latency_ms": latency_ms,
                "fps": self.meter.fps,
                "presented": matches!(presented, Presented::Shown(_)),
                "recording": self.recording.as_ref().map(|r| r.dir.display().to_string()),
            }))?;
        }
        if let Some(dir) = self.dump_dir.clone() {
            dump_presented(&dir, &canvas, presented, window, index, frame.height, last)?;
        }
        // The frame shown before hands its image back to the pipeline (no fresh buffer).
        if let Some(old) = self.shown.replace(Shown { composited, canvas }) {
            self.pipeline.recycle(old.composited.rgba8);
        }
        self.state.advance();
        Ok(true)
    }

    /// Presents the canvas on screen again (after an expose or a resize).
    fn redraw(&mut self, presenter: &mut Presenter) -> Result<()> {
        if let Some(s) = &self.shown {
            presenter.upload(&s.canvas)?;
            presenter.present()?;
        }
        Ok(())
    }

    fn finish(&mut self) {
        if let Some(rec) = self.recording.take() {
            outln!("recorded {} frame(s) to {}", rec.frames, rec.dir.display());
        }
        match self.meter.summary() {
            Some((median, p95)) => outln!(
                "preview: {} frame(s) presented; camera-to-screen latency median {median:.1} ms, p95 {p95:.1} ms",
                self.frames
            ),
            None => outln!("preview: no frame presented"),
        }
    }
}

/// Writes the presented canvas and where it is on screen (test hook).
fn dump_presented(
    dir: &Path,
    canvas: &Image,
    presented: Presented,
    window: &Window,
    index: u64,
    frame_height: u32,
    last: bool,
) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let png = output::png_bytes(canvas)?;
    let png_path = dir.join("presented.png");
    pa_model::export::write_atomic(&png_path, &png)
        .with_context(|| format!("writing {}", png_path.display()))?;
    let inner = window.inner_size();
    let position = window.inner_position().ok().map(|p| [p.x, p.y]);
    let viewport = match presented {
        Presented::Shown(Rect { x, y, w, h }) => Some([x, y, w, h]),
        Presented::Skipped => None,
    };
    let info = serde_json::json!({
        "frame": index,
        "canvas": [canvas.width, canvas.height],
        "frame_height": frame_height,
        "bar_height": canvas.height - frame_height,
        "window_inner": [inner.width, inner.height],
        "window_position": position,
        "viewport": viewport,
        "final": last,
    });
    let json_path = dir.join("presented.json");
    pa_model::export::write_atomic(&json_path, info.to_string().as_bytes())
        .with_context(|| format!("writing {}", json_path.display()))?;
    Ok(())
}

fn print_help() {
    outln!("keys:");
    for l in HELP {
        outln!("  {l}");
    }
}

/// The winit application: the window, its presenter and the preview.
struct App {
    preview: Preview,
    instance: Option<wgpu::Instance>,
    window_size: (u32, u32),
    window: Option<Arc<Window>>,
    presenter: Option<Presenter>,
    modifiers: ModifiersState,
    cursor: Option<(f64, f64)>,
    dragging: bool,
    exit_after: Option<u64>,
    hold: Duration,
    hold_until: Option<Instant>,
    error: Option<anyhow::Error>,
}

impl App {
    fn fail(&mut self, event_loop: &ActiveEventLoop, e: anyhow::Error) {
        if self.error.is_none() {
            self.error = Some(e);
        }
        event_loop.exit();
    }

    fn scrub_to_cursor(&mut self) {
        let (Some((x, _)), Some(shown)) = (self.cursor, &self.preview.shown) else {
            return;
        };
        let Some(window) = &self.window else {
            return;
        };
        let size = window.inner_size();
        let canvas = (shown.canvas.width, shown.canvas.height);
        let Some(rect) = layout::letterbox((size.width, size.height), canvas) else {
            return;
        };
        // The whole width of the image spans the clip; x is clamped to the image.
        let cx = layout::canvas_x_from_window(rect, canvas.0, x);
        let f = layout::scrub_frame(cx, canvas.0, self.preview.state.last_frame);
        self.preview.state.set_frame(f);
    }

    fn on_window_event(&mut self, event_loop: &ActiveEventLoop, event: WindowEvent) -> Result<()> {
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => {
                if let Some(p) = &mut self.presenter {
                    p.resize(size.width, size.height);
                }
                if let Some(w) = &self.window {
                    w.request_redraw();
                }
            }
            WindowEvent::ModifiersChanged(m) => self.modifiers = m.state(),
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => {
                if let Some(action) = action_for(
                    &event.logical_key,
                    self.modifiers.shift_key(),
                    self.preview.state.placing,
                ) {
                    if (!event.repeat || repeats(action)) && !self.preview.act(action) {
                        event_loop.exit();
                    }
                }
            }
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Left,
                ..
            } => {
                self.dragging = state == ElementState::Pressed;
                if self.dragging {
                    self.preview.state.playing = false;
                    self.scrub_to_cursor();
                }
            }
            WindowEvent::CursorMoved { position, .. } => {
                self.cursor = Some((position.x, position.y));
                if self.dragging {
                    self.scrub_to_cursor();
                }
            }
            WindowEvent::CursorLeft { .. } => self.dragging = false,
            WindowEvent::RedrawRequested => {
                let (Some(presenter), Some(window)) = (&mut self.presenter, &self.window) else {
                    return Ok(());
                };
                if self.hold_until.is_some() {
                    self.preview.redraw(presenter)?;
                } else {
                    let last = self
                        .exit_after
                        .is_some_and(|n| self.preview.frames + 1 >= n);
                    if self.preview.tick(presenter, window, last)? && last {
                        self.hold_until = Some(Instant::now() + self.hold);
                    }
                }
            }
            _ => {}
        }
        Ok(())
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_some() {
            return;
        }
        let Some(instance) = self.instance.take() else {
            return;
        };
        let attrs = Window::default_attributes()
            .with_title("Props Alive preview")
            .with_inner_size(winit::dpi::PhysicalSize::new(
                self.window_size.0,
                self.window_size.1,
            ));
        let result = event_loop
            .create_window(attrs)
            .context("opening the preview window")
            .and_then(|w| {
                let w = Arc::new(w);
                let p = Presenter::new(instance, w.clone())?;
                Ok((w, p))
            });
        match result {
            Ok((w, p)) => {
                outln!("window: {}", p.description);
                w.request_redraw();
                self.window = Some(w);
                self.presenter = Some(p);
            }
            Err(e) => self.fail(event_loop, e),
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        if let Err(e) = self.on_window_event(event_loop, event) {
            self.fail(event_loop, e);
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        match self.hold_until {
            Some(until) if Instant::now() >= until => event_loop.exit(),
            Some(until) => event_loop.set_control_flow(ControlFlow::WaitUntil(until)),
            None => match &self.window {
                // Minimised: nothing to show, so no frame is processed; look again soon.
                Some(w) if w.inner_size().width == 0 || w.inner_size().height == 0 => {
                    event_loop.set_control_flow(ControlFlow::WaitUntil(
                        Instant::now() + Duration::from_millis(100),
                    ));
                }
                Some(w) => {
                    event_loop.set_control_flow(ControlFlow::Poll);
                    w.request_redraw();
                }
                None => {}
            },
        }
    }
}

pub fn run(args: Args) -> Result<()> {
    // The display first: without one there is no point generating anything.
    const NEEDS_DISPLAY: &str = "the preview needs a display (DISPLAY or WAYLAND_DISPLAY; on a \
         machine without one, run it under Xvfb: `xvfb-run propsalive preview`)";
    let has_display = ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()));
    if !has_display {
        bail!("no display: {NEEDS_DISPLAY}");
    }
    let event_loop = EventLoop::new().map_err(|e| {
        // winit's message starts with its own source location ("os error at FILE:LINE: ..."):
        // only the reason is for the user.
        let text = e.to_string();
        let reason = match text.split_once(": ") {
            Some((head, rest)) if head.contains(".rs:") => rest.to_string(),
            _ => text,
        };
        anyhow::anyhow!("cannot open the window system ({reason}); {NEEDS_DISPLAY}")
    })?;
    let desc = wgpu::InstanceDescriptor::new_with_display_handle_from_env(Box::new(
        event_loop.owned_display_handle(),
    ));
    let instance = wgpu::Instance::new(desc);

    if args.exit_after_frames == Some(0) {
        bail!("--exit-after-frames must be at least 1");
    }
    if args.shot.is_none() && args.camera_size.is_some() {
        bail!("--camera-size is for a camera input: `propsalive preview SHOT.toml --input camera:/dev/videoN --camera-size WxH`");
    }
    if args.shot.is_none() && args.hide.overrides() != Default::default() {
        bail!("--hide and --cover are for a shot (its board): `propsalive preview SHOT.toml --input ... --hide cover --cover FILE`");
    }
    if args.shot.is_none() && args.tracking != crate::cmd::track::Tracking::Full {
        bail!(
            "--tracking is for a shot's input; the built-in scene is tracked by the full detector"
        );
    }
    if args.shot.is_some() && args.size.is_some() {
        bail!("--size is for the built-in scene; stills are shown at their own size");
    }
    let overlays =
        state::Overlays::parse(&args.overlays).map_err(|e| anyhow::anyhow!("--overlays: {e}"))?;
    let setup = match (&args.shot, &args.input) {
        (None, None) => setup::setup_scene(args.size.as_deref(), &args.diminish)?,
        (Some(shot), Some(input)) => {
            setup::setup_shot(
                shot,
                input,
                args.camera_size.as_deref(),
                &args.diminish,
                &args.hide,
                args.tracking,
            )?
        }
        (Some(_), None) => bail!(
            "a shot needs --input FOLDER, VIDEO or camera:/dev/videoN; run `propsalive preview` with no arguments for the built-in scene"
        ),
        (None, Some(_)) => bail!("--input needs the shot file: `propsalive preview SHOT.toml --input FOLDER|VIDEO|camera:/dev/videoN`"),
    };
    let setup::Setup {
        renderer,
        pipeline,
        source,
        mut state,
        fps,
        axes_len_m,
        frame_size,
    } = setup;
    outln!("source: {}", source.describe());
    if args.paused {
        state.playing = false;
    }
    state.overlays = overlays;
    let shot_placement = match &args.shot {
        Some(p) => pa_pipeline::shot::Shot::load(p)?.placement,
        None => pa_pipeline::shot::Placement::default(),
    };
    let (placer, placement) = place::Placer::new(args.shot.clone(), &shot_placement);
    state.set_placement(placement);
    state.placing = args.place;
    let log = args.log.as_deref().map(JsonLog::create).transpose()?;
    let fill = pipeline.settings.fill;
    let captures = Captures::open(&args.capture_dir);
    let bar = BarLayout::for_width(frame_size.0);
    let window_size = layout::initial_window((frame_size.0, frame_size.1 + bar.height), MAX_WINDOW);
    print_help();

    let mut app = App {
        preview: Preview {
            renderer,
            pipeline,
            source,
            state,
            fps,
            axes_len_m,
            fill,
            onion_twin: None,
            captures,
            capture_sel: None,
            lineup: None,
            record_root: args.record_dir.clone(),
            recording: None,
            log,
            dump_dir: args.dump_presented.clone(),
            meter: Meter::default(),
            shown: None,
            toast: None,
            frames: 0,
            source_failures: 0,
            last_warning: String::new(),
            placer,
        },
        instance: Some(instance),
        window_size,
        window: None,
        presenter: None,
        modifiers: ModifiersState::empty(),
        cursor: None,
        dragging: false,
        exit_after: args.exit_after_frames.filter(|&n| n > 0),
        hold: Duration::from_millis(args.hold_ms),
        hold_until: None,
        error: None,
    };
    event_loop
        .run_app(&mut app)
        .context("running the window's event loop")?;
    app.preview.finish();
    // The surface goes before the window it draws into.
    app.presenter = None;
    app.window = None;
    match app.error {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_about_lists_the_keys() {
        let s = long_about();
        for l in HELP {
            assert!(s.contains(l));
        }
    }
}
