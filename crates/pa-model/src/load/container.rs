//! The GLB container: its JSON and binary chunks, every length checked.

use crate::ErrorKind;

const GLB_JSON: u32 = 0x4E4F_534A;
const GLB_BIN: u32 = 0x004E_4942;

fn le_u32(bytes: &[u8], at: usize) -> Option<u32> {
    let b = bytes.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// Splits a GLB container into its JSON and binary chunks (a `.gltf` is all JSON). Every
/// length is checked against the bytes present; chunks of unknown types are skipped, as the
/// spec asks. Errors are [`ErrorKind::Parse`].
pub(super) fn split_container(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>), ErrorKind> {
    if !bytes.starts_with(b"glTF") {
        return Ok((bytes, None));
    }
    let header = |at| {
        le_u32(bytes, at)
            .ok_or_else(|| ErrorKind::Parse("GLB header is truncated (12 bytes needed)".into()))
    };
    let version = header(4)?;
    if version != 2 {
        return Err(ErrorKind::Parse(format!("GLB version {version} is not 2")));
    }
    let length = header(8)? as usize;
    if length < 12 || length > bytes.len() {
        return Err(ErrorKind::Parse(format!(
            "GLB header declares {length} bytes but the file has {} (at least 12 needed)",
            bytes.len()
        )));
    }
    let body = &bytes[12..length];
    let mut at = 0usize;
    let mut json = None;
    let mut bin = None;
    let mut chunk = 0usize;
    while body.len() - at >= 8 {
        let (Some(len), Some(ty)) = (le_u32(body, at), le_u32(body, at + 4)) else {
            break;
        };
        let len = len as usize;
        let start = at + 8;
        let Some(data) = start.checked_add(len).and_then(|end| body.get(start..end)) else {
            return Err(ErrorKind::Parse(format!(
                "GLB chunk {chunk} declares {len} bytes but only {} remain: truncated or \
                 corrupt file",
                body.len() - start
            )));
        };
        match (chunk, ty) {
            (0, GLB_JSON) => json = Some(data),
            (0, _) => {
                return Err(ErrorKind::Parse(format!(
                    "GLB chunk 0 has type {ty:#010x}, not JSON"
                )))
            }
            (_, GLB_BIN) if bin.is_none() => bin = Some(data),
            _ => {}
        }
        at = start + len;
        chunk += 1;
    }
    let json = json.ok_or_else(|| ErrorKind::Parse("GLB file has no JSON chunk".into()))?;
    Ok((json, bin))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glb_container_lengths_are_checked() {
        assert!(split_container(b"glTF").is_err());
        let mut glb = b"glTF".to_vec();
        glb.extend(2u32.to_le_bytes());
        glb.extend(20u32.to_le_bytes());
        glb.extend(0u32.to_le_bytes()); // empty JSON chunk
        glb.extend(GLB_JSON.to_le_bytes());
        let (json, bin) = split_container(&glb).expect("valid container");
        assert!(json.is_empty() && bin.is_none());
        // A chunk length that wraps around past the end.
        glb[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        let e = split_container(&glb).expect_err("chunk past the end");
        assert!(e.to_string().contains("chunk 0"), "{e}");
        // Version and header length.
        glb[4..8].copy_from_slice(&1u32.to_le_bytes());
        assert!(split_container(&glb)
            .expect_err("v1")
            .to_string()
            .contains("version 1"));
    }
}
