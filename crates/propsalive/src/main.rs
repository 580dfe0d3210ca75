//! `propsalive`: the Props Alive command-line tool.
//!
//! The CLI is parsed in two stages (as ripgrep does): clap turns the raw flags into the
//! `Args` structs of each command module, and each module resolves them into a checked
//! configuration before any work starts, so that bad input fails fast with a clear message.

// Printing goes through `output`'s macros, which never panic on a closed or full stream.
#![deny(clippy::print_stdout, clippy::print_stderr)]

#[macro_use]
mod output;
mod cmd;
mod logger;

use anyhow::Result;
use clap::{Parser, Subcommand};

/// Props Alive: augmented-reality stop-motion animation.
///
/// A physical key prop stands on a printed marker; Props Alive tracks it, animates its rigged
/// digital twin through the in-between poses, textures the twin from the live camera image and
/// composites the shot.
#[derive(Parser)]
#[command(name = "propsalive", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the built-in default job (nothing to download): writes out/demo/.
    Demo(cmd::demo::Args),
    /// Measure our methods against the paper's on generated scenes with ground truth.
    Eval(cmd::eval::Args),
    /// Time the pipeline per stage on generated frames (sizes x prop vertices x props).
    #[command(long_about = cmd::bench::LONG_ABOUT)]
    Bench(cmd::bench::Args),
    /// Print a glTF model's nodes, skins, animations, counts and textures.
    Inspect(cmd::inspect::Args),
    /// Render a model's animation to PNG frames (camera framed automatically unless given).
    Render(cmd::render::Args),
    /// Write the model posed at one animation time as OBJ, STL or GLB (for 3D printing).
    Export(cmd::export::Args),
    /// Write a new shot file for a model: board, key poses, camera, the prop standing on the sheet.
    New(cmd::new::Args),
    /// Write a printable AprilTag marker or board (or a shot's, with its footprints): SVG at true size and PNG at a given DPI.
    Marker(cmd::marker::Args),
    /// Detect and track the marker in an image, a folder of images or a video; JSON lines.
    Track(cmd::track::Args),
    /// Camera intrinsics and distortion from chessboard or AprilTag board images (OpenCV YAML).
    Calibrate(cmd::calibrate::Args),
    /// Stop-motion take: stills, a video or a camera through the pipeline, resumable.
    Run(cmd::run::Args),
    /// Refine the key prop's [placement] from frames of it on the marker (--write: into the shot).
    Register(cmd::register::Args),
    /// Live preview window: the composited view at camera rate, with keys and a status bar.
    #[command(long_about = cmd::preview::long_about())]
    Preview(cmd::preview::Args),
}

fn main() -> std::process::ExitCode {
    logger::init();
    let cli = Cli::parse();
    let result: Result<()> = match cli.command {
        Command::Demo(args) => cmd::demo::run(args),
        Command::Eval(args) => cmd::eval::run(args),
        Command::Bench(args) => cmd::bench::run(args),
        Command::Inspect(args) => cmd::inspect::run(args),
        Command::Render(args) => cmd::render::run(args),
        Command::Export(args) => cmd::export::run(args),
        Command::New(args) => cmd::new::run(args),
        Command::Marker(args) => cmd::marker::run(args),
        Command::Track(args) => cmd::track::run(args),
        Command::Calibrate(args) => cmd::calibrate::run(args),
        Command::Run(args) => cmd::run::run(args),
        Command::Preview(args) => cmd::preview::run(args),
        Command::Register(args) => cmd::register::run(args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            errln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
