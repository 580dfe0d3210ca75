//! The methods `propsalive eval` compares on the generated scenes: the paper's pipeline, each
//! of our changes alone, ours in full, ours with a clean plate (aligned to the frame, and as
//! the tracked poses put it), the patch fill (alone and with the clean plate), the model's own
//! texture, two
//! key poses, the paper and ours on a tripod camera, and ours without relighting or feathered
//! seams, with only one of them. The report's tables and curves are
//! keyed by [`Method::name`] (curves are drawn for the methods named `ours:...`,
//! `ours, two...` and `paper...`).

use pa_pipeline::ar::{ArSettings, Fill, LiveLook, Texturing};

use crate::scene::CameraPath;

/// One compared method.
pub struct Method {
    /// The name in the report.
    pub name: &'static str,
    /// The pipeline's settings.
    pub settings: ArSettings,
    /// The animation frames of the key poses present.
    pub key_frames: Vec<u32>,
    /// How the camera moves.
    pub camera_path: CameraPath,
}

/// The methods, in the report's order.
pub fn methods() -> Vec<Method> {
    let ours = ArSettings::ours();
    vec![
        Method {
            name: "paper (live, no visibility, rectangle fill)",
            settings: ArSettings::paper(),
            key_frames: vec![0],
            camera_path: CameraPath::Handheld,
        },
        Method {
            name: "live + visibility, rectangle fill",
            settings: ArSettings {
                fill: Fill::PaperRectangle,
                ..ours
            },
            key_frames: vec![0],
            camera_path: CameraPath::Handheld,
        },
        Method {
            name: "live, no visibility, ray fill",
            settings: ArSettings {
                texturing: Texturing::Live { visibility: false },
                ..ours
            },
            key_frames: vec![0],
            camera_path: CameraPath::Handheld,
        },
        Method {
            name: "ours: live + visibility, ray fill",
            settings: ours,
            key_frames: vec![0],
            camera_path: CameraPath::Handheld,
        },
        Method {
            name: "ours with clean plate",
            settings: ArSettings {
                fill: Fill::CleanPlate,
                ..ours
            },
            key_frames: vec![0],
            camera_path: CameraPath::Handheld,
        },
        Method {
            name: "ours with clean plate, not aligned",
            settings: ArSettings {
                fill: Fill::CleanPlate,
                align_plate: false,
                ..ours
            },
            key_frames: vec![0],
            camera_path: CameraPath::Handheld,
        },
        Method {
            name: "ours, patch fill",
            settings: ArSettings {
                fill: Fill::Patch { plate: false },
                ..ours
            },
            key_frames: vec![0],
            camera_path: CameraPath::Handheld,
        },
        Method {
            name: "ours, patch fill with clean plate",
            settings: ArSettings {
                fill: Fill::Patch { plate: true },
                ..ours
            },
            key_frames: vec![0],
            camera_path: CameraPath::Handheld,
        },
        Method {
            name: "model texture (no live sampling), ray fill",
            settings: ArSettings {
                texturing: Texturing::ModelTexture,
                ..ours
            },
            key_frames: vec![0],
            camera_path: CameraPath::Handheld,
        },
        Method {
            name: "ours, two key poses (frames 0 and 24)",
            settings: ours,
            key_frames: vec![0, 24],
            camera_path: CameraPath::Handheld,
        },
        Method {
            name: "tripod camera: paper",
            settings: ArSettings::paper(),
            key_frames: vec![0],
            camera_path: CameraPath::Static,
        },
        Method {
            name: "tripod camera: ours",
            settings: ours,
            key_frames: vec![0],
            camera_path: CameraPath::Static,
        },
        // How a live sample becomes the twin's colour (issue 13): ours relits it at the
        // in-between's normal and feathers the seams; these rows take one or both away.
        Method {
            name: "ours: plain look (not relit, hard seams)",
            settings: ArSettings {
                look: LiveLook::PLAIN,
                ..ours
            },
            key_frames: vec![0],
            camera_path: CameraPath::Handheld,
        },
        Method {
            name: "ours: relit, hard seams",
            settings: ArSettings {
                look: LiveLook {
                    relight: true,
                    feather: false,
                    sun: true,
                    grazing: true,
                },
                ..ours
            },
            key_frames: vec![0],
            camera_path: CameraPath::Handheld,
        },
        Method {
            name: "ours: feathered seams, not relit",
            settings: ArSettings {
                look: LiveLook {
                    relight: false,
                    feather: true,
                    sun: false,
                    grazing: false,
                },
                ..ours
            },
            key_frames: vec![0],
            camera_path: CameraPath::Handheld,
        },
        Method {
            name: "ours: first-order light (no sun, no cast shadows)",
            settings: ArSettings {
                look: LiveLook {
                    sun: false,
                    ..LiveLook::RELIT_FEATHERED
                },
                ..ours
            },
            key_frames: vec![0],
            camera_path: CameraPath::Handheld,
        },
        Method {
            name: "ours: no grazing reflection",
            settings: ArSettings {
                look: LiveLook {
                    grazing: false,
                    ..LiveLook::RELIT_FEATHERED
                },
                ..ours
            },
            key_frames: vec![0],
            camera_path: CameraPath::Handheld,
        },
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_methods_are_pinned() {
        let m = methods();
        let names: Vec<_> = m.iter().map(|m| m.name).collect();
        assert_eq!(
            names,
            [
                "paper (live, no visibility, rectangle fill)",
                "live + visibility, rectangle fill",
                "live, no visibility, ray fill",
                "ours: live + visibility, ray fill",
                "ours with clean plate",
                "ours with clean plate, not aligned",
                "ours, patch fill",
                "ours, patch fill with clean plate",
                "model texture (no live sampling), ray fill",
                "ours, two key poses (frames 0 and 24)",
                "tripod camera: paper",
                "tripod camera: ours",
                "ours: plain look (not relit, hard seams)",
                "ours: relit, hard seams",
                "ours: feathered seams, not relit",
                "ours: first-order light (no sun, no cast shadows)",
                "ours: no grazing reflection",
            ]
        );
        let keys: Vec<_> = m.iter().map(|m| m.key_frames.clone()).collect();
        assert_eq!(keys[9], [0, 24]);
        assert!(keys.iter().enumerate().all(|(i, k)| i == 9 || k == &[0]));
        let tripod = m
            .iter()
            .filter(|m| m.camera_path == CameraPath::Static)
            .count();
        assert_eq!(tripod, 2);
        assert!(matches!(m[4].settings.fill, Fill::CleanPlate));
        assert!(m[4].settings.align_plate);
        assert!(matches!(m[5].settings.fill, Fill::CleanPlate));
        assert!(!m[5].settings.align_plate);
        assert!(matches!(m[6].settings.fill, Fill::Patch { plate: false }));
        assert!(matches!(m[7].settings.fill, Fill::Patch { plate: true }));
        assert!(matches!(m[8].settings.texturing, Texturing::ModelTexture));
        let looks: Vec<_> = m.iter().map(|m| m.settings.look).collect();
        // Every row but the look's own ablations has our look (the paper's rows: plain).
        for (i, l) in looks.iter().enumerate() {
            let paper = m[i].name.contains("paper");
            match i {
                12 => assert_eq!(*l, LiveLook::PLAIN),
                13 => assert!(l.relight && !l.feather),
                14 => assert!(!l.relight && l.feather),
                15 => assert!(l.relight && l.feather && !l.sun),
                16 => assert!(l.relight && l.sun && !l.grazing),
                _ if paper => assert_eq!(*l, LiveLook::PLAIN, "{}", m[i].name),
                _ => assert_eq!(*l, LiveLook::RELIT_FEATHERED, "{}", m[i].name),
            }
        }
    }
}
