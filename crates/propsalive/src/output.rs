//! Standard output and error that never panic.
//!
//! `println!` panics ("failed printing to stdout") when stdout is closed (`propsalive inspect
//! M | head -1`) or on a full disk. Every line the binary prints goes through the macros
//! below instead (clippy's `print_stdout`/`print_stderr` lints, denied in `main.rs`, keep it
//! so):
//! - `outln!`/`out!`: standard output. A closed pipe ends the program quietly (exit 0: the
//!   reader has what it wanted); any other failure (a full disk) ends it with a message on
//!   stderr and exit 1. Files of a take are written atomically, so ending here loses nothing.
//! - `errln!`: standard error; a failure to write a diagnostic is ignored.

use std::io::Write;

/// Writes to stdout, ending the program as the module docs say on failure.
pub fn write_out(args: std::fmt::Arguments<'_>, newline: bool) {
    let stdout = std::io::stdout();
    let mut lock = stdout.lock();
    let result = lock
        .write_fmt(args)
        .and_then(|()| {
            if newline {
                lock.write_all(b"\n")
            } else {
                Ok(())
            }
        })
        .and_then(|()| lock.flush());
    if let Err(e) = result {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        let _ = writeln!(
            std::io::stderr(),
            "error: cannot write to standard output: {e}"
        );
        std::process::exit(1);
    }
}

/// Writes to stderr, ignoring failure.
pub fn write_err(args: std::fmt::Arguments<'_>, newline: bool) {
    let stderr = std::io::stderr();
    let mut lock = stderr.lock();
    let _ = lock.write_fmt(args);
    if newline {
        let _ = lock.write_all(b"\n");
    }
}

/// `println!` that never panics (see the module docs).
macro_rules! outln {
    () => { $crate::output::write_out(format_args!(""), true) };
    ($($t:tt)*) => { $crate::output::write_out(format_args!($($t)*), true) };
}

/// `print!` that never panics.
macro_rules! out {
    ($($t:tt)*) => { $crate::output::write_out(format_args!($($t)*), false) };
}

/// `eprintln!` that never panics.
macro_rules! errln {
    () => { $crate::output::write_err(format_args!(""), true) };
    ($($t:tt)*) => { $crate::output::write_err(format_args!($($t)*), true) };
}
