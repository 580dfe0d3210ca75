//! What the user can ask the preview for ([`Action`]), the key list ([`HELP`]) and which
//! actions a held key repeats. The mapping from a window system's key events to actions lives
//! with the window (the binary's `cmd/preview/keys.rs`); this part is pure.

/// What the user asked for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    /// Move the animation by this many frames (wraps around the clip).
    Step(i32),
    /// Scrub the animation by this many frames (clamps at the clip's ends).
    Scrub(i32),
    /// Go to the first animation frame.
    First,
    /// Go to the last animation frame.
    Last,
    /// Play or pause the animation.
    PlayPause,
    /// The next key prop is now in front of the camera.
    NextKeyPose,
    ToggleDiminish,
    /// The next fill of the preview's list (the real prop removed another way).
    CycleFill,
    /// Shadows on or off (the key prop's lifted, the twin's cast).
    ToggleShadows,
    ToggleAxes,
    ToggleMasks,
    ToggleOnion,
    ToggleLineUp,
    /// Line up against an earlier (-1) or later (+1) captured frame.
    SelectCapture(i32),
    /// Save the current composited frame.
    Capture,
    /// Start or stop recording composited frames.
    ToggleRecording,
    /// Print the keys and show them on screen.
    Help,
    Quit,
}

/// The keys, one line each, as printed at start and on `H` (and drawn on screen).
pub const HELP: &[&str] = &[
    "Left/Right    step the animation one frame (Shift: ten)",
    "Home/End      first / last animation frame",
    "[ ] or drag   scrub the animation (drag across the image)",
    "Space         play / pause the animation",
    "K             next key pose (the key prop in front of the camera)",
    "D             diminished reality on / off",
    "F             next fill (rays, plate, rectangle, ...)",
    "S             shadows on / off (lift the prop's, cast the twin's)",
    "A             tracked marker axes",
    "M             masks (key pose magenta, twin cyan)",
    "O             onion skin (previous in-between red, next green)",
    "L             line-up: a captured frame at 50%",
    "PgUp/PgDn     line up an earlier / later capture",
    "C or Enter    capture the composited frame (PNG)",
    "R             start / stop recording (numbered PNGs)",
    "H             this help",
    "Q or Esc      quit",
];

/// Whether a held key's auto-repeat should repeat the action (stepping and scrubbing do;
/// toggles, captures and recording do not).
pub fn repeats(action: Action) -> bool {
    matches!(action, Action::Step(_) | Action::Scrub(_))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_motion_repeats() {
        assert!(repeats(Action::Step(1)));
        assert!(repeats(Action::Scrub(-1)));
        assert!(!repeats(Action::Capture));
        assert!(!repeats(Action::ToggleRecording));
        assert!(!repeats(Action::PlayPause));
        assert!(!repeats(Action::CycleFill));
        assert!(!repeats(Action::ToggleShadows));
    }
}
