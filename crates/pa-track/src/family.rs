//! The AprilTag families: layouts and code tables, and the quick code lookup.
//!
//! The tables are those of the AprilTag library (AprilRobotics/apriltag, BSD 2-clause), as
//! kornia-apriltag 0.2 (Apache-2.0) ships them; see `data/tags/LICENSE`. Each family's codes
//! are a data file under `data/tags/`, compiled in with `include_bytes!`: a sequence of
//! unsigned LEB128 varints, the first the first code, each next one the number of
//! [`CODE_STEP`] strides from the previous code (mod `2^nbits`). The AprilTag generator
//! walks the code space in strides of that prime, so the tables shrink about fourfold
//! (325 KB for all nine families instead of 1.3 MB of u64). `family/tests.rs` pins each
//! table's count and hash.
//!
//! [`QuickDecode`] is kornia-apriltag's lookup (same tables, same search order, so the same
//! answers): the code is split into four chunks; a code within Hamming distance 3 of a valid
//! one matches it exactly in at least one chunk, so only the valid codes sharing a chunk
//! value are compared, chunk 0 first, each chunk's candidates in id order, and the first
//! within `max_hamming` wins.

use crate::TagFamily;

/// The stride of the AprilTag code generator (a prime), which the data files count in.
pub(crate) const CODE_STEP: u64 = 982_451_653;

/// The detector's default Hamming radius, which kornia-apriltag's tables were built with;
/// a different radius must not exceed the family's [`FamilyDef::max_safe_hamming`].
pub(crate) const DEFAULT_MAX_HAMMING: u8 = 2;

/// A tag family's layout and its code table.
#[derive(Debug)]
pub(crate) struct FamilyDef {
    /// Bits in a code.
    pub nbits: usize,
    /// Cells across the border square (the detected quad), including the border.
    pub width_at_border: usize,
    /// Cells across the whole tag image.
    pub total_width: usize,
    /// Whether the border is white inside black (the circle, custom and standard families).
    pub reversed_border: bool,
    /// The minimum Hamming distance between two codes of the family.
    pub min_hamming: u8,
    /// Cell of each bit, most significant first, relative to the border square's corner.
    pub bit_x: &'static [i8],
    pub bit_y: &'static [i8],
    /// Number of codes (ids).
    pub count: usize,
    /// The encoded code table (see the module docs).
    data: &'static [u8],
}

impl FamilyDef {
    /// The largest Hamming radius that cannot confuse two codes: `(min_hamming - 1) / 2`.
    pub fn max_safe_hamming(&self) -> u8 {
        self.min_hamming.saturating_sub(1) / 2
    }

    /// The valid codes, in id order.
    pub fn codes(&self) -> Vec<usize> {
        decode_codes(self.data, self.nbits)
    }
}

/// Decodes a code table file (see the module docs).
fn decode_codes(data: &[u8], nbits: usize) -> Vec<usize> {
    let mask = if nbits >= 64 {
        u64::MAX
    } else {
        (1u64 << nbits) - 1
    };
    let mut out = Vec::new();
    let (mut acc, mut shift) = (0u64, 0u32);
    let mut prev: Option<u64> = None;
    for &b in data {
        acc |= u64::from(b & 0x7f).checked_shl(shift).unwrap_or(0);
        if b & 0x80 != 0 {
            shift += 7;
            continue;
        }
        let code = match prev {
            None => acc,
            Some(p) => p.wrapping_add(acc.wrapping_mul(CODE_STEP)),
        } & mask;
        out.push(code as usize);
        prev = Some(code);
        (acc, shift) = (0, 0);
    }
    out
}

macro_rules! tags_file {
    ($name:literal) => {
        include_bytes!(concat!("../data/tags/", $name, ".bin"))
    };
}

/// The bit layout of the 36-bit families.
const BITS36_X: &[i8] = &[
    1, 2, 3, 4, 5, 2, 3, 4, 3, 6, 6, 6, 6, 6, 5, 5, 5, 4, 6, 5, 4, 3, 2, 5, 4, 3, 4, 1, 1, 1, 1, 1,
    2, 2, 2, 3,
];
const BITS36_Y: &[i8] = &[
    1, 1, 1, 1, 1, 2, 2, 2, 3, 1, 2, 3, 4, 5, 2, 3, 4, 3, 6, 6, 6, 6, 6, 5, 5, 5, 4, 6, 5, 4, 3, 2,
    5, 4, 3, 4,
];

static TAG36H11: FamilyDef = FamilyDef {
    nbits: 36,
    width_at_border: 8,
    total_width: 10,
    reversed_border: false,
    min_hamming: 11,
    bit_x: BITS36_X,
    bit_y: BITS36_Y,
    count: 587,
    data: tags_file!("tag36h11"),
};

static TAG36H10: FamilyDef = FamilyDef {
    nbits: 36,
    width_at_border: 8,
    total_width: 10,
    reversed_border: false,
    min_hamming: 10,
    bit_x: BITS36_X,
    bit_y: BITS36_Y,
    count: 2320,
    data: tags_file!("tag36h10"),
};

static TAG25H9: FamilyDef = FamilyDef {
    nbits: 25,
    width_at_border: 7,
    total_width: 9,
    reversed_border: false,
    min_hamming: 9,
    bit_x: &[
        1, 2, 3, 4, 2, 3, 5, 5, 5, 5, 4, 4, 5, 4, 3, 2, 4, 3, 1, 1, 1, 1, 2, 2, 3,
    ],
    bit_y: &[
        1, 1, 1, 1, 2, 2, 1, 2, 3, 4, 2, 3, 5, 5, 5, 5, 4, 4, 5, 4, 3, 2, 4, 3, 3,
    ],
    count: 35,
    data: tags_file!("tag25h9"),
};

static TAG16H5: FamilyDef = FamilyDef {
    nbits: 16,
    width_at_border: 6,
    total_width: 8,
    reversed_border: false,
    min_hamming: 5,
    bit_x: &[1, 2, 3, 2, 4, 4, 4, 3, 4, 3, 2, 3, 1, 1, 1, 2],
    bit_y: &[1, 1, 1, 2, 1, 2, 3, 2, 4, 4, 4, 3, 4, 3, 2, 3],
    count: 30,
    data: tags_file!("tag16h5"),
};

static TAGCIRCLE21H7: FamilyDef = FamilyDef {
    nbits: 21,
    width_at_border: 5,
    total_width: 9,
    reversed_border: true,
    min_hamming: 7,
    bit_x: &[
        1, 2, 3, 1, 2, 6, 6, 6, 3, 3, 3, 2, 1, 3, 2, -2, -2, -2, 1, 1, 2,
    ],
    bit_y: &[
        -2, -2, -2, 1, 1, 1, 2, 3, 1, 2, 6, 6, 6, 3, 3, 3, 2, 1, 3, 2, 2,
    ],
    count: 38,
    data: tags_file!("tagcircle21h7"),
};

// kornia-apriltag 0.2's `bit_x` here has 50 entries for 49 bits (one `-2` too many before
// the last three); only the first `nbits` are read, and the table is kept as shipped.
static TAGCIRCLE49H12: FamilyDef = FamilyDef {
    nbits: 49,
    width_at_border: 5,
    total_width: 11,
    reversed_border: true,
    min_hamming: 12,
    bit_x: &[
        1, 2, 3, -1, 0, 1, 2, 3, 4, 5, 1, 2, 7, 7, 7, 6, 6, 6, 6, 6, 6, 6, 3, 3, 3, 2, 1, 5, 4, 3,
        2, 1, 0, -1, 3, 2, -3, -3, -3, -2, -2, -2, -2, -2, -2, -2, -2, 1, 1, 2,
    ],
    bit_y: &[
        -3, -3, -3, -2, -2, -2, -2, -2, -2, -2, 1, 1, 1, 2, 3, -1, 0, 1, 2, 3, 4, 5, 1, 2, 7, 7, 7,
        6, 6, 6, 6, 6, 6, 6, 3, 3, 3, 2, 1, 5, 4, 3, 2, 1, 0, -1, 3, 2, 2,
    ],
    count: 65535,
    data: tags_file!("tagcircle49h12"),
};

static TAGCUSTOM48H12: FamilyDef = FamilyDef {
    nbits: 48,
    width_at_border: 6,
    total_width: 10,
    reversed_border: true,
    min_hamming: 12,
    bit_x: &[
        -2, -1, 0, 1, 2, 3, 4, 5, 6, 1, 2, 3, 7, 7, 7, 7, 7, 7, 7, 7, 7, 4, 4, 4, 7, 6, 5, 4, 3, 2,
        1, 0, -1, 4, 3, 2, -2, -2, -2, -2, -2, -2, -2, -2, -2, 1, 1, 1,
    ],
    bit_y: &[
        -2, -2, -2, -2, -2, -2, -2, -2, -2, 1, 1, 1, -2, -1, 0, 1, 2, 3, 4, 5, 6, 1, 2, 3, 7, 7, 7,
        7, 7, 7, 7, 7, 7, 4, 4, 4, 7, 6, 5, 4, 3, 2, 1, 0, -1, 4, 3, 2,
    ],
    count: 42211,
    data: tags_file!("tagcustom48h12"),
};

static TAGSTANDARD41H12: FamilyDef = FamilyDef {
    nbits: 41,
    width_at_border: 5,
    total_width: 9,
    reversed_border: true,
    min_hamming: 12,
    bit_x: &[
        -2, -1, 0, 1, 2, 3, 4, 5, 1, 2, 6, 6, 6, 6, 6, 6, 6, 6, 3, 3, 6, 5, 4, 3, 2, 1, 0, -1, 3,
        2, -2, -2, -2, -2, -2, -2, -2, -2, 1, 1, 2,
    ],
    bit_y: &[
        -2, -2, -2, -2, -2, -2, -2, -2, 1, 1, -2, -1, 0, 1, 2, 3, 4, 5, 1, 2, 6, 6, 6, 6, 6, 6, 6,
        6, 3, 3, 6, 5, 4, 3, 2, 1, 0, -1, 3, 2, 2,
    ],
    count: 2115,
    data: tags_file!("tagstandard41h12"),
};

static TAGSTANDARD52H13: FamilyDef = FamilyDef {
    nbits: 52,
    width_at_border: 6,
    total_width: 10,
    reversed_border: true,
    min_hamming: 13,
    bit_x: &[
        -2, -1, 0, 1, 2, 3, 4, 5, 6, 1, 2, 3, 2, 7, 7, 7, 7, 7, 7, 7, 7, 7, 4, 4, 4, 3, 7, 6, 5, 4,
        3, 2, 1, 0, -1, 4, 3, 2, 3, -2, -2, -2, -2, -2, -2, -2, -2, -2, 1, 1, 1, 2,
    ],
    bit_y: &[
        -2, -2, -2, -2, -2, -2, -2, -2, -2, 1, 1, 1, 2, -2, -1, 0, 1, 2, 3, 4, 5, 6, 1, 2, 3, 2, 7,
        7, 7, 7, 7, 7, 7, 7, 7, 4, 4, 4, 3, 7, 6, 5, 4, 3, 2, 1, 0, -1, 4, 3, 2, 3,
    ],
    count: 48714,
    data: tags_file!("tagstandard52h13"),
};

impl TagFamily {
    /// The family's layout and code table.
    pub(crate) fn def(self) -> &'static FamilyDef {
        match self {
            TagFamily::Tag36h11 => &TAG36H11,
            TagFamily::Tag36h10 => &TAG36H10,
            TagFamily::Tag25h9 => &TAG25H9,
            TagFamily::Tag16h5 => &TAG16H5,
            TagFamily::TagCircle21h7 => &TAGCIRCLE21H7,
            TagFamily::TagCircle49h12 => &TAGCIRCLE49H12,
            TagFamily::TagCustom48h12 => &TAGCUSTOM48H12,
            TagFamily::TagStandard41h12 => &TAGSTANDARD41H12,
            TagFamily::TagStandard52h13 => &TAGSTANDARD52H13,
        }
    }
}

/// Hamming-radius lookup of observed codes in a family's code table (see the module docs).
#[derive(Debug, Clone)]
pub(crate) struct QuickDecode {
    /// Per chunk, the ids grouped by chunk value (each group in id order).
    chunk_ids: [Vec<u16>; 4],
    /// Per chunk, where each chunk value's group starts in `chunk_ids` (`capacity + 1`).
    chunk_offsets: [Vec<u32>; 4],
    shifts: [usize; 4],
    chunk_mask: usize,
    max_hamming: u32,
}

impl QuickDecode {
    /// The lookup over `codes` (at most 65,536 of them: ids are `u16`) within `max_hamming`.
    pub fn new(nbits: usize, codes: &[usize], max_hamming: u8) -> Self {
        let chunk_size = nbits.div_ceil(4);
        let capacity = 1usize << chunk_size;
        let chunk_mask = capacity - 1;
        let shifts = [0, chunk_size, chunk_size * 2, chunk_size * 3];
        let mut offsets: [Vec<u32>; 4] = std::array::from_fn(|_| vec![0u32; capacity + 1]);
        for &code in codes {
            for i in 0..4 {
                offsets[i][((code >> shifts[i]) & chunk_mask) + 1] += 1;
            }
        }
        for offset in &mut offsets {
            for j in 0..capacity {
                offset[j + 1] += offset[j];
            }
        }
        let mut cursors = offsets.clone();
        let mut ids: [Vec<u16>; 4] = std::array::from_fn(|_| vec![0u16; codes.len()]);
        for (id, &code) in codes.iter().enumerate() {
            for i in 0..4 {
                let val = (code >> shifts[i]) & chunk_mask;
                ids[i][cursors[i][val] as usize] = id as u16;
                cursors[i][val] += 1;
            }
        }
        Self {
            chunk_ids: ids,
            chunk_offsets: offsets,
            shifts,
            chunk_mask,
            max_hamming: u32::from(max_hamming),
        }
    }

    /// `(id, hamming)` of the first valid code within `max_hamming` of `observed`.
    pub fn decode(&self, observed: usize, codes: &[usize]) -> Option<(u16, u8)> {
        for i in 0..4 {
            let val = (observed >> self.shifts[i]) & self.chunk_mask;
            let start = self.chunk_offsets[i][val] as usize;
            let end = self.chunk_offsets[i][val + 1] as usize;
            for &id in &self.chunk_ids[i][start..end] {
                let dist = (observed ^ codes[id as usize]).count_ones();
                if dist <= self.max_hamming {
                    return Some((id, dist as u8));
                }
            }
        }
        None
    }
}

#[cfg(test)]
mod tests;
