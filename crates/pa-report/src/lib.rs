//! The reports of `propsalive eval` and `propsalive bench`: Markdown tables and text, JSON
//! documents, the summary statistics behind them (means, medians, 95th percentiles) and the
//! hand-drawn SVG plots, written atomically through `pa-io`.
//!
//! Also the JSON lines of `propsalive track` ([`track`], from `pa-track`'s outputs) and the
//! probes of the machine a benchmark runs on ([`system`]: memory, load, CPU, from `/proc`).
//!
//! The measuring (running the pipeline, timing it) stays with the caller, which hands plain
//! numbers in ([`eval::EvalReport`], [`bench::BenchReport`]); every function here is pure
//! except the `write` ones. GPU-free: no renderer, no pipeline types.

pub mod bench;
pub mod eval;
pub mod plot;
pub mod stats;
pub mod system;
pub mod track;

use std::path::{Path, PathBuf};

/// What went wrong writing a report.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// A report file could not be written ("writing PATH", then `pa-io`'s error).
    #[error("writing {}", path.display())]
    Write {
        path: PathBuf,
        #[source]
        source: pa_io::IoError,
    },
    /// A report file could not be written; `pa-io`'s error as it is (it names the file).
    #[error(transparent)]
    File(#[from] pa_io::IoError),
    /// A JSON document could not be serialised.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

/// Writes `bytes` to `path` atomically (temporary file, sync, rename); the error says
/// "writing PATH" ([`ReportError::Write`]).
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<(), ReportError> {
    pa_io::write_atomic(path, bytes).map_err(|source| ReportError::Write {
        path: path.to_path_buf(),
        source,
    })
}
