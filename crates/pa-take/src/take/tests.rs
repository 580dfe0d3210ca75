use super::*;
use crate::log::{write_durable, Written};
use crate::mp4::{check_mp4_target, mp4_is_current, mp4_is_ours, take_hash, write_mp4, Mp4Written};
use crate::{encode, read_log, write_log};

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
        width: 32,
        height: 24,
        unit,
    }
}

/// Writes frame `i` (a 32x24 red of level `i * 20`) with its log entry, as a run does.
fn add_frame(take: &mut Take, i: usize, name: &str, stamp: (u64, u64)) {
    let rgba: Vec<u8> = (0..32 * 24)
        .flat_map(|_| [(i * 20) as u8, 0, 0, 255])
        .collect();
    let png = encode(&rgba, None, 8, 32, 24).expect("png");
    let rel = format!("frames/{}", frame_name(i));
    write_durable(&take.out.join(&rel), &png).expect("write");
    let mut e = take.new_entry(i, name, stamp, i as u32);
    e.output = Some(rel.clone());
    e.written = Some(vec![Written::of(rel, &png)]);
    e.camera_from_marker = Some(
        glam::Mat4::from_translation(glam::Vec3::Z)
            .to_cols_array()
            .to_vec(),
    );
    take.entries.insert(i, e);
}

#[test]
fn plans_follow_the_log_and_the_files() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut take = take_in(dir.path(), PassSet::default(), "still");
    add_frame(&mut take, 0, "a.png", (10, 1));
    add_frame(&mut take, 1, "b.png", (10, 2));
    let mut skipped = take.new_entry(2, "c.png", (10, 3), 2);
    skipped.skipped = Some("unreadable: x".into());
    take.entries.insert(2, skipped);
    assert_eq!(take.plan(0, "a.png", (10, 1)), Plan::Done);
    assert_eq!(take.plan(2, "c.png", (10, 3)), Plan::Done);
    assert_eq!(take.plan(3, "d.png", (10, 4)), Plan::Process(None));
    assert_eq!(
        take.plan(0, "a.png", (11, 1)),
        Plan::Process(Some("re-shot: frame 0 replaced (a.png)".into()))
    );
    assert_eq!(
        take.plan(2, "c.png", (10, 9)),
        Plan::Process(Some(
            "re-shot: still 2 (c.png) was skipped before; trying again".into()
        ))
    );
    std::fs::write(dir.path().join("frames/000001.png"), b"not the frame").expect("write");
    assert!(
        matches!(take.plan(1, "b.png", (10, 2)), Plan::Process(Some(m)) if m.starts_with("frame 1 re-rendered: frames/000001.png has 13 bytes")),
    );
    std::fs::remove_file(dir.path().join("frames/000001.png")).expect("rm");
    assert_eq!(take.plan(1, "b.png", (10, 2)), Plan::Process(None));
    take.stale.insert(0);
    assert_eq!(
        take.plan(0, "a.png", (10, 1)),
        Plan::Process(Some("settings changed: frame 0 re-rendered".into()))
    );
    // An entry of an older version (no `written`) is redone.
    take.stale.clear();
    if let Some(e) = take.entries.get_mut(&0) {
        e.written = None;
    }
    assert_eq!(
        take.plan(0, "a.png", (10, 1)),
        Plan::Process(Some(
            "frame 0 re-rendered: the log has no record of what was written (a take of an older version)"
                .into()
        ))
    );
    // Asking for passes re-renders frames that lack them.
    take.passes = PassSet::all();
    assert_eq!(take.plan(0, "a.png", (10, 1)), Plan::Process(None));
}

#[test]
fn foreign_files_camera_numbering_and_folders() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut take = take_in(dir.path(), PassSet::default(), "frame");
    add_frame(&mut take, 0, "inputs/000000.png", (1, 1));
    assert!(foreign_files(&take).expect("list").is_empty());
    for f in [
        "frames/x10.png",
        "frames/x9.png",
        "masks/000000.png",
        "frames/.hidden",
    ] {
        std::fs::write(dir.path().join(f), b"x").expect("write");
    }
    assert_eq!(
        foreign_files(&take).expect("list"),
        ["frames/x9.png", "frames/x10.png", "masks/000000.png"]
    );
    assert_eq!(camera_start_index(&take), 1);
    std::fs::write(dir.path().join("inputs/000004.png"), b"x").expect("write");
    std::fs::write(dir.path().join("inputs/note.txt"), b"x").expect("write");
    assert_eq!(camera_start_index(&take), 5);
    take.entries.clear();
    std::fs::remove_file(dir.path().join("inputs/000004.png")).expect("rm");
    assert_eq!(camera_start_index(&take), 0);

    // Folders and files of the take must be what they claim.
    assert!(check_take_folders(dir.path()).is_ok());
    std::fs::remove_dir(dir.path().join("twin")).expect("rm");
    std::fs::write(dir.path().join("twin"), b"x").expect("write");
    let err = check_take_folders(dir.path()).expect_err("a file as twin/");
    assert_eq!(
        err.to_string(),
        format!(
            "{}: is a regular file, not a folder; a take's twin/ must be a real folder inside it",
            dir.path().join("twin").display()
        )
    );
    std::fs::remove_file(dir.path().join("twin")).expect("rm");
    std::fs::create_dir(dir.path().join("log.jsonl")).expect("mkdir");
    let err = check_take_folders(dir.path()).expect_err("a folder as log");
    assert_eq!(
        err.to_string(),
        format!(
            "{}: is a folder, not a regular file",
            dir.path().join("log.jsonl").display()
        )
    );

    // Stale temporaries go, the rest stays.
    std::fs::write(dir.path().join("frames/.000000.png.tmp-99"), b"x").expect("write");
    remove_stale_temps(&dir.path().join("frames"));
    assert!(!dir.path().join("frames/.000000.png.tmp-99").exists());
    assert!(dir.path().join("frames/000000.png").exists());
}

#[test]
fn one_run_per_take() {
    let dir = tempfile::tempdir().expect("tmp");
    let lock = lock_take(dir.path()).expect("lock");
    assert!(lock.is_some());
    let err = lock_take(dir.path()).expect_err("held");
    let text = err.to_string();
    assert!(
        text.starts_with(&format!(
            "{}: another run is writing this take (propsalive run, pid {}",
            dir.path().display(),
            std::process::id()
        )) && text.ends_with("); wait for it to end, or use another --out folder"),
        "{text}"
    );
    drop(lock);
    assert!(lock_take(dir.path()).expect("free again").is_some());
}

#[test]
fn a_take_never_overlaps_its_input() {
    let dir = tempfile::tempdir().expect("tmp");
    let stills = dir.path().join("stills");
    std::fs::create_dir(&stills).expect("mkdir");
    let out = stills.join("take");
    let err = check_no_overlap(&stills, InputKind::Folder, &out, None).expect_err("inside");
    assert!(
        err.to_string().starts_with(&format!(
            "--input {} and --out {} overlap (",
            stills.display(),
            out.display()
        )),
        "{err}"
    );
    let elsewhere = dir.path().join("take");
    assert!(check_no_overlap(&stills, InputKind::Folder, &elsewhere, None).is_ok());
    let mp4 = stills.join("take.mp4");
    let err =
        check_no_overlap(&stills, InputKind::Folder, &elsewhere, Some(&mp4)).expect_err("mp4");
    assert_eq!(
        err.to_string(),
        format!(
            "--mp4 {} is the input or inside the input folder; name a file elsewhere",
            mp4.display()
        )
    );
    // A video: the MP4 may sit beside it, not be it.
    let video = dir.path().join("clip.mp4");
    std::fs::write(&video, b"x").expect("write");
    let beside = dir.path().join("out.mp4");
    assert!(check_no_overlap(&video, InputKind::Video, &elsewhere, Some(&beside)).is_ok());
    assert!(check_no_overlap(&video, InputKind::Video, &elsewhere, Some(&video)).is_err());
}

#[test]
fn the_mp4_record_tells_our_file_from_others() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut take = take_in(dir.path(), PassSet::default(), "still");
    assert_eq!(
        write_mp4(
            &dir.path().join("none.mp4"),
            dir.path(),
            &take.entries,
            3,
            24.0,
            false
        )
        .expect("no frames"),
        Mp4Written::NoFrames
    );
    add_frame(&mut take, 0, "a.png", (1, 1));
    add_frame(&mut take, 2, "c.png", (1, 3));
    write_log(&take.log_path, &take.entries).expect("log");
    let mp4 = dir.path().join("take.mp4");
    let written = write_mp4(&mp4, dir.path(), &take.entries, 3, 24.0, false).expect("mp4");
    let Mp4Written::Written { frames, held, .. } = &written else {
        panic!("{written:?}");
    };
    assert_eq!((*frames, *held), (3, 1));
    let line = written.line(&mp4);
    assert!(
        line.starts_with("mp4: 3 frame(s) at 24 fps, ")
            && line.ends_with(&format!(
                " MB, H.264 -> {} (1 frame(s) the take lacks hold the frame before)",
                mp4.display()
            )),
        "{line}"
    );
    let reader = pa_video::VideoReader::open(&mp4).expect("reads back");
    assert_eq!(reader.info().frame_count, Some(3));
    let entries = read_log(&take.log_path).expect("log").entries;
    assert!(mp4_is_ours(&mp4, dir.path()));
    assert!(mp4_is_current(&mp4, dir.path(), &take_hash(&entries, 3)));
    assert!(!mp4_is_current(&mp4, dir.path(), &take_hash(&entries, 1)));
    // Written again (it is the take's own), refused when it is not.
    write_mp4(&mp4, dir.path(), &take.entries, 3, 24.0, false).expect("rewrite own mp4");
    std::fs::write(&mp4, b"someone else's video").expect("replace");
    assert!(!mp4_is_ours(&mp4, dir.path()));
    let err = write_mp4(&mp4, dir.path(), &take.entries, 3, 24.0, false).expect_err("refused");
    assert_eq!(
        err.to_string(),
        format!(
            "--mp4 {} exists and is not the MP4 this take wrote; pass --force to replace it",
            mp4.display()
        )
    );
    let err = check_mp4_target(&mp4, dir.path(), false).expect_err("refused");
    assert!(err
        .to_string()
        .ends_with("pass --force to replace it, or name another file"));
    assert!(check_mp4_target(&mp4, dir.path(), true).is_ok());
    let err = check_mp4_target(dir.path(), dir.path(), true).expect_err("a folder");
    assert_eq!(
        err.to_string(),
        format!(
            "--mp4 {} is a folder; give a file name",
            dir.path().display()
        )
    );
    write_mp4(&mp4, dir.path(), &take.entries, 3, 24.0, true).expect("--force");
    assert!(mp4_is_ours(&mp4, dir.path()));

    // The camera of the take.
    let k = pa_camera::Intrinsics::from_fov_y(0.8, 32, 24).expect("k");
    let exported = crate::camera_export::export_camera(dir.path(), &take.entries, 3, &k, 24.0)
        .expect("camera.gltf");
    assert_eq!(
        exported.to_string(),
        format!(
            "camera: 2 tracked still(s) exported to {} (glTF 2.0, Y-up, 24 fps)",
            dir.path().join("camera.gltf").display()
        )
    );
    assert!(dir.path().join("camera.gltf").is_file());
    assert_eq!(
        crate::camera_export::export_camera(dir.path(), &BTreeMap::new(), 3, &k, 24.0)
            .expect("no pose")
            .to_string(),
        "note: no still of the take was tracked: no camera.gltf written"
    );
}
