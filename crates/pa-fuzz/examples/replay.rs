//! Runs a fuzz target on files and says what each does: `ok`, or the panic with its location.
//! For AFL's crashes and hangs, minimised inputs and regression files:
//!
//! ```text
//! cargo run -p pa-fuzz --example replay -- <target> <file>...
//! cargo run -p pa-fuzz --example replay -- --minimise <target> <file> <out-file>
//! ```
//!
//! Each file runs in this process: an abort, an out-of-memory or a hang stops it there (the
//! name of the file being run is printed first). Exit status 1 when any file panicked.

use std::time::Instant;

use pa_fuzz::harness;

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let minimise = args.first().is_some_and(|a| a == "--minimise");
    if minimise {
        args.remove(0);
    }
    let usage =
        "usage: replay [--minimise] <target> <file>... (targets: gltf shot calibration mp4 still)";
    let Some(name) = args.first() else {
        eprintln!("{usage}");
        std::process::exit(2);
    };
    let Some(target) = pa_fuzz::target(name) else {
        eprintln!("unknown target {name:?}; {usage}");
        std::process::exit(2);
    };
    if minimise {
        let (Some(input), Some(out)) = (args.get(1), args.get(2)) else {
            eprintln!("{usage}");
            std::process::exit(2);
        };
        let data = std::fs::read(input).unwrap_or_else(|e| panic!("{input}: {e}"));
        let crash = match harness::run_caught(target, &data) {
            Ok(()) => {
                eprintln!("{input}: does not panic (nothing to minimise)");
                std::process::exit(1);
            }
            Err(c) => c,
        };
        let small = harness::minimise(target, &data, &crash, 20_000);
        std::fs::write(out, &small).unwrap_or_else(|e| panic!("{out}: {e}"));
        println!("{crash}\n{} -> {} bytes: {out}", data.len(), small.len());
        pa_fuzz::cleanup();
        return;
    }
    let mut failed = false;
    for file in &args[1..] {
        eprint!("{file}: ");
        let data = match std::fs::read(file) {
            Ok(d) => d,
            Err(e) => {
                eprintln!("cannot read: {e}");
                failed = true;
                continue;
            }
        };
        let t0 = Instant::now();
        let result = harness::run_caught(target, &data);
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        match result {
            Ok(()) => eprintln!("ok ({ms:.1} ms)"),
            Err(c) => {
                eprintln!("{c} ({ms:.1} ms)");
                failed = true;
            }
        }
    }
    pa_fuzz::cleanup();
    std::process::exit(i32::from(failed));
}
