//! The passes of a take (`--passes plate,twin,masks`) and the PNG encoding of its frames.

use crate::TakeError;

/// The passes asked for with `--passes`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PassSet {
    pub plate: bool,
    pub twin: bool,
    pub masks: bool,
}

impl PassSet {
    /// Every pass.
    pub fn all() -> Self {
        PassSet {
            plate: true,
            twin: true,
            masks: true,
        }
    }

    /// Reads `--passes` (already split at commas): plate, twin, masks (or mask), all; case
    /// and surrounding spaces do not matter, empty items are ignored.
    pub fn parse(list: &[String]) -> Result<PassSet, TakeError> {
        let mut p = PassSet::default();
        for item in list {
            match item.trim().to_ascii_lowercase().as_str() {
                "plate" => p.plate = true,
                "twin" => p.twin = true,
                "masks" | "mask" => p.masks = true,
                "all" => p = PassSet::all(),
                "" => {}
                other => {
                    return Err(TakeError::UnknownPass {
                        name: other.to_string(),
                    })
                }
            }
        }
        Ok(p)
    }

    /// True when any pass is asked for.
    pub fn any(self) -> bool {
        self.plate || self.twin || self.masks
    }

    /// The folders of the passes asked for.
    pub fn dirs(self) -> Vec<&'static str> {
        [
            (self.plate, "plate"),
            (self.twin, "twin"),
            (self.masks, "masks"),
        ]
        .into_iter()
        .filter_map(|(on, d)| on.then_some(d))
        .collect()
    }
}

/// PNG bytes of an RGBA8 image at `bit_depth`: 16-bit keeps `input`'s own 16-bit values
/// where the 8-bit result equals the input's 8-bit pixel, and widens (`v * 257`) elsewhere.
pub fn encode(
    out8: &[u8],
    input: Option<&image::DynamicImage>,
    bit_depth: u8,
    w: u32,
    h: u32,
) -> Result<Vec<u8>, TakeError> {
    let mut png = Vec::new();
    let mut cur = std::io::Cursor::new(&mut png);
    let wrong_size = || TakeError::BufferSize { what: "frame" };
    if bit_depth == 16 {
        let data: Vec<u16> = match input {
            Some(input) => {
                let in16 = input.to_rgba16();
                let in8 = input.to_rgba8();
                let mut data = Vec::with_capacity(out8.len());
                for ((o, i8), i16) in out8
                    .chunks_exact(4)
                    .zip(in8.as_raw().chunks_exact(4))
                    .zip(in16.as_raw().chunks_exact(4))
                {
                    if o == i8 {
                        data.extend_from_slice(i16);
                    } else {
                        data.extend(o.iter().map(|&v| v as u16 * 257));
                    }
                }
                data
            }
            None => out8.iter().map(|&v| v as u16 * 257).collect(),
        };
        let img = image::ImageBuffer::<image::Rgba<u16>, _>::from_raw(w, h, data)
            .ok_or_else(wrong_size)?;
        img.write_to(&mut cur, image::ImageFormat::Png)?;
    } else {
        let img = image::RgbaImage::from_raw(w, h, out8.to_vec()).ok_or_else(wrong_size)?;
        img.write_to(&mut cur, image::ImageFormat::Png)?;
    }
    Ok(png)
}

/// The masks pass: 8-bit RGB, R = key pose, G = twin.
pub fn encode_masks(key: &[bool], twin: &[bool], w: u32, h: u32) -> Result<Vec<u8>, TakeError> {
    let data: Vec<u8> = key
        .iter()
        .zip(twin)
        .flat_map(|(&k, &t)| [if k { 255 } else { 0 }, if t { 255 } else { 0 }, 0])
        .collect();
    let img =
        image::RgbImage::from_raw(w, h, data).ok_or(TakeError::BufferSize { what: "mask" })?;
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    Ok(png)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all_passes() -> PassSet {
        PassSet {
            plate: true,
            twin: true,
            masks: true,
        }
    }

    #[test]
    fn passes_parse() {
        let p = PassSet::parse(&["plate".into(), "masks".into()]).expect("passes");
        assert_eq!(p.dirs(), ["plate", "masks"]);
        assert_eq!(PassSet::parse(&["all".into()]).expect("all"), all_passes());
        assert!(PassSet::parse(&["depth".into()]).is_err());
        assert!(!PassSet::default().any());
        let err = PassSet::parse(&[" Twin".into(), "depth".into()]).expect_err("unknown");
        assert_eq!(
            err.to_string(),
            "--passes: unknown pass \"depth\" (use plate, twin, masks or all, comma-separated)"
        );
    }

    #[test]
    fn sixteen_bits_keep_the_input_where_the_frame_did_not_change() {
        let mut input = image::ImageBuffer::<image::Rgba<u16>, _>::new(2, 1);
        input.put_pixel(0, 0, image::Rgba([1000, 2000, 3000, 65535]));
        input.put_pixel(1, 0, image::Rgba([1000, 2000, 3000, 65535]));
        let input = image::DynamicImage::ImageRgba16(input);
        let mut out8 = input.to_rgba8().into_raw();
        out8[4] = 200;
        let png = encode(&out8, Some(&input), 16, 2, 1).expect("png");
        let back = image::load_from_memory(&png).expect("decode").to_rgba16();
        assert_eq!(back.get_pixel(0, 0).0, [1000, 2000, 3000, 65535]);
        assert_eq!(back.get_pixel(1, 0).0[0], 200 * 257);
        let png8 = encode(&out8, None, 8, 2, 1).expect("png");
        assert_eq!(
            image::load_from_memory(&png8)
                .expect("decode")
                .to_rgba8()
                .into_raw(),
            out8
        );
        assert!(encode(&out8, None, 8, 3, 1).is_err());
        let masks = encode_masks(&[true, false], &[false, true], 2, 1).expect("masks");
        let back = image::load_from_memory(&masks).expect("decode").to_rgb8();
        assert_eq!(back.into_raw(), [255, 0, 0, 0, 255, 0]);
        let err = encode_masks(&[true], &[true], 2, 1).expect_err("size");
        assert_eq!(err.to_string(), "mask buffer has the wrong size");
    }
}
