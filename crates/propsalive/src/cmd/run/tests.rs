use super::*;
use pa_camera::Intrinsics;
use pa_take::mp4::mp4_is_ours;
use pa_take::{file_stamp, foreign_files, Entry, TakeCamera, TakeVideo, TAKE_DIRS};
use pa_video::source::{CameraSource, VideoSource};
use pa_video::{Frame, Timestamp, VideoError, VideoReader};
use std::collections::HashSet;

/// The take's log ([`pa_take::read_log`]), its entries.
fn read_log(path: &Path) -> Result<BTreeMap<usize, Entry>> {
    Ok(pa_take::read_log(path)?.entries)
}

impl Progress {
    /// A silent one (tests).
    fn hidden() -> Self {
        Progress {
            bar: ProgressBar::hidden(),
            plain: false,
            started: Instant::now(),
            last_line: None,
            total: None,
        }
    }
}

/// Writes `camera.gltf` from the log's poses of stills `0..n` ([`pa_take::camera_export`])
/// and says what it did.
fn export_camera(
    out: &Path,
    entries: &BTreeMap<usize, Entry>,
    n: usize,
    intrinsics: &Intrinsics,
    fps: f32,
) -> Result<()> {
    let exported = pa_take::camera_export::export_camera(out, entries, n, intrinsics, fps)?;
    errln!("{exported}");
    Ok(())
}

/// Encodes the take's frames `0..n` as an H.264 MP4 ([`pa_take::mp4::write_mp4`]) and says
/// what it wrote.
fn write_mp4(
    mp4: &Path,
    out: &Path,
    entries: &BTreeMap<usize, Entry>,
    n: usize,
    fps: f32,
    force: bool,
) -> Result<()> {
    let written = pa_take::mp4::write_mp4(mp4, out, entries, n, fps, force)?;
    errln!("{}", written.line(mp4));
    Ok(())
}

/// A fake live camera: `frames` frames, then "disconnected" once, then nothing.
struct FakeCamera {
    frames: u64,
    given: u64,
    lost: bool,
}

fn synth(i: u64, w: u32, h: u32) -> Vec<u8> {
    (0..w * h)
        .flat_map(|p| {
            [
                (p % 251) as u8,
                (i * 40 % 256) as u8,
                (p / w * 3 % 256) as u8,
                255,
            ]
        })
        .collect()
}

impl pa_video::FrameSource for FakeCamera {
    fn next_frame(&mut self) -> Result<Option<Frame>, VideoError> {
        if self.given < self.frames {
            let i = self.given;
            self.given += 1;
            return Ok(Some(Frame {
                index: i,
                pts: Timestamp {
                    ticks: i as i64,
                    timescale: 24,
                },
                width: 64,
                height: 48,
                rgba: synth(i, 64, 48),
            }));
        }
        if self.lost {
            return Ok(None);
        }
        self.lost = true;
        Err(VideoError::DeviceLost {
            device: "/dev/video7".into(),
            frames: self.given,
        })
    }
    fn frame_size(&self) -> (u32, u32) {
        (64, 48)
    }
    fn fps(&self) -> Option<Fps> {
        Fps::new(24, 1).ok()
    }
    fn describe(&self) -> String {
        "fake camera".into()
    }
}

/// A fake video: frames 0.. with a decode error at the given indices.
struct FakeVideo {
    frames: usize,
    bad: Vec<usize>,
    at: usize,
}

impl pa_video::FrameSource for FakeVideo {
    fn next_frame(&mut self) -> Result<Option<Frame>, VideoError> {
        let i = self.at;
        if i >= self.frames {
            return Ok(None);
        }
        self.at += 1;
        if self.bad.contains(&i) {
            return Err(VideoError::Decode {
                path: "clip.mp4".into(),
                frame: i as u64,
                detail: "damaged slice".into(),
            });
        }
        Ok(Some(Frame {
            index: i as u64,
            pts: Timestamp {
                ticks: i as i64,
                timescale: 24,
            },
            width: 64,
            height: 48,
            rgba: synth(i as u64, 64, 48),
        }))
    }
    fn frame_size(&self) -> (u32, u32) {
        (64, 48)
    }
    fn fps(&self) -> Option<Fps> {
        Fps::new(24, 1).ok()
    }
    fn describe(&self) -> String {
        "fake video".into()
    }
}

/// Inverts the frame, "tracks" it at 1 m (a pose moving with the index), and reports the
/// left half as key pose and a square as twin. Sets `stop` after `stop_after` frames.
struct FakeProcessor {
    calls: usize,
    stop_after: Option<(usize, &'static AtomicBool)>,
}

impl FrameProcessor for FakeProcessor {
    fn process(
        &mut self,
        rgba8: &[u8],
        w: u32,
        h: u32,
        anim_frame: u32,
        _index: usize,
    ) -> Result<Processed> {
        self.calls += 1;
        if let Some((n, flag)) = self.stop_after {
            if self.calls >= n {
                flag.store(true, Ordering::SeqCst);
            }
        }
        let n = (w * h) as usize;
        let key: Vec<bool> = (0..n).map(|p| (p as u32 % w) < w / 2).collect();
        let twin: Vec<bool> = (0..n)
            .map(|p| (p as u32 % w) < 8 && (p as u32 / w) < 8)
            .collect();
        let out: Vec<u8> = rgba8
            .chunks_exact(4)
            .flat_map(|p| [255 - p[0], 255 - p[1], 255 - p[2], 255])
            .collect();
        let twin_rgba: Vec<u8> = twin
            .iter()
            .flat_map(|&t| if t { [200, 100, 50, 255] } else { [0; 4] })
            .collect();
        Ok(Processed {
            rgba8: out.clone(),
            pose: Some(glam::Mat4::from_translation(glam::Vec3::new(
                0.01 * anim_frame as f32,
                0.0,
                1.0,
            ))),
            reprojection_px: Some(0.1),
            used_ids: Some(vec![anim_frame, 7]),
            timings: StageTimings::default(),
            passes: Some(FramePasses {
                plate_rgba8: out,
                twin_rgba8: twin_rgba,
                key_mask: key,
                twin_mask: twin,
            }),
        })
    }
}

fn take_in(dir: &Path, passes: PassSet, unit: &'static str) -> Take {
    for d in TAKE_DIRS {
        std::fs::create_dir_all(dir.join(d)).expect("mkdir");
    }
    Take {
        out: dir.to_path_buf(),
        log_path: dir.join("log.jsonl"),
        entries: BTreeMap::new(),
        stale: HashSet::new(),
        exposure: 1,
        bit_depth: 8,
        shot_hash: "0".into(),
        key_name: "A".into(),
        passes,
        width: 64,
        height: 48,
        unit,
    }
}

fn all_passes() -> PassSet {
    PassSet {
        plate: true,
        twin: true,
        masks: true,
    }
}

#[test]
fn a_lost_camera_ends_the_take_cleanly_and_keeps_it() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut take = take_in(dir.path(), all_passes(), "frame");
    let mut source = TakeCamera {
        source: CameraSource::new(FakeCamera {
            frames: 3,
            given: 0,
            lost: false,
        }),
        inputs_dir: dir.path().join("inputs"),
        next_index: 0,
    };
    let stop = AtomicBool::new(false);
    let mut processor = FakeProcessor {
        calls: 0,
        stop_after: None,
    };
    let o = run_take(
        &mut take,
        &mut source,
        &mut processor,
        &mut BTreeMap::new(),
        None,
        None,
        &stop,
        &mut Progress::hidden(),
    )
    .expect("a lost camera is not an error");
    assert!(
        matches!(&o.end, End::Lost(m) if m.contains("/dev/video7") && m.contains("disconnected")),
        "{o:?}"
    );
    assert_eq!((o.processed, o.skipped_read), (3, 0));
    // Everything captured is in the take, known to the log.
    let log = read_log(&take.log_path).expect("log");
    assert_eq!(log.keys().copied().collect::<Vec<_>>(), [0, 1, 2]);
    for (i, e) in &log {
        assert_eq!(e.input, format!("inputs/{i:06}.png"));
        assert_eq!(
            e.output.as_deref(),
            Some(format!("frames/{i:06}.png").as_str())
        );
        let stamp = file_stamp(&dir.path().join(&e.input)).expect("input saved");
        assert_eq!((e.input_bytes, e.input_mtime_ns), stamp);
        let saved = image::open(dir.path().join(&e.input))
            .expect("png")
            .to_rgba8();
        assert_eq!(
            saved.as_raw(),
            &synth(*i as u64, 64, 48),
            "input {i} saved as captured"
        );
        for p in e.passes.as_ref().expect("passes") {
            assert!(dir.path().join(p).is_file(), "{p}");
        }
    }
    assert!(foreign_files(&take).expect("list").is_empty());
    // A capture cut short after saving an input (before its log line): kept, and the next
    // capture numbers on after it.
    std::fs::copy(
        dir.path().join("inputs/000002.png"),
        dir.path().join("inputs/000003.png"),
    )
    .expect("copy");
    assert_eq!(camera_start_index(&take), 4);
    assert!(foreign_files(&take).expect("list").is_empty());
    std::fs::remove_file(dir.path().join("inputs/000003.png")).expect("rm");
    assert_eq!(camera_start_index(&take), 3);
    // The end of the run: camera.gltf and the MP4 of what was captured.
    export_camera(
        dir.path(),
        &take.entries,
        3,
        &Intrinsics::from_fov_y(0.8, 64, 48).expect("k"),
        24.0,
    )
    .expect("camera.gltf");
    assert!(dir.path().join("camera.gltf").is_file());
    let mp4 = dir.path().join("take.mp4");
    write_mp4(&mp4, dir.path(), &take.entries, 3, 24.0, false).expect("mp4");
    let reader = VideoReader::open(&mp4).expect("reads back");
    assert_eq!(reader.info().frame_count, Some(3));
    assert_eq!(reader.info().fps, Fps::new(24, 1).ok());
    // Written again after a resumed run (it is the take's own), refused when it is not.
    assert!(mp4_is_ours(&mp4, dir.path()));
    write_mp4(&mp4, dir.path(), &take.entries, 3, 24.0, false).expect("rewrite own mp4");
    std::fs::write(&mp4, b"someone else's video").expect("replace");
    assert!(!mp4_is_ours(&mp4, dir.path()));
    let err = write_mp4(&mp4, dir.path(), &take.entries, 3, 24.0, false).expect_err("refused");
    assert!(err.to_string().contains("--force"), "{err}");
    assert!(check_mp4_target(&mp4, dir.path(), false).is_err());
    assert!(check_mp4_target(&mp4, dir.path(), true).is_ok());

    // The camera keeps going after the take's last index on the next run.
    let mut source = TakeCamera {
        source: CameraSource::new(FakeCamera {
            frames: 2,
            given: 0,
            lost: false,
        }),
        inputs_dir: dir.path().join("inputs"),
        next_index: 3,
    };
    let o = run_take(
        &mut take,
        &mut source,
        &mut processor,
        &mut BTreeMap::new(),
        None,
        Some(1),
        &stop,
        &mut Progress::hidden(),
    )
    .expect("run");
    assert_eq!(
        (o.processed, o.end),
        (1, End::Finished),
        "--frames 1 stops after one"
    );
    assert_eq!(read_log(&take.log_path).expect("log").len(), 4);
}

#[test]
fn a_damaged_video_frame_is_skipped_and_logged() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut take = take_in(dir.path(), PassSet::default(), "frame");
    let mut source = TakeVideo {
        source: VideoSource::new(
            FakeVideo {
                frames: 5,
                bad: vec![2],
                at: 0,
            },
            Path::new("clip.mp4"),
            Some(5),
        ),
        stamp: (1000, 7),
    };
    let stop = AtomicBool::new(false);
    let mut processor = FakeProcessor {
        calls: 0,
        stop_after: None,
    };
    let o = run_take(
        &mut take,
        &mut source,
        &mut processor,
        &mut BTreeMap::new(),
        Some(5),
        None,
        &stop,
        &mut Progress::hidden(),
    )
    .expect("run");
    assert_eq!((o.processed, o.skipped_read, o.end), (4, 1, End::Finished));
    let log = read_log(&take.log_path).expect("log");
    assert_eq!(log.len(), 5);
    assert!(
        log[&2]
            .skipped
            .as_deref()
            .is_some_and(|s| s.starts_with("unreadable") && s.contains("damaged slice")),
        "{:?}",
        log[&2]
    );
    // Frame i of the video stays still i after the damaged one.
    assert_eq!(log[&3].anim_frame, 3);
    let f3 = image::open(dir.path().join("frames/000003.png"))
        .expect("frame")
        .to_rgba8();
    assert_eq!(
        f3.as_raw()[1],
        255 - 3 * 40,
        "frame 3 is the video's frame 3"
    );
    assert!(!dir.path().join("frames/000002.png").exists());
    assert!(log
        .values()
        .all(|e| e.input == "clip.mp4" && e.input_bytes == 1000));
    // A changed video (another size or mtime) re-renders every frame; the same is done.
    take.entries = log;
    assert!(matches!(take.plan(1, "clip.mp4", (1000, 7)), Plan::Done));
    assert!(matches!(take.plan(2, "clip.mp4", (1000, 7)), Plan::Done));
    assert!(
        matches!(take.plan(1, "clip.mp4", (1000, 8)), Plan::Process(Some(m)) if m.starts_with("re-shot"))
    );
    // Asking for passes re-renders frames that lack them.
    take.passes = all_passes();
    assert!(matches!(
        take.plan(1, "clip.mp4", (1000, 7)),
        Plan::Process(None)
    ));
}

#[test]
fn ctrl_c_finishes_the_current_frame_and_stops() {
    static STOP_FLAG: AtomicBool = AtomicBool::new(false);
    let dir = tempfile::tempdir().expect("tmp");
    let mut take = take_in(dir.path(), PassSet::default(), "frame");
    let mut source = TakeVideo {
        source: VideoSource::new(
            FakeVideo {
                frames: 6,
                bad: vec![],
                at: 0,
            },
            Path::new("clip.mp4"),
            Some(6),
        ),
        stamp: (1, 1),
    };
    let mut processor = FakeProcessor {
        calls: 0,
        stop_after: Some((2, &STOP_FLAG)),
    };
    let o = run_take(
        &mut take,
        &mut source,
        &mut processor,
        &mut BTreeMap::new(),
        Some(6),
        None,
        &STOP_FLAG,
        &mut Progress::hidden(),
    )
    .expect("run");
    assert_eq!((o.processed, o.end), (2, End::Interrupted));
    let log = read_log(&take.log_path).expect("log");
    assert_eq!(log.keys().copied().collect::<Vec<_>>(), [0, 1]);
    assert!(dir.path().join("frames/000001.png").is_file());
}

#[test]
fn inputs_and_passes_parse() {
    // What each input form parses to is pa_video::source's test (`inputs_parse`); here, that
    // the binary's wrapper passes a folder through and names the flag in its errors.
    let dir = tempfile::tempdir().expect("tmp");
    assert_eq!(
        parse_input(dir.path()).expect("folder"),
        InputSpec::Folder(dir.path().to_path_buf())
    );
    let err = parse_input(&dir.path().join("nope.mp4")).expect_err("missing");
    assert!(err.to_string().starts_with("--input "), "{err}");
    assert!(err.to_string().contains("no such file"), "{err}");
    let p = PassSet::parse(&["plate".into(), "masks".into()]).expect("passes");
    assert_eq!(p.dirs(), ["plate", "masks"]);
    assert_eq!(PassSet::parse(&["all".into()]).expect("all"), all_passes());
    assert!(PassSet::parse(&["depth".into()]).is_err());
    assert!(!PassSet::default().any());
}
