//! Bounds-checked reading of glTF accessors (strided views, normalised integers, matrix column
//! padding, sparse substitution). Every byte range is checked against its buffer view and
//! buffer before it is read, so a hostile file cannot make us read out of range or allocate
//! more than its own data (plus a fixed cap for view-less accessors).

use gltf::accessor::{DataType, Dimensions};

use crate::ErrorKind;

/// The most elements an accessor without a buffer view (all zeros plus sparse values) may have.
pub const MAX_VIEWLESS_ELEMENTS: usize = 1 << 24;

fn err(index: usize, message: impl Into<String>) -> ErrorKind {
    ErrorKind::Accessor {
        index,
        message: message.into(),
    }
}

/// Number of components of an element type.
pub fn component_count(d: Dimensions) -> usize {
    match d {
        Dimensions::Scalar => 1,
        Dimensions::Vec2 => 2,
        Dimensions::Vec3 => 3,
        Dimensions::Vec4 => 4,
        Dimensions::Mat2 => 4,
        Dimensions::Mat3 => 9,
        Dimensions::Mat4 => 16,
    }
}

fn component_size(t: DataType) -> usize {
    match t {
        DataType::I8 | DataType::U8 => 1,
        DataType::I16 | DataType::U16 => 2,
        DataType::U32 | DataType::F32 => 4,
    }
}

/// Rows and columns of an element (vectors are one column).
fn shape(d: Dimensions) -> (usize, usize) {
    match d {
        Dimensions::Mat2 => (2, 2),
        Dimensions::Mat3 => (3, 3),
        Dimensions::Mat4 => (4, 4),
        other => (component_count(other), 1),
    }
}

/// Byte size of one element, with the spec's 4-byte column alignment for matrices.
fn element_layout(d: Dimensions, t: DataType) -> (usize, usize) {
    let (rows, cols) = shape(d);
    let cs = component_size(t);
    if cols == 1 {
        (rows * cs, rows * cs)
    } else {
        let col_stride = (rows * cs).div_ceil(4) * 4;
        (col_stride * cols, col_stride)
    }
}

fn read_component(bytes: &[u8], t: DataType, normalized: bool) -> f64 {
    // `bytes` has exactly component_size(t) bytes (checked by the caller).
    let mut b4 = [0u8; 4];
    b4[..bytes.len()].copy_from_slice(bytes);
    match t {
        DataType::I8 => {
            let v = b4[0] as i8 as f64;
            if normalized {
                (v / 127.0).max(-1.0)
            } else {
                v
            }
        }
        DataType::U8 => {
            let v = b4[0] as f64;
            if normalized {
                v / 255.0
            } else {
                v
            }
        }
        DataType::I16 => {
            let v = i16::from_le_bytes([b4[0], b4[1]]) as f64;
            if normalized {
                (v / 32767.0).max(-1.0)
            } else {
                v
            }
        }
        DataType::U16 => {
            let v = u16::from_le_bytes([b4[0], b4[1]]) as f64;
            if normalized {
                v / 65535.0
            } else {
                v
            }
        }
        DataType::U32 => u32::from_le_bytes(b4) as f64,
        DataType::F32 => f32::from_le_bytes(b4) as f64,
    }
}

/// Checked slice of a buffer view: returns (bytes of the view, stride).
fn view_bytes<'b>(
    acc_index: usize,
    view: &gltf::buffer::View<'_>,
    buffers: &'b [Vec<u8>],
) -> Result<&'b [u8], ErrorKind> {
    let buffer = buffers.get(view.buffer().index()).ok_or_else(|| {
        err(
            acc_index,
            format!("buffer view {} names a missing buffer", view.index()),
        )
    })?;
    let start = view.offset();
    let end = start.checked_add(view.length()).ok_or_else(|| {
        err(
            acc_index,
            format!("buffer view {} range overflows", view.index()),
        )
    })?;
    buffer.get(start..end).ok_or_else(|| {
        err(
            acc_index,
            format!(
                "buffer view {} (bytes {start}..{end}) is outside buffer {} ({} bytes): \
                 truncated or corrupt buffer",
                view.index(),
                view.buffer().index(),
                buffer.len()
            ),
        )
    })
}

/// Reads `count` elements from `bytes` at `offset` with `stride`, appending components.
#[allow(clippy::too_many_arguments)]
fn read_elements(
    acc_index: usize,
    bytes: &[u8],
    offset: usize,
    stride: usize,
    count: usize,
    d: Dimensions,
    t: DataType,
    normalized: bool,
    out: &mut Vec<f64>,
) -> Result<(), ErrorKind> {
    let (elem_size, col_stride) = element_layout(d, t);
    let (rows, cols) = shape(d);
    let cs = component_size(t);
    if count == 0 {
        return Ok(());
    }
    let last = (count - 1)
        .checked_mul(stride)
        .and_then(|x| x.checked_add(offset))
        .and_then(|x| x.checked_add(elem_size))
        .ok_or_else(|| err(acc_index, "byte range overflows"))?;
    if last > bytes.len() {
        return Err(err(
            acc_index,
            format!(
                "{count} elements of {elem_size} bytes (stride {stride}, offset {offset}) need \
                 {last} bytes but the buffer view has {}: accessor out of range",
                bytes.len()
            ),
        ));
    }
    out.reserve(count * rows * cols);
    for i in 0..count {
        let base = offset + i * stride;
        for c in 0..cols {
            for r in 0..rows {
                let at = base + c * col_stride + r * cs;
                out.push(read_component(&bytes[at..at + cs], t, normalized));
            }
        }
    }
    Ok(())
}

/// Reads an accessor as a flat list of f64 components (count x components), applying
/// normalisation and sparse substitution.
pub fn read_f64(accessor: &gltf::Accessor<'_>, buffers: &[Vec<u8>]) -> Result<Vec<f64>, ErrorKind> {
    let index = accessor.index();
    let d = accessor.dimensions();
    let t = accessor.data_type();
    let n = component_count(d);
    let count = accessor.count();
    let normalized = accessor.normalized();
    let (elem_size, _) = element_layout(d, t);

    let mut out: Vec<f64> = Vec::new();
    match accessor.view() {
        Some(view) => {
            let bytes = view_bytes(index, &view, buffers)?;
            let stride = view.stride().unwrap_or(elem_size);
            if stride < elem_size {
                return Err(err(
                    index,
                    format!("byte stride {stride} is smaller than the element size {elem_size}"),
                ));
            }
            read_elements(
                index,
                bytes,
                accessor.offset(),
                stride,
                count,
                d,
                t,
                normalized,
                &mut out,
            )?;
        }
        None => {
            if count > MAX_VIEWLESS_ELEMENTS {
                return Err(err(
                    index,
                    format!(
                        "count {count} without a buffer view is absurd (limit \
                         {MAX_VIEWLESS_ELEMENTS})"
                    ),
                ));
            }
            out = vec![0.0; count * n];
        }
    }

    if let Some(sparse) = accessor.sparse() {
        let sc = sparse.count();
        if sc > count {
            return Err(err(
                index,
                format!("sparse count {sc} exceeds accessor count {count}"),
            ));
        }
        let iv = sparse.indices();
        let it = match iv.index_type() {
            gltf::accessor::sparse::IndexType::U8 => DataType::U8,
            gltf::accessor::sparse::IndexType::U16 => DataType::U16,
            gltf::accessor::sparse::IndexType::U32 => DataType::U32,
        };
        let ibytes = view_bytes(index, &iv.view(), buffers)?;
        let mut idx = Vec::new();
        let isz = component_size(it);
        read_elements(
            index,
            ibytes,
            iv.offset(),
            isz,
            sc,
            Dimensions::Scalar,
            it,
            false,
            &mut idx,
        )?;
        let vv = sparse.values();
        let vbytes = view_bytes(index, &vv.view(), buffers)?;
        let mut vals = Vec::new();
        read_elements(
            index,
            vbytes,
            vv.offset(),
            elem_size,
            sc,
            d,
            t,
            normalized,
            &mut vals,
        )?;
        for (k, &i) in idx.iter().enumerate() {
            let i = i as usize;
            if i >= count {
                return Err(err(
                    index,
                    format!("sparse index {i} is past the accessor count {count}"),
                ));
            }
            out[i * n..(i + 1) * n].copy_from_slice(&vals[k * n..(k + 1) * n]);
        }
    }
    Ok(out)
}

/// Checks an accessor's element type.
pub fn expect_dims(
    accessor: &gltf::Accessor<'_>,
    allowed: &[Dimensions],
    what: &str,
) -> Result<(), ErrorKind> {
    if allowed.contains(&accessor.dimensions()) {
        Ok(())
    } else {
        Err(err(
            accessor.index(),
            format!(
                "{what} must be {:?}, found {:?}",
                allowed,
                accessor.dimensions()
            ),
        ))
    }
}

/// Reads a VEC3 float accessor.
pub fn read_vec3(
    accessor: &gltf::Accessor<'_>,
    buffers: &[Vec<u8>],
    what: &str,
) -> Result<Vec<glam::Vec3>, ErrorKind> {
    expect_dims(accessor, &[Dimensions::Vec3], what)?;
    let v = read_f64(accessor, buffers)?;
    let out: Vec<glam::Vec3> = v
        .chunks_exact(3)
        .map(|c| glam::Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32))
        .collect();
    if let Some(bad) = out.iter().position(|p| !p.is_finite()) {
        return Err(err(
            accessor.index(),
            format!("{what} element {bad} is not finite"),
        ));
    }
    Ok(out)
}

/// Reads a scalar accessor of unsigned integers (indices, joint indices) as u32.
pub fn read_u32(accessor: &gltf::Accessor<'_>, buffers: &[Vec<u8>]) -> Result<Vec<u32>, ErrorKind> {
    match accessor.data_type() {
        DataType::U8 | DataType::U16 | DataType::U32 => {}
        other => {
            return Err(err(
                accessor.index(),
                format!("integer data expected, found {other:?}"),
            ))
        }
    }
    Ok(read_f64(accessor, buffers)?
        .into_iter()
        .map(|v| v as u32)
        .collect())
}
