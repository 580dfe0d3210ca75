//! A small deterministic mutator (no coverage feedback): bit flips, random and "interesting"
//! bytes and integers (both byte orders), arithmetic on bytes and words, deletes, inserts,
//! duplicated and overwritten ranges, splices with another input, dictionary tokens and,
//! for text, numbers replaced by awkward ones. Stacks 1 to 8 of them per input.

/// xorshift64*: tiny, fast, and the same sequence on every platform.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed.max(1))
    }

    pub fn next_u64(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    /// Uniform in `0..n` (`n > 0`).
    pub fn below(&mut self, n: usize) -> usize {
        debug_assert!(n > 0);
        (self.next_u64() % n as u64) as usize
    }

    pub fn chance(&mut self, one_in: usize) -> bool {
        self.below(one_in) == 0
    }
}

const INTERESTING_8: &[u8] = &[0, 1, 2, 0x10, 0x20, 0x40, 0x7f, 0x80, 0x81, 0xfe, 0xff];
const INTERESTING_32: &[u32] = &[
    0,
    1,
    2,
    3,
    4,
    7,
    8,
    16,
    255,
    256,
    1000,
    4096,
    32767,
    32768,
    65535,
    65536,
    0x00ff_ffff,
    0x7fff_fffe,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_fffe,
    0xffff_ffff,
];
/// Replacements for a number in text.
const AWKWARD_NUMBERS: &[&str] = &[
    "0",
    "-0",
    "1",
    "-1",
    "2",
    "255",
    "256",
    "65536",
    "4294967295",
    "4294967296",
    "-2147483649",
    "18446744073709551615",
    "18446744073709551616",
    "9223372036854775808",
    "1e308",
    "1e309",
    "-1e309",
    "1e-320",
    "nan",
    "NaN",
    "inf",
    "-inf",
    ".inf",
    "0.5",
    "1.0e0",
    "0x10",
    "1_000",
    "",
];

/// Mutates inputs of one target.
#[derive(Debug, Clone)]
pub struct Mutator {
    pub rng: Rng,
    /// Tokens inserted or written over the input (an AFL dictionary's values).
    pub dictionary: Vec<Vec<u8>>,
    /// Longest output.
    pub max_len: usize,
}

impl Mutator {
    pub fn new(seed: u64, dictionary: Vec<Vec<u8>>, max_len: usize) -> Self {
        Self {
            rng: Rng::new(seed),
            dictionary,
            max_len: max_len.max(1),
        }
    }

    /// A mutant of `input`; `others` are splice partners (may be empty).
    pub fn mutate(&mut self, input: &[u8], others: &[Vec<u8>]) -> Vec<u8> {
        let mut data = input.to_vec();
        let stack = 1 << self.rng.below(4);
        for _ in 0..stack {
            self.mutate_once(&mut data, others);
        }
        data.truncate(self.max_len);
        data
    }

    fn mutate_once(&mut self, data: &mut Vec<u8>, others: &[Vec<u8>]) {
        let r = &mut self.rng;
        if data.is_empty() {
            let n = 1 + r.below(8);
            data.extend((0..n).map(|_| r.next_u64() as u8));
            return;
        }
        let len = data.len();
        match r.below(15) {
            0 => {
                let i = r.below(len);
                data[i] ^= 1 << r.below(8);
            }
            1 => {
                let i = r.below(len);
                data[i] = r.next_u64() as u8;
            }
            2 => {
                let i = r.below(len);
                data[i] = INTERESTING_8[r.below(INTERESTING_8.len())];
            }
            3 | 4 => {
                // A 16-, 32- or 64-bit interesting value (or its negation), either byte order.
                let mut v = u64::from(INTERESTING_32[r.below(INTERESTING_32.len())]);
                if r.chance(4) {
                    v = v.wrapping_neg();
                }
                let width = [2usize, 4, 8][r.below(3)];
                let le = v.to_le_bytes();
                let be = v.to_be_bytes();
                let bytes = if r.chance(2) {
                    &le[..width]
                } else {
                    &be[8 - width..]
                };
                let at = r.below(len);
                for (k, b) in bytes.iter().enumerate() {
                    if let Some(d) = data.get_mut(at + k) {
                        *d = *b;
                    }
                }
            }
            5 => {
                let i = r.below(len);
                let delta = 1 + r.below(35) as u8;
                data[i] = if r.chance(2) {
                    data[i].wrapping_add(delta)
                } else {
                    data[i].wrapping_sub(delta)
                };
            }
            6 => {
                // Arithmetic on a big-endian 32-bit word (box sizes, counts, offsets).
                if len >= 4 {
                    let i = r.below(len - 3);
                    let w = u32::from_be_bytes([data[i], data[i + 1], data[i + 2], data[i + 3]]);
                    let delta = 1 + r.below(64) as u32;
                    let w = if r.chance(2) {
                        w.wrapping_add(delta)
                    } else {
                        w.wrapping_sub(delta)
                    };
                    data[i..i + 4].copy_from_slice(&w.to_be_bytes());
                }
            }
            7 => {
                let most = if r.chance(8) { 512 } else { 16 };
                let n = 1 + r.below(len.min(most));
                let at = r.below(len - n + 1);
                data.drain(at..at + n);
            }
            8 => {
                let n = 1 + r.below(16);
                let at = r.below(len + 1);
                let fill: Vec<u8> = if r.chance(2) {
                    vec![r.next_u64() as u8; n]
                } else {
                    (0..n).map(|_| r.next_u64() as u8).collect()
                };
                data.splice(at..at, fill);
            }
            9 => {
                // Duplicate a range somewhere (repeats structures: boxes, array items).
                let n = 1 + r.below(len.min(256));
                let from = r.below(len - n + 1);
                let chunk = data[from..from + n].to_vec();
                let at = r.below(len + 1);
                data.splice(at..at, chunk);
            }
            10 => {
                // Overwrite a range with another range of the same input.
                let n = 1 + r.below(len.min(64));
                let from = r.below(len - n + 1);
                let to = r.below(len - n + 1);
                let chunk = data[from..from + n].to_vec();
                data[to..to + n].copy_from_slice(&chunk);
            }
            11 => {
                // Splice: our head, another input's tail (or a chunk of it).
                if let Some(other) = pick(r, others) {
                    if !other.is_empty() {
                        let cut = r.below(len + 1);
                        let from = r.below(other.len());
                        data.truncate(cut);
                        if r.chance(2) {
                            data.extend_from_slice(&other[from..]);
                        } else {
                            let n = 1 + r.below((other.len() - from).min(256));
                            data.extend_from_slice(&other[from..from + n]);
                        }
                    }
                }
            }
            12 | 13 => {
                // A dictionary token, inserted or written over.
                if let Some(token) = pick(r, &self.dictionary) {
                    let at = r.below(len + 1);
                    if r.chance(2) {
                        data.splice(at..at, token.iter().copied());
                    } else {
                        for (k, b) in token.iter().enumerate() {
                            match data.get_mut(at + k) {
                                Some(d) => *d = *b,
                                None => data.push(*b),
                            }
                        }
                    }
                }
            }
            _ => {
                // A number in text replaced by an awkward one.
                let start = r.below(len);
                if let Some(s) = (start..len).find(|&i| data[i].is_ascii_digit()) {
                    let mut s = s;
                    if s > 0 && matches!(data[s - 1], b'-' | b'+') {
                        s -= 1;
                    }
                    let e = (s + 1..len)
                        .find(|&i| {
                            !matches!(data[i], b'0'..=b'9' | b'.' | b'e' | b'E' | b'-' | b'+')
                        })
                        .unwrap_or(len);
                    let n = AWKWARD_NUMBERS[r.below(AWKWARD_NUMBERS.len())];
                    data.splice(s..e, n.bytes());
                } else {
                    let i = r.below(len);
                    data[i] ^= 1 << r.below(8);
                }
            }
        }
    }
}

fn pick<'a>(r: &mut Rng, items: &'a [Vec<u8>]) -> Option<&'a Vec<u8>> {
    if items.is_empty() {
        None
    } else {
        Some(&items[r.below(items.len())])
    }
}

/// Reads an AFL dictionary (`name="value"` or `"value"` lines, `\xNN`, `\\`, `\"` escapes;
/// `#` comments). Lines it cannot read are skipped.
pub fn parse_dictionary(text: &str) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    for line in text.lines() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let (Some(a), Some(b)) = (line.find('"'), line.rfind('"')) else {
            continue;
        };
        if b <= a {
            continue;
        }
        let body = &line.as_bytes()[a + 1..b];
        let mut token = Vec::new();
        let mut i = 0;
        while i < body.len() {
            if body[i] == b'\\' && i + 1 < body.len() {
                match body[i + 1] {
                    b'x' if i + 3 < body.len() => {
                        let hex = std::str::from_utf8(&body[i + 2..i + 4]).unwrap_or("");
                        if let Ok(v) = u8::from_str_radix(hex, 16) {
                            token.push(v);
                        }
                        i += 4;
                    }
                    c => {
                        token.push(c);
                        i += 2;
                    }
                }
            } else {
                token.push(body[i]);
                i += 1;
            }
        }
        if !token.is_empty() {
            out.push(token);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deterministic_and_bounded() {
        let seed = b"camera_matrix: [1, 2, 3]".to_vec();
        let run = || {
            let mut m = Mutator::new(7, vec![b"nan".to_vec()], 64);
            (0..500)
                .map(|_| m.mutate(&seed, std::slice::from_ref(&seed)))
                .collect::<Vec<_>>()
        };
        let a = run();
        assert_eq!(a, run());
        assert!(a.iter().all(|m| m.len() <= 64));
        assert!(a.iter().filter(|m| **m != seed).count() > 450);
    }

    #[test]
    fn reads_afl_dictionaries() {
        let d = parse_dictionary("# c\nkw_a=\"moov\"\n\"\\x00\\x01\\\"\"\nbad\n");
        assert_eq!(d, vec![b"moov".to_vec(), vec![0, 1, b'"']]);
    }
}
