//! AprilTag detection, with corners converted once, here, to the project's convention.
//!
//! Pipeline per pass (the AprilTag 3 algorithm; our own implementation in `segment.rs` and
//! `quad.rs`, the tag family code tables vendored in `family.rs`): adaptive binarisation,
//! connected components, boundary clusters between black and white components, a quad fit
//! per cluster, decoding on the full-resolution image. On the conformance photos its quads
//! and corners agree with the AprilTag C library's to a median of 0.0003 px (47/47 tags; see
//! `tests/conformance.rs`).
//!
//! Conversion at the boundary (tested against the AprilTag C library's detections on real
//! photos and against the canonical rendered tags):
//! - Position: the quad fit, like the C library, puts the centre of pixel (0, 0) at
//!   (0.5, 0.5). Ours (OpenCV) puts it at (0, 0): `ours = fit - (0.5, 0.5)`.
//! - Order: the decoded orientation turns the quad's homography so that tag coordinates
//!   (-1,-1), (1,-1), (1,1), (-1,1) are the printed tag's top-left, top-right, bottom-right,
//!   bottom-left; the corners are those four projected through it, giving `[top-left,
//!   top-right, bottom-right, bottom-left]` of the tag as printed (OpenCV's
//!   clockwise-from-top-left convention applied to the printed tag; OpenCV's own ArUco
//!   AprilTag dictionary labels the corners turned by 180 degrees, see the crate docs).

use std::collections::HashMap;

use glam::DVec2;
use rayon::prelude::*;

use crate::quad::{
    decode, fit_quad, may_decode, refine_edges_reference, FamilyCodes, FitScratch, Homography,
    QuadParams,
};
use crate::segment::{threshold, Segmenter};

use crate::family::DEFAULT_MAX_HAMMING;
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
        min_side_px(&self.corners_px)
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
    /// Refine the edges of quads found at reduced resolution (decimation > 1: the second and
    /// fallback passes) on the full-resolution image, as the AprilTag C library's
    /// `refine_edges` does. Quads found at full resolution are fitted to the full-resolution
    /// boundary already and are used as fitted: refining them too moved the corners by
    /// 0.3 px (median) away from the C library's on the conformance photos, lost 2 of their
    /// 47 tags, and put the corners of the sharp canonical tags 0.3 px off (0.01 px
    /// unrefined).
    pub refine_edges: bool,
    /// Binarisation split between local min and max (0.5 = the C library).
    pub threshold_split: f32,
    /// Bit errors corrected (0..=2 for tag36h11; more means more false positives).
    pub max_hamming: u8,
    /// Minimum decision margin to accept a detection.
    pub min_decision_margin: f32,
    /// A second pass at this decimation whose detections are merged in (tags the first pass
    /// found keep its corners). Its 12 px binarisation neighbourhood (24 px at decimation
    /// 2) finds strongly defocused tags the full-resolution pass misses (a 150-300 px tag
    /// blurred with sigma 8 px, `examples/blur_probe.rs`); about a third of the full-search
    /// time. `None` = single pass.
    pub second_pass_decimate: Option<u32>,
    /// Thorough mode: one more pass at decimation 1 on the frame upsampled 2x (bilinear,
    /// pixel-centre aligned), whose corners are mapped back with `x = (u + 0.5) / 2 - 0.5`.
    /// For very small tags; costs about 4x a full-resolution pass. Tags found by the earlier
    /// passes keep their corners. Off by default (on the conformance photos the
    /// full-resolution pass already finds all 47 tags).
    pub upsample_pass: bool,
    /// When the other passes find nothing, one more pass at this decimation (for tags that
    /// fill much of a large frame, whose edges span more than the binarisation
    /// neighbourhood). Costs a quarter-resolution pass on frames without tags only.
    pub fallback_decimate: Option<u32>,
    /// Binarisation: tiles whose local max - min is below this are left undecided (the C
    /// library's `min_white_black_diff`; it uses 5, [`DetectorConfig::c_reference`] too).
    /// The default, 20, skips sensor noise on flat backgrounds: about 70x faster full-frame
    /// search on frames with a few grey levels of noise (see `examples/track_bench.rs`), the
    /// same 47/47 recall on the conformance photos; tags with under 20 grey levels of
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

    /// Per-still speed: the quad search at decimation 2 only, its quads edge-refined on the
    /// full-resolution image (what the AprilTag C library does at `quad_decimate = 2`), the
    /// quarter-resolution fallback kept. A quarter of the pixels of the default's
    /// full-resolution pass; misses small tags the default finds (on the conformance photos,
    /// tags of about 27 px, it finds 34 of 47, the same as the C library at decimate 2).
    /// Measured against the C library by `examples/apriltag_compare.rs`.
    pub fn fast() -> Self {
        Self {
            decimate: 2,
            second_pass_decimate: None,
            ..Self::default()
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

/// A reusable detector. Working buffers are cached per image size, so feed it frames of a
/// few sizes only.
pub struct Detector {
    config: DetectorConfig,
    families: Vec<(TagFamily, FamilyCodes)>,
    buffers: HashMap<(u32, u32, u32), PassBuffers>,
    order: Vec<(u32, u32, u32)>,
}

const MAX_CACHED_DECODERS: usize = 8;

/// The boundary points use 16-bit half-pixel coordinates.
const MAX_SIDE: u32 = 32_767;

/// Per-size working buffers of one pass (decimated and binarised image, components).
#[derive(Default)]
struct PassBuffers {
    decimated: Vec<u8>,
    bin: Vec<u8>,
    scratch: Vec<u8>,
    seg: Segmenter,
    fit: FitScratch,
}

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
        let mut families = Vec::new();
        for f in &config.families {
            if families.iter().any(|(g, _)| g == f) {
                continue;
            }
            let def = f.def();
            // As kornia-apriltag did: a radius other than the default must be safe.
            if config.max_hamming != DEFAULT_MAX_HAMMING
                && config.max_hamming > def.max_safe_hamming()
            {
                return Err(TrackError::MaxHammingTooLarge {
                    max_hamming: config.max_hamming,
                    min_hamming: def.min_hamming,
                    max_safe: def.max_safe_hamming(),
                });
            }
            families.push((*f, FamilyCodes::new(def, config.max_hamming)));
        }
        Ok(Self {
            config,
            families,
            buffers: HashMap::new(),
            order: Vec::new(),
        })
    }

    /// The settings.
    pub fn config(&self) -> &DetectorConfig {
        &self.config
    }

    /// Takes the working buffers of a pass out of the cache (fresh ones the first time);
    /// [`Detector::put_buffers`] returns them.
    fn take_buffers(&mut self, width: u32, height: u32, decimate: u32) -> PassBuffers {
        let key = (width, height, decimate);
        self.buffers.remove(&key).unwrap_or_default()
    }

    fn put_buffers(&mut self, width: u32, height: u32, decimate: u32, buf: PassBuffers) {
        let key = (width, height, decimate);
        if !self.order.contains(&key) {
            if self.order.len() >= MAX_CACHED_DECODERS {
                let old = self.order.remove(0);
                self.buffers.remove(&old);
            }
            self.order.push(key);
        }
        self.buffers.insert(key, buf);
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
        if image.width > MAX_SIDE || image.height > MAX_SIDE {
            return Err(TrackError::Config(format!(
                "image {}x{} too large for the detector (at most {MAX_SIDE} px a side)",
                image.width, image.height
            )));
        }
        let mut out = self.detect_passes(image)?;
        out.retain(|d| inside_frame(d, image));
        if out.is_empty() {
            if let Some(d) = self
                .config
                .fallback_decimate
                .filter(|d| image.width / d >= 64 && image.height / d >= 64)
            {
                out = self.run_pass(image, d)?;
                out.retain(|d| inside_frame(d, image));
            }
        }
        Ok(out)
    }

    /// One pass of quad search at `decimate` and decoding at full resolution.
    fn run_pass(&mut self, image: &GrayImage, decimate: u32) -> Result<Vec<Detection>, TrackError> {
        let mut buf = self.take_buffers(image.width, image.height, decimate);
        let out = Self::pass(&self.config, &self.families, &mut buf, image, decimate);
        self.put_buffers(image.width, image.height, decimate, buf);
        out
    }

    /// Two passes at once, on two threads (their buffers are separate); results in order.
    fn run_two_passes(
        &mut self,
        image: &GrayImage,
        d1: u32,
        d2: u32,
    ) -> Result<(Vec<Detection>, Vec<Detection>), TrackError> {
        let (w, h) = (image.width, image.height);
        let (mut b1, mut b2) = (self.take_buffers(w, h, d1), self.take_buffers(w, h, d2));
        let (config, families) = (&self.config, &self.families);
        let (r1, r2) = rayon::join(
            || Self::pass(config, families, &mut b1, image, d1),
            || Self::pass(config, families, &mut b2, image, d2),
        );
        self.put_buffers(w, h, d1, b1);
        self.put_buffers(w, h, d2, b2);
        Ok((r1?, r2?))
    }

    fn pass(
        config: &DetectorConfig,
        families: &[(TagFamily, FamilyCodes)],
        buf: &mut PassBuffers,
        image: &GrayImage,
        decimate: u32,
    ) -> Result<Vec<Detection>, TrackError> {
        let (w, h) = (image.width as usize, image.height as usize);
        let split = config.threshold_split;
        let min_diff = config.min_white_black_diff;
        let refine = config.refine_edges;
        let min_margin = config.min_decision_margin;
        let normal_border = families.iter().any(|(_, f)| !f.reversed_border());
        let reversed_border = families.iter().any(|(_, f)| f.reversed_border());
        let tag_width = (families
            .iter()
            .map(|(_, f)| f.width_at_border())
            .min()
            .unwrap_or(8) as u32
            / decimate)
            .max(3);
        let d = decimate as usize;
        let (qw, qh) = (1 + (w - 1) / d, 1 + (h - 1) / d);
        if qw < 8 || qh < 8 {
            return Ok(Vec::new());
        }
        // The image the quads are searched in (stride decimation, as the reference).
        let gray_q: &[u8] = if d > 1 {
            buf.decimated.clear();
            for sy in 0..qh {
                let src = &image.data[sy * d * w..];
                buf.decimated.extend((0..qw).map(|sx| src[sx * d]));
            }
            &buf.decimated
        } else {
            &image.data
        };
        threshold(
            gray_q,
            qw,
            qh,
            min_diff,
            split,
            &mut buf.bin,
            &mut buf.scratch,
        );
        buf.seg.segment(&buf.bin, qw, qh);
        let params = QuadParams::default();
        let max_cluster = 3 * (2 * qw + 2 * qh);
        // Quad fit and decoding per cluster, on the pool's threads (each cluster is
        // independent; the results keep the clusters' order, so the output does not depend
        // on the scheduling).
        let clusters = buf.seg.clusters_mut();
        let fit_one = |fit: &mut FitScratch, cluster: &mut Vec<crate::quad::Pt>| {
            if cluster.len() < 24 || cluster.len() > max_cluster {
                return Vec::new();
            }
            let Some(mut q) = fit_quad(
                gray_q,
                qw,
                qh,
                cluster,
                tag_width,
                normal_border,
                reversed_border,
                &params,
                fit,
            ) else {
                return Vec::new();
            };
            if decimate > 1 {
                let d = decimate as f64;
                for p in &mut q.p {
                    *p = (*p - DVec2::splat(0.5)) * d + DVec2::splat(0.5);
                }
            }
            // Quads found at full resolution sit on the full-resolution boundary already
            // (refining them too moves the corners by 0.3 px on average from the reference
            // library's and 0.3 px off the truth on sharp synthetic tags).
            if refine && decimate > 1 {
                // Most quads of a noisy frame are noise: read them at these corners first,
                // and refine only those that may decode (the refinement costs more than
                // the reading; `may_decode`).
                let hom = Homography::from_quad(&q.p);
                let may = hom.is_some_and(|hom| {
                    families.iter().any(|(_, f)| {
                        f.reversed_border() == q.reversed_border
                            && may_decode(&image.data, w, h, f, &hom, DECODE_SHARPENING)
                    })
                });
                if !may {
                    return Vec::new();
                }
                refine_edges_reference(&image.data, w, h, &mut q, decimate as f64 + 1.0);
            }
            decode_quad(&image.data, w, h, families, &q, min_margin)
        };
        let found: Vec<Vec<Detection>> = if clusters.len() >= 2 * PAR_MIN_CLUSTERS {
            clusters
                .par_iter_mut()
                .with_min_len(PAR_MIN_CLUSTERS)
                .map_init(FitScratch::default, fit_one)
                .collect()
        } else {
            clusters
                .iter_mut()
                .map(|c| fit_one(&mut buf.fit, c))
                .collect()
        };
        let mut out: Vec<Detection> = Vec::new();
        for det in found.into_iter().flatten() {
            // Overlapping detections of the same tag: keep the better one.
            let dup = out.iter().position(|o| {
                o.id == det.id
                    && o.family == det.family
                    && o.center_px().distance(det.center_px()) < 0.5 * o.min_side_px().max(2.0)
            });
            match dup {
                Some(i) => {
                    let o = &out[i];
                    if (det.hamming, -det.decision_margin) < (o.hamming, -o.decision_margin) {
                        out[i] = det;
                    }
                }
                None => out.push(det),
            }
        }
        Ok(out)
    }

    fn detect_passes(&mut self, image: &GrayImage) -> Result<Vec<Detection>, TrackError> {
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
        if let [d1, d2] = passes[..] {
            let (first, second) = self.run_two_passes(image, d1, d2)?;
            merge_new(&mut out, first);
            merge_new(&mut out, second);
        } else {
            for decimate in passes {
                let raw = self.run_pass(image, decimate)?;
                merge_new(&mut out, raw);
            }
        }
        if self.config.upsample_pass
            && (image.width as u64 * image.height as u64) <= 16_000_000
            && 2 * image.width.max(image.height) <= MAX_SIDE
        {
            let up = upsample2(image);
            let mut raw = self.run_pass(&up, 1)?;
            for d in &mut raw {
                for c in &mut d.corners_px {
                    *c = (*c + DVec2::splat(0.5)) * 0.5 - DVec2::splat(0.5);
                }
            }
            merge_new(&mut out, raw);
        }
        Ok(out)
    }
}

/// The decoder's sharpening of the bit values (the reference library's `decode_sharpening`).
const DECODE_SHARPENING: f64 = 0.25;

/// Clusters per parallel job of the quad fit (most clusters are small and rejected early).
const PAR_MIN_CLUSTERS: usize = 64;

/// Decodes one fitted quad (C library coordinates) against the families: the detections,
/// corners in our convention.
fn decode_quad(
    gray: &[u8],
    w: usize,
    h: usize,
    families: &[(TagFamily, FamilyCodes)],
    q: &crate::quad::RawQuad,
    min_margin: f32,
) -> Vec<Detection> {
    let mut out = Vec::new();
    let Some(hom) = Homography::from_quad(&q.p) else {
        return out;
    };
    for (family, codes) in families {
        if codes.reversed_border() != q.reversed_border {
            continue;
        }
        let Some(dec) = decode(gray, w, h, codes, &hom, DECODE_SHARPENING) else {
            continue;
        };
        if dec.margin < min_margin {
            continue;
        }
        let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .map(|(x, y)| dec.h.project(x, y) - DVec2::splat(0.5));
        if !corners.iter().all(|c| c.is_finite()) {
            continue;
        }
        out.push(Detection {
            family: *family,
            id: dec.id as u32,
            corners_px: corners,
            hamming: dec.hamming,
            decision_margin: dec.margin,
        });
    }
    out
}

/// Adds the detections of a later pass that the earlier passes did not find.
fn merge_new(out: &mut Vec<Detection>, new: Vec<Detection>) {
    let first = out.len();
    for d in new {
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

/// A tag cut by the frame edge can still decode, with a corner on the edge and wrong by many
/// pixels; a whole tag has its quiet zone inside the frame, so its corners are at least a
/// pixel from the edge. Detections with a corner closer than that are dropped.
/// The shortest side of a quadrilateral given by its corners in order, pixels.
pub(crate) fn min_side_px(corners: &[DVec2; 4]) -> f64 {
    (0..4)
        .map(|i| corners[i].distance(corners[(i + 1) % 4]))
        .fold(f64::INFINITY, f64::min)
}

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
