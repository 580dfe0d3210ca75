use super::*;

/// The inverse of [`decode_codes`]: what `data/tags/*.bin` holds.
fn encode_codes(codes: &[usize], nbits: usize) -> Vec<u8> {
    let mask = (1u64 << nbits) - 1;
    // The inverse of the (odd) step mod 2^64, by Newton's iteration (3 -> 96 correct bits).
    let mut inv = CODE_STEP;
    for _ in 0..5 {
        inv = inv.wrapping_mul(2u64.wrapping_sub(CODE_STEP.wrapping_mul(inv)));
    }
    assert_eq!(CODE_STEP.wrapping_mul(inv), 1);
    let mut out = Vec::new();
    let mut prev: Option<u64> = None;
    for &c in codes {
        let c = c as u64;
        let mut v = match prev {
            None => c,
            Some(p) => c.wrapping_sub(p).wrapping_mul(inv) & mask,
        };
        prev = Some(c);
        loop {
            let b = (v & 0x7f) as u8;
            v >>= 7;
            if v == 0 {
                out.push(b);
                break;
            }
            out.push(b | 0x80);
        }
    }
    out
}

/// FNV-1a 64 over the codes as little-endian u64.
fn fnv1a(codes: &[usize]) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for &c in codes {
        for b in (c as u64).to_le_bytes() {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    }
    h
}

/// splitmix64, for reproducible random codes.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
}

/// Observed codes for a family: valid codes with 0-4 random bits flipped, and random codes.
fn observed_codes(codes: &[usize], nbits: usize, n: usize, seed: u64) -> Vec<usize> {
    let mut rng = Rng(seed);
    let mask = (1usize << nbits) - 1;
    (0..n)
        .map(|i| {
            if i % 5 == 4 {
                return rng.next() as usize & mask;
            }
            let mut c = codes[rng.next() as usize % codes.len()];
            for _ in 0..i % 5 {
                c ^= 1 << (rng.next() as usize % nbits);
            }
            c
        })
        .collect()
}

/// Per family: (count, FNV-1a of the codes, data file bytes, first code, layout hash).
const PINNED: [(TagFamily, usize, u64, usize, usize, u64); 9] = [
    (
        TagFamily::Tag36h11,
        587,
        0x53ca_4261_158b_8ef4,
        3222,
        0xd_7e00_984b,
        0x3c2b_8759_3abc_9d48,
    ),
    (
        TagFamily::Tag36h10,
        2320,
        0x41d6_2056_6490_e537,
        12730,
        0x1_a42f_9469,
        0xd73a_8b51_fb7b_25e9,
    ),
    (
        TagFamily::Tag25h9,
        35,
        0x3033_17a2_2a30_058a,
        138,
        0x156_f1f4,
        0xc7b0_c4a8_a9a6_80bb,
    ),
    (
        TagFamily::Tag16h5,
        30,
        0xec1a_e005_51d8_4855,
        84,
        0x27c8,
        0x920e_fc85_4cbf_f73e,
    ),
    (
        TagFamily::TagCircle21h7,
        38,
        0x711b_0fed_af5f_36f7,
        58,
        0x15_7863,
        0xc791_a4e2_8eeb_935a,
    ),
    (
        TagFamily::TagCircle49h12,
        65535,
        0x701b_9a22_538e_59bf,
        129_754,
        0xc6c9_21d8_614a,
        0xbc08_d154_c909_80ea,
    ),
    (
        TagFamily::TagCustom48h12,
        42211,
        0x3382_4c85_20fa_125e,
        85988,
        0xd6c8_ae76_dff0,
        0x4ab0_6005_7b28_09f4,
    ),
    (
        TagFamily::TagStandard41h12,
        2115,
        0x901b_33b4_7849_524d,
        5498,
        0x1bd_8a64_ad10,
        0x8331_b08f_67bf_b5cd,
    ),
    (
        TagFamily::TagStandard52h13,
        48714,
        0x6162_ec50_5c69_f313,
        87159,
        0x4_064a_1965_1ff1,
        0x4cdc_8c32_54cf_5611,
    ),
];

#[test]
fn vendored_tables_are_pinned() {
    let mut total = 0;
    for (fam, count, hash, bytes, first, layout) in PINNED {
        let def = fam.def();
        let codes = def.codes();
        assert_eq!(codes.len(), count, "{fam}");
        assert_eq!(def.count, count, "{fam}");
        assert_eq!(fnv1a(&codes), hash, "{fam}");
        assert_eq!(def.data.len(), bytes, "{fam}");
        assert_eq!(codes[0], first, "{fam}");
        assert!(codes.iter().all(|&c| c >> def.nbits == 0), "{fam}");
        // The encoding is canonical: re-encoding gives the file back.
        assert_eq!(encode_codes(&codes, def.nbits), def.data, "{fam}");
        assert!(def.bit_x.len() >= def.nbits && def.bit_y.len() == def.nbits);
        assert_eq!(layout_hash(def), layout, "{fam}");
        total += bytes;
    }
    assert_eq!(total, 324_631);
}

/// FNV-1a of a family's layout (sizes, border, minimum distance, bit cells).
fn layout_hash(d: &FamilyDef) -> u64 {
    let mut v = vec![
        d.nbits,
        d.width_at_border,
        d.total_width,
        usize::from(d.reversed_border),
        usize::from(d.min_hamming),
        d.bit_x.len(),
        d.bit_y.len(),
    ];
    v.extend(d.bit_x.iter().chain(d.bit_y).map(|&b| usize::from(b as u8)));
    fnv1a(&v)
}

/// Within a safe radius at most one code is near enough, so the lookup must find exactly
/// the code a brute-force scan finds.
#[test]
fn quick_decode_matches_brute_force_within_safe_radius() {
    for fam in TagFamily::ALL {
        let def = fam.def();
        let codes = def.codes();
        for mh in 0..=def.max_safe_hamming().min(3) {
            let quick = QuickDecode::new(def.nbits, &codes, mh);
            let n = if codes.len() > 5000 { 300 } else { 2000 };
            for obs in observed_codes(&codes, def.nbits, n, 7 + u64::from(mh)) {
                let brute = codes.iter().enumerate().find_map(|(id, &c)| {
                    let d = (obs ^ c).count_ones();
                    (d <= u32::from(mh)).then_some((id as u16, d as u8))
                });
                assert_eq!(quick.decode(obs, &codes), brute, "{fam} mh {mh} {obs:#x}");
            }
        }
    }
}

#[test]
fn unsafe_radius_is_refused_as_kornia_did() {
    let err = crate::Detector::new(crate::DetectorConfig {
        families: vec![TagFamily::Tag16h5],
        max_hamming: 3,
        ..Default::default()
    })
    .err()
    .map(|e| e.to_string());
    assert_eq!(
        err.as_deref(),
        Some("AprilTag detector: max_hamming 3 exceeds safe limit for this tag family (min_hamming=5, max safe value is 2)")
    );
    for fam in TagFamily::ALL {
        for mh in 0..=3 {
            let ok = crate::Detector::new(crate::DetectorConfig {
                families: vec![fam],
                max_hamming: mh,
                ..Default::default()
            })
            .is_ok();
            assert_eq!(ok, fam != TagFamily::Tag16h5 || mh != 3, "{fam} {mh}");
        }
    }
}
