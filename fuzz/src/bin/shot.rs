//! AFL target `shot`: see `pa_fuzz::shot` and README.md.

fn main() {
    // One scratch folder for the whole campaign: AFL's fork server is this process's parent,
    // the same for every target process AFL starts, and none of them gets to clean up.
    pa_fuzz::set_scratch_root(std::env::temp_dir().join(format!(
        "pa-fuzz-afl-shot-{}",
        std::os::unix::process::parent_id()
    )));
    afl::fuzz!(|data: &[u8]| {
        pa_fuzz::shot(data);
    });
    pa_fuzz::cleanup();
}
