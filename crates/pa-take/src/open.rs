//! Opening a take for a run ([`open_take`]): its folders made and checked, its lock taken,
//! stale temporaries removed, its log read, and the refusals of a take made with other
//! settings or holding files its log does not know.

use std::collections::HashSet;
use std::path::Path;

use crate::{
    check_take_folders, foreign_files, lock_take, remove_stale_temps, PassSet, Take, TakeError,
    TAKE_DIRS,
};

/// The settings of this run, which a take's logged frames must share.
#[derive(Debug, Clone)]
pub struct TakeSettings {
    pub exposure: u32,
    pub bit_depth: u8,
    pub shot_hash: String,
    pub key_name: String,
    pub passes: PassSet,
    pub width: u32,
    pub height: u32,
    /// "still" or "frame".
    pub unit: &'static str,
}

/// A take opened for a run: the take and its lock (held until dropped; `None` on a read-only
/// file system).
#[derive(Debug)]
pub struct Opened {
    pub take: Take,
    pub lock: Option<pa_io::FileLock>,
}

fn create_dir(p: &Path) -> Result<(), TakeError> {
    std::fs::create_dir_all(p).map_err(|source| TakeError::CreateDir {
        path: p.to_path_buf(),
        source,
    })
}

/// Opens the take in `out` for a run with `settings`: makes the folder, takes the lock,
/// refuses links where the take's folders are, makes `frames/`, the pass folders and (`live`)
/// `inputs/`, removes stale temporaries and reads the log. Refuses a take with frames made
/// with other settings (with `force` and not `live`, they are re-rendered) and, without
/// `force`, files in the output folders the log does not know (with it: a warning note).
/// Notes for stderr (log lines ignored, the warning) go to `say` as they come.
pub fn open_take(
    out: &Path,
    settings: TakeSettings,
    live: bool,
    force: bool,
    say: &mut dyn FnMut(String),
) -> Result<Opened, TakeError> {
    create_dir(out)?;
    // One run per take: held until this process ends, however it ends.
    let lock = lock_take(out)?;
    check_take_folders(out)?;
    create_dir(&out.join("frames"))?;
    let mut dirs: Vec<&str> = settings.passes.dirs();
    if live {
        dirs.push("inputs");
    }
    for d in &dirs {
        create_dir(&out.join(d))?;
    }
    for d in TAKE_DIRS {
        remove_stale_temps(&out.join(d));
    }
    remove_stale_temps(out);
    let log_path = out.join("log.jsonl");
    let log = crate::read_log(&log_path)?;
    for note in &log.notes {
        say(note.to_string());
    }
    let entries = log.entries;

    // Settings of an existing take.
    let stale: HashSet<usize> = entries
        .values()
        .filter(|e| {
            e.exposure != settings.exposure
                || e.bit_depth != settings.bit_depth
                || e.shot_hash != settings.shot_hash
        })
        .map(|e| e.index)
        .collect();
    if !stale.is_empty() && (live || !force) {
        return Err(TakeError::StaleSettings {
            out: out.to_path_buf(),
            frames: stale.len(),
            live,
        });
    }
    let take = Take {
        out: out.to_path_buf(),
        log_path,
        entries,
        stale,
        exposure: settings.exposure,
        bit_depth: settings.bit_depth,
        shot_hash: settings.shot_hash,
        key_name: settings.key_name,
        passes: settings.passes,
        width: settings.width,
        height: settings.height,
        unit: settings.unit,
    };

    // Files the log does not know.
    let foreign = foreign_files(&take)?;
    if !foreign.is_empty() {
        if !force {
            return Err(TakeError::ForeignFiles {
                out: out.to_path_buf(),
                files: foreign,
            });
        }
        say(format!(
            "warning: --force: {} file(s) in {} are not from this take ({}); those a {} maps to will be replaced",
            foreign.len(),
            out.display(),
            first_files(&foreign),
            take.unit
        ));
    }
    Ok(Opened { take, lock })
}

/// The first five of `files`, comma-separated, with `, ...` when there are more.
pub(crate) fn first_files(files: &[String]) -> String {
    let list = files.iter().take(5).cloned().collect::<Vec<_>>().join(", ");
    let more = if files.len() > 5 { ", ..." } else { "" };
    format!("{list}{more}")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(exposure: u32) -> TakeSettings {
        TakeSettings {
            exposure,
            bit_depth: 8,
            shot_hash: "0".into(),
            key_name: "A".into(),
            passes: PassSet::default(),
            width: 4,
            height: 4,
            unit: "still",
        }
    }

    #[test]
    fn a_take_with_other_settings_or_unknown_files_is_refused_with_the_runs_messages() {
        let dir = tempfile::tempdir().expect("tmp");
        let out = dir.path().join("take");
        let mut said = Vec::new();
        let Opened { mut take, lock } =
            open_take(&out, settings(1), false, false, &mut |n| said.push(n)).expect("open");
        assert!(out.join("frames").is_dir() && said.is_empty());
        let mut e = take.new_entry(0, "a.png", (1, 2), 0);
        e.output = Some("frames/000000.png".into());
        take.entries.insert(0, e);
        crate::write_log(&take.log_path, &take.entries).expect("log");
        assert_eq!(
            take.tally(1),
            crate::Tally {
                produced: 1,
                skipped: 0,
                past_end: 0
            }
        );
        assert_eq!(take.tally(0).past_end, 1);
        drop(lock);

        let err = open_take(&out, settings(2), false, false, &mut |_| {}).expect_err("stale");
        assert_eq!(
            err.to_string(),
            format!("{}: 1 frame(s) of this take were made with another exposure, bit depth or shot file; use a new --out folder, or --force to re-render them", out.display())
        );
        let err = open_take(&out, settings(2), true, true, &mut |_| {}).expect_err("live");
        assert!(err.to_string().ends_with("use a new --out folder"), "{err}");
        let opened = open_take(&out, settings(2), false, true, &mut |_| {}).expect("--force");
        assert_eq!(opened.take.stale.len(), 1);
        drop(opened);

        for i in 1..8 {
            std::fs::write(out.join("frames").join(crate::frame_name(i)), b"x").expect("write");
        }
        let err = open_take(&out, settings(1), false, false, &mut |_| {}).expect_err("foreign");
        assert_eq!(
            err.to_string(),
            format!("{}: 7 file(s) this take's log does not know (frames/000001.png, frames/000002.png, frames/000003.png, frames/000004.png, frames/000005.png, ...): another take? Refusing to overwrite; use a new --out folder, or --force", out.display())
        );
        let mut said = Vec::new();
        open_take(&out, settings(1), false, true, &mut |n| said.push(n)).expect("--force");
        assert_eq!(
            said,
            [format!("warning: --force: 7 file(s) in {} are not from this take (frames/000001.png, frames/000002.png, frames/000003.png, frames/000004.png, frames/000005.png, ...); those a still maps to will be replaced", out.display())]
        );
    }
}
