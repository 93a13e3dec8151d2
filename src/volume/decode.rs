//! Sample decoding shared by the volume readers: the sample types files may
//! hold, binary samples in either byte order and ASCII values
//! (range-checked against the declared type), made into [`Samples`]. The
//! bytes themselves (byte order, decompression) are `crate::bytes`'s.
//!
//! Files may hold `int8`, `int32` and `uint32` too; they become a
//! [`Samples`] type without loss (`int8` widens to `i16`; `int32` and
//! `uint32` narrow to `i16` or `u16` when every value fits, else become
//! `f32` when every value is exactly representable, else are an error).
//! `float64` (MetaImage's `MET_DOUBLE`) is rounded to `f32`, the precision
//! every method renders in; a finite value beyond `f32`'s range is an error.

use std::borrow::Cow;

use anyhow::{anyhow, bail, Result};

use super::Samples;
use crate::bytes::Endian;

/// A sample type as stored in a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum RawType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl RawType {
    pub(crate) fn size(self) -> usize {
        match self {
            RawType::I8 | RawType::U8 => 1,
            RawType::I16 | RawType::U16 => 2,
            RawType::I32 | RawType::U32 | RawType::F32 => 4,
            RawType::F64 => 8,
        }
    }

    pub(crate) fn name(self) -> &'static str {
        match self {
            RawType::I8 => "int8",
            RawType::U8 => "uint8",
            RawType::I16 => "int16",
            RawType::U16 => "uint16",
            RawType::I32 => "int32",
            RawType::U32 => "uint32",
            RawType::F32 => "float32",
            RawType::F64 => "float64",
        }
    }
}

/// `count * ty.size()`, or an error (counts come from headers).
pub(crate) fn byte_len(source: &str, count: usize, ty: RawType) -> Result<usize> {
    count
        .checked_mul(ty.size())
        .ok_or_else(|| anyhow!("{source}: {count} samples of {} overflow the byte count", ty.name()))
}

/// Samples from exactly `count` values of `ty` in `bytes` (whose length the
/// caller has checked to be `count * ty.size()`). Bytes given owned (an
/// inflated stream) become `u8` samples without a copy.
pub(crate) fn decode_binary(source: &str, bytes: Cow<'_, [u8]>, ty: RawType, endian: Endian, count: usize) -> Result<Samples> {
    let need = byte_len(source, count, ty)?;
    if bytes.len() != need {
        bail!("{source}: {} bytes of {} data where {count} samples need {need}", bytes.len(), ty.name());
    }
    Ok(match ty {
        RawType::U8 => Samples::U8(bytes.into_owned()),
        RawType::I8 => Samples::I16(bytes.iter().map(|&b| b as i8 as i16).collect()),
        RawType::I16 => Samples::I16(endian.words::<i16>(&bytes)),
        RawType::U16 => Samples::U16(endian.words::<u16>(&bytes)),
        RawType::I32 => narrow_i32(source, endian.words::<i32>(&bytes))?,
        RawType::U32 => narrow_ints(source, "uint32", endian.words::<u32>(&bytes))?,
        RawType::F32 => Samples::F32(endian.words::<f32>(&bytes)),
        RawType::F64 => narrow_f64(source, endian.words::<f64>(&bytes))?,
    })
}

/// `int32` samples as the narrowest [`Samples`] type that holds them exactly.
pub(crate) fn narrow_i32(source: &str, v: Vec<i32>) -> Result<Samples> {
    narrow_ints(source, "int32", v)
}

/// 32-bit integer samples (`type_name` in errors) as the narrowest
/// [`Samples`] type that holds them exactly.
pub(crate) fn narrow_ints<T: Copy + Into<i64>>(source: &str, type_name: &str, v: Vec<T>) -> Result<Samples> {
    let (lo, hi) = v.iter().fold((i64::MAX, i64::MIN), |(lo, hi), &x| (lo.min(x.into()), hi.max(x.into())));
    if lo >= i16::MIN as i64 && hi <= i16::MAX as i64 {
        return Ok(Samples::I16(v.into_iter().map(|x| x.into() as i16).collect()));
    }
    if lo >= 0 && hi <= u16::MAX as i64 {
        return Ok(Samples::U16(v.into_iter().map(|x| x.into() as u16).collect()));
    }
    const EXACT: i64 = 1 << 24;
    if let Some(i) = v.iter().position(|&x| !(-EXACT..=EXACT).contains(&x.into())) {
        bail!(
            "{source}: {type_name} sample {i} is {}: {type_name} data is kept only when it fits int16, uint16 or \
             (exactly) float32, and this volume's range [{lo}, {hi}] fits none",
            v[i].into()
        );
    }
    Ok(Samples::F32(v.into_iter().map(|x| x.into() as f32).collect()))
}

/// `float64` samples rounded to `f32`; a finite value beyond `f32`'s range
/// is an error (NaN and infinities are left for [`super::Volume::new`]).
pub(crate) fn narrow_f64(source: &str, v: Vec<f64>) -> Result<Samples> {
    if let Some(i) = v.iter().position(|x| x.is_finite() && !(x.abs() <= f32::MAX as f64)) {
        bail!("{source}: float64 sample {i} is {}, beyond float32's range (samples are kept as float32)", v[i]);
    }
    Ok(Samples::F32(v.into_iter().map(|x| x as f32).collect()))
}

/// ASCII-whitespace-separated tokens with their byte offsets.
pub(crate) struct Tokens<'a> {
    b: &'a [u8],
    pos: usize,
}

impl<'a> Tokens<'a> {
    pub(crate) fn new(b: &'a [u8]) -> Self {
        Tokens { b, pos: 0 }
    }

    /// The next token (bytes, not necessarily UTF-8) and its offset.
    pub(crate) fn next_token(&mut self) -> Option<(&'a [u8], usize)> {
        while self.pos < self.b.len() && self.b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        let start = self.pos;
        while self.pos < self.b.len() && !self.b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        (start < self.pos).then(|| (&self.b[start..self.pos], start))
    }

    /// Bytes consumed so far.
    pub(crate) fn pos(&self) -> usize {
        self.pos
    }
}

/// Exactly `count` ASCII values of `ty` from `tokens`: integers must be
/// integers within the declared type's range; floats parse as f32 (NaN and
/// infinities are left for [`super::Volume::new`] to reject by index).
/// `what` names the data in errors; `base` is added to reported offsets.
pub(crate) fn parse_ascii<'a>(
    source: &str,
    what: &str,
    tokens: &mut Tokens<'a>,
    ty: RawType,
    type_name: &str,
    count: usize,
    base: usize,
) -> Result<Samples> {
    // At most one value per two bytes remains: bounds the allocation.
    let cap = count.min(tokens.b.len().saturating_sub(tokens.pos) / 2 + 1);
    let mut next = |i: usize| -> Result<(&'a str, usize)> {
        let (t, at) = tokens.next_token().ok_or_else(|| {
            anyhow!("{source}: truncated {what}: {i} of {count} values, then the end of the data")
        })?;
        let t = std::str::from_utf8(t)
            .map_err(|_| anyhow!("{source}: non-text bytes in {what} at byte {}", base + at))?;
        Ok((t, at + base))
    };
    fn ints<'t, T: TryFrom<i64> + Copy>(
        source: &str,
        what: &str,
        type_name: &str,
        count: usize,
        cap: usize,
        next: &mut dyn FnMut(usize) -> Result<(&'t str, usize)>,
    ) -> Result<Vec<T>> {
        let mut out = Vec::with_capacity(cap);
        for i in 0..count {
            let (t, at) = next(i)?;
            let v: i64 = t
                .parse()
                .map_err(|_| anyhow!("{source}: bad {type_name} value '{t}' in {what} (value {i}, byte {at})"))?;
            let x = T::try_from(v).map_err(|_| {
                anyhow!("{source}: value {v} in {what} (value {i}, byte {at}) is out of range for {type_name}")
            })?;
            out.push(x);
        }
        Ok(out)
    }
    Ok(match ty {
        RawType::U8 => Samples::U8(ints(source, what, type_name, count, cap, &mut next)?),
        RawType::I8 => {
            Samples::I16(ints::<i8>(source, what, type_name, count, cap, &mut next)?.into_iter().map(i16::from).collect())
        }
        RawType::I16 => Samples::I16(ints(source, what, type_name, count, cap, &mut next)?),
        RawType::U16 => Samples::U16(ints(source, what, type_name, count, cap, &mut next)?),
        RawType::I32 => narrow_i32(source, ints(source, what, type_name, count, cap, &mut next)?)?,
        RawType::U32 => narrow_ints::<u32>(source, type_name, ints(source, what, type_name, count, cap, &mut next)?)?,
        RawType::F64 => {
            let mut out = Vec::with_capacity(cap);
            for i in 0..count {
                let (t, at) = next(i)?;
                let v: f64 = t
                    .parse()
                    .map_err(|_| anyhow!("{source}: bad {type_name} value '{t}' in {what} (value {i}, byte {at})"))?;
                out.push(v);
            }
            narrow_f64(source, out)?
        }
        RawType::F32 => {
            let mut out = Vec::with_capacity(cap);
            for i in 0..count {
                let (t, at) = next(i)?;
                let v: f32 = t
                    .parse()
                    .map_err(|_| anyhow!("{source}: bad {type_name} value '{t}' in {what} (value {i}, byte {at})"))?;
                out.push(v);
            }
            Samples::F32(out)
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn b(x: &[u8]) -> Cow<'_, [u8]> {
        Cow::Borrowed(x)
    }

    #[test]
    fn binary_both_endians_and_widening() {
        let s = decode_binary("f", b(&[1, 2, 3, 4]), RawType::I16, Endian::Big, 2).unwrap();
        assert_eq!(s, Samples::I16(vec![0x0102, 0x0304]));
        let s = decode_binary("f", b(&[1, 2, 3, 4]), RawType::U16, Endian::Little, 2).unwrap();
        assert_eq!(s, Samples::U16(vec![0x0201, 0x0403]));
        assert_eq!(decode_binary("f", b(&[0xff]), RawType::I8, Endian::Big, 1).unwrap(), Samples::I16(vec![-1]));
        assert!(decode_binary("f", b(&[1, 2, 3]), RawType::I16, Endian::Big, 2).is_err());
        assert_eq!(narrow_i32("f", vec![-5, 7]).unwrap(), Samples::I16(vec![-5, 7]));
        assert_eq!(narrow_i32("f", vec![0, 60000]).unwrap(), Samples::U16(vec![0, 60000]));
        assert_eq!(narrow_i32("f", vec![-1, 70000]).unwrap(), Samples::F32(vec![-1.0, 70000.0]));
        let e = narrow_i32("f", vec![0, 1 << 25]).unwrap_err().to_string();
        assert!(e.contains("sample 1 is 33554432"), "{e}");
        // uint32 and float64: the same bound at two sizes, and f32's range.
        assert_eq!(narrow_ints("f", "uint32", vec![0u32, 1 << 24]).unwrap(), Samples::F32(vec![0.0, 16777216.0]));
        let e = narrow_ints("f", "uint32", vec![0u32, (1 << 24) + 1]).unwrap_err().to_string();
        assert!(e.contains("uint32 sample 1 is 16777217"), "{e}");
        let s = decode_binary("f", b(&0.1f64.to_be_bytes()), RawType::F64, Endian::Big, 1).unwrap();
        assert_eq!(s, Samples::F32(vec![0.1f32]));
        assert_eq!(narrow_f64("f", vec![f32::MAX as f64]).unwrap(), Samples::F32(vec![f32::MAX]));
        let e = narrow_f64("f", vec![0.0, 1e39]).unwrap_err().to_string();
        assert!(e.contains("float64 sample 1 is 1000000000000000000000000000000000000000"), "{e}");
    }

    #[test]
    fn ascii_ranges() {
        let p = |t: &str, ty, n| parse_ascii("f", "data", &mut Tokens::new(t.as_bytes()), ty, "T", n, 0);
        assert_eq!(p(" 0 255\n", RawType::U8, 2).unwrap(), Samples::U8(vec![0, 255]));
        assert!(p("0 256", RawType::U8, 2).unwrap_err().to_string().contains("value 256 in data (value 1, byte 2) is out of range for T"));
        assert!(p("-129", RawType::I8, 1).unwrap_err().to_string().contains("out of range"));
        assert!(p("1.5", RawType::I16, 1).unwrap_err().to_string().contains("bad T value '1.5'"));
        assert!(p("1 2", RawType::F32, 3).unwrap_err().to_string().contains("truncated data: 2 of 3"));
        assert_eq!(p("1.5 -2e3", RawType::F32, 2).unwrap(), Samples::F32(vec![1.5, -2000.0]));
        // A huge count costs nothing until values arrive.
        assert!(p("1", RawType::F32, usize::MAX).is_err());
    }
}
