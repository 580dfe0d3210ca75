//! The preview's key map: a pressed key (winit's logical key) and the modifiers -> an
//! [`Action`]. Pure, tested without a window.

use pa_overlay::action::Action;
use winit::keyboard::{Key, NamedKey};

/// The action of a key press; `None` for keys without one. Letters work in either case and
/// with Caps Lock; `shift` only changes the arrows' step.
pub fn action_for(key: &Key, shift: bool) -> Option<Action> {
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
                'a' => Some(Action::ToggleAxes),
                'm' => Some(Action::ToggleMasks),
                'o' => Some(Action::ToggleOnion),
                'l' => Some(Action::ToggleLineUp),
                'c' => Some(Action::Capture),
                'r' => Some(Action::ToggleRecording),
                'h' | '?' => Some(Action::Help),
                'q' => Some(Action::Quit),
                _ => None,
            }
        }
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
        assert_eq!(action_for(&left, false), Some(Action::Step(-1)));
        assert_eq!(action_for(&right, false), Some(Action::Step(1)));
        assert_eq!(action_for(&left, true), Some(Action::Step(-10)));
        assert_eq!(action_for(&right, true), Some(Action::Step(10)));
        assert_eq!(
            action_for(&Key::Named(NamedKey::Home), false),
            Some(Action::First)
        );
        assert_eq!(
            action_for(&Key::Named(NamedKey::End), false),
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
            ("a", Action::ToggleAxes),
            ("m", Action::ToggleMasks),
            ("o", Action::ToggleOnion),
            ("l", Action::ToggleLineUp),
            ("c", Action::Capture),
            ("r", Action::ToggleRecording),
            ("h", Action::Help),
            ("q", Action::Quit),
        ] {
            assert_eq!(action_for(&ch(k), false), Some(a), "{k}");
            assert_eq!(
                action_for(&ch(&k.to_uppercase()), true),
                Some(a),
                "{k} shifted"
            );
        }
    }

    #[test]
    fn the_other_keys() {
        assert_eq!(action_for(&ch("["), false), Some(Action::Scrub(-1)));
        assert_eq!(action_for(&ch("]"), false), Some(Action::Scrub(1)));
        // Shift+[ types '{' on US layouts.
        assert_eq!(action_for(&ch("{"), true), Some(Action::Scrub(-10)));
        assert_eq!(
            action_for(&Key::Named(NamedKey::Space), false),
            Some(Action::PlayPause)
        );
        assert_eq!(
            action_for(&Key::Named(NamedKey::Enter), false),
            Some(Action::Capture)
        );
        assert_eq!(
            action_for(&Key::Named(NamedKey::Escape), false),
            Some(Action::Quit)
        );
        assert_eq!(
            action_for(&Key::Named(NamedKey::PageUp), false),
            Some(Action::SelectCapture(-1))
        );
        assert_eq!(action_for(&ch("x"), false), None);
        assert_eq!(action_for(&ch("ab"), false), None);
        assert_eq!(action_for(&Key::Named(NamedKey::F1), false), None);
        assert_eq!(action_for(&Key::Dead(None), false), None);
    }
}
