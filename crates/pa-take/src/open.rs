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
