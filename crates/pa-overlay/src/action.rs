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
    /// The board hidden (the shot's `hide`: cover or plate) or shown.
    ToggleHide,
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
    /// Placement mode on or off: the key pose's outline over the frame, and the nudge keys.
    TogglePlace,
    /// Move the key prop's placement by one step (`fine`: a small one).
    Nudge {
        nudge: Nudge,
        fine: bool,
    },
    /// Register the placement on the last frames seen.
    Register,
    /// Write the placement into the shot file.
    WritePlacement,
}

/// One step of the placement: along the marker's x or y on the table, the lift (marker z,
/// negative is up) or the yaw, in the direction of the sign.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Nudge {
    X(i8),
    Y(i8),
    Lift(i8),
    Yaw(i8),
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
    "B             board hidden / shown (the shot's hide: cover or plate)",
    "A             tracked marker axes",
    "M             masks (key pose magenta, twin cyan)",
    "O             onion skin (previous in-between red, next green)",
    "L             line-up: a captured frame at 50%",
    "PgUp/PgDn     line up an earlier / later capture",
    "C or Enter    capture the composited frame (PNG)",
    "R             start / stop recording (numbered PNGs)",
    "P             placement: the key pose's outline, and these keys:",
    "  arrows        move it on the table 2 mm (Shift: 0.5 mm)",
    "  , .           turn it 1 degree (Shift: 0.2)",
    "  PgUp/PgDn     lift / lower it 2 mm (Shift: 0.5 mm)",
    "G             register the placement on the last frames seen",
    "W             write the placement into the shot file (backup .bak)",
    "H             this help",
    "Q or Esc      quit",
];

/// Whether a held key's auto-repeat should repeat the action (stepping, scrubbing and
/// nudging do; toggles, captures, recording, registering and writing do not).
pub fn repeats(action: Action) -> bool {
    matches!(
        action,
        Action::Step(_) | Action::Scrub(_) | Action::Nudge { .. }
    )
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
        assert!(repeats(Action::Nudge {
            nudge: Nudge::Yaw(1),
            fine: true
        }));
        assert!(!repeats(Action::Register));
        assert!(!repeats(Action::WritePlacement));
    }
}
