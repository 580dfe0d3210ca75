//! The libraries' `log` messages on stderr: our crates' warnings and errors always (a model
//! whose weights were renormalised, a shot whose model has no skin, ...); with
//! `PROPSALIVE_LOG=error|warn|info|debug|trace` that level for every crate, the graphics stack
//! included (wgpu and the drivers report adapters they could not open as errors, which is
//! noise on a machine without those drivers). No dependency beyond `log` itself.

use log::{Level, LevelFilter, Log, Metadata, Record};

struct Stderr {
    level: LevelFilter,
    /// Only our crates' messages (no `PROPSALIVE_LOG` given).
    ours_only: bool,
}

/// Targets of this workspace's crates.
fn is_ours(target: &str) -> bool {
    target.starts_with("pa_") || target.starts_with("propsalive")
}

impl Log for Stderr {
    fn enabled(&self, metadata: &Metadata<'_>) -> bool {
        metadata.level() <= self.level && (!self.ours_only || is_ours(metadata.target()))
    }

    fn log(&self, record: &Record<'_>) {
        if !self.enabled(record.metadata()) {
            return;
        }
        let tag = match record.level() {
            Level::Error => "error",
            Level::Warn => "warning",
            Level::Info => "note",
            Level::Debug => "debug",
            Level::Trace => "trace",
        };
        errln!("{tag}: {}", record.args());
    }

    fn flush(&self) {}
}

/// The level `PROPSALIVE_LOG` asks for, if any.
fn level_from_env() -> Option<LevelFilter> {
    let v = std::env::var("PROPSALIVE_LOG").ok()?;
    Some(match v.to_ascii_lowercase().as_str() {
        "off" => LevelFilter::Off,
        "error" => LevelFilter::Error,
        "info" => LevelFilter::Info,
        "debug" => LevelFilter::Debug,
        "trace" => LevelFilter::Trace,
        _ => LevelFilter::Warn,
    })
}

/// Installs the logger (once; later calls do nothing).
pub fn init() {
    let asked = level_from_env();
    let level = asked.unwrap_or(LevelFilter::Warn);
    let logger = Box::leak(Box::new(Stderr {
        level,
        ours_only: asked.is_none(),
    }));
    if log::set_logger(logger).is_ok() {
        log::set_max_level(level);
    }
}
