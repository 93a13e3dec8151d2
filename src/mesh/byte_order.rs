//! Recognising little-endian floats in a file whose format is big-endian
//! (VTK legacy BINARY, PLOT3D as volbench reads it).
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
}

impl std::fmt::Display for LittleEndianEvidence {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "the values look little-endian: read big-endian (as the format requires) {} of {} are \
             implausible (e.g. {:e}), byte-swapped all are ordinary numbers (that one {:e}); write the \
             file big-endian",
            self.implausible, self.total, self.example, self.swapped
        )
    }
}

fn implausible(v: f64) -> bool {
    !v.is_finite() || (v != 0.0 && v.abs() < TINY)
}

fn decode(c: &[u8], big: bool) -> f64 {
    match (c.len(), big) {
        (4, true) => f32::from_be_bytes([c[0], c[1], c[2], c[3]]) as f64,
        (4, false) => f32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64,
        (_, true) => f64::from_be_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]),
        (_, false) => f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]),
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
}
