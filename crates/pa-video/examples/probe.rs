//! Prints what the reader makes of a file: `cargo run -p pa-video --example probe -- FILE...`.
fn main() {
    for arg in std::env::args().skip(1) {
        match pa_video::VideoReader::open(&arg) {
            Ok(mut r) => {
                println!("{:?}", r.info());
                let mut n = 0;
                loop {
                    match r.next_frame() {
                        Ok(Some(_)) => n += 1,
                        Ok(None) => break,
                        Err(e) => {
                            println!("error after {n} frames: {e}");
                            break;
                        }
                    }
                }
                println!("{n} frames");
            }
            Err(e) => println!("{e}"),
        }
    }
}
