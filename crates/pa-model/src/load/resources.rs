//! Buffers and images: the GLB binary chunk, data URIs and files beside the model (which
//! must stay in its folder), images decoded within their budgets, and materials.

use std::borrow::Cow;
use std::io::Read as _;
use std::path::{Component, Path, PathBuf};

use base64::Engine as _;

use super::{Loader, Want};
use crate::{ErrorKind, Image, Material};

impl<'a> Loader<'a> {
    pub(super) fn load_buffers(&mut self, blob: Option<&'a [u8]>) -> Result<(), ErrorKind> {
        for buffer in self.doc.buffers() {
            let index = buffer.index();
            let declared = buffer.length();
            let truncated = |present: usize| ErrorKind::Buffer {
                index,
                message: format!(
                    "declares {declared} bytes but only {present} are present: truncated or \
                     corrupt buffer"
                ),
            };
            let data: Cow<'a, [u8]> = match buffer.source() {
                gltf::buffer::Source::Bin => {
                    let blob = blob.ok_or_else(|| ErrorKind::Buffer {
                        index,
                        message: "refers to the GLB binary chunk, which is missing".into(),
                    })?;
                    Cow::Borrowed(blob.get(..declared).ok_or_else(|| truncated(blob.len()))?)
                }
                gltf::buffer::Source::Uri(uri) => {
                    let mut data = self.read_uri(uri, Want::Prefix(declared as u64), &|m| {
                        ErrorKind::Buffer { index, message: m }
                    })?;
                    if data.len() < declared {
                        return Err(truncated(data.len()));
                    }
                    data.truncate(declared);
                    Cow::Owned(data)
                }
            };
            self.buffers.push(data);
        }
        Ok(())
    }

    /// Reads a data URI or a regular file relative to the model's folder. `wrap` turns a
    /// message naming the URI into the error for the object that refers to it.
    fn read_uri(
        &mut self,
        uri: &str,
        want: Want,
        wrap: &dyn Fn(String) -> ErrorKind,
    ) -> Result<Vec<u8>, ErrorKind> {
        let limit = self.options.limits.max_file_bytes;
        if let Some(rest) = uri.strip_prefix("data:") {
            let (header, payload) = rest
                .split_once(',')
                .ok_or_else(|| wrap(format!("data URI {:?} has no ',' separator", short(uri))))?;
            if !header.ends_with(";base64") {
                return Err(wrap(format!(
                    "data URI {:?} is not base64-encoded",
                    short(uri)
                )));
            }
            let decoded_size = payload.len() as u64 / 4 * 3;
            if decoded_size > limit {
                return Err(wrap(format!("data URI decodes to more than {limit} bytes")));
            }
            self.charge_input(decoded_size, || format!("data URI {:?}", short(uri)))?;
            return base64::engine::general_purpose::STANDARD
                .decode(payload.trim())
                .map_err(|e| {
                    wrap(format!(
                        "data URI {:?} is not valid base64: {e}",
                        short(uri)
                    ))
                });
        }
        let path = self
            .resolve_relative(uri)
            .map_err(|e| wrap(e.to_string()))?;
        let cannot = |e: pa_io::IoError| wrap(format!("cannot read {uri:?}: {e}"));
        let file = pa_io::open_regular(&path).map_err(cannot)?;
        let size = file
            .metadata()
            .map_err(|e| wrap(format!("cannot read {uri:?} ({}): {e}", path.display())))?
            .len();
        if size > limit {
            return Err(cannot(pa_io::IoError::TooLarge {
                path,
                size,
                limit,
                what: "a file a glTF model refers to",
            }));
        }
        let to_read = match want {
            Want::Prefix(n) => size.min(n),
            Want::Whole => size,
        };
        self.charge_input(to_read, || format!("file {uri:?}"))?;
        let mut bytes = Vec::with_capacity(to_read as usize);
        file.take(to_read)
            .read_to_end(&mut bytes)
            .map_err(|e| wrap(format!("cannot read {uri:?} ({}): {e}", path.display())))?;
        Ok(bytes)
    }
    /// Resolves a relative URI inside the model's folder, refusing anything that escapes it
    /// ([`ErrorKind::UriEscapes`], [`ErrorKind::UnsupportedUri`]).
    fn resolve_relative(&self, uri: &str) -> Result<PathBuf, ErrorKind> {
        let escapes = || ErrorKind::UriEscapes { uri: uri.into() };
        if uri.contains("://") || uri.starts_with("file:") {
            return Err(ErrorKind::UnsupportedUri {
                uri: uri.into(),
                reason: "only relative paths and data: URIs are read".into(),
            });
        }
        let decoded = percent_decode(uri).ok_or_else(|| ErrorKind::UnsupportedUri {
            uri: uri.into(),
            reason: "bad percent-encoding".into(),
        })?;
        if decoded.contains('\0') {
            return Err(escapes());
        }
        let normalised = decoded.replace('\\', "/");
        let rel = Path::new(&normalised);
        let looks_windows_absolute = normalised.len() >= 2 && normalised.as_bytes()[1] == b':';
        if rel.is_absolute() || looks_windows_absolute {
            return Err(escapes());
        }
        for c in rel.components() {
            match c {
                Component::Normal(_) | Component::CurDir => {}
                _ => return Err(escapes()),
            }
        }
        let base = self.base_dir.ok_or_else(|| ErrorKind::UnsupportedUri {
            uri: uri.into(),
            reason: "a model loaded from memory cannot refer to external files".into(),
        })?;
        let joined = base.join(rel);
        // Symbolic links must not lead out of the folder either.
        if let (Ok(base_c), Ok(file_c)) = (base.canonicalize(), joined.canonicalize()) {
            if !file_c.starts_with(&base_c) {
                return Err(escapes());
            }
        }
        Ok(joined)
    }

    pub(super) fn load_images(&mut self) -> Result<Vec<Image>, ErrorKind> {
        let mut images = Vec::new();
        let mut total: u64 = 0;
        for image in self.doc.images() {
            let index = image.index();
            let name = image.name().map(str::to_string);
            if self.options.skip_images {
                images.push(Image {
                    name,
                    width: 0,
                    height: 0,
                    rgba8: Vec::new(),
                });
                continue;
            }
            let image_err = |message: String| ErrorKind::Image { index, message };
            let encoded: Cow<'_, [u8]> = match image.source() {
                gltf::image::Source::View { view, .. } => {
                    let buffer = self
                        .buffers
                        .get(view.buffer().index())
                        .ok_or_else(|| image_err("buffer view names a missing buffer".into()))?;
                    let start = view.offset();
                    let end = start.saturating_add(view.length());
                    Cow::Borrowed(buffer.get(start..end).ok_or_else(|| {
                        image_err(format!(
                            "buffer view {} is outside its buffer: truncated or corrupt",
                            view.index()
                        ))
                    })?)
                }
                gltf::image::Source::Uri { uri, .. } => {
                    Cow::Owned(self.read_uri(uri, Want::Whole, &image_err)?)
                }
            };
            let lim = &self.options.limits;
            let reader = image::ImageReader::new(std::io::Cursor::new(&*encoded))
                .with_guessed_format()
                .map_err(|e| image_err(format!("cannot read: {e}")))?;
            let (w, h) = reader
                .into_dimensions()
                .map_err(|e| image_err(format!("cannot decode: {e}")))?;
            if w > lim.max_image_side || h > lim.max_image_side {
                return Err(image_err(format!(
                    "{w}x{h} is larger than the limit of {} px a side",
                    lim.max_image_side
                )));
            }
            total += w as u64 * h as u64 * 4;
            if total > lim.max_image_bytes {
                return Err(ErrorKind::TooLarge {
                    what: "decoded images".into(),
                    size: total,
                    limit: lim.max_image_bytes,
                });
            }
            let mut reader = image::ImageReader::new(std::io::Cursor::new(&*encoded))
                .with_guessed_format()
                .map_err(|e| image_err(format!("cannot read: {e}")))?;
            let mut limits = image::Limits::default();
            limits.max_image_width = Some(lim.max_image_side);
            limits.max_image_height = Some(lim.max_image_side);
            limits.max_alloc = Some(lim.max_image_bytes);
            reader.limits(limits);
            let decoded = reader
                .decode()
                .map_err(|e| image_err(format!("cannot decode: {e}")))?
                .to_rgba8();
            images.push(Image {
                name,
                width: decoded.width(),
                height: decoded.height(),
                rgba8: decoded.into_raw(),
            });
        }
        Ok(images)
    }

    pub(super) fn load_materials(&self, images: &[Image]) -> Vec<Material> {
        self.doc
            .materials()
            .map(|m| {
                let pbr = m.pbr_metallic_roughness();
                let base_color_image = pbr
                    .base_color_texture()
                    .map(|info| info.texture().source().index())
                    .filter(|&i| i < images.len());
                Material {
                    name: m.name().map(str::to_string),
                    base_color_factor: pbr.base_color_factor(),
                    base_color_image,
                    double_sided: m.double_sided(),
                }
            })
            .collect()
    }
}

fn short(s: &str) -> String {
    if s.len() > 48 {
        let cut = s.char_indices().nth(48).map(|(i, _)| i).unwrap_or(s.len());
        format!("{}...", &s[..cut])
    } else {
        s.to_string()
    }
}

fn percent_decode(s: &str) -> Option<String> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = s.get(i + 1..i + 3)?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}
