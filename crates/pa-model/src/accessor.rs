//! Bounds-checked reading of glTF accessors (strided views, normalised integers, matrix column
//! padding, sparse substitution). Every byte range is checked against its buffer view and
//! buffer before it is read, so a hostile file cannot make us read out of range or allocate
//! more than its own data (plus a fixed cap for view-less accessors). Values are decoded
//! straight into the output type (`f32` or `u32`), with no wider intermediate; the loader
//! checks the decoded sizes against its budgets before it reads anything (see the crate
//! documentation).

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

/// Checked slice of a buffer view.
fn view_bytes<'b, B: AsRef<[u8]>>(
    acc_index: usize,
    view: &gltf::buffer::View<'_>,
    buffers: &'b [B],
) -> Result<&'b [u8], ErrorKind> {
    let buffer = buffers
        .get(view.buffer().index())
        .map(AsRef::as_ref)
        .ok_or_else(|| {
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

/// The layout of the elements to read from a byte slice.
#[derive(Clone, Copy)]
struct Layout {
    offset: usize,
    stride: usize,
    /// Elements the accessor declares (all must lie inside the view).
    count: usize,
    d: Dimensions,
    t: DataType,
    normalized: bool,
}

/// Checks that all `layout.count` elements lie inside `bytes`, then appends the components of
/// the first `take` of them, converted by `conv`.
fn read_elements<T>(
    acc_index: usize,
    bytes: &[u8],
    layout: Layout,
    take: usize,
    conv: &impl Fn(f64) -> T,
    out: &mut Vec<T>,
) -> Result<(), ErrorKind> {
    let Layout {
        offset,
        stride,
        count,
        d,
        t,
        normalized,
    } = layout;
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
    let take = take.min(count);
    // `take * stride <= last <= bytes.len()`, so this cannot overflow.
    out.reserve(take * rows * cols);
    for i in 0..take {
        let base = offset + i * stride;
        for c in 0..cols {
            for r in 0..rows {
                let at = base + c * col_stride + r * cs;
                out.push(conv(read_component(&bytes[at..at + cs], t, normalized)));
            }
        }
    }
    Ok(())
}

/// Reads the first `max_elements` elements of an accessor (all of them when it has fewer) as
/// a flat list of components converted by `conv`, applying normalisation and sparse
/// substitution. Every element the accessor declares is still range-checked.
fn read_as<T: Copy + Default, B: AsRef<[u8]>>(
    accessor: &gltf::Accessor<'_>,
    buffers: &[B],
    max_elements: usize,
    conv: impl Fn(f64) -> T,
) -> Result<Vec<T>, ErrorKind> {
    let index = accessor.index();
    let d = accessor.dimensions();
    let t = accessor.data_type();
    let n = component_count(d);
    let count = accessor.count();
    let take = count.min(max_elements);
    let normalized = accessor.normalized();
    let (elem_size, _) = element_layout(d, t);

    let mut out: Vec<T> = Vec::new();
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
            let layout = Layout {
                offset: accessor.offset(),
                stride,
                count,
                d,
                t,
                normalized,
            };
            read_elements(index, bytes, layout, take, &conv, &mut out)?;
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
            out = vec![T::default(); take * n];
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
        let mut idx: Vec<u64> = Vec::new();
        let ilayout = Layout {
            offset: iv.offset(),
            stride: component_size(it),
            count: sc,
            d: Dimensions::Scalar,
            t: it,
            normalized: false,
        };
        read_elements(index, ibytes, ilayout, sc, &|v| v as u64, &mut idx)?;
        let vv = sparse.values();
        let vbytes = view_bytes(index, &vv.view(), buffers)?;
        let mut vals = Vec::new();
        let vlayout = Layout {
            offset: vv.offset(),
            stride: elem_size,
            count: sc,
            d,
            t,
            normalized,
        };
        read_elements(index, vbytes, vlayout, sc, &conv, &mut vals)?;
        for (k, &i) in idx.iter().enumerate() {
            let Ok(i) = usize::try_from(i) else {
                return Err(err(index, format!("sparse index {i} is too large")));
            };
            if i >= count {
                return Err(err(
                    index,
                    format!("sparse index {i} is past the accessor count {count}"),
                ));
            }
            if i < take {
                out[i * n..(i + 1) * n].copy_from_slice(&vals[k * n..(k + 1) * n]);
            }
        }
    }
    Ok(out)
}

/// Reads an accessor as a flat list of f64 components (count x components), applying
/// normalisation and sparse substitution.
pub fn read_f64<B: AsRef<[u8]>>(
    accessor: &gltf::Accessor<'_>,
    buffers: &[B],
) -> Result<Vec<f64>, ErrorKind> {
    read_as(accessor, buffers, usize::MAX, |v| v)
}

/// Reads an accessor as a flat list of f32 components (count x components), applying
/// normalisation and sparse substitution.
pub fn read_f32<B: AsRef<[u8]>>(
    accessor: &gltf::Accessor<'_>,
    buffers: &[B],
) -> Result<Vec<f32>, ErrorKind> {
    read_as(accessor, buffers, usize::MAX, |v| v as f32)
}

/// [`read_f32`] of at most the first `max_elements` elements (the rest are range-checked but
/// not decoded).
pub fn read_f32_prefix<B: AsRef<[u8]>>(
    accessor: &gltf::Accessor<'_>,
    buffers: &[B],
    max_elements: usize,
) -> Result<Vec<f32>, ErrorKind> {
    read_as(accessor, buffers, max_elements, |v| v as f32)
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
pub fn read_vec3<B: AsRef<[u8]>>(
    accessor: &gltf::Accessor<'_>,
    buffers: &[B],
    what: &str,
) -> Result<Vec<glam::Vec3>, ErrorKind> {
    expect_dims(accessor, &[Dimensions::Vec3], what)?;
    let v = read_f32(accessor, buffers)?;
    let out: Vec<glam::Vec3> = v.chunks_exact(3).map(glam::Vec3::from_slice).collect();
    if let Some(bad) = out.iter().position(|p| !p.is_finite()) {
        return Err(err(
            accessor.index(),
            format!("{what} element {bad} is not finite"),
        ));
    }
    Ok(out)
}

/// Reads a scalar accessor of unsigned integers (indices, joint indices) as u32.
pub fn read_u32<B: AsRef<[u8]>>(
    accessor: &gltf::Accessor<'_>,
    buffers: &[B],
) -> Result<Vec<u32>, ErrorKind> {
    match accessor.data_type() {
        DataType::U8 | DataType::U16 | DataType::U32 => {}
        other => {
            return Err(err(
                accessor.index(),
                format!("integer data expected, found {other:?}"),
            ))
        }
    }
    read_as(accessor, buffers, usize::MAX, |v| v as u32)
}
