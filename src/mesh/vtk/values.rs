//! Typed values of a legacy VTK array: the declared data types, ASCII
//! values checked against them, big-endian BINARY values decoded (and
//! little-endian ones recognised), read and skipped through the shared
//! tokenizer (`crate::vtk_legacy`).

use anyhow::Result;

use crate::vtk_legacy::Lines as Reader;

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum DType {
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    U64,
    I64,
    F32,
    F64,
}

impl DType {
    pub(super) fn parse(s: &str) -> Option<DType> {
        Some(match s.to_ascii_lowercase().as_str() {
            "unsigned_char" => DType::U8,
            "char" => DType::I8,
            "unsigned_short" => DType::U16,
            "short" => DType::I16,
            "unsigned_int" => DType::U32,
            "int" => DType::I32,
            // Legacy binary files store vtkIdType as 32-bit ints.
            "vtkidtype" => DType::I32,
            "unsigned_long" | "vtktypeuint64" => DType::U64,
            "long" | "vtktypeint64" => DType::I64,
            "float" => DType::F32,
            "double" => DType::F64,
            _ => return None,
        })
    }
    pub(super) fn size(self) -> usize {
        match self {
            DType::U8 | DType::I8 => 1,
            DType::U16 | DType::I16 => 2,
            DType::U32 | DType::I32 | DType::F32 => 4,
            DType::U64 | DType::I64 | DType::F64 => 8,
        }
    }
    pub(super) fn is_float(self) -> bool {
        matches!(self, DType::F32 | DType::F64)
    }
    /// Evidence that a BINARY array of this type, big-endian by the
    /// format, was written little-endian (`byte_order`).
    fn looks_little_endian(self, bytes: &[u8]) -> Option<crate::bytes::byte_order::LittleEndianEvidence> {
        use crate::bytes::byte_order::{looks_little_endian, looks_little_endian_int};
        match self {
            DType::F32 | DType::F64 => looks_little_endian(bytes, self.size()),
            DType::I8 | DType::I16 | DType::I32 | DType::I64 => looks_little_endian_int(bytes, self.size(), true),
            DType::U8 | DType::U16 | DType::U32 | DType::U64 => looks_little_endian_int(bytes, self.size(), false),
        }
    }
    /// The VTK name of the type, for messages.
    fn name(self) -> &'static str {
        match self {
            DType::U8 => "unsigned_char",
            DType::I8 => "char",
            DType::U16 => "unsigned_short",
            DType::I16 => "short",
            DType::U32 => "unsigned_int",
            DType::I32 => "int",
            DType::U64 => "unsigned_long",
            DType::I64 => "long",
            DType::F32 => "float",
            DType::F64 => "double",
        }
    }
    /// The range of an integer type.
    fn int_range(self) -> (i128, i128) {
        match self {
            DType::U8 => (0, u8::MAX as i128),
            DType::I8 => (i8::MIN as i128, i8::MAX as i128),
            DType::U16 => (0, u16::MAX as i128),
            DType::I16 => (i16::MIN as i128, i16::MAX as i128),
            DType::U32 => (0, u32::MAX as i128),
            DType::I32 => (i32::MIN as i128, i32::MAX as i128),
            DType::U64 => (0, u64::MAX as i128),
            DType::I64 | DType::F32 | DType::F64 => (i64::MIN as i128, i64::MAX as i128),
        }
    }
}

/// Words that start a section: met where a value was expected, they mean
/// the array before them is shorter than its header says.
const SECTION_KEYWORDS: [&str; 21] = [
    "DATASET", "POINTS", "CELLS", "CELL_TYPES", "OFFSETS", "CONNECTIVITY", "POINT_DATA", "CELL_DATA",
    "SCALARS", "LOOKUP_TABLE", "COLOR_SCALARS", "VECTORS", "NORMALS", "TENSORS", "TENSORS6",
    "TEXTURE_COORDINATES", "GLOBAL_IDS", "PEDIGREE_IDS", "FIELD", "METADATA", "INFORMATION",
];

/// One ASCII value of the integer type `dt`; `Err` says why it does not fit.
fn parse_ascii_int(t: &str, dt: DType) -> std::result::Result<i64, String> {
    let name = dt.name();
    match t.parse::<i128>() {
        Ok(v) => {
            let (lo, hi) = dt.int_range();
            if v < lo || v > hi {
                return Err(format!("does not fit the type {name} ({lo} to {hi})"));
            }
            // unsigned_long values beyond i64 are clamped, as in binary files.
            Ok(v.min(i64::MAX as i128) as i64)
        }
        Err(_) if t.parse::<f64>().is_ok() => Err(format!("is not an integer, as the type {name} requires")),
        Err(_) => Err("is not an integer".to_string()),
    }
}

/// One ASCII value of type `dt` as f64; `Err` says why it does not fit.
/// NaN and infinities are left to validation, which names the point.
fn parse_ascii_f64(t: &str, dt: DType) -> std::result::Result<f64, String> {
    if !dt.is_float() {
        return parse_ascii_int(t, dt).map(|v| v as f64);
    }
    let v: f64 = t.parse().map_err(|_| "is not a number".to_string())?;
    if dt == DType::F32 && v.is_finite() && v.abs() > f32::MAX as f64 {
        return Err(format!("is beyond the f32 range (|v| <= {:e}) of the declared type float", f32::MAX));
    }
    Ok(v)
}

/// When a big-endian int read from a BINARY file is wrong but byte-swapped
/// would be `expected`, say so.
pub(super) fn swapped_hint(binary: bool, v: i64, expected: i32) -> &'static str {
    if binary && i32::try_from(v).is_ok_and(|v| v.swap_bytes() == expected) {
        " (byte-swapped it would be right: the file looks little-endian, but VTK legacy BINARY files are \
         big-endian)"
    } else {
        ""
    }
}

impl<'a> Reader<'a> {
    fn token(&mut self, what: &str) -> Result<&'a str> {
        self.skip_ws();
        let start = self.pos;
        while self.pos < self.b.len() && !self.b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        if start == self.pos {
            return Err(self.err(format!("truncated file: expected {what}, found end of file")));
        }
        std::str::from_utf8(&self.b[start..self.pos])
            .map_err(|_| self.err(format!("expected {what}, found non-text bytes")))
    }

    pub(super) fn peek_word(&mut self) -> &'a str {
        self.skip_ws();
        let start = self.pos;
        let mut end = start;
        while end < self.b.len() && !self.b[end].is_ascii_whitespace() {
            end += 1;
        }
        std::str::from_utf8(&self.b[start..end]).unwrap_or("")
    }

    /// The next ASCII value of `what` (value `i` of `n`), checked against
    /// its type `dt` by `parse`.
    fn ascii_value<T>(
        &mut self,
        parse: fn(&str, DType) -> std::result::Result<T, String>,
        dt: DType,
        what: &str,
        i: usize,
        n: usize,
    ) -> Result<T> {
        let t = self.token(what).map_err(|e| {
            if self.pos >= self.b.len() {
                self.err(format!("truncated file: {what} needs {n} values, found {i} before the end of the file"))
            } else {
                e
            }
        })?;
        parse(t, dt).map_err(|why| {
            // Point at the value, not past it.
            self.pos -= t.len();
            if SECTION_KEYWORDS.iter().any(|k| k.eq_ignore_ascii_case(t)) {
                self.err(format!("count mismatch: {what} needs {n} values, found {i} before '{t}'"))
            } else {
                self.err(format!("value '{t}' in {what} (value {i} of {n}) {why}"))
            }
        })
    }

    pub(super) fn values_f64(&mut self, n: usize, dt: DType, what: &str) -> Result<Vec<f64>> {
        if self.binary {
            let s = self.binary_bytes(n, dt.size(), what)?;
            if let Some(evidence) = dt.looks_little_endian(s) {
                self.pos -= s.len();
                return Err(self.err(format!("{what}: {evidence}")));
            }
            let w = dt.size();
            Ok(s.chunks_exact(w).map(|c| decode_f64(c, dt)).collect())
        } else {
            let mut out = Vec::with_capacity(n.min(self.b.len() - self.pos));
            for i in 0..n {
                out.push(self.ascii_value(parse_ascii_f64, dt, what, i, n)?);
            }
            Ok(out)
        }
    }

    pub(super) fn values_i64(&mut self, n: usize, dt: DType, what: &str) -> Result<Vec<i64>> {
        if dt.is_float() {
            return Err(self.err(format!("{what} must have an integer type, not a float type")));
        }
        if self.binary {
            // (Counts, indices and cell types are checked one by one, with a
            // byte-swap hint where they fail: `swapped_hint`.)
            let s = self.binary_bytes(n, dt.size(), what)?;
            let w = dt.size();
            Ok(s.chunks_exact(w).map(|c| decode_i64(c, dt)).collect())
        } else {
            let mut out = Vec::with_capacity(n.min(self.b.len() - self.pos));
            for i in 0..n {
                out.push(self.ascii_value(parse_ascii_int, dt, what, i, n)?);
            }
            Ok(out)
        }
    }

    /// Skips `n` values (binary: bytes; ASCII: tokens, each checked against
    /// `dt` like the values that are read).
    pub(super) fn skip_values(&mut self, n: usize, dt: DType, what: &str) -> Result<()> {
        if self.binary {
            self.binary_bytes(n, dt.size(), what)?;
        } else {
            for i in 0..n {
                self.ascii_value(parse_ascii_f64, dt, what, i, n)?;
            }
        }
        Ok(())
    }

    pub(super) fn dtype(&self, s: Option<&&str>, what: &str) -> Result<DType> {
        let s = s.ok_or_else(|| self.err(format!("missing data type for {what}")))?;
        DType::parse(s).ok_or_else(|| self.err(format!("unsupported data type '{s}' for {what}")))
    }

}

fn decode_f64(c: &[u8], dt: DType) -> f64 {
    match dt {
        DType::F32 => f32::from_be_bytes([c[0], c[1], c[2], c[3]]) as f64,
        DType::F64 => f64::from_be_bytes(c.try_into().unwrap()),
        _ => decode_i64(c, dt) as f64,
    }
}

fn decode_i64(c: &[u8], dt: DType) -> i64 {
    match dt {
        DType::U8 => c[0] as i64,
        DType::I8 => c[0] as i8 as i64,
        DType::U16 => u16::from_be_bytes([c[0], c[1]]) as i64,
        DType::I16 => i16::from_be_bytes([c[0], c[1]]) as i64,
        DType::U32 => u32::from_be_bytes([c[0], c[1], c[2], c[3]]) as i64,
        DType::I32 => i32::from_be_bytes([c[0], c[1], c[2], c[3]]) as i64,
        DType::U64 => u64::from_be_bytes(c.try_into().unwrap()).min(i64::MAX as u64) as i64,
        DType::I64 => i64::from_be_bytes(c.try_into().unwrap()),
        DType::F32 => f32::from_be_bytes([c[0], c[1], c[2], c[3]]) as i64,
        DType::F64 => f64::from_be_bytes(c.try_into().unwrap()) as i64,
    }
}
