//! The preview's key map: a pressed key (winit's logical key) and the modifiers -> an
//! [`Action`]. Pure, tested without a window.

use pa_overlay::action::{Action, Nudge};
use winit::keyboard::{Key, NamedKey};

/// The action of a key press; `None` for keys without one. Letters work in either case and
/// with Caps Lock; `shift` only changes the steps. In placement mode (`placing`) the arrows,
/// PgUp/PgDn and `,` `.` nudge the placement instead.
pub fn action_for(key: &Key, shift: bool, placing: bool) -> Option<Action> {
    if placing {
        if let Some(nudge) = nudge_for(key) {
            let fine = shift || matches!(key, Key::Character(c) if c == "<" || c == ">");
            return Some(Action::Nudge { nudge, fine });
        }
    }
    let step = if shift { 10 } else { 1 };
    match key {
        Key::Named(named) => match named {
            NamedKey::ArrowLeft => Some(Action::Step(-step)),
            NamedKey::ArrowRight => Some(Action::Step(step)),
            NamedKey::Home => Some(Action::First),
            NamedKey::End => Some(Action::Last),
            NamedKey::Space => Some(Action::PlayPause),
            NamedKey::Enter => Some(Action::Capture),
            NamedKey::Escape => Some(Action::Quit),
            NamedKey::PageUp => Some(Action::SelectCapture(-1)),
            NamedKey::PageDown => Some(Action::SelectCapture(1)),
            _ => None,
        },
        Key::Character(s) => {
            let mut chars = s.chars();
            let c = chars.next()?;
            if chars.next().is_some() {
                return None;
            }
            match c.to_ascii_lowercase() {
                ' ' => Some(Action::PlayPause),
                '[' | '{' => Some(Action::Scrub(-step)),
                ']' | '}' => Some(Action::Scrub(step)),
                'k' => Some(Action::NextKeyPose),
                'd' => Some(Action::ToggleDiminish),
                'f' => Some(Action::CycleFill),
                's' => Some(Action::ToggleShadows),
                'b' => Some(Action::ToggleHide),
                'a' => Some(Action::ToggleAxes),
                'm' => Some(Action::ToggleMasks),
                'o' => Some(Action::ToggleOnion),
                'l' => Some(Action::ToggleLineUp),
                'c' => Some(Action::Capture),
                'r' => Some(Action::ToggleRecording),
                'h' | '?' => Some(Action::Help),
                'q' => Some(Action::Quit),
                'p' => Some(Action::TogglePlace),
                'g' => Some(Action::Register),
                'w' => Some(Action::WritePlacement),
                _ => None,
            }
        }
        _ => None,
    }
}

/// The placement nudge of a key: arrows on the table (marker x, y), PgUp/PgDn the lift (up
/// is marker -z), `,` `.` (`<` `>` with Shift) the yaw.
fn nudge_for(key: &Key) -> Option<Nudge> {
    match key {
        Key::Named(NamedKey::ArrowLeft) => Some(Nudge::X(-1)),
        Key::Named(NamedKey::ArrowRight) => Some(Nudge::X(1)),
        Key::Named(NamedKey::ArrowUp) => Some(Nudge::Y(-1)),
        Key::Named(NamedKey::ArrowDown) => Some(Nudge::Y(1)),
        Key::Named(NamedKey::PageUp) => Some(Nudge::Lift(-1)),
        Key::Named(NamedKey::PageDown) => Some(Nudge::Lift(1)),
        Key::Character(c) if c == "," || c == "<" => Some(Nudge::Yaw(-1)),
        Key::Character(c) if c == "." || c == ">" => Some(Nudge::Yaw(1)),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ch(s: &str) -> Key {
        Key::Character(s.into())
    }

    #[test]
    fn arrows_step_one_or_ten() {
        let left = Key::Named(NamedKey::ArrowLeft);
        let right = Key::Named(NamedKey::ArrowRight);
        assert_eq!(action_for(&left, false, false), Some(Action::Step(-1)));
        assert_eq!(action_for(&right, false, false), Some(Action::Step(1)));
        assert_eq!(action_for(&left, true, false), Some(Action::Step(-10)));
        assert_eq!(action_for(&right, true, false), Some(Action::Step(10)));
        assert_eq!(
            action_for(&Key::Named(NamedKey::Home), false, false),
            Some(Action::First)
        );
        assert_eq!(
            action_for(&Key::Named(NamedKey::End), false, false),
            Some(Action::Last)
        );
    }

    #[test]
    fn letters_in_either_case() {
        for (k, a) in [
            ("k", Action::NextKeyPose),
            ("d", Action::ToggleDiminish),
            ("f", Action::CycleFill),
            ("s", Action::ToggleShadows),
            ("b", Action::ToggleHide),
            ("a", Action::ToggleAxes),
            ("m", Action::ToggleMasks),
            ("o", Action::ToggleOnion),
            ("l", Action::ToggleLineUp),
            ("c", Action::Capture),
            ("r", Action::ToggleRecording),
            ("h", Action::Help),
            ("q", Action::Quit),
            ("p", Action::TogglePlace),
            ("g", Action::Register),
            ("w", Action::WritePlacement),
        ] {
            assert_eq!(action_for(&ch(k), false, false), Some(a), "{k}");
            assert_eq!(
                action_for(&ch(&k.to_uppercase()), true, false),
                Some(a),
                "{k} shifted"
            );
        }
    }

    #[test]
    fn the_other_keys() {
        assert_eq!(action_for(&ch("["), false, false), Some(Action::Scrub(-1)));
        assert_eq!(action_for(&ch("]"), false, false), Some(Action::Scrub(1)));
        // Shift+[ types '{' on US layouts.
        assert_eq!(action_for(&ch("{"), true, false), Some(Action::Scrub(-10)));
        assert_eq!(
            action_for(&Key::Named(NamedKey::Space), false, false),
            Some(Action::PlayPause)
        );
        assert_eq!(
            action_for(&Key::Named(NamedKey::Enter), false, false),
            Some(Action::Capture)
        );
        assert_eq!(
            action_for(&Key::Named(NamedKey::Escape), false, false),
            Some(Action::Quit)
        );
        assert_eq!(
            action_for(&Key::Named(NamedKey::PageUp), false, false),
            Some(Action::SelectCapture(-1))
        );
        assert_eq!(action_for(&ch("x"), false, false), None);
        assert_eq!(action_for(&ch("ab"), false, false), None);
        assert_eq!(action_for(&Key::Named(NamedKey::F1), false, false), None);
        assert_eq!(action_for(&Key::Dead(None), false, false), None);
    }

    #[test]
    fn placement_mode_keys_nudge() {
        let named = |k| Key::Named(k);
        for (key, nudge) in [
            (named(NamedKey::ArrowLeft), Nudge::X(-1)),
            (named(NamedKey::ArrowRight), Nudge::X(1)),
            (named(NamedKey::ArrowUp), Nudge::Y(-1)),
            (named(NamedKey::ArrowDown), Nudge::Y(1)),
            (named(NamedKey::PageUp), Nudge::Lift(-1)),
            (named(NamedKey::PageDown), Nudge::Lift(1)),
            (ch(","), Nudge::Yaw(-1)),
            (ch("."), Nudge::Yaw(1)),
        ] {
            assert_eq!(
                action_for(&key, false, true),
                Some(Action::Nudge { nudge, fine: false }),
                "{key:?}"
            );
            assert_eq!(
                action_for(&key, true, true),
                Some(Action::Nudge { nudge, fine: true }),
                "{key:?}"
            );
        }
        // Shift+, types '<' on US layouts: a fine step.
        assert_eq!(
            action_for(&ch("<"), true, true),
            Some(Action::Nudge {
                nudge: Nudge::Yaw(-1),
                fine: true
            })
        );
        // Outside placement mode the keys keep their meaning.
        assert_eq!(
            action_for(&named(NamedKey::ArrowLeft), false, false),
            Some(Action::Step(-1))
        );
        assert_eq!(
            action_for(&named(NamedKey::PageUp), false, false),
            Some(Action::SelectCapture(-1))
        );
        assert_eq!(action_for(&ch(","), false, false), None);
        // The other keys work in placement mode too.
        assert_eq!(action_for(&ch("g"), false, true), Some(Action::Register));
        assert_eq!(action_for(&ch("K"), true, true), Some(Action::NextKeyPose));
    }
}
