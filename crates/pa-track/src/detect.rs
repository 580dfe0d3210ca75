//! AprilTag detection (via `kornia-apriltag`), with corners converted once, here, to the
//! project's convention.
//!
//! Conversion at the boundary (tested against the AprilTag C library's detections on real
//! photos and against the canonical rendered tags):
//! - Position: kornia, like the C library, puts the centre of pixel (0, 0) at (0.5, 0.5).
//!   Ours (OpenCV) puts it at (0, 0): `ours = kornia - (0.5, 0.5)`.
//! - Order: kornia's `quad.corners` are in geometric order only (not rotated by the decoded
//!   orientation); the decoded orientation lives in its homography, whose tag coordinates
//!   (-1,-1), (1,-1), (1,1), (-1,1) are the printed tag's top-left, top-right, bottom-right,
//!   bottom-left. We project those four through the homography and snap each to the nearest
//!   quad corner, giving `[top-left, top-right, bottom-right, bottom-left]` of the tag as
//!   printed (OpenCV's clockwise-from-top-left convention applied to the printed tag; OpenCV's
//!   own ArUco AprilTag dictionary labels the corners turned by 180 degrees, see the crate
//!   docs).

use std::collections::HashMap;

use glam::DVec2;
use kornia_apriltag::{family::TagFamilyKind, AprilTagDecoder, DecodeTagsConfig};
use kornia_image::{Image, ImageSize};

use crate::TrackError;

/// An 8-bit greyscale image, row-major, `data.len() == width * height`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GrayImage {
    pub width: u32,
    pub height: u32,
    pub data: Vec<u8>,
}

impl GrayImage {
    /// A new image filled with `value`.
    pub fn filled(width: u32, height: u32, value: u8) -> Self {
        Self {
            width,
            height,
            data: vec![value; width as usize * height as usize],
        }
    }

    /// Wraps a buffer; fails when its length is not `width * height`.
    pub fn new(width: u32, height: u32, data: Vec<u8>) -> Result<Self, TrackError> {
        if data.len() != width as usize * height as usize {
            return Err(TrackError::BadImage {
                width,
                height,
                len: data.len(),
            });
        }
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// From interleaved 8-bit RGB (`3 * width * height` bytes), with Rec. 601 luma.
    pub fn from_rgb(width: u32, height: u32, rgb: &[u8]) -> Result<Self, TrackError> {
        if rgb.len() != 3 * width as usize * height as usize {
            return Err(TrackError::BadImage {
                width,
                height,
                len: rgb.len(),
            });
        }
        let data = rgb
            .chunks_exact(3)
            .map(|p| ((77 * p[0] as u32 + 150 * p[1] as u32 + 29 * p[2] as u32 + 128) >> 8) as u8)
            .collect();
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// The pixel at (x, y), or `None` outside the image.
    pub fn get(&self, x: u32, y: u32) -> Option<u8> {
        (x < self.width && y < self.height)
            .then(|| self.data[y as usize * self.width as usize + x as usize])
    }

    /// A copy of the rectangle `[x0, x0 + w) x [y0, y0 + h)` (clamped to the image).
    pub fn crop(&self, x0: u32, y0: u32, w: u32, h: u32) -> GrayImage {
        let x0 = x0.min(self.width);
        let y0 = y0.min(self.height);
        let w = w.min(self.width - x0);
        let h = h.min(self.height - y0);
        let mut data = Vec::with_capacity(w as usize * h as usize);
        for y in y0..y0 + h {
            let row = y as usize * self.width as usize;
            data.extend_from_slice(&self.data[row + x0 as usize..row + (x0 + w) as usize]);
        }
        GrayImage {
            width: w,
            height: h,
            data,
        }
    }

    /// Scales up by an integer factor with nearest neighbour and pads with `border` pixels of
    /// value `pad` on every side (used to show and test the canonical tag images).
    pub fn upscale_pad(&self, factor: u32, border: u32, pad: u8) -> GrayImage {
        let w = self.width * factor + 2 * border;
        let h = self.height * factor + 2 * border;
        let mut out = GrayImage::filled(w, h, pad);
        for y in 0..self.height * factor {
            for x in 0..self.width * factor {
                let v =
                    self.data[(y / factor) as usize * self.width as usize + (x / factor) as usize];
                out.data[(y + border) as usize * w as usize + (x + border) as usize] = v;
            }
        }
        out
    }
}

impl From<&image::GrayImage> for GrayImage {
    fn from(img: &image::GrayImage) -> Self {
        Self {
            width: img.width(),
            height: img.height(),
            data: img.as_raw().clone(),
        }
    }
}

impl From<&image::RgbImage> for GrayImage {
    fn from(img: &image::RgbImage) -> Self {
        // Length is guaranteed by `image`.
        let data = img
            .as_raw()
            .chunks_exact(3)
            .map(|p| ((77 * p[0] as u32 + 150 * p[1] as u32 + 29 * p[2] as u32 + 128) >> 8) as u8)
            .collect();
        Self {
            width: img.width(),
            height: img.height(),
            data,
        }
    }
}

impl From<&image::DynamicImage> for GrayImage {
    fn from(img: &image::DynamicImage) -> Self {
        match img {
            image::DynamicImage::ImageLuma8(g) => g.into(),
            other => (&other.to_rgb8()).into(),
        }
    }
}

impl From<GrayImage> for image::GrayImage {
    fn from(g: GrayImage) -> Self {
        // `GrayImage` keeps `data.len() == width * height`; fall back to an empty image if a
        // caller broke that invariant through the public fields.
        image::GrayImage::from_raw(g.width, g.height, g.data)
            .unwrap_or_else(|| image::GrayImage::new(0, 0))
    }
}

/// AprilTag families the detector supports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TagFamily {
    Tag36h11,
    Tag36h10,
    Tag25h9,
    Tag16h5,
    TagCircle21h7,
    TagCircle49h12,
    TagCustom48h12,
    TagStandard41h12,
    TagStandard52h13,
}

impl TagFamily {
    /// All families.
    pub const ALL: [TagFamily; 9] = [
        TagFamily::Tag36h11,
        TagFamily::Tag36h10,
        TagFamily::Tag25h9,
        TagFamily::Tag16h5,
        TagFamily::TagCircle21h7,
        TagFamily::TagCircle49h12,
        TagFamily::TagCustom48h12,
        TagFamily::TagStandard41h12,
        TagFamily::TagStandard52h13,
    ];

    /// The usual name (`tag36h11`, `tagStandard41h12`, ...).
    pub fn name(self) -> &'static str {
        match self {
            TagFamily::Tag36h11 => "tag36h11",
            TagFamily::Tag36h10 => "tag36h10",
            TagFamily::Tag25h9 => "tag25h9",
            TagFamily::Tag16h5 => "tag16h5",
            TagFamily::TagCircle21h7 => "tagCircle21h7",
            TagFamily::TagCircle49h12 => "tagCircle49h12",
            TagFamily::TagCustom48h12 => "tagCustom48h12",
            TagFamily::TagStandard41h12 => "tagStandard41h12",
            TagFamily::TagStandard52h13 => "tagStandard52h13",
        }
    }

    pub(crate) fn kind(self) -> TagFamilyKind {
        match self {
            TagFamily::Tag36h11 => TagFamilyKind::Tag36H11,
            TagFamily::Tag36h10 => TagFamilyKind::Tag36H10,
            TagFamily::Tag25h9 => TagFamilyKind::Tag25H9,
            TagFamily::Tag16h5 => TagFamilyKind::Tag16H5,
            TagFamily::TagCircle21h7 => TagFamilyKind::TagCircle21H7,
            TagFamily::TagCircle49h12 => TagFamilyKind::TagCircle49H12,
            TagFamily::TagCustom48h12 => TagFamilyKind::TagCustom48H12,
            TagFamily::TagStandard41h12 => TagFamilyKind::TagStandard41H12,
            TagFamily::TagStandard52h13 => TagFamilyKind::TagStandard52H13,
        }
    }

    fn from_kind(kind: &TagFamilyKind) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.kind() == *kind)
    }
}

impl std::fmt::Display for TagFamily {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for TagFamily {
    type Err = TrackError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let norm: String = s
            .chars()
            .filter(|c| c.is_ascii_alphanumeric())
            .collect::<String>()
            .to_ascii_lowercase();
        Self::ALL
            .into_iter()
            .find(|f| f.name().to_ascii_lowercase() == norm)
            .ok_or_else(|| TrackError::UnknownFamily(s.to_string()))
    }
}

/// One detected tag, corners in the project's convention (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Detection {
    pub family: TagFamily,
    pub id: u32,
    /// `[top-left, top-right, bottom-right, bottom-left]` of the printed tag (outer corners
    /// of the black border), pixels, OpenCV pixel-centre convention.
    pub corners_px: [DVec2; 4],
    /// Corrected bit errors.
    pub hamming: u8,
    /// Decoder confidence (higher is better).
    pub decision_margin: f32,
}

impl Detection {
    /// The tag centre (intersection of the diagonals).
    pub fn center_px(&self) -> DVec2 {
        let [a, b, c, d] = self.corners_px;
        let (p, r) = (a, c - a);
        let (q, s) = (b, d - b);
        let den = r.perp_dot(s);
        if den.abs() < 1e-12 {
            return (a + b + c + d) * 0.25;
        }
        p + r * ((q - p).perp_dot(s) / den)
    }

    /// The shortest side in pixels.
    pub fn min_side_px(&self) -> f64 {
        (0..4)
            .map(|i| self.corners_px[i].distance(self.corners_px[(i + 1) % 4]))
            .fold(f64::INFINITY, f64::min)
    }
}

/// Detector settings.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct DetectorConfig {
    /// Families to look for (default: tag36h11).
    pub families: Vec<TagFamily>,
    /// Decimation before quad search (1 = full resolution, 2 = faster, misses small tags).
    pub decimate: u32,
    /// Refine edges on the full-resolution image after quad fitting.
    pub refine_edges: bool,
    /// Binarisation split between local min and max (0.5 = the C library).
    pub threshold_split: f32,
    /// Bit errors corrected (0..=2 for tag36h11; more means more false positives).
    pub max_hamming: u8,
    /// Minimum decision margin to accept a detection.
    pub min_decision_margin: f32,
    /// A second pass at this decimation whose detections are merged in (tags the first pass
    /// found keep its corners). kornia-apriltag 0.2 at decimation 1 misses many sharp,
    /// in-plane-rotated tags that decimation 2 finds, and vice versa for small tags; the two
    /// passes together find both. `None` = single pass.
    pub second_pass_decimate: Option<u32>,
    /// Thorough mode: one more pass at decimation 1 on the frame upsampled 2x (bilinear,
    /// pixel-centre aligned), whose corners are mapped back with `x = (u + 0.5) / 2 - 0.5`.
    /// Finds small (10-35 px), strongly tilted tags that kornia-apriltag 0.2 misses at the
    /// original resolution; costs about 4x a full-resolution pass. Tags found by the earlier
    /// passes keep their corners. Off by default.
    pub upsample_pass: bool,
    /// When the other passes find nothing, one more pass at this decimation (for tags that
    /// fill much of a large frame: kornia-apriltag 0.2 misses a 900 px tag at full and half
    /// resolution). Costs a quarter-resolution pass on frames without tags only.
    pub fallback_decimate: Option<u32>,
    /// Binarisation: tiles whose local max - min is below this are left undecided (the C
    /// library's `min_white_black_diff`; it uses 5, [`DetectorConfig::c_reference`] too).
    /// The default, 20, skips sensor noise on flat backgrounds: 10-40x faster full-frame
    /// search on frames with a few grey levels of noise (see `examples/track_bench.rs`), the
    /// same 40/47 recall on the conformance photos; tags with under 20 grey levels of
    /// black/white contrast are missed.
    pub min_white_black_diff: u8,
}

impl Default for DetectorConfig {
    fn default() -> Self {
        Self {
            families: vec![TagFamily::Tag36h11],
            decimate: 1,
            refine_edges: true,
            threshold_split: 0.5,
            max_hamming: 2,
            min_decision_margin: 0.0,
            second_pass_decimate: Some(2),
            upsample_pass: false,
            fallback_decimate: Some(4),
            min_white_black_diff: 20,
        }
    }
}

impl DetectorConfig {
    /// These settings plus the 2x-upsampled pass ([`DetectorConfig::upsample_pass`]):
    /// better recall of small tilted tags, several times slower (opt-in).
    pub fn thorough(self) -> Self {
        Self {
            upsample_pass: true,
            ..self
        }
    }

    /// The settings of the AprilTag C library's reference detections in the conformance data
    /// (quad_decimate = 1, refine_edges = false).
    pub fn c_reference() -> Self {
        Self {
            refine_edges: false,
            second_pass_decimate: None,
            min_white_black_diff: 5,
            ..Self::default()
        }
    }
}

/// A reusable detector. Decoders are cached per image size (the underlying library allocates
/// per size), so feed it frames of a few sizes only.
pub struct Detector {
    config: DetectorConfig,
    decoders: HashMap<(u32, u32, u32), AprilTagDecoder>,
    order: Vec<(u32, u32, u32)>,
}

const MAX_CACHED_DECODERS: usize = 8;

impl Detector {
    /// A detector with the given settings.
    pub fn new(config: DetectorConfig) -> Result<Self, TrackError> {
        if config.families.is_empty() {
            return Err(TrackError::Config("no tag family configured".into()));
        }
        if config.decimate == 0
            || config.decimate > 8
            || config.second_pass_decimate.is_some_and(|d| d == 0 || d > 8)
            || config.fallback_decimate.is_some_and(|d| d == 0 || d > 8)
        {
            return Err(TrackError::Config(format!(
                "decimate must be 1..=8, got {}",
                config.decimate
            )));
        }
        if !(0.0..=1.0).contains(&config.threshold_split) {
            return Err(TrackError::Config(format!(
                "threshold_split must be in [0, 1], got {}",
                config.threshold_split
            )));
        }
        if config.max_hamming > 3 {
            return Err(TrackError::Config(format!(
                "max_hamming must be 0..=3, got {}",
                config.max_hamming
            )));
        }
        Ok(Self {
            config,
            decoders: HashMap::new(),
            order: Vec::new(),
        })
    }

    /// The settings.
    pub fn config(&self) -> &DetectorConfig {
        &self.config
    }

    fn decoder(
        &mut self,
        width: u32,
        height: u32,
        decimate: u32,
    ) -> Result<&mut AprilTagDecoder, TrackError> {
        let key = (width, height, decimate);
        if !self.decoders.contains_key(&key) {
            let mut kinds = Vec::new();
            for f in &self.config.families {
                let kind = f.kind();
                if self.config.max_hamming != 2 {
                    let fam = kornia_apriltag::family::TagFamily::try_from(&kind)
                        .map_err(TrackError::detector)?
                        .with_max_hamming(self.config.max_hamming)
                        .map_err(TrackError::detector)?;
                    kinds.push(TagFamilyKind::Custom(std::sync::Arc::new(fam)));
                } else {
                    kinds.push(kind);
                }
            }
            let mut cfg = DecodeTagsConfig::new(kinds).map_err(TrackError::detector)?;
            cfg.downscale_factor = decimate as usize;
            cfg.refine_edges_enabled = self.config.refine_edges;
            cfg.threshold_split = self.config.threshold_split;
            cfg.min_white_black_difference = self.config.min_white_black_diff;
            let size = ImageSize {
                width: width as usize,
                height: height as usize,
            };
            let dec = AprilTagDecoder::new(cfg, size).map_err(TrackError::detector)?;
            if self.order.len() >= MAX_CACHED_DECODERS {
                let old = self.order.remove(0);
                self.decoders.remove(&old);
            }
            self.order.push(key);
            self.decoders.insert(key, dec);
        }
        self.decoders
            .get_mut(&key)
            .ok_or_else(|| TrackError::Config("decoder cache".into()))
    }

    /// Detects all tags in a frame. A frame without tags gives an empty list; frames too small
    /// for the detector (under 8x8) give an empty list too.
    pub fn detect(&mut self, image: &GrayImage) -> Result<Vec<Detection>, TrackError> {
        if image.data.len() != image.width as usize * image.height as usize {
            return Err(TrackError::BadImage {
                width: image.width,
                height: image.height,
                len: image.data.len(),
            });
        }
        if image.width < 8 || image.height < 8 {
            return Ok(Vec::new());
        }
        let families = self.config.families.clone();
        let min_margin = self.config.min_decision_margin;
        let size = ImageSize {
            width: image.width as usize,
            height: image.height as usize,
        };
        let kimg = Image::<u8, 1>::new(size, image.data.clone()).map_err(TrackError::detector)?;
        let mut out = self.detect_passes(image, &kimg)?;
        out.retain(|d| inside_frame(d, image));
        if out.is_empty() {
            if let Some(d) = self
                .config
                .fallback_decimate
                .filter(|d| image.width / d >= 64 && image.height / d >= 64)
            {
                let dec = self.decoder(image.width, image.height, d)?;
                let raw = dec.decode(&kimg).map_err(TrackError::detector)?;
                dec.clear();
                out = convert(&raw, &families, min_margin);
                out.retain(|d| inside_frame(d, image));
            }
        }
        Ok(out)
    }

    fn detect_passes(
        &mut self,
        image: &GrayImage,
        kimg: &Image<u8, 1>,
    ) -> Result<Vec<Detection>, TrackError> {
        let families = self.config.families.clone();
        let min_margin = self.config.min_decision_margin;
        let mut passes = vec![self.config.decimate];
        if let Some(d) = self
            .config
            .second_pass_decimate
            .filter(|d| *d != self.config.decimate)
        {
            // Decimated passes need the decimated image to be a workable size.
            if image.width / d >= 8 && image.height / d >= 8 {
                passes.push(d);
            }
        }
        let mut out: Vec<Detection> = Vec::new();
        for decimate in passes {
            let dec = self.decoder(image.width, image.height, decimate)?;
            let raw = dec.decode(kimg).map_err(TrackError::detector)?;
            dec.clear();
            let first = out.len();
            for d in convert(&raw, &families, min_margin) {
                let dup = out[..first].iter().any(|o| {
                    o.id == d.id
                        && o.family == d.family
                        && o.center_px().distance(d.center_px()) < 0.5 * o.min_side_px().max(2.0)
                });
                if !dup {
                    out.push(d);
                }
            }
        }
        if self.config.upsample_pass && (image.width as u64 * image.height as u64) <= 16_000_000 {
            let up = upsample2(image);
            let size = ImageSize {
                width: up.width as usize,
                height: up.height as usize,
            };
            let kup = Image::<u8, 1>::new(size, up.data).map_err(TrackError::detector)?;
            let dec = self.decoder(up.width, up.height, 1)?;
            let raw = dec.decode(&kup).map_err(TrackError::detector)?;
            dec.clear();
            let first = out.len();
            for mut d in convert(&raw, &families, min_margin) {
                for c in &mut d.corners_px {
                    *c = (*c + DVec2::splat(0.5)) * 0.5 - DVec2::splat(0.5);
                }
                let dup = out[..first].iter().any(|o| {
                    o.id == d.id
                        && o.family == d.family
                        && o.center_px().distance(d.center_px()) < 0.5 * o.min_side_px().max(2.0)
                });
                if !dup {
                    out.push(d);
                }
            }
        }
        Ok(out)
    }
}

/// A tag cut by the frame edge can still decode, with a corner on the edge and wrong by many
/// pixels; a whole tag has its quiet zone inside the frame, so its corners are at least a
/// pixel from the edge. Detections with a corner closer than that are dropped.
fn inside_frame(d: &Detection, image: &GrayImage) -> bool {
    let (w, h) = (image.width as f64, image.height as f64);
    d.corners_px
        .iter()
        .all(|c| c.x >= 0.5 && c.y >= 0.5 && c.x <= w - 1.5 && c.y <= h - 1.5)
}

/// 2x bilinear upsampling with pixel centres aligned: output pixel `j` samples the input at
/// `(j + 0.5) / 2 - 0.5`, i.e. weights 3/4, 1/4 of the two nearest input pixels.
pub fn upsample2(image: &GrayImage) -> GrayImage {
    let (w, h) = (image.width as usize, image.height as usize);
    let (w2, h2) = (2 * w, 2 * h);
    // Horizontal pass into u16 (x4 scale).
    let mut horiz = vec![0u16; w2 * h];
    for y in 0..h {
        let row = &image.data[y * w..(y + 1) * w];
        let out = &mut horiz[y * w2..(y + 1) * w2];
        for x in 0..w {
            let c = row[x] as u16 * 3;
            let l = row[x.saturating_sub(1)] as u16;
            let r = row[(x + 1).min(w - 1)] as u16;
            out[2 * x] = c + l;
            out[2 * x + 1] = c + r;
        }
    }
    let mut data = vec![0u8; w2 * h2];
    for y in 0..h {
        let c = &horiz[y * w2..(y + 1) * w2];
        let u = &horiz[y.saturating_sub(1) * w2..(y.saturating_sub(1) + 1) * w2];
        let d = &horiz[(y + 1).min(h - 1) * w2..((y + 1).min(h - 1) + 1) * w2];
        let (top, bottom) = data[2 * y * w2..(2 * y + 2) * w2].split_at_mut(w2);
        for x in 0..w2 {
            // (3c + n) / 16, rounded.
            top[x] = ((3 * c[x] as u32 + u[x] as u32 + 8) >> 4) as u8;
            bottom[x] = ((3 * c[x] as u32 + d[x] as u32 + 8) >> 4) as u8;
        }
    }
    GrayImage {
        width: w2 as u32,
        height: h2 as u32,
        data,
    }
}

fn convert(
    raw: &[kornia_apriltag::decoder::Detection],
    families: &[TagFamily],
    min_margin: f32,
) -> Vec<Detection> {
    {
        let mut out = Vec::with_capacity(raw.len());
        for d in raw.iter() {
            if d.decision_margin < min_margin {
                continue;
            }
            let family = match &d.tag_family_kind {
                TagFamilyKind::Custom(_) => families.get(d._family_idx).copied(),
                k => TagFamily::from_kind(k),
            };
            let Some(family) = family.or(families.first().copied()) else {
                continue;
            };
            out.push(Detection {
                family,
                id: d.id as u32,
                corners_px: oriented_corners(&d.quad),
                hamming: d.hamming,
                decision_margin: d.decision_margin,
            });
        }
        out
    }
}

impl Detector {
    /// Detects tags inside a region of interest `[x0, x0 + w) x [y0, y0 + h)` only; corners
    /// come back in full-frame coordinates. The region is grown to a multiple of 32 pixels
    /// (fewer decoder sizes to cache) and clamped to the frame.
    pub fn detect_roi(
        &mut self,
        image: &GrayImage,
        x0: u32,
        y0: u32,
        w: u32,
        h: u32,
    ) -> Result<Vec<Detection>, TrackError> {
        let round = |v: u32, max: u32| (v.div_ceil(32) * 32).min(max);
        let w = round(w.max(32), image.width);
        let h = round(h.max(32), image.height);
        let x0 = x0.min(image.width - w);
        let y0 = y0.min(image.height - h);
        if w == image.width && h == image.height {
            return self.detect(image);
        }
        let crop = image.crop(x0, y0, w, h);
        let mut dets = self.detect(&crop)?;
        let off = DVec2::new(x0 as f64, y0 as f64);
        for d in &mut dets {
            for c in &mut d.corners_px {
                *c += off;
            }
        }
        Ok(dets)
    }
}

/// Kornia quad -> our corners: printed TL, TR, BR, BL, OpenCV pixel centres.
fn oriented_corners(quad: &kornia_apriltag::quad::Quad) -> [DVec2; 4] {
    let tag = [(-1.0f32, -1.0f32), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
    let corners: Vec<DVec2> = quad
        .corners
        .iter()
        .map(|c| DVec2::new(c.x as f64, c.y as f64))
        .collect();
    let mut out = [DVec2::ZERO; 4];
    // Pick the rotation/winding of the quad corners that best matches the projected tag corners.
    let proj: Vec<DVec2> = tag
        .iter()
        .map(|&(x, y)| {
            let p = quad.homography_project(x, y);
            DVec2::new(p.x as f64, p.y as f64)
        })
        .collect();
    let mut best = (f64::INFINITY, [0usize, 1, 2, 3]);
    for start in 0..4 {
        for dir in [1usize, 3] {
            let perm = [
                start,
                (start + dir) % 4,
                (start + 2 * dir) % 4,
                (start + 3 * dir) % 4,
            ];
            let e: f64 = (0..4)
                .map(|i| corners[perm[i]].distance_squared(proj[i]))
                .sum();
            if e < best.0 {
                best = (e, perm);
            }
        }
    }
    for i in 0..4 {
        out[i] = corners[best.1[i]] - DVec2::splat(0.5);
    }
    out
}
