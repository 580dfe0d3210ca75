//! The preview's state machine: which animation frame is shown, play/pause, the key prop in
//! front of the camera, diminishing and the overlays. [`PreviewState::apply`] turns an
//! [`Action`] into the new state and, for actions with side effects (files, quitting), an
//! [`Effect`] the window code carries out. Pure, tested without a window.

use crate::action::{Action, Nudge};
use crate::OverlayError;

/// A key pose: an animation frame that exists as a physical prop.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct KeyPose {
    pub name: String,
    pub frame: u32,
}

/// The overlays drawn over the composited frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Overlays {
    /// The tracked marker's axes.
    pub axes: bool,
    /// The key-pose and twin masks, tinted.
    pub masks: bool,
    /// The twin's silhouette at the previous and next in-between.
    pub onion: bool,
    /// A captured frame at 50 %.
    pub line_up: bool,
    /// The key list on screen.
    pub help: bool,
}

impl Overlays {
    /// Overlays named on the command line (`axes`, `masks`, `onion`, `lineup`, `help`).
    pub fn parse(names: &[String]) -> Result<Self, OverlayError> {
        let mut o = Self::default();
        for n in names {
            match n.trim().to_ascii_lowercase().as_str() {
                "axes" => o.axes = true,
                "masks" => o.masks = true,
                "onion" => o.onion = true,
                "lineup" | "line-up" => o.line_up = true,
                "help" => o.help = true,
                "" => {}
                other => {
                    return Err(OverlayError::UnknownOverlay {
                        name: other.to_string(),
                    })
                }
            }
        }
        Ok(o)
    }
}

/// What the window code must do after an action.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Effect {
    /// Nothing beyond the state change.
    None,
    /// Save the current composited frame.
    Capture,
    /// Start recording (the state says `recording`).
    StartRecording,
    /// Stop recording.
    StopRecording,
    /// Print the key list.
    PrintHelp,
    /// Select another capture for the line-up (-1 earlier, +1 later).
    SelectCapture(i32),
    /// Turning the line-up on: it needs a capture to show.
    LineUpOn,
    Quit,
    /// The placement changed: draw the twin there.
    PlacementChanged,
    /// Register the placement on the last frames seen (then [`PreviewState::set_placement`]).
    Register,
    /// Write the placement into the shot file (then [`PreviewState::placement_written`]).
    WritePlacement,
}

/// A normal placement step on the table and in lift (millimetres) and in yaw (degrees).
pub const STEP_MM: f64 = 2.0;
pub const STEP_DEG: f64 = 1.0;
/// A fine step (Shift).
pub const FINE_STEP_MM: f64 = 0.5;
pub const FINE_STEP_DEG: f64 = 0.2;

/// Where the key prop stands on the marker, as the preview nudges it (the shot's
/// `[placement]`: marker-frame translation, metres, and yaw, degrees).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlacementValues {
    pub translation_m: [f64; 3],
    pub yaw_deg: f64,
}

impl PlacementValues {
    /// Moved by one nudge.
    pub fn nudged(&self, nudge: Nudge, fine: bool) -> Self {
        let (mm, deg) = if fine {
            (FINE_STEP_MM, FINE_STEP_DEG)
        } else {
            (STEP_MM, STEP_DEG)
        };
        let mut p = *self;
        match nudge {
            Nudge::X(d) => p.translation_m[0] += d as f64 * mm * 1e-3,
            Nudge::Y(d) => p.translation_m[1] += d as f64 * mm * 1e-3,
            Nudge::Lift(d) => p.translation_m[2] += d as f64 * mm * 1e-3,
            Nudge::Yaw(d) => p.yaw_deg += d as f64 * deg,
        }
        p
    }

    /// One line for the screen: millimetres and degrees.
    pub fn describe(&self) -> String {
        let t = self.translation_m;
        format!(
            "x {:+.1} mm  y {:+.1} mm  lift {:+.1} mm  yaw {:+.1} deg",
            t[0] * 1e3,
            t[1] * 1e3,
            t[2] * 1e3,
            self.yaw_deg
        )
    }
}

/// Everything the user controls.
#[derive(Debug, Clone, PartialEq)]
pub struct PreviewState {
    /// The animation frame shown (0-based).
    pub anim_frame: u32,
    /// The clip's last frame.
    pub last_frame: u32,
    pub playing: bool,
    /// The key poses (at least one) and which one is in front of the camera.
    pub key_poses: Vec<KeyPose>,
    pub key: usize,
    /// Diminished reality: the real prop is removed where the twin does not cover it.
    pub diminish: bool,
    /// The fills to cycle through (names, at least one) and the one used.
    pub fills: Vec<String>,
    pub fill: usize,
    /// Shadows: the key prop's cast shadow lifted, the twin's cast.
    pub shadows: bool,
    /// The board hidden as the shot's `hide` says (cover or plate); off shows it.
    pub hide_board: bool,
    pub overlays: Overlays,
    pub recording: bool,
    /// Placement mode: the key pose's outline is drawn and the nudge keys move it.
    pub placing: bool,
    /// The key prop's placement (`None` until the window code sets it).
    pub placement: Option<PlacementValues>,
    /// The placement differs from what the shot file holds.
    pub placement_edited: bool,
}

impl PreviewState {
    /// A playing preview at frame 0 with the given key poses (an empty list gets one at frame
    /// 0), diminishing on, no overlays.
    pub fn new(last_frame: u32, mut key_poses: Vec<KeyPose>, present_key: usize) -> Self {
        if key_poses.is_empty() {
            key_poses.push(KeyPose {
                name: "key".into(),
                frame: 0,
            });
        }
        let key = present_key.min(key_poses.len() - 1);
        Self {
            anim_frame: 0,
            last_frame,
            playing: true,
            key_poses,
            key,
            diminish: true,
            fills: vec!["rays".into()],
            fill: 0,
            shadows: false,
            hide_board: true,
            overlays: Overlays::default(),
            recording: false,
            placing: false,
            placement: None,
            placement_edited: false,
        }
    }

    /// The fills to cycle through with `F` (an empty list keeps the current one) and the
    /// one in use (clamped to the list).
    pub fn with_fills(mut self, fills: Vec<String>, current: usize) -> Self {
        if !fills.is_empty() {
            self.fill = current.min(fills.len() - 1);
            self.fills = fills;
        }
        self
    }

    /// The name of the fill in use.
    pub fn fill_name(&self) -> &str {
        &self.fills[self.fill.min(self.fills.len() - 1)]
    }

    /// A new placement (a registration's answer): edited unless it is the one already there.
    pub fn set_placement(&mut self, p: PlacementValues) {
        if self.placement != Some(p) {
            self.placement_edited = self.placement.is_some();
        }
        self.placement = Some(p);
    }

    /// The placement was written into the shot file.
    pub fn placement_written(&mut self) {
        self.placement_edited = false;
    }

    /// Number of frames in the clip.
    pub fn frame_count(&self) -> u32 {
        self.last_frame + 1
    }

    /// The key pose in front of the camera.
    pub fn key_pose(&self) -> &KeyPose {
        &self.key_poses[self.key.min(self.key_poses.len() - 1)]
    }

    /// Sets the animation frame (clamped to the clip), e.g. from a mouse drag.
    pub fn set_frame(&mut self, frame: u32) {
        self.anim_frame = frame.min(self.last_frame);
    }

    /// After a camera frame was shown: a playing animation moves on one frame (looping).
    pub fn advance(&mut self) {
        if self.playing {
            self.anim_frame = if self.anim_frame >= self.last_frame {
                0
            } else {
                self.anim_frame + 1
            };
        }
    }

    /// Applies one action.
    pub fn apply(&mut self, action: Action) -> Effect {
        let n = self.frame_count() as i64;
        match action {
            Action::Step(d) => {
                self.anim_frame = (self.anim_frame as i64 + d as i64).rem_euclid(n) as u32;
                Effect::None
            }
            Action::Scrub(d) => {
                self.anim_frame = (self.anim_frame as i64 + d as i64).clamp(0, n - 1) as u32;
                Effect::None
            }
            Action::First => {
                self.anim_frame = 0;
                Effect::None
            }
            Action::Last => {
                self.anim_frame = self.last_frame;
                Effect::None
            }
            Action::PlayPause => {
                self.playing = !self.playing;
                Effect::None
            }
            Action::NextKeyPose => {
                self.key = (self.key + 1) % self.key_poses.len();
                Effect::None
            }
            Action::ToggleDiminish => {
                self.diminish = !self.diminish;
                Effect::None
            }
            Action::CycleFill => {
                // Choosing a fill means diminishing with it.
                self.fill = (self.fill + 1) % self.fills.len();
                self.diminish = true;
                Effect::None
            }
            Action::ToggleShadows => {
                self.shadows = !self.shadows;
                Effect::None
            }
            Action::ToggleHide => {
                self.hide_board = !self.hide_board;
                Effect::None
            }
            Action::ToggleAxes => {
                self.overlays.axes = !self.overlays.axes;
                Effect::None
            }
            Action::ToggleMasks => {
                self.overlays.masks = !self.overlays.masks;
                Effect::None
            }
            Action::ToggleOnion => {
                self.overlays.onion = !self.overlays.onion;
                Effect::None
            }
            Action::ToggleLineUp => {
                self.overlays.line_up = !self.overlays.line_up;
                if self.overlays.line_up {
                    Effect::LineUpOn
                } else {
                    Effect::None
                }
            }
            Action::SelectCapture(d) => Effect::SelectCapture(d),
            Action::Capture => Effect::Capture,
            Action::ToggleRecording => {
                self.recording = !self.recording;
                if self.recording {
                    Effect::StartRecording
                } else {
                    Effect::StopRecording
                }
            }
            Action::Help => {
                self.overlays.help = !self.overlays.help;
                Effect::PrintHelp
            }
            Action::Quit => Effect::Quit,
            Action::TogglePlace => {
                self.placing = !self.placing;
                Effect::None
            }
            Action::Nudge { nudge, fine } => match (self.placing, self.placement) {
                (true, Some(p)) => {
                    self.placement = Some(p.nudged(nudge, fine));
                    self.placement_edited = true;
                    Effect::PlacementChanged
                }
                _ => Effect::None,
            },
            Action::Register => Effect::Register,
            Action::WritePlacement => Effect::WritePlacement,
        }
    }

    /// The overlay flags as a short string for the status line: upper case = on.
    pub fn flags(&self) -> String {
        let f = |on: bool, c: char| {
            if on {
                c.to_ascii_uppercase()
            } else {
                c
            }
        };
        [
            f(self.diminish, 'd'),
            f(self.overlays.axes, 'a'),
            f(self.overlays.masks, 'm'),
            f(self.overlays.onion, 'o'),
            f(self.overlays.line_up, 'l'),
        ]
        .iter()
        .collect()
    }
}

/// The capture selected after moving `delta` from `current` among `len` captures; the latest
/// when none was selected. `None` when there is no capture.
pub fn select_capture(current: Option<usize>, len: usize, delta: i32) -> Option<usize> {
    if len == 0 {
        return None;
    }
    let cur = current.unwrap_or(len - 1).min(len - 1) as i64;
    Some((cur + delta as i64).clamp(0, len as i64 - 1) as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state() -> PreviewState {
        PreviewState::new(
            48,
            vec![
                KeyPose {
                    name: "A".into(),
                    frame: 0,
                },
                KeyPose {
                    name: "B".into(),
                    frame: 24,
                },
            ],
            0,
        )
    }

    #[test]
    fn stepping_wraps_and_scrubbing_clamps() {
        let mut s = state();
        assert_eq!(s.apply(Action::Step(-1)), Effect::None);
        assert_eq!(s.anim_frame, 48);
        s.apply(Action::Step(1));
        assert_eq!(s.anim_frame, 0);
        s.apply(Action::Step(10));
        s.apply(Action::Step(10));
        assert_eq!(s.anim_frame, 20);
        s.apply(Action::Step(-30));
        assert_eq!(s.anim_frame, 39);
        s.apply(Action::Scrub(20));
        assert_eq!(s.anim_frame, 48);
        s.apply(Action::Scrub(-100));
        assert_eq!(s.anim_frame, 0);
        s.apply(Action::Last);
        assert_eq!(s.anim_frame, 48);
        s.apply(Action::First);
        assert_eq!(s.anim_frame, 0);
        s.set_frame(1000);
        assert_eq!(s.anim_frame, 48);
    }

    #[test]
    fn playing_advances_and_loops_paused_holds() {
        let mut s = state();
        assert!(s.playing);
        s.set_frame(47);
        s.advance();
        assert_eq!(s.anim_frame, 48);
        s.advance();
        assert_eq!(s.anim_frame, 0);
        s.apply(Action::PlayPause);
        assert!(!s.playing);
        s.advance();
        assert_eq!(s.anim_frame, 0);
    }

    #[test]
    fn key_poses_cycle() {
        let mut s = state();
        assert_eq!(s.key_pose().frame, 0);
        s.apply(Action::NextKeyPose);
        assert_eq!(s.key_pose().name, "B");
        assert_eq!(s.key_pose().frame, 24);
        s.apply(Action::NextKeyPose);
        assert_eq!(s.key_pose().name, "A");
        // No key poses given: one at frame 0.
        let one = PreviewState::new(10, vec![], 3);
        assert_eq!(one.key_pose().frame, 0);
    }

    #[test]
    fn toggles_and_effects() {
        let mut s = state();
        assert_eq!(s.flags(), "Damol");
        s.apply(Action::ToggleDiminish);
        s.apply(Action::ToggleAxes);
        s.apply(Action::ToggleMasks);
        assert_eq!(s.apply(Action::ToggleOnion), Effect::None);
        assert_eq!(s.apply(Action::ToggleLineUp), Effect::LineUpOn);
        assert_eq!(s.flags(), "dAMOL");
        assert_eq!(s.apply(Action::ToggleLineUp), Effect::None);
        assert!(!s.diminish && s.overlays.axes && s.overlays.masks && s.overlays.onion);
        assert_eq!(s.apply(Action::ToggleRecording), Effect::StartRecording);
        assert!(s.recording);
        assert_eq!(s.apply(Action::ToggleRecording), Effect::StopRecording);
        assert!(!s.recording);
        assert_eq!(s.apply(Action::Capture), Effect::Capture);
        assert_eq!(s.apply(Action::Help), Effect::PrintHelp);
        assert!(s.overlays.help);
        assert_eq!(s.apply(Action::Quit), Effect::Quit);
        assert_eq!(
            s.apply(Action::SelectCapture(-1)),
            Effect::SelectCapture(-1)
        );
    }

    #[test]
    fn fills_cycle_and_shadows_toggle() {
        let mut s = state();
        assert_eq!((s.fill_name(), s.shadows), ("rays", false));
        let mut s2 = state().with_fills(vec![], 3);
        assert_eq!(s2.fill_name(), "rays", "an empty list keeps the fill");
        assert_eq!(s2.apply(Action::CycleFill), Effect::None);
        assert_eq!(s2.fill_name(), "rays", "one fill cycles to itself");
        s = s.with_fills(vec!["rays".into(), "plate".into(), "rectangle".into()], 1);
        assert_eq!(s.fill_name(), "plate");
        s.diminish = false;
        assert_eq!(s.apply(Action::CycleFill), Effect::None);
        assert_eq!((s.fill_name(), s.diminish), ("rectangle", true));
        s.apply(Action::CycleFill);
        assert_eq!(s.fill_name(), "rays");
        assert_eq!(state().with_fills(vec!["a".into()], 9).fill, 0);
        assert_eq!(s.apply(Action::ToggleShadows), Effect::None);
        assert!(s.hide_board, "the shot's hide is on at the start");
        assert_eq!(s.apply(Action::ToggleHide), Effect::None);
        assert!(!s.hide_board);
        s.apply(Action::ToggleHide);
        assert!(s.hide_board);
        assert!(s.shadows);
        s.apply(Action::ToggleShadows);
        assert!(!s.shadows);
        // The status line's flags are unchanged by both.
        assert_eq!(s.flags(), state().flags());
    }

    #[test]
    fn placement_mode_nudges_registers_and_writes() {
        let mut s = state();
        let nudge = |n, fine| Action::Nudge { nudge: n, fine };
        // Nothing to nudge until a placement is set, and only in placement mode.
        assert_eq!(s.apply(nudge(Nudge::X(1), false)), Effect::None);
        let start = PlacementValues {
            translation_m: [0.003, -0.004, -0.0009],
            yaw_deg: 25.0,
        };
        s.set_placement(start);
        assert!(!s.placement_edited);
        assert_eq!(s.apply(nudge(Nudge::X(1), false)), Effect::None);
        assert_eq!(s.placement, Some(start));
        assert_eq!(s.apply(Action::TogglePlace), Effect::None);
        assert!(s.placing);
        // Normal steps: 2 mm and 1 degree; fine: 0.5 mm and 0.2 degree.
        for (n, fine) in [
            (Nudge::X(1), false),
            (Nudge::X(-1), true),
            (Nudge::Y(-1), false),
            (Nudge::Lift(-1), true),
            (Nudge::Yaw(1), false),
            (Nudge::Yaw(-1), true),
        ] {
            assert_eq!(s.apply(nudge(n, fine)), Effect::PlacementChanged);
        }
        let p = s.placement.expect("placement");
        let want = [0.003 + 0.002 - 0.0005, -0.004 - 0.002, -0.0009 - 0.0005];
        for (got, want) in p.translation_m.iter().zip(want) {
            assert!((got - want).abs() < 1e-12, "{p:?}");
        }
        assert!((p.yaw_deg - 25.8).abs() < 1e-12, "{p:?}");
        assert!(s.placement_edited);
        assert_eq!(
            p.describe(),
            "x +4.5 mm  y -6.0 mm  lift -1.4 mm  yaw +25.8 deg"
        );
        assert_eq!(s.apply(Action::WritePlacement), Effect::WritePlacement);
        s.placement_written();
        assert!(!s.placement_edited);
        assert_eq!(s.apply(Action::Register), Effect::Register);
        s.set_placement(start);
        assert!(s.placement_edited && s.placement == Some(start));
        // The same placement again is no edit.
        s.placement_written();
        s.set_placement(start);
        assert!(!s.placement_edited);
        // Placement mode off: the keys do nothing.
        s.apply(Action::TogglePlace);
        assert_eq!(s.apply(nudge(Nudge::Y(1), false)), Effect::None);
        assert_eq!(s.placement, Some(start));
        // The flags of the status line are unchanged by placement mode.
        assert_eq!(s.flags(), "Damol");
    }

    #[test]
    fn overlays_from_the_command_line() {
        let names = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let o = Overlays::parse(&names(&["axes", " Onion", "line-up", ""])).unwrap();
        assert!(o.axes && o.onion && o.line_up && !o.masks && !o.help);
        assert_eq!(Overlays::parse(&[]).unwrap(), Overlays::default());
        let e = Overlays::parse(&names(&["axes", "bogus"])).unwrap_err();
        let e = e.to_string();
        assert!(e.contains("\"bogus\""), "{e}");
        assert_eq!(
            e,
            "unknown overlay \"bogus\" (axes, masks, onion, lineup, help)"
        );
    }

    #[test]
    fn capture_selection() {
        assert_eq!(select_capture(None, 0, -1), None);
        assert_eq!(select_capture(None, 3, 0), Some(2));
        assert_eq!(select_capture(None, 3, -1), Some(1));
        assert_eq!(select_capture(Some(0), 3, -1), Some(0));
        assert_eq!(select_capture(Some(1), 3, 5), Some(2));
        // A stale selection past the end is clamped.
        assert_eq!(select_capture(Some(9), 3, 0), Some(2));
    }
}
