//! Recognising little-endian numbers in a file whose format is big-endian
//! (VTK legacy BINARY, PLOT3D as volbench reads it): floats
//! ([`looks_little_endian`]) and integers ([`looks_little_endian_int`]).
//!
//! Read with the wrong byte order, ordinary numbers turn absurd: 1.0f32
//! written little-endian reads big-endian as 4.6e-41, a subnormal, and any
//! float whose low mantissa byte is small reads as a number below 1e-30.
//! Such a mesh loaded "fine" and rendered blank. An array is taken for
//! little-endian when, read big-endian, at least 1 in 16 of its non-zero
//! values is implausible (NaN, infinite, or non-zero below 1e-30 in
//! magnitude) while byte-swapped none is. Genuine big-endian data is
//! rejected only if it holds that many non-zero values below 1e-30 and
//! also byte-swaps into plausible numbers throughout, which real data does
//! not (1.0, 0.5 or any float with zero low bytes swaps into a subnormal).

//!
//! Integers have no implausible bit patterns, but data read in the wrong
//! order moves its least significant byte, the one that varies most, to the
//! top: values that were small or changed smoothly from one to the next
//! become large and jump by multiples of 256. An integer array is taken
//! for little-endian when its total variation (the sum of |v[i] - v[i-1]|,
//! starting from 0, so a constant array counts its magnitude) read
//! big-endian is more than 16 times that of the byte-swapped values.
//! Smooth or small big-endian data varies far less as read than swapped,
//! and noise fills both bytes alike; what is rejected is data whose every
//! value is a multiple of 256 plus sign extension, e.g. a constant field of
//! 256 stored as `unsigned_short`, which is no ordinary data either.

use super::Endian;

/// Magnitudes below this (other than 0) are implausible in a mesh file.
const TINY: f64 = 1e-30;

/// Evidence that an array of floats is little-endian.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LittleEndianEvidence {
    /// Values that are implausible read big-endian.
    pub implausible: usize,
    /// Values in the array.
    pub total: usize,
    /// The first implausible value, read big-endian.
    pub example: f64,
    /// The same value byte-swapped.
    pub swapped: f64,
    /// For integers: how many times the big-endian reading's total
    /// variation exceeds the byte-swapped one's (module docs); `None` for
    /// floats, whose evidence is `implausible`.
    pub variation_ratio: Option<f64>,
}

impl std::fmt::Display for LittleEndianEvidence {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.variation_ratio {
            None => write!(
                f,
                "the values look little-endian: read big-endian (as the format requires) {} of {} are \
                 implausible (e.g. {:e}), byte-swapped all are ordinary numbers (that one {:e})",
                self.implausible, self.total, self.example, self.swapped
            )?,
            Some(r) => write!(
                f,
                "the integers look little-endian: read big-endian (as the format requires) they vary {r:.0} \
                 times more from one value to the next than byte-swapped (e.g. {} where byte-swapped \
                 gives {})",
                self.example, self.swapped
            )?,
        }
        write!(f, "; write the file big-endian")
    }
}

fn implausible(v: f64) -> bool {
    !v.is_finite() || (v != 0.0 && v.abs() < TINY)
}

fn decode(c: &[u8], big: bool) -> f64 {
    let e = if big { Endian::Big } else { Endian::Little };
    match c.len() {
        4 => e.read::<f32>(c) as f64,
        _ => e.read::<f64>(c),
    }
}

/// `Some` if `bytes`, an array of `width`-byte floats (4 or 8) stored
/// big-endian according to its format, look little-endian (module docs).
pub fn looks_little_endian(bytes: &[u8], width: usize) -> Option<LittleEndianEvidence> {
    if width != 4 && width != 8 {
        return None;
    }
    let mut implausible_be = 0usize;
    let mut nonzero = 0usize;
    let mut first: Option<(f64, f64)> = None;
    for c in bytes.chunks_exact(width) {
        let (be, le) = (decode(c, true), decode(c, false));
        if implausible(le) {
            return None;
        }
        nonzero += (be != 0.0) as usize;
        if implausible(be) {
            implausible_be += 1;
            first.get_or_insert((be, le));
        }
    }
    let (example, swapped) = first?;
    (implausible_be * 16 >= nonzero).then_some(LittleEndianEvidence {
        implausible: implausible_be,
        total: bytes.len() / width,
        example,
        swapped,
        variation_ratio: None,
    })
}

/// Reads a `width`-byte integer, most significant byte first.
fn int_value(c: &[u8], signed: bool) -> i128 {
    let mut v: i128 = if signed && c[0] & 0x80 != 0 { -1 } else { 0 };
    for &b in c {
        v = (v << 8) | b as i128;
    }
    v
}

/// `Some` if `bytes`, an array of `width`-byte integers (2, 4 or 8;
/// `signed` two's complement) stored big-endian according to its format,
/// look little-endian (module docs).
pub fn looks_little_endian_int(bytes: &[u8], width: usize, signed: bool) -> Option<LittleEndianEvidence> {
    if !matches!(width, 2 | 4 | 8) {
        return None;
    }
    let (mut prev_be, mut prev_le) = (0i128, 0i128);
    let (mut var_be, mut var_le) = (0f64, 0f64);
    let (mut differ, mut first) = (0usize, None);
    let mut swapped = [0u8; 8];
    for c in bytes.chunks_exact(width) {
        let sw = &mut swapped[..width];
        sw.copy_from_slice(c);
        sw.reverse();
        let (be, le) = (int_value(c, signed), int_value(sw, signed));
        var_be += (be - prev_be).unsigned_abs() as f64;
        var_le += (le - prev_le).unsigned_abs() as f64;
        (prev_be, prev_le) = (be, le);
        if be != le {
            differ += 1;
            first.get_or_insert((be as f64, le as f64));
        }
    }
    let (example, swapped) = first?;
    (var_be > 16.0 * var_le).then_some(LittleEndianEvidence {
        implausible: differ,
        total: bytes.len() / width,
        example,
        swapped,
        variation_ratio: Some(if var_le > 0.0 { var_be / var_le } else { f64::INFINITY }),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn f32s(v: &[f32], be: bool) -> Vec<u8> {
        v.iter().flat_map(|x| if be { x.to_be_bytes() } else { x.to_le_bytes() }).collect()
    }

    #[test]
    fn little_endian_floats_are_recognised() {
        let round = [0.0f32, 1.0, 0.5, 2.0, 0.0, 0.0, 1.0, 3.0];
        let e = looks_little_endian(&f32s(&round, false), 4).expect("little-endian");
        assert_eq!((e.implausible, e.total, e.swapped), (5, 8, 1.0));
        assert!(e.example > 0.0 && e.example < 1e-40, "{e:?}");
        // Random-looking values (low mantissa bytes not zero).
        let mixed: Vec<f32> = (0..200).map(|i| 0.1 + 0.37 * i as f32 - 1e-3 * (i * i) as f32).collect();
        assert!(looks_little_endian(&f32s(&mixed, false), 4).is_some());
        let d: Vec<u8> = [0.0f64, 1.0, 0.25, 7.5].iter().flat_map(|x| x.to_le_bytes()).collect();
        assert!(looks_little_endian(&d, 8).is_some());
        // Big-endian data is left alone, including tiny values among others.
        assert!(looks_little_endian(&f32s(&round, true), 4).is_none());
        assert!(looks_little_endian(&f32s(&mixed, true), 4).is_none());
        assert!(looks_little_endian(&f32s(&[1.0, 1e-35, 2.0, 3.0], true), 4).is_none());
        let d: Vec<u8> = [0.0f64, 1.0, 0.25, 7.5].iter().flat_map(|x| x.to_be_bytes()).collect();
        assert!(looks_little_endian(&d, 8).is_none());
        assert!(looks_little_endian(&[], 4).is_none());
        assert!(looks_little_endian(&f32s(&[0.0; 4], false), 4).is_none());
    }

    #[test]
    fn little_endian_integers_are_recognised() {
        let le = |v: &[i64], w: usize| -> Vec<u8> { v.iter().flat_map(|x| x.to_le_bytes()[..w].to_vec()).collect() };
        let be = |v: &[i64], w: usize| -> Vec<u8> { v.iter().flat_map(|x| x.to_be_bytes()[8 - w..].to_vec()).collect() };
        let small = [0i64, 1, 2, 30, 7, -5, 100, 0];
        for w in [2, 4, 8] {
            let e = looks_little_endian_int(&le(&small, w), w, true).expect("little-endian");
            assert_eq!((e.total, e.swapped), (8, 1.0), "width {w}: {e:?}");
            assert!(looks_little_endian_int(&be(&small, w), w, true).is_none(), "width {w}");
        }
        let e = looks_little_endian_int(&le(&[1, 2, 3], 2), 2, false).unwrap();
        assert_eq!((e.example, e.swapped), (256.0, 1.0));
        // A smooth CT-like ramp filling both bytes, either way round.
        let ramp: Vec<i64> = (0..500).map(|i| -1024 + 8 * i + (i * 7919) % 5).collect();
        assert!(looks_little_endian_int(&le(&ramp, 2), 2, true).is_some());
        assert!(looks_little_endian_int(&be(&ramp, 2), 2, true).is_none());
        // Noise filling both bytes cannot be told apart: left alone.
        let noise: Vec<i64> = (0..500).map(|i| (i * 40503) % 65536).collect();
        assert!(looks_little_endian_int(&le(&noise, 2), 2, false).is_none());
        assert!(looks_little_endian_int(&le(&[0, 0], 4), 4, true).is_none());
        assert!(looks_little_endian_int(&[1, 2], 1, false).is_none());
    }
}
