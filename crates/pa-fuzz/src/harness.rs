//! What the drivers share: the corpus and regression folders, the list of open regressions,
//! running a target with its panic caught, and minimising a crashing input.

use std::cell::RefCell;
use std::panic::{self, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::Once;

use crate::Target;

/// This crate's folder (corpus, regressions).
pub fn crate_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The committed seed corpus of a target.
pub fn corpus_dir(target: &str) -> PathBuf {
    crate_dir().join("corpus").join(target)
}

/// The regression files of a target: every input that ever crashed it.
pub fn regressions_dir(target: &str) -> PathBuf {
    crate_dir().join("regressions").join(target)
}

/// The list of regressions still open (not fixed yet).
pub fn open_list_path() -> PathBuf {
    crate_dir().join("regressions").join("OPEN.txt")
}

/// The files of a folder (not recursive, hidden files and `README*` left out), sorted by name;
/// empty when the folder does not exist.
pub fn files_in(dir: &Path) -> Vec<PathBuf> {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut files: Vec<PathBuf> = rd
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .filter(|p| {
            let name = p.file_name().unwrap_or_default().to_string_lossy();
            !name.starts_with('.') && !name.starts_with("README")
        })
        .collect();
    files.sort();
    files
}

/// One line of `regressions/OPEN.txt`: `<target>/<file>  <what it does, free text>`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OpenRegression {
    /// Relative to `regressions/`, e.g. `gltf/accessor-overflow`.
    pub path: String,
    /// The rest of the line (the panic message and location when it was filed).
    pub note: String,
}

/// Reads `regressions/OPEN.txt` (missing file: none open). Blank lines and lines starting
/// with `#` are comments.
pub fn open_regressions() -> Vec<OpenRegression> {
    let text = std::fs::read_to_string(open_list_path()).unwrap_or_default();
    text.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .map(|l| {
            let (path, note) = l.split_once(char::is_whitespace).unwrap_or((l, ""));
            OpenRegression {
                path: path.to_string(),
                note: note.trim().to_string(),
            }
        })
        .collect()
}

/// A caught panic: its message and `file:line:column`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Crash {
    pub message: String,
    pub location: String,
}

impl std::fmt::Display for Crash {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "panicked at {}: {}", self.location, self.message)
    }
}

thread_local! {
    /// `Some` while the thread runs a target under [`run_caught`]: the last panic seen.
    static CAPTURE: RefCell<Option<Option<Crash>>> = const { RefCell::new(None) };
}

static HOOK: Once = Once::new();

/// Installs (once) a panic hook that records panics of threads inside [`run_caught`] quietly
/// and leaves every other panic to the previous hook.
fn install_hook() {
    HOOK.call_once(|| {
        let previous = panic::take_hook();
        panic::set_hook(Box::new(move |info| {
            let captured = CAPTURE.with(|c| {
                let mut c = c.borrow_mut();
                match c.as_mut() {
                    Some(slot) => {
                        let message = if let Some(s) = info.payload().downcast_ref::<&str>() {
                            (*s).to_string()
                        } else if let Some(s) = info.payload().downcast_ref::<String>() {
                            s.clone()
                        } else {
                            "(a panic payload that is not a string)".to_string()
                        };
                        let location = info
                            .location()
                            .map(|l| format!("{}:{}:{}", l.file(), l.line(), l.column()))
                            .unwrap_or_else(|| "(unknown location)".into());
                        *slot = Some(Crash { message, location });
                        true
                    }
                    None => false,
                }
            });
            if !captured {
                previous(info);
            }
        }));
    });
}

/// Runs `target` on `data`; `Err` with the panic when it panicked (printed nowhere).
pub fn run_caught(target: Target, data: &[u8]) -> Result<(), Crash> {
    install_hook();
    CAPTURE.with(|c| *c.borrow_mut() = Some(None));
    let result = panic::catch_unwind(AssertUnwindSafe(|| target(data)));
    let crash = CAPTURE.with(|c| c.borrow_mut().take()).flatten();
    match result {
        Ok(()) => Ok(()),
        Err(_) => Err(crash.unwrap_or(Crash {
            message: "(panic not seen by the hook)".into(),
            location: "(unknown location)".into(),
        })),
    }
}

/// Shrinks a crashing input while it still panics at the same location: removes chunks
/// (halving their size down to one byte), then lowers bytes towards `'0'` and `0`. At most
/// `max_runs` runs of the target.
pub fn minimise(target: Target, data: &[u8], crash: &Crash, max_runs: usize) -> Vec<u8> {
    let mut best = data.to_vec();
    let mut runs = 0usize;
    let still_crashes = |candidate: &[u8], runs: &mut usize| -> bool {
        *runs += 1;
        matches!(run_caught(target, candidate), Err(c) if c.location == crash.location)
    };
    let mut chunk = best.len().next_power_of_two().max(1);
    while chunk >= 1 && runs < max_runs {
        let mut i = 0;
        while i < best.len() && runs < max_runs {
            let end = (i + chunk).min(best.len());
            let mut candidate = Vec::with_capacity(best.len() - (end - i));
            candidate.extend_from_slice(&best[..i]);
            candidate.extend_from_slice(&best[end..]);
            if still_crashes(&candidate, &mut runs) {
                best = candidate;
            } else {
                i += chunk;
            }
        }
        chunk /= 2;
    }
    for i in 0..best.len() {
        if runs >= max_runs {
            break;
        }
        for simpler in [b'0', 0u8] {
            if best[i] == simpler {
                break;
            }
            let mut candidate = best.clone();
            candidate[i] = simpler;
            if still_crashes(&candidate, &mut runs) {
                best = candidate;
                break;
            }
        }
    }
    best
}

/// A short stable name for an input (FNV-1a, 64 bits, hex).
pub fn content_name(data: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in data {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{h:016x}")
}
