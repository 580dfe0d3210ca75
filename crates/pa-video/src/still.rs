//! Stills: one image file as a frame (PNG, JPEG, TIFF), read safely.
//!
//! Every still a command reads comes through [`read_still`] (or [`still_dimensions`] for the
//! header alone):
//! - only a regular file is opened (a FIFO or device is refused at once, never blocks);
//! - the file and the decoded image have budgets ([`StillBudget`]), checked from the header
//!   before any pixel is decoded, so a 20000x20000 PNG is a clear error, not an abort;
//! - a **truncated** file is an error for every format: the PNG and TIFF decoders say so, and
//!   a JPEG (whose decoder pads a cut-off scan with grey without a word) is walked marker by
//!   marker and must reach its end-of-image marker.

use std::io::{BufReader, Cursor, Seek};
use std::path::{Path, PathBuf};

use image::{DynamicImage, ImageFormat, ImageReader, Limits};

/// Size limits for one still.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StillBudget {
    /// The file, bytes.
    pub max_file_bytes: u64,
    /// Width and height, pixels.
    pub max_side_px: u32,
    /// Width x height, pixels.
    pub max_pixels: u64,
}

impl Default for StillBudget {
    /// 512 MiB files, sides up to 16384 px, 40 Mpixel (8K UHD is 33 Mpixel).
    fn default() -> Self {
        Self {
            max_file_bytes: 512 << 20,
            max_side_px: 16384,
            max_pixels: 40_000_000,
        }
    }
}

impl StillBudget {
    fn limits(&self) -> Limits {
        // The sides are checked by `check` (with a clearer message); the decoder's own limit is
        // on memory.
        let mut l = Limits::default();
        l.max_image_width = None;
        l.max_image_height = None;
        // RGBA16 of the largest image, plus the decoder's own buffers.
        l.max_alloc = Some(self.max_pixels.saturating_mul(8).saturating_add(64 << 20));
        l
    }

    fn check(&self, path: &Path, (w, h): (u32, u32)) -> Result<(), StillError> {
        if w == 0 || h == 0 {
            return Err(StillError::Invalid {
                path: path.to_path_buf(),
                why: format!("{w}x{h} pixels"),
            });
        }
        if w > self.max_side_px || h > self.max_side_px || (w as u64) * (h as u64) > self.max_pixels
        {
            return Err(StillError::TooLarge {
                path: path.to_path_buf(),
                width: w,
                height: h,
                budget: *self,
            });
        }
        Ok(())
    }
}

/// Why a still cannot be used; every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum StillError {
    #[error(transparent)]
    Io(#[from] pa_io::IoError),
    #[error("{}: not a PNG, JPEG or TIFF image", path.display())]
    UnknownFormat { path: PathBuf },
    #[error("{}: truncated {format} (the file ends before the image does)", path.display())]
    Truncated { path: PathBuf, format: &'static str },
    #[error(
        "{}: {width}x{height} pixels, over the limit for a still ({} px a side, {} Mpixel)",
        path.display(), budget.max_side_px, budget.max_pixels / 1_000_000
    )]
    TooLarge {
        path: PathBuf,
        width: u32,
        height: u32,
        budget: StillBudget,
    },
    #[error("{}: {why}", path.display())]
    Invalid { path: PathBuf, why: String },
}

impl StillError {
    fn decode(path: &Path, e: image::ImageError) -> Self {
        let why = match e {
            image::ImageError::Limits(_) => "over the decoder's memory limit for a still".into(),
            image::ImageError::IoError(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
                "truncated (the file ends before the image does)".into()
            }
            other => format!("cannot decode it: {other}"),
        };
        Self::Invalid {
            path: path.to_path_buf(),
            why,
        }
    }
}

fn reader<R: std::io::BufRead + Seek>(
    path: &Path,
    r: R,
    budget: &StillBudget,
) -> Result<ImageReader<R>, StillError> {
    let mut reader =
        ImageReader::new(r)
            .with_guessed_format()
            .map_err(|e| StillError::Invalid {
                path: path.to_path_buf(),
                why: format!("cannot read it: {e}"),
            })?;
    match reader.format() {
        Some(ImageFormat::Png | ImageFormat::Jpeg | ImageFormat::Tiff) => {}
        _ => {
            return Err(StillError::UnknownFormat {
                path: path.to_path_buf(),
            })
        }
    }
    reader.limits(budget.limits());
    Ok(reader)
}

/// The width and height of a still from its header.
pub fn still_dimensions(path: &Path, budget: &StillBudget) -> Result<(u32, u32), StillError> {
    let file = pa_io::open_regular(path)?;
    let reader = reader(path, BufReader::new(file), budget)?;
    let dims = reader
        .into_dimensions()
        .map_err(|e| StillError::decode(path, e))?;
    budget.check(path, dims)?;
    Ok(dims)
}

/// Reads and decodes a still (see the module docs for what is refused).
pub fn read_still(path: &Path, budget: &StillBudget) -> Result<DynamicImage, StillError> {
    let bytes = pa_io::read_regular(path, budget.max_file_bytes, "a still")?;
    decode_still(path, &bytes, budget)
}

/// Decodes the bytes of a still named `path` (used in messages only).
pub fn decode_still(
    path: &Path,
    bytes: &[u8],
    budget: &StillBudget,
) -> Result<DynamicImage, StillError> {
    let probe = reader(path, Cursor::new(bytes), budget)?;
    if probe.format() == Some(ImageFormat::Jpeg) && !jpeg_is_complete(bytes) {
        return Err(StillError::Truncated {
            path: path.to_path_buf(),
            format: "JPEG",
        });
    }
    let dims = probe
        .into_dimensions()
        .map_err(|e| StillError::decode(path, e))?;
    budget.check(path, dims)?;
    reader(path, Cursor::new(bytes), budget)?
        .decode()
        .map_err(|e| StillError::decode(path, e))
}

/// True when a JPEG's marker segments, walked from its start, reach the end-of-image marker
/// (EOI) after at least one scan. A file cut anywhere before that returns false. Entropy-coded
/// data is skipped as JPEG defines it: `FF 00` is a stuffed byte and `FF D0..D7` restart
/// markers; any other `FF xx` ends the scan.
pub fn jpeg_is_complete(b: &[u8]) -> bool {
    if b.len() < 4 || b[0] != 0xFF || b[1] != 0xD8 {
        return false;
    }
    let mut i = 2usize;
    let mut scans = 0usize;
    loop {
        // Find the next marker (fill bytes FF FF ... allowed).
        if i >= b.len() || b[i] != 0xFF {
            return false;
        }
        while i < b.len() && b[i] == 0xFF {
            i += 1;
        }
        let Some(&marker) = b.get(i) else {
            return false;
        };
        i += 1;
        match marker {
            0xD9 => return scans > 0,
            0xD0..=0xD7 | 0x01 => continue,
            _ => {}
        }
        let (Some(&hi), Some(&lo)) = (b.get(i), b.get(i + 1)) else {
            return false;
        };
        let len = u16::from_be_bytes([hi, lo]) as usize;
        if len < 2 {
            return false;
        }
        i += len;
        if i > b.len() {
            return false;
        }
        if marker == 0xDA {
            scans += 1;
            // Entropy-coded data up to the next marker that is not a stuffed byte or a restart.
            loop {
                let Some(pos) = b[i..].iter().position(|&x| x == 0xFF) else {
                    return false;
                };
                i += pos;
                match b.get(i + 1) {
                    None => return false,
                    Some(0x00) | Some(0xD0..=0xD7) => i += 2,
                    Some(0xFF) => i += 1,
                    Some(_) => break,
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn encode(format: ImageFormat, w: u32, h: u32) -> Vec<u8> {
        let img = image::RgbImage::from_fn(w, h, |x, y| {
            image::Rgb([
                (x * 7 % 256) as u8,
                (y * 5 % 256) as u8,
                ((x ^ y) % 256) as u8,
            ])
        });
        let mut out = Cursor::new(Vec::new());
        DynamicImage::ImageRgb8(img)
            .write_to(&mut out, format)
            .expect("encode");
        out.into_inner()
    }

    #[test]
    fn whole_files_decode() {
        for f in [ImageFormat::Png, ImageFormat::Jpeg, ImageFormat::Tiff] {
            let b = encode(f, 64, 48);
            let img = decode_still(Path::new("a"), &b, &StillBudget::default()).expect("decodes");
            assert_eq!((img.width(), img.height()), (64, 48), "{f:?}");
        }
        assert!(jpeg_is_complete(&encode(ImageFormat::Jpeg, 64, 48)));
    }

    #[test]
    fn regression_truncated_jpeg_is_refused_like_a_truncated_png() {
        // A JPEG cut anywhere in its scan decoded as a half-grey picture without a warning.
        let jpeg = encode(ImageFormat::Jpeg, 96, 64);
        for cut in [jpeg.len() - 2, jpeg.len() * 3 / 4, jpeg.len() / 2, 100] {
            let e = decode_still(Path::new("s.jpg"), &jpeg[..cut], &StillBudget::default())
                .expect_err("truncated JPEG");
            assert!(e.to_string().contains("s.jpg"), "{e}");
            assert!(e.to_string().contains("truncated"), "{e}");
        }
        let png = encode(ImageFormat::Png, 96, 64);
        let e = decode_still(
            Path::new("s.png"),
            &png[..png.len() / 2],
            &StillBudget::default(),
        )
        .expect_err("truncated PNG");
        assert!(e.to_string().contains("s.png"), "{e}");
    }

    #[test]
    fn regression_huge_still_is_refused_from_its_header() {
        // A 20000x20000 PNG aborted `run` at 3.1 GB; refused before any pixel is decoded.
        let budget = StillBudget {
            max_side_px: 100,
            ..StillBudget::default()
        };
        let b = encode(ImageFormat::Png, 120, 10);
        let e = decode_still(Path::new("big.png"), &b, &budget).expect_err("too wide");
        assert!(matches!(e, StillError::TooLarge { width: 120, .. }), "{e}");
    }

    #[test]
    fn garbage_is_not_an_image() {
        let e = decode_still(
            Path::new("x.png"),
            b"not an image at all",
            &StillBudget::default(),
        )
        .expect_err("garbage");
        assert!(e.to_string().contains("x.png"), "{e}");
    }
}
