//! Reading boxes: a bounds-checked big-endian cursor and the child-box iterator.

use super::{FourCc, Mp4Error};

/// Bounds-checked big-endian reader over a byte slice.
pub(crate) struct Cur<'a> {
    data: &'a [u8],
    pos: usize,
    what: &'static str,
}

impl<'a> Cur<'a> {
    pub(crate) fn new(data: &'a [u8], what: &'static str) -> Self {
        Cur { data, pos: 0, what }
    }
    fn take(&mut self, n: usize) -> Result<&'a [u8], Mp4Error> {
        if self.data.len() - self.pos < n {
            return Err(Mp4Error::Truncated {
                what: self.what,
                len: self.data.len(),
                need: n,
                at: self.pos,
            });
        }
        let s = &self.data[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    pub(crate) fn skip(&mut self, n: usize) -> Result<(), Mp4Error> {
        self.take(n).map(|_| ())
    }
    pub(crate) fn u8(&mut self) -> Result<u8, Mp4Error> {
        Ok(self.take(1)?[0])
    }
    pub(crate) fn u16(&mut self) -> Result<u16, Mp4Error> {
        let b = self.take(2)?;
        Ok(u16::from_be_bytes([b[0], b[1]]))
    }
    pub(crate) fn u32(&mut self) -> Result<u32, Mp4Error> {
        let b = self.take(4)?;
        Ok(u32::from_be_bytes([b[0], b[1], b[2], b[3]]))
    }
    pub(crate) fn u64(&mut self) -> Result<u64, Mp4Error> {
        let b = self.take(8)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(u64::from_be_bytes(a))
    }
    pub(super) fn fourcc(&mut self) -> Result<FourCc, Mp4Error> {
        let b = self.take(4)?;
        Ok([b[0], b[1], b[2], b[3]])
    }
    pub(super) fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }
    pub(super) fn rest(&mut self) -> &'a [u8] {
        let s = &self.data[self.pos..];
        self.pos = self.data.len();
        s
    }
    /// Reads a table of `count` entries of `entry_bytes` each, refusing counts that do not fit
    /// in the box (so nothing is allocated for entries that are not there).
    pub(super) fn table(&mut self, count: u32, entry_bytes: usize) -> Result<&'a [u8], Mp4Error> {
        let need = (count as usize).checked_mul(entry_bytes);
        match need {
            Some(n) if n <= self.remaining() => self.take(n),
            _ => Err(Mp4Error::TableOverrun {
                what: self.what,
                count,
                remaining: self.remaining(),
            }),
        }
    }
}

/// Iterates over the child boxes packed in `data` as `(type, payload)`.
///
/// With `lenient`, trailing bytes too short for a box header and a zero-size terminator end
/// the list quietly (QuickTime sample entries have them); otherwise they are errors.
pub(crate) fn child_boxes(
    data: &[u8],
    lenient: bool,
) -> impl Iterator<Item = Result<(FourCc, &[u8]), Mp4Error>> {
    let mut pos = 0usize;
    let mut done = false;
    std::iter::from_fn(move || {
        if done || pos >= data.len() {
            return None;
        }
        let rest = &data[pos..];
        if rest.len() < 8 {
            done = true;
            return if lenient || rest.iter().all(|&b| b == 0) {
                None
            } else {
                Some(Err(Mp4Error::StrayBytes { count: rest.len() }))
            };
        }
        let size32 = u32::from_be_bytes([rest[0], rest[1], rest[2], rest[3]]) as u64;
        let kind: FourCc = [rest[4], rest[5], rest[6], rest[7]];
        let (size, header) = match size32 {
            0 if lenient => {
                done = true;
                return None;
            }
            0 => (rest.len() as u64, 8u64),
            1 => {
                if rest.len() < 16 {
                    done = true;
                    return Some(Err(Mp4Error::HeaderTruncated { kind }));
                }
                let mut a = [0u8; 8];
                a.copy_from_slice(&rest[8..16]);
                (u64::from_be_bytes(a), 16u64)
            }
            s => (s, 8u64),
        };
        if size < header || size > rest.len() as u64 {
            done = true;
            return Some(Err(Mp4Error::BoxOverrun {
                kind,
                size,
                remaining: rest.len(),
            }));
        }
        let payload = &rest[header as usize..size as usize];
        pos += size as usize;
        Some(Ok((kind, payload)))
    })
}

pub(super) fn find_child<'a>(data: &'a [u8], kind: &FourCc) -> Result<Option<&'a [u8]>, Mp4Error> {
    for b in child_boxes(data, false) {
        let (k, payload) = b?;
        if &k == kind {
            return Ok(Some(payload));
        }
    }
    Ok(None)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn child_boxes_reject_overruns() {
        let data = [0, 0, 0, 16, b'f', b'r', b'e', b'e', 0, 0, 0, 0];
        let r: Vec<_> = child_boxes(&data, false).collect();
        assert!(r[0]
            .as_ref()
            .is_err_and(|e| e.to_string().contains("claims 16 bytes")));
        let data = [0, 0, 0, 4, b'f', b'r', b'e', b'e'];
        assert!(child_boxes(&data, false).next().is_some_and(|r| r.is_err()));
        let data = [0, 0, 0, 8, b'f', b'r', b'e', b'e', 0, 0, 0, 0];
        let r: Vec<_> = child_boxes(&data, true).collect();
        assert_eq!(r.len(), 1);
    }
}
