//! Accessor reading with every offset, stride, count and index checked, from the JSON
//! itself: the `gltf` crate's reader panics on some inconsistent files (an index
//! accessor of floats, an accessor of count 0, a stride shorter than an element) and
//! reads sparse indices with `unreachable!`; a panic is an abort for an app built with
//! `panic = "abort"`, so no `catch_unwind` can stand in for these checks.

use super::{GltfError, MAX_ACCESSOR_ELEMENTS};
use gltf::json::{
    self,
    accessor::{ComponentType, Type},
    validation::Checked,
};

/// An accessor's layout, checked.
struct Layout {
    component: ComponentType,
    normalized: bool,
    dims: usize,
    count: usize,
}

impl Layout {
    fn component_size(&self) -> usize {
        match self.component {
            ComponentType::I8 | ComponentType::U8 => 1,
            ComponentType::I16 | ComponentType::U16 => 2,
            ComponentType::U32 | ComponentType::F32 => 4,
        }
    }

    fn element_size(&self) -> usize {
        self.component_size() * self.dims
    }

    /// Element `i`'s components (`bytes` holds at least one element).
    fn decode(&self, bytes: &[u8], out: &mut [f64; 4]) {
        let size = self.component_size();
        for (k, c) in out.iter_mut().take(self.dims).enumerate() {
            let b = &bytes[k * size..(k + 1) * size];
            *c = match (self.component, self.normalized) {
                (ComponentType::I8, false) => f64::from(b[0] as i8),
                (ComponentType::I8, true) => (f64::from(b[0] as i8) / 127.0).max(-1.0),
                (ComponentType::U8, false) => f64::from(b[0]),
                (ComponentType::U8, true) => f64::from(b[0]) / 255.0,
                (ComponentType::I16, n) => {
                    let v = f64::from(i16::from_le_bytes([b[0], b[1]]));
                    if n { (v / 32767.0).max(-1.0) } else { v }
                }
                (ComponentType::U16, n) => {
                    let v = f64::from(u16::from_le_bytes([b[0], b[1]]));
                    if n { v / 65535.0 } else { v }
                }
                (ComponentType::U32, _) => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                (ComponentType::F32, _) => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            };
        }
    }
}

/// `bytes[offset..offset + len]` of a buffer view, or an error naming what is short.
fn view_bytes<'a>(
    root: &json::Root,
    buffers: &'a [Vec<u8>],
    view: usize,
    what: &str,
) -> Result<(&'a [u8], Option<usize>), GltfError> {
    let bad = |why: String| GltfError::Buffer(format!("{what}: buffer view {view}: {why}"));
    let v = root
        .buffer_views
        .get(view)
        .ok_or_else(|| bad("does not exist".into()))?;
    let buffer = buffers
        .get(v.buffer.value())
        .ok_or_else(|| bad(format!("buffer {} does not exist", v.buffer.value())))?;
    let start = v.byte_offset.map_or(0, |o| o.0);
    let end = start.checked_add(v.byte_length.0);
    match end {
        Some(end) if end <= buffer.len() as u64 => Ok((
            &buffer[start as usize..end as usize],
            v.byte_stride.map(|s| s.0),
        )),
        _ => Err(bad(format!(
            "bytes {start} + {} pass the end of buffer {} ({} bytes)",
            v.byte_length.0,
            v.buffer.value(),
            buffer.len()
        ))),
    }
}

/// Calls `f` with each element of accessor `index` (its first `dims` components, as
/// `f64`, normalized integers mapped to [0, 1] or [−1, 1]), sparse substitutions
/// applied. `what` names the accessor in errors. `integer` asks for unsigned integer
/// scalars (indices), else three-component vectors (positions).
pub(super) fn for_each_element(
    root: &json::Root,
    buffers: &[Vec<u8>],
    index: usize,
    what: &str,
    integer: bool,
    mut f: impl FnMut(&[f64]),
) -> Result<(), GltfError> {
    let bad = |why: String| GltfError::Parse(format!("{what}: accessor {index}: {why}"));
    let accessor = root
        .accessors
        .get(index)
        .ok_or_else(|| bad("does not exist".into()))?;
    let (Checked::Valid(component), Checked::Valid(ty)) =
        (&accessor.component_type, &accessor.type_)
    else {
        return Err(bad("invalid componentType or type".into()));
    };
    let dims = match ty {
        Type::Scalar => 1,
        Type::Vec2 => 2,
        Type::Vec3 => 3,
        Type::Vec4 => 4,
        Type::Mat2 | Type::Mat3 | Type::Mat4 => {
            return Err(bad("a matrix accessor is not read".into()));
        }
    };
    let layout = Layout {
        component: component.0,
        normalized: accessor.normalized,
        dims,
        count: usize::try_from(accessor.count.0).unwrap_or(usize::MAX),
    };
    if !integer && dims != 3 {
        return Err(bad(format!(
            "positions must be VEC3, not {dims} components"
        )));
    }
    if integer
        && (dims != 1
            || layout.normalized
            || !matches!(
                layout.component,
                ComponentType::U8 | ComponentType::U16 | ComponentType::U32
            ))
    {
        return Err(bad(
            "indices must be unsigned integer scalars (5121, 5123 or 5125)".into(),
        ));
    }
    if layout.count == 0 || layout.count > MAX_ACCESSOR_ELEMENTS {
        return Err(bad(format!(
            "count {} (1 to {MAX_ACCESSOR_ELEMENTS} elements are read)",
            accessor.count.0
        )));
    }
    let size = layout.element_size();
    // The base elements: a buffer view's, or zeros.
    let base = match accessor.buffer_view {
        None => None,
        Some(view) => {
            let (bytes, stride) = view_bytes(root, buffers, view.value(), what)?;
            let stride = stride.unwrap_or(size);
            if stride < size {
                return Err(bad(format!(
                    "byteStride {stride} is shorter than an element ({size} bytes)"
                )));
            }
            let offset = accessor.byte_offset.map_or(0, |o| o.0);
            let end = (layout.count as u64 - 1)
                .checked_mul(stride as u64)
                .and_then(|e| e.checked_add(offset))
                .and_then(|e| e.checked_add(size as u64));
            match end {
                Some(end) if end <= bytes.len() as u64 => {
                    Some((&bytes[offset as usize..end as usize], stride))
                }
                _ => {
                    return Err(bad(format!(
                        "{} elements of {size} bytes every {stride} from byte {offset} pass the end of \
                         buffer view {} ({} bytes)",
                        layout.count,
                        view.value(),
                        bytes.len()
                    )));
                }
            }
        }
    };
    let sparse = match &accessor.sparse {
        None => Vec::new(),
        Some(s) => sparse_elements(root, buffers, s, &layout, what, index)?,
    };
    let mut next_sparse = sparse.iter().peekable();
    let mut element = [0.0f64; 4];
    for i in 0..layout.count {
        // Sorted by index; a repeated index: the last one wins.
        let mut substitute = None;
        while let Some(&&(j, bytes)) = next_sparse.peek() {
            if j != i {
                break;
            }
            substitute = Some(bytes);
            next_sparse.next();
        }
        match (substitute, base) {
            (Some(bytes), _) => layout.decode(bytes, &mut element),
            (None, Some((bytes, stride))) => {
                layout.decode(&bytes[i * stride..i * stride + size], &mut element);
            }
            (None, None) => element = [0.0; 4],
        }
        f(&element[..dims]);
    }
    Ok(())
}

/// A sparse accessor's substitutions: (element index, its bytes), sorted by index.
fn sparse_elements<'a>(
    root: &json::Root,
    buffers: &'a [Vec<u8>],
    sparse: &json::accessor::sparse::Sparse,
    layout: &Layout,
    what: &str,
    index: usize,
) -> Result<Vec<(usize, &'a [u8])>, GltfError> {
    let bad = |why: String| GltfError::Parse(format!("{what}: accessor {index}: sparse: {why}"));
    let count = usize::try_from(sparse.count.0).unwrap_or(usize::MAX);
    if count == 0 || count > layout.count {
        return Err(bad(format!(
            "count {} (1 to the accessor's {})",
            sparse.count.0, layout.count
        )));
    }
    let Checked::Valid(index_type) = &sparse.indices.component_type else {
        return Err(bad("invalid index componentType".into()));
    };
    let index_size = match index_type.0 {
        ComponentType::U8 => 1,
        ComponentType::U16 => 2,
        ComponentType::U32 => 4,
        _ => return Err(bad("indices must be unsigned integers".into())),
    };
    let slice = |view: usize, offset: u64, element: usize| -> Result<&'a [u8], GltfError> {
        let (bytes, _) = view_bytes(root, buffers, view, what)?;
        let end = (count as u64)
            .checked_mul(element as u64)
            .and_then(|n| n.checked_add(offset));
        match end {
            Some(end) if end <= bytes.len() as u64 => Ok(&bytes[offset as usize..end as usize]),
            _ => Err(bad(format!(
                "{count} elements of {element} bytes from byte {offset} pass the end of buffer view {view}"
            ))),
        }
    };
    let indices = slice(
        sparse.indices.buffer_view.value(),
        sparse.indices.byte_offset.0,
        index_size,
    )?;
    let size = layout.element_size();
    let values = slice(
        sparse.values.buffer_view.value(),
        sparse.values.byte_offset.0,
        size,
    )?;
    let mut out = Vec::with_capacity(count);
    for k in 0..count {
        let b = &indices[k * index_size..(k + 1) * index_size];
        let i = match index_size {
            1 => usize::from(b[0]),
            2 => usize::from(u16::from_le_bytes([b[0], b[1]])),
            _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize,
        };
        if i >= layout.count {
            return Err(bad(format!(
                "index {i} is past the accessor's {} elements",
                layout.count
            )));
        }
        out.push((i, &values[k * size..(k + 1) * size]));
    }
    out.sort_by_key(|&(i, _)| i);
    Ok(out)
}
