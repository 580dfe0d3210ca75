//! Hostile calibration input (issue 11): a FIFO given as an image is skipped at once instead
//! of blocking, and a tag board with ids past its family's codes or with an id twice is
//! refused.

use std::time::Duration;

use glam::DVec2;
use pa_calib::{CalibrateError, Calibrator, ChessboardSize, ImageOutcome, Target};
use pa_track::board::BoardTag;
use pa_track::{Board, TagFamily};

fn within<T: Send + 'static>(what: &str, f: impl FnOnce() -> T + Send + 'static) -> T {
    pa_testkit::hostile::within(what, Duration::from_secs(20), f)
}

#[test]
fn a_fifo_or_device_given_as_an_image_is_skipped_at_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    let fifo = dir.path().join("view.png");
    pa_testkit::hostile::mkfifo(&fifo);
    for path in [fifo, "/dev/zero".into()] {
        let name = path.display().to_string();
        let outcome = within(&name, move || {
            let mut cal = Calibrator::new(Target::Chessboard {
                size: ChessboardSize { rows: 6, cols: 9 },
                square_m: 0.025,
            })
            .expect("valid target");
            cal.add_file(&path)
        })
        .expect("skipped, not an error");
        match outcome {
            ImageOutcome::Skipped(reason) => {
                let r = reason.to_string();
                assert!(r.contains(&name) && r.contains("not a regular file"), "{r}");
            }
            other => panic!("{name}: {other:?}"),
        }
    }
}

fn tag(id: u32, x: f64) -> BoardTag {
    BoardTag {
        id,
        center_m: DVec2::new(x, 0.0),
        size_m: 0.04,
        rotation_rad: 0.0,
    }
}

fn board_err(tags: Vec<BoardTag>) -> String {
    let board = Board {
        family: TagFamily::Tag36h11,
        tags,
    };
    match Calibrator::new(Target::TagBoard { board, min_tags: 1 }) {
        Err(e @ CalibrateError::InvalidTarget { .. }) => e.to_string(),
        Err(e) => panic!("unexpected error {e}"),
        Ok(_) => panic!("accepted"),
    }
}

#[test]
fn boards_with_impossible_or_repeated_ids_are_refused() {
    // tag36h11 has 587 codes: ids 0..=586.
    let e = board_err(vec![tag(586, 0.0), tag(587, 0.05)]);
    assert!(e.contains("587") && e.contains("tag36h11"), "{e}");
    let e = board_err(vec![tag(u32::MAX, 0.0)]);
    assert!(e.contains(&u32::MAX.to_string()), "{e}");
    let e = board_err(vec![tag(3, 0.0), tag(4, 0.05), tag(3, 0.1)]);
    assert!(e.contains("tag id 3") && e.contains("twice"), "{e}");
    let e = board_err(vec![tag(1, f64::NAN)]);
    assert!(e.contains("finite"), "{e}");
    let mut t = tag(1, 0.0);
    t.size_m = f64::INFINITY;
    let e = board_err(vec![t]);
    assert!(e.contains("finite"), "{e}");
    // The last code is fine.
    let board = Board {
        family: TagFamily::Tag36h11,
        tags: vec![tag(0, 0.0), tag(586, 0.05)],
    };
    assert!(Calibrator::new(Target::TagBoard { board, min_tags: 1 }).is_ok());
}
