//! The preview's files: captured frames (`capture_NNNN.png`, numbered after the highest one
//! in the folder, written atomically and never over an existing file), recordings (a new
//! `take_NNN/` folder per recording with `NNNNNN.png` frames) and the JSON Lines log.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use super::draw::Image;

/// The number in `NAME` when it is `{prefix}{digits}{suffix}`.
pub fn parse_numbered(name: &str, prefix: &str, suffix: &str) -> Option<u32> {
    let digits = name.strip_prefix(prefix)?.strip_suffix(suffix)?;
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

/// One more than the highest number among `names` (1 when there is none).
pub fn next_number<'a>(
    names: impl IntoIterator<Item = &'a str>,
    prefix: &str,
    suffix: &str,
) -> u32 {
    names
        .into_iter()
        .filter_map(|n| parse_numbered(n, prefix, suffix))
        .max()
        .map_or(1, |n| n.saturating_add(1))
}

/// File names in a folder (empty when it does not exist).
fn names_in(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .map(|rd| {
            rd.flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default()
}

/// PNG bytes of an image.
pub fn png_bytes(img: &Image) -> Result<Vec<u8>> {
    let buf = image::RgbaImage::from_raw(img.width, img.height, img.rgba8.clone())
        .context("image buffer has the wrong size")?;
    let mut png = Vec::new();
    buf.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    Ok(png)
}

pub use pa_model::export::write_new_atomic;

/// The capture folder: numbering and the list of captured frames (for the line-up).
pub struct Captures {
    pub dir: PathBuf,
    next: u32,
    /// Captured frames in the folder, oldest first.
    pub files: Vec<PathBuf>,
}

const CAPTURE_PREFIX: &str = "capture_";

impl Captures {
    /// Looks at the folder (it is created on the first capture).
    pub fn open(dir: &Path) -> Self {
        let names = names_in(dir);
        let mut numbered: Vec<(u32, &String)> = names
            .iter()
            .filter_map(|n| parse_numbered(n, CAPTURE_PREFIX, ".png").map(|k| (k, n)))
            .collect();
        numbered.sort();
        Self {
            dir: dir.to_path_buf(),
            next: next_number(names.iter().map(String::as_str), CAPTURE_PREFIX, ".png"),
            files: numbered.iter().map(|(_, n)| dir.join(n)).collect(),
        }
    }

    /// Saves `img` as the next `capture_NNNN.png`; never replaces a file (a name taken since
    /// the folder was read is skipped). Returns the path.
    pub fn save(&mut self, img: &Image) -> Result<PathBuf> {
        std::fs::create_dir_all(&self.dir)
            .with_context(|| format!("creating {}", self.dir.display()))?;
        let png = png_bytes(img)?;
        for _ in 0..10_000 {
            let path = self
                .dir
                .join(format!("{CAPTURE_PREFIX}{:04}.png", self.next));
            self.next = self.next.saturating_add(1);
            if write_new_atomic(&path, &png)
                .with_context(|| format!("writing {}", path.display()))?
            {
                self.files.push(path.clone());
                return Ok(path);
            }
        }
        anyhow::bail!("{}: no free capture name", self.dir.display())
    }
}

/// A recording in progress: `take_NNN/NNNNNN.png`.
pub struct Recording {
    pub dir: PathBuf,
    pub frames: u64,
}

impl Recording {
    /// Creates the next free `take_NNN` folder in `root` (creating a folder is atomic and
    /// fails on an existing one, so takes are never mixed).
    pub fn start(root: &Path) -> Result<Self> {
        std::fs::create_dir_all(root).with_context(|| format!("creating {}", root.display()))?;
        let names = names_in(root);
        let mut n = next_number(names.iter().map(String::as_str), "take_", "");
        for _ in 0..10_000 {
            let dir = root.join(format!("take_{n:03}"));
            match std::fs::create_dir(&dir) {
                Ok(()) => return Ok(Self { dir, frames: 0 }),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => n += 1,
                Err(e) => {
                    return Err(e).with_context(|| format!("creating {}", dir.display()));
                }
            }
        }
        anyhow::bail!("{}: no free take name", root.display())
    }

    /// Appends one frame (written atomically).
    pub fn push(&mut self, img: &Image) -> Result<PathBuf> {
        let path = self.dir.join(format!("{:06}.png", self.frames));
        let png = png_bytes(img)?;
        pa_model::export::write_atomic(&path, &png)
            .with_context(|| format!("writing {}", path.display()))?;
        self.frames += 1;
        Ok(path)
    }
}

/// The `--log` file: one JSON object per presented frame, flushed line by line.
pub struct JsonLog {
    path: PathBuf,
    out: std::io::BufWriter<std::fs::File>,
}

impl JsonLog {
    /// Creates (or truncates) the log.
    pub fn create(path: &Path) -> Result<Self> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        }
        // Never a FIFO (it would block the window), a device or a link.
        pa_io::check_replaceable(path)?;
        let f = std::fs::File::create(path)
            .with_context(|| format!("creating the log {}", path.display()))?;
        Ok(Self {
            path: path.to_path_buf(),
            out: std::io::BufWriter::new(f),
        })
    }

    /// Writes one line and flushes it.
    pub fn line(&mut self, value: &serde_json::Value) -> Result<()> {
        writeln!(self.out, "{value}")
            .and_then(|_| self.out.flush())
            .with_context(|| format!("writing the log {}", self.path.display()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbering() {
        assert_eq!(
            parse_numbered("capture_0007.png", "capture_", ".png"),
            Some(7)
        );
        assert_eq!(parse_numbered("capture_.png", "capture_", ".png"), None);
        assert_eq!(parse_numbered("capture_7a.png", "capture_", ".png"), None);
        assert_eq!(parse_numbered("take_012", "take_", ""), Some(12));
        assert_eq!(next_number([], "capture_", ".png"), 1);
        assert_eq!(
            next_number(
                [
                    "capture_0002.png",
                    "x.png",
                    "capture_0010.png",
                    "capture_0003.png"
                ],
                "capture_",
                ".png"
            ),
            11
        );
    }

    #[test]
    fn captures_are_numbered_and_never_overwrite() {
        let dir = tempfile::tempdir().unwrap();
        let caps_dir = dir.path().join("caps");
        let img = Image::filled(4, 3, [10, 20, 30]);
        let mut caps = Captures::open(&caps_dir);
        assert!(caps.files.is_empty());
        let a = caps.save(&img).unwrap();
        assert!(a.ends_with("capture_0001.png"));
        // Someone else writes the next name meanwhile: it is kept, and skipped.
        std::fs::write(caps_dir.join("capture_0002.png"), b"precious").unwrap();
        let b = caps.save(&img).unwrap();
        assert!(b.ends_with("capture_0003.png"), "{}", b.display());
        assert_eq!(
            std::fs::read(caps_dir.join("capture_0002.png")).unwrap(),
            b"precious"
        );
        // A new session continues after the highest number and lists the captures in order.
        let caps2 = Captures::open(&caps_dir);
        assert_eq!(caps2.files.len(), 3);
        assert!(caps2.files[2].ends_with("capture_0003.png"));
        let decoded = image::open(&b).unwrap().to_rgba8();
        assert_eq!(decoded.get_pixel(1, 1).0, [10, 20, 30, 255]);
        // No temporary files are left.
        let names = names_in(&caps_dir);
        assert!(names.iter().all(|n| !n.contains(".tmp-")), "{names:?}");
        assert!(!write_new_atomic(&a, b"x").unwrap());
    }

    #[test]
    fn recordings_get_new_takes() {
        let dir = tempfile::tempdir().unwrap();
        let img = Image::filled(2, 2, [1, 2, 3]);
        let mut r1 = Recording::start(dir.path()).unwrap();
        r1.push(&img).unwrap();
        r1.push(&img).unwrap();
        assert!(r1.dir.ends_with("take_001"));
        assert!(r1.dir.join("000001.png").is_file());
        let r2 = Recording::start(dir.path()).unwrap();
        assert!(r2.dir.ends_with("take_002"));
        assert_eq!(r1.frames, 2);
    }

    #[test]
    fn log_lines() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("sub/log.jsonl");
        let mut log = JsonLog::create(&p).unwrap();
        log.line(&serde_json::json!({"frame": 0})).unwrap();
        log.line(&serde_json::json!({"frame": 1})).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert_eq!(text, "{\"frame\":0}\n{\"frame\":1}\n");
    }
}
