//! The report of `propsalive bench`: the Markdown table of the timings per configuration and
//! stage (median / 95th percentile), the text around it and the JSON document.

use std::fmt::Write as _;
use std::path::Path;

use serde_json::{json, Value};

use crate::stats::Stat;
use crate::{write_file, ReportError};

/// The results of one configuration.
#[derive(Debug, Clone)]
pub struct BenchRow {
    /// The texture stage's renderer (`cpu`, `gpu`).
    pub render_path: &'static str,
    /// Frame size, pixels.
    pub width: u32,
    pub height: u32,
    /// The prop's vertex count asked for, and the generated prop's.
    pub requested_vertices: u32,
    pub actual_vertices: usize,
    /// Props per frame.
    pub props: u32,
    /// Timed frames, and those the tracker tracked.
    pub frames: usize,
    pub tracked: usize,
    /// Per stage ([`STAGES`]), ms.
    pub stages: Vec<(&'static str, Stat)>,
    pub gpu_wait: Stat,
    pub end_to_end: Stat,
    pub psnr_prop: Option<f64>,
    pub peak_rss_mb: Option<f64>,
    pub rss_start_mb: Option<f64>,
    /// What the peak covers: "timed loop" or "process".
    pub peak_scope: &'static str,
    /// The frames the bench holds in memory, MiB.
    pub held_mb: f64,
    /// Wall time of the configuration, seconds.
    pub seconds: f64,
    /// 1-minute load average at the start and the end of the configuration.
    pub load_start: Option<f64>,
    pub load_end: Option<f64>,
}

/// The stages timed, in table order.
pub const STAGES: [&str; 6] = [
    "track",
    "animate",
    "texture",
    "diminish",
    "composite",
    "readback",
];

/// A table cell: median / p95, ms.
fn cell(s: Stat) -> String {
    format!("{:.1} / {:.1}", s.median, s.p95)
}

/// A load average, or `n/a`.
fn load(l: Option<f64>) -> String {
    l.map_or_else(|| "n/a".to_string(), |l| format!("{l:.2}"))
}

/// Frames per second at the median time `s` (ms).
pub fn fps(s: Stat) -> f64 {
    1000.0 / s.median
}

fn stat_json(s: Stat) -> Value {
    json!({"median": s.median, "p95": s.p95})
}

/// The table (Markdown): a header and a line per configuration.
pub fn table(rows: &[BenchRow]) -> String {
    let mut t = String::new();
    let _ = writeln!(
        t,
        "| path | size | vertices | props | track | animate | texture | diminish | composite | readback | end-to-end | fps | prop PSNR dB | peak RSS MiB | tracked | load start / end |"
    );
    let _ = writeln!(
        t,
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for r in rows {
        let _ = write!(
            t,
            "| {} | {}x{} | {} | {} |",
            r.render_path, r.width, r.height, r.actual_vertices, r.props
        );
        for (_, s) in &r.stages {
            let _ = write!(t, " {} |", cell(*s));
        }
        let _ = writeln!(
            t,
            " {} | {:.1} | {} | {} | {}/{} | {} / {} |",
            cell(r.end_to_end),
            fps(r.end_to_end),
            r.psnr_prop
                .map(|p| format!("{p:.2}"))
                .unwrap_or_else(|| "-".into()),
            r.peak_rss_mb
                .map(|m| format!("{m:.0}"))
                .unwrap_or_else(|| "n/a".into()),
            r.tracked,
            r.frames,
            load(r.load_start),
            load(r.load_end)
        );
    }
    t
}

/// What `propsalive bench` measured, with the machine it ran on.
#[derive(Debug, Clone)]
pub struct BenchReport {
    pub adapter: String,
    pub backend: String,
    /// CPU model and the cores available.
    pub cpu: String,
    pub cores: usize,
    /// 1-minute load average before and after the run.
    pub load_start: Option<f64>,
    pub load_end: Option<f64>,
    /// The pipeline settings timed, in words.
    pub method: &'static str,
    /// The render path the pipeline picks on this machine.
    pub auto_path: &'static str,
    /// Timed and warm-up frames per configuration.
    pub frames: u32,
    pub warmup: u32,
    pub seed: u64,
    /// Wall time of the whole run, seconds.
    pub total_seconds: f64,
    pub rows: Vec<BenchRow>,
}

const PROPS_MEANING: &str = "N props = one ArPipeline drawing N props a frame (add_prop): track, \
                             fill and composite once, pose and draw per prop; N copies of the bust \
                             at distinct spots on the set (the board's centre, beside it, rows \
                             behind it), all N in the input, the ground truth and the prop PSNR";
const READBACK_MEANING: &str = "readback = mapping GPU results and copying them to CPU memory \
                                (unpad, depth decode), taken out of texture; texture includes \
                                waiting for the GPU (gpu_wait), which on a software rasteriser is \
                                the rasterisation itself";

impl BenchReport {
    /// The report printed (Markdown): the machine and settings, then the table.
    pub fn markdown(&self) -> String {
        let (adapter, backend, cpu, cores) = (&self.adapter, &self.backend, &self.cpu, self.cores);
        let (props_meaning, readback_meaning) = (PROPS_MEANING, READBACK_MEANING);
        let mut out = String::new();
        let _ = writeln!(out, "# propsalive bench\n");
        let _ = writeln!(out, "- adapter: {adapter}");
        let _ = writeln!(out, "- backend: {backend}");
        let _ = writeln!(
            out,
            "- CPU: {cpu}, {cores} cores available; 1-minute load average {} at the start, {} at \
         the end (other work on the machine slows a software rasteriser a lot; each \
         configuration's own in the table)",
            load(self.load_start),
            load(self.load_end)
        );
        let _ = writeln!(out, "- method: {}", self.method);
        let _ = writeln!(
            out,
            "- render path: cpu = our rasteriser (pa-raster), gpu = wgpu on the adapter above; \
         the pipeline picks {} on this machine",
            self.auto_path
        );
        let _ = writeln!(
            out,
            "- frames: {} timed after {} warm-up per configuration; times in ms, median / p95; \
         fps = 1000 / median end-to-end",
            self.frames, self.warmup
        );
        let _ = writeln!(out, "- {props_meaning}");
        let _ = writeln!(out, "- {readback_meaning}");
        let _ = writeln!(
        out,
        "- peak RSS: the process's high-water mark during the timed loop, including the frames \
         the bench holds (input, ground truth, output)\n"
    );
        out.push_str(&table(&self.rows));
        out
    }

    /// The JSON document.
    pub fn json(&self) -> Value {
        let json_rows: Vec<Value> = self
            .rows
            .iter()
            .map(|r| {
                let stages: serde_json::Map<String, Value> = r
                    .stages
                    .iter()
                    .map(|(n, s)| (n.to_string(), stat_json(*s)))
                    .collect();
                json!({
                    "render_path": r.render_path,
                    "width": r.width,
                    "height": r.height,
                    "requested_vertices": r.requested_vertices,
                    "vertices": r.actual_vertices,
                    "props": r.props,
                    "frames": r.frames,
                    "tracked_frames": r.tracked,
                    "stages_ms": stages,
                    "gpu_wait_ms": stat_json(r.gpu_wait),
                    "end_to_end_ms": stat_json(r.end_to_end),
                    "fps": fps(r.end_to_end),
                    "prop_psnr_db": r.psnr_prop,
                    "peak_rss_mib": r.peak_rss_mb,
                    "rss_before_timed_loop_mib": r.rss_start_mb,
                    "peak_rss_scope": r.peak_scope,
                    "held_frames_mib": r.held_mb,
                    "seconds": r.seconds,
                    "load_average_start": r.load_start,
                    "load_average_end": r.load_end,
                })
            })
            .collect();
        json!({
            "adapter": self.adapter,
            "backend": self.backend,
            "default_render_path": self.auto_path,
            "cpu": self.cpu,
            "cores": self.cores,
            "load_average_start": self.load_start,
            "load_average_end": self.load_end,
            "method": self.method,
            "frames": self.frames,
            "warmup": self.warmup,
            "seed": self.seed,
            "stages": STAGES,
            "props_meaning": PROPS_MEANING,
            "readback_meaning": READBACK_MEANING,
            "total_seconds": self.total_seconds,
            "configs": json_rows,
        })
    }

    /// Writes [`BenchReport::json`] to `path` atomically.
    pub fn write_json(&self, path: &Path) -> Result<(), ReportError> {
        write_file(path, serde_json::to_string_pretty(&self.json())?.as_bytes())
    }
}
