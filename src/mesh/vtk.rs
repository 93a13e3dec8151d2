//! VTK legacy (`.vtk`) reader for `UNSTRUCTURED_GRID` files.
//!
//! Both ASCII and BINARY (big-endian) encodings, file versions up to 4.x
//! (`CELLS n size` with a count before each cell) and 5.x (`OFFSETS` /
//! `CONNECTIVITY`). Every section of the format is parsed (so unfamiliar but
//! legal content such as `FIELD` blocks, `METADATA`, vectors or cell data is
//! skipped correctly). Cells: every linear 3-D type (tetra, voxel,
//! hexahedron, wedge, pyramid) is split into tets conformingly by `cells`;
//! vertex, line and surface cells are skipped and counted; other types are
//! refused, named with their counts. The scalar is the point array the
//! caller names (a `SCALARS`, `VECTORS` or `FIELD` array; several
//! components by magnitude; a cell array of that name is refused as cell
//! data), else the first one-component `SCALARS` array of `POINT_DATA`;
//! files that store their point data only as a `FIELD` (such as VTK's own
//! `post.vtk`, whose point data is `FIELD FieldData 1` / `Pressure 1 2288
//! float`) fall back to the first one-component field array of the right
//! length.
//!
//! Every value must fit the type the file declares for its array (or, for
//! `CELLS` and `CELL_TYPES` in files before 5.x, the `int` the format
//! implies): in ASCII `unsigned_char 300`, a negative value for an unsigned
//! type or `1.5` for an integer type is an error, as is a `float` beyond
//! f32's range. BINARY files are big-endian; little-endian arrays, float or
//! integer, are recognised (`byte_order`) and rejected as such instead of
//! loading as subnormals or huge integers and rendering blank. Lines must end in LF or CRLF (CR-only
//! files are reported as such).
//!
//! All errors name the file, the problem and the byte offset.

use crate::vtk_legacy::Lines as Reader;
use super::cells::RawCells;
use super::TetMesh;
use anyhow::{anyhow, bail, Result};
use std::path::Path;

/// VTK cell type of a linear tetrahedron.
pub const VTK_TETRA: i64 = super::cells::VTK_TETRA as i64;

#[derive(Debug, Clone, Copy, PartialEq)]
enum DType {
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
    fn parse(s: &str) -> Option<DType> {
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
    fn size(self) -> usize {
        match self {
            DType::U8 | DType::I8 => 1,
            DType::U16 | DType::I16 => 2,
            DType::U32 | DType::I32 | DType::F32 => 4,
            DType::U64 | DType::I64 | DType::F64 => 8,
        }
    }
    fn is_float(self) -> bool {
        matches!(self, DType::F32 | DType::F64)
    }
    /// Evidence that a BINARY array of this type, big-endian by the
    /// format, was written little-endian (`byte_order`).
    fn looks_little_endian(self, bytes: &[u8]) -> Option<super::byte_order::LittleEndianEvidence> {
        use super::byte_order::{looks_little_endian, looks_little_endian_int};
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
fn swapped_hint(binary: bool, v: i64, expected: i32) -> &'static str {
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

    fn peek_word(&mut self) -> &'a str {
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

    fn values_f64(&mut self, n: usize, dt: DType, what: &str) -> Result<Vec<f64>> {
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

    fn values_i64(&mut self, n: usize, dt: DType, what: &str) -> Result<Vec<i64>> {
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
    fn skip_values(&mut self, n: usize, dt: DType, what: &str) -> Result<()> {
        if self.binary {
            self.binary_bytes(n, dt.size(), what)?;
        } else {
            for i in 0..n {
                self.ascii_value(parse_ascii_f64, dt, what, i, n)?;
            }
        }
        Ok(())
    }

    fn dtype(&self, s: Option<&&str>, what: &str) -> Result<DType> {
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

/// Why `bytes`, whose first line is not a legacy VTK header, are not a
/// legacy VTK file, when they are recognisably something else.
fn not_legacy_vtk(bytes: &[u8]) -> Option<&'static str> {
    let head = &bytes[..bytes.len().min(256)];
    let text = String::from_utf8_lossy(head);
    if bytes.starts_with(b"\xef\xbb\xbf") {
        Some("it starts with a UTF-8 byte-order mark; the first line must be '# vtk DataFile Version x.y'")
    } else if text.trim_start().starts_with("<?xml") || text.contains("<VTKFile") {
        Some("this is an XML VTK file; give it the extension .vtu (or .pvtu) to read it as one")
    } else {
        None
    }
}

/// The major version of a legacy file's `x.y`, if this reader supports it
/// (1 to 5).
fn legacy_major_version(version: &str) -> Option<u32> {
    let (major, minor) = version.split_once('.').unwrap_or((version, "0"));
    if minor.is_empty() || !minor.bytes().all(|c| c.is_ascii_digit()) {
        return None;
    }
    major.parse::<u32>().ok().filter(|m| (1..=5).contains(m))
}

#[derive(Clone, Copy, PartialEq)]
enum Owner {
    None,
    Points,
    Cells,
}

/// Reads a VTK legacy `UNSTRUCTURED_GRID` of tetrahedra with point scalars
/// (ASCII or big-endian BINARY) and validates it. The mesh is named after the
/// file stem.
pub fn read_vtk_legacy(path: impl AsRef<Path>) -> Result<TetMesh> {
    read_vtk_legacy_array(path, None)
}

/// [`read_vtk_legacy`] with the point array `array` (a `SCALARS`, `VECTORS`
/// or `FIELD` array; vectors by magnitude) as the scalar.
pub fn read_vtk_legacy_array(path: impl AsRef<Path>, array: Option<&str>) -> Result<TetMesh> {
    let path = path.as_ref();
    let bytes = crate::fsio::read_input(path, "VTK file", crate::fsio::MAX_INPUT_BYTES)?;
    parse_vtk_bytes_array(&path.display().to_string(), &bytes, array)
}

/// [`read_vtk_legacy`] on the bytes of a file already in memory. `name` (the
/// file path, or any label) is quoted in every error, and its file stem names
/// the mesh. Never panics on malformed input: every count is checked against
/// the bytes that remain before anything is allocated from it.
pub fn parse_vtk_bytes(name: &str, bytes: &[u8]) -> Result<TetMesh> {
    parse_vtk_bytes_array(name, bytes, None)
}

/// [`parse_vtk_bytes`] with the point array `want` as the scalar.
pub fn parse_vtk_bytes_array(name: &str, bytes: &[u8], want: Option<&str>) -> Result<TetMesh> {
    let mut r = Reader { name, b: bytes, pos: 0, binary: false };

    // Header: version line, title, encoding, DATASET.
    let version_line = r.raw_line("the '# vtk DataFile Version' line").map_err(|e| match not_legacy_vtk(bytes) {
        Some(what) => anyhow!("{name}: not a VTK legacy file: {what}"),
        None => e,
    })?;
    let version = version_line
        .strip_prefix("# vtk DataFile Version")
        .ok_or_else(|| match not_legacy_vtk(bytes) {
            Some(what) => anyhow!("{name}: not a VTK legacy file: {what}"),
            None => anyhow!("{name}: not a VTK legacy file (first line is not '# vtk DataFile Version x.y')"),
        })?
        .trim();
    let major = legacy_major_version(version).ok_or_else(|| {
        anyhow!(
            "{name}: unsupported VTK legacy file version '{}': this reader knows versions 1.0 to 4.2 \
             (CELLS with a vertex count before each cell) and 5.x (CELLS as OFFSETS and CONNECTIVITY arrays)",
            version.escape_debug()
        )
    })?;
    r.raw_line("the title line")?;
    let enc = r.keyword_line("ASCII or BINARY")?;
    match enc.first().map(|s| s.to_ascii_uppercase()).as_deref() {
        Some("ASCII") => r.binary = false,
        Some("BINARY") => r.binary = true,
        other => bail!(r.err(format!("expected ASCII or BINARY, found {:?}", other.unwrap_or("nothing")))),
    }
    let ds = r.keyword_line("DATASET")?;
    if ds.first().map(|s| s.to_ascii_uppercase()).as_deref() != Some("DATASET") {
        bail!(r.err(format!("expected DATASET, found '{}'", ds.join(" "))));
    }
    match ds.get(1).map(|s| s.to_ascii_uppercase()).as_deref() {
        Some("UNSTRUCTURED_GRID") => {}
        other => bail!(r.err(format!(
            "unsupported DATASET {}: only UNSTRUCTURED_GRID (of tetrahedra) is supported",
            other.unwrap_or("(missing)")
        ))),
    }

    let mut points: Option<Vec<[f64; 3]>> = None;
    let mut cells: Option<(Vec<usize>, Vec<u32>)> = None; // offsets, connectivity
    let mut n_cells: Option<usize> = None;
    let mut types: Option<Vec<u8>> = None;
    let mut owner = Owner::None;
    let mut owner_count = 0usize;
    let mut scalars: Option<Vec<f64>> = None;
    let mut field_scalars: Option<Vec<f64>> = None;
    let mut seen_point_arrays: Vec<String> = Vec::new();

    while !r.at_end() {
        let line = r.keyword_line("a section keyword")?;
        let kw = line[0].to_ascii_uppercase();
        let n_points = points.as_ref().map_or(0, |p| p.len());
        // Tuples per attribute array in the current POINT_DATA / CELL_DATA.
        let need_owner = |r: &Reader, kw: &str| -> Result<usize> {
            if owner == Owner::None {
                Err(r.err(format!("{kw} outside POINT_DATA / CELL_DATA")))
            } else {
                Ok(owner_count)
            }
        };
        match kw.as_str() {
            "METADATA" => r.skip_metadata()?,
            "FIELD" => {
                let n_arrays = r.count(line.get(2), "FIELD array count")?;
                for _ in 0..n_arrays {
                    let h = r.keyword_line("a FIELD array header")?;
                    if h[0] == "NULL_ARRAY" {
                        continue;
                    }
                    let ncomp = r.count(h.get(1), "FIELD array component count")?;
                    let ntup = r.count(h.get(2), "FIELD array tuple count")?;
                    let dt = r.dtype(h.get(3), &format!("FIELD array '{}'", h[0]))?;
                    let n = ncomp
                        .checked_mul(ntup)
                        .ok_or_else(|| r.err(format!("FIELD array '{}' size overflows", h[0])))?;
                    let what = format!("FIELD array '{}'", h[0]);
                    let named = want.is_some_and(|w| w == h[0]);
                    if named && owner == Owner::Cells {
                        bail!(r.err(cell_data_refusal(h[0])));
                    }
                    if owner == Owner::Points && ntup == n_points && (named || (want.is_none() && ncomp == 1 && field_scalars.is_none())) {
                        field_scalars = Some(magnitudes(r.values_f64(n, dt, &what)?, ncomp));
                        if named {
                            scalars = field_scalars.clone();
                        }
                    } else {
                        r.skip_values(n, dt, &what)?;
                    }
                    if owner == Owner::Points {
                        seen_point_arrays.push(format!("FIELD {} ({ncomp} components)", h[0]));
                    }
                    if r.peek_word().eq_ignore_ascii_case("METADATA") {
                        r.keyword_line("METADATA")?;
                        r.skip_metadata()?;
                    }
                }
            }
            "POINTS" => {
                if points.is_some() {
                    bail!(r.err("second POINTS section"));
                }
                let n = r.count(line.get(1), "POINTS count")?;
                let dt = r.dtype(line.get(2), "POINTS")?;
                let n3 = n.checked_mul(3).ok_or_else(|| r.err("POINTS count overflows"))?;
                let v = r.values_f64(n3, dt, "POINTS")?;
                points = Some(v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect());
            }
            "CELLS" => {
                if cells.is_some() {
                    bail!(r.err("second CELLS section"));
                }
                let Some(np) = points.as_ref().map(|p| p.len()) else {
                    bail!(r.err("CELLS before POINTS"));
                };
                let a = r.count(line.get(1), "CELLS count")?;
                let b = r.count(line.get(2), "CELLS size")?;
                let (offsets, conn) = if major >= 5 {
                    let h = r.keyword_line("OFFSETS")?;
                    if !h[0].eq_ignore_ascii_case("OFFSETS") {
                        bail!(r.err(format!(
                            "expected OFFSETS after CELLS, found '{}': a version {version} file lists its cells \
                             as OFFSETS and CONNECTIVITY arrays (files up to version 4.2 put a vertex count before \
                             each cell)",
                            h[0]
                        )));
                    }
                    let dt = r.dtype(h.get(1), "OFFSETS")?;
                    let offsets = r.values_i64(a, dt, "OFFSETS")?;
                    let h = r.keyword_line("CONNECTIVITY")?;
                    if !h[0].eq_ignore_ascii_case("CONNECTIVITY") {
                        bail!(r.err(format!("expected CONNECTIVITY after OFFSETS, found '{}'", h[0])));
                    }
                    let dt = r.dtype(h.get(1), "CONNECTIVITY")?;
                    let conn = r.values_i64(b, dt, "CONNECTIVITY")?;
                    if offsets.first().is_some_and(|&o| o != 0)
                        || offsets.last().is_some_and(|&o| o as usize != b)
                        || offsets.windows(2).any(|w| w[1] < w[0])
                    {
                        bail!(r.err(format!(
                            "count mismatch: OFFSETS must rise from 0 to the CONNECTIVITY size {b}"
                        )));
                    }
                    (offsets, conn)
                } else {
                    if r.peek_word().eq_ignore_ascii_case("OFFSETS") {
                        bail!(r.err(format!(
                            "OFFSETS after CELLS: that layout needs file version 5.x, but the header says {version}"
                        )));
                    }
                    let flat = r.values_i64(b, DType::I32, "CELLS")?;
                    // Each cell takes at least its vertex count, so `a <= b`,
                    // and `b` values were just read: both bound the allocations.
                    if a > b {
                        bail!(r.err(format!(
                            "count mismatch: CELLS declares {a} cells in only {b} values"
                        )));
                    }
                    let mut offsets = Vec::with_capacity(a + 1);
                    let mut conn = Vec::with_capacity(b - a);
                    let mut i = 0usize;
                    offsets.push(0);
                    for c in 0..a {
                        let Some(&k) = flat.get(i) else {
                            bail!(r.err(format!(
                                "count mismatch: CELLS size {b} ends inside cell {c} of {a}"
                            )));
                        };
                        // `i < b`, so `b - i - 1` cannot underflow; comparing
                        // against it cannot overflow whatever `k` is.
                        if k < 0 || k as u64 > (b - i - 1) as u64 {
                            bail!(r.err(format!(
                                "count mismatch: cell {c} claims {k} vertices, beyond CELLS size {b}{}",
                                swapped_hint(r.binary, k, 4)
                            )));
                        }
                        let k = k as usize;
                        conn.extend_from_slice(&flat[i + 1..i + 1 + k]);
                        i += 1 + k;
                        offsets.push(conn.len() as i64);
                    }
                    if i != b {
                        bail!(r.err(format!(
                            "count mismatch: CELLS declares size {b} but its {a} cells use {i} values"
                        )));
                    }
                    (offsets, conn)
                };
                let nc = offsets.len().saturating_sub(1);
                let mut conn32 = Vec::with_capacity(conn.len());
                for c in 0..nc {
                    let (s, e) = (offsets[c] as usize, offsets[c + 1] as usize);
                    for &v in &conn[s..e] {
                        if v < 0 || v as usize >= np {
                            bail!(r.err(format!(
                                "cell {c} has vertex index {v} out of range (file has {np} points)"
                            )));
                        }
                        conn32.push(v as u32);
                    }
                }
                n_cells = Some(nc);
                cells = Some((offsets.iter().map(|&o| o as usize).collect(), conn32));
            }
            "CELL_TYPES" => {
                let n = r.count(line.get(1), "CELL_TYPES count")?;
                let Some(nc) = n_cells else { bail!(r.err("CELL_TYPES before CELLS")) };
                if n != nc {
                    bail!(r.err(format!("count mismatch: CELL_TYPES has {n} entries but CELLS has {nc} cells")));
                }
                let t = r.values_i64(n, DType::I32, "CELL_TYPES")?;
                // Types beyond a byte are no VTK cell; a byte-swapped 10..14 says why.
                if let Some(c) = t.iter().position(|&t| !(0..=255).contains(&t)) {
                    let hint = (VTK_TETRA..=14).map(|k| swapped_hint(r.binary, t[c], k as i32)).find(|h| !h.is_empty());
                    bail!(r.err(format!("unknown cell type {} at cell {c}{}", t[c], hint.unwrap_or(""))));
                }
                types = Some(t.iter().map(|&t| t as u8).collect());
            }
            "POINT_DATA" | "CELL_DATA" => {
                let n = r.count(line.get(1), &format!("{kw} count"))?;
                let (o, expect, what) = if kw == "POINT_DATA" {
                    (Owner::Points, points.as_ref().map(|p| p.len()), "POINTS")
                } else {
                    (Owner::Cells, n_cells, "CELLS")
                };
                match expect {
                    Some(e) if e == n => {}
                    Some(e) => bail!(r.err(format!("count mismatch: {kw} {n} but {what} has {e}"))),
                    None => bail!(r.err(format!("{kw} before {what}"))),
                }
                owner = o;
                owner_count = n;
            }
            "SCALARS" => {
                let n = need_owner(&r, "SCALARS")?;
                let name = line.get(1).copied().unwrap_or("?");
                let dt = r.dtype(line.get(2), &format!("SCALARS '{name}'"))?;
                let ncomp = match line.get(3) {
                    Some(s) => s.parse::<usize>().ok().filter(|&k| (1..=4).contains(&k)).ok_or_else(|| {
                        r.err(format!("bad component count '{s}' for SCALARS '{name}'"))
                    })?,
                    None => 1,
                };
                if r.peek_word().eq_ignore_ascii_case("LOOKUP_TABLE") {
                    r.keyword_line("LOOKUP_TABLE")?;
                }
                let what = format!("SCALARS '{name}'");
                if owner == Owner::Points {
                    seen_point_arrays.push(format!("SCALARS {name} ({ncomp} components)"));
                }
                let named = want == Some(name);
                if named && owner == Owner::Cells {
                    bail!(r.err(cell_data_refusal(name)));
                }
                if owner == Owner::Points && (named || (want.is_none() && ncomp == 1 && scalars.is_none())) {
                    scalars = Some(magnitudes(r.values_f64(r.product(n, ncomp, &what)?, dt, &what)?, ncomp));
                } else {
                    r.skip_values(r.product(n, ncomp, &what)?, dt, &what)?;
                }
            }
            "LOOKUP_TABLE" => {
                let size = r.count(line.get(2), "LOOKUP_TABLE size")?;
                let n = size.checked_mul(4).ok_or_else(|| r.err("LOOKUP_TABLE size overflows"))?;
                let dt = if r.binary { DType::U8 } else { DType::F64 };
                r.skip_values(n, dt, "LOOKUP_TABLE")?;
            }
            "COLOR_SCALARS" => {
                let n = need_owner(&r, "COLOR_SCALARS")?;
                let k = r.count(line.get(2), "COLOR_SCALARS component count")?;
                let dt = if r.binary { DType::U8 } else { DType::F64 };
                r.skip_values(r.product(n, k, "COLOR_SCALARS")?, dt, "COLOR_SCALARS")?;
            }
            "VECTORS" | "NORMALS" | "TENSORS" | "TENSORS6" | "GLOBAL_IDS" | "PEDIGREE_IDS" => {
                let n = need_owner(&r, &kw)?;
                let k = match kw.as_str() {
                    "VECTORS" | "NORMALS" => 3,
                    "TENSORS" => 9,
                    "TENSORS6" => 6,
                    _ => 1,
                };
                let dt = r.dtype(line.get(2), &kw)?;
                let aname = line.get(1).copied().unwrap_or("?");
                if owner == Owner::Points {
                    seen_point_arrays.push(format!("{kw} {aname} ({k} components)"));
                }
                if want == Some(aname) && owner == Owner::Cells {
                    bail!(r.err(cell_data_refusal(aname)));
                }
                if want == Some(aname) && owner == Owner::Points {
                    scalars = Some(magnitudes(r.values_f64(r.product(n, k, &kw)?, dt, &kw)?, k));
                } else {
                    r.skip_values(r.product(n, k, &kw)?, dt, &kw)?;
                }
            }
            "TEXTURE_COORDINATES" => {
                let n = need_owner(&r, &kw)?;
                let k = r.count(line.get(2), "TEXTURE_COORDINATES dimension")?;
                let dt = r.dtype(line.get(3), &kw)?;
                r.skip_values(r.product(n, k, &kw)?, dt, &kw)?;
            }
            _ => bail!(r.err(format!("bad keyword '{}'", line[0].escape_debug()))),
        }
    }

    let points = points.ok_or_else(|| r.err("no POINTS section"))?;
    let (offsets, conn) = cells.ok_or_else(|| r.err("no CELLS section"))?;
    let types = types.ok_or_else(|| r.err("no CELL_TYPES section"))?;
    if let Some(w) = want {
        if scalars.is_none() {
            bail!(r.err(format!(
                "no point array named '{w}'; point arrays: {}",
                if seen_point_arrays.is_empty() { "none".to_string() } else { seen_point_arrays.join(", ") }
            )));
        }
    }
    let scalars = scalars.or(field_scalars).ok_or_else(|| {
        r.err(format!(
            "no point scalars: need POINT_DATA with a one-component SCALARS (or FIELD) array; found {}",
            if seen_point_arrays.is_empty() { "none".to_string() } else { seen_point_arrays.join(", ") }
        ))
    })?;
    let stem = Path::new(name).file_stem().map_or_else(|| "vtk".to_string(), |s| s.to_string_lossy().into_owned());
    RawCells { points, scalars, types, offsets, conn }.into_tet_mesh(name, stem)
}

/// The error for a `--scalar` that names a cell array.
pub(crate) fn cell_data_refusal(array: &str) -> String {
    format!(
        "'{array}' is cell data (one value per cell); volbench needs a point array (one value per point: \
         convert with VTK's vtkCellDataToPointData, ParaView's 'Cell Data to Point Data')"
    )
}

/// One value per tuple: the value itself, or the magnitude of a vector.
fn magnitudes(v: Vec<f64>, ncomp: usize) -> Vec<f64> {
    if ncomp <= 1 {
        return v;
    }
    v.chunks_exact(ncomp).map(|c| c.iter().map(|x| x * x).sum::<f64>().sqrt()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const ASCII: &str = "# vtk DataFile Version 3.0
two tets
ASCII
DATASET UNSTRUCTURED_GRID
POINTS 5 float
0 0 0  1 0 0  0 1 0
0 0 1  1 1 1
CELLS 2 10
4 0 1 2 3
4 1 3 2 4
CELL_TYPES 2
10
10
CELL_DATA 2
SCALARS cellid int 1
LOOKUP_TABLE default
0 1
POINT_DATA 5
VECTORS v float
0 0 0 0 0 0 0 0 0 0 0 0 0 0 0
SCALARS temp double
LOOKUP_TABLE default
0.5 1.5 2.5 3.5 4.5
SCALARS other float
LOOKUP_TABLE default
9 9 9 9 9
";

    fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    #[test]
    fn ascii_file() {
        let tmp = tempfile::tempdir().unwrap();
        let p = write(tmp.path(), "two.vtk", ASCII.as_bytes());
        let m = read_vtk_legacy(&p).unwrap();
        assert_eq!(m.name, "two");
        assert_eq!(m.points.len(), 5);
        assert_eq!(m.tets.len(), 2);
        assert_eq!(m.scalars, vec![0.5, 1.5, 2.5, 3.5, 4.5]);
        // Second tet (1,2,3,4) is inverted in the file.
        assert_eq!(m.stats.reoriented, 1);
    }

    #[test]
    fn ascii_version5_offsets() {
        let s = "# vtk DataFile Version 5.1\nv5\nASCII\nDATASET UNSTRUCTURED_GRID\n\
                 POINTS 4 double\n0 0 0 1 0 0 0 1 0 0 0 1\n\
                 METADATA\nINFORMATION 0\n\n\
                 CELLS 2 4\nOFFSETS vtktypeint64\n0 4\nCONNECTIVITY vtktypeint64\n0 1 2 3\n\
                 CELL_TYPES 1\n10\nPOINT_DATA 4\nSCALARS s float 1\nLOOKUP_TABLE default\n1 2 3 4\n";
        let tmp = tempfile::tempdir().unwrap();
        let p = write(tmp.path(), "v5.vtk", s.as_bytes());
        let m = read_vtk_legacy(&p).unwrap();
        assert_eq!(m.tets, vec![[0, 1, 2, 3]]);
        assert_eq!(m.scalars, vec![1.0, 2.0, 3.0, 4.0]);
    }

    /// A binary file built like VTK's post.vtk: FieldData first, point scalars
    /// only as a FIELD array.
    #[test]
    fn binary_with_field_blocks() {
        let mut b: Vec<u8> = Vec::new();
        b.extend_from_slice(b"# vtk DataFile Version 3.0\nvtk output\nBINARY\nDATASET UNSTRUCTURED_GRID\n");
        b.extend_from_slice(b"FIELD FieldData 1\nProperties 1 2 float\n");
        for v in [1.0f32, 2.0] {
            b.extend_from_slice(&v.to_be_bytes());
        }
        b.extend_from_slice(b"\nPOINTS 4 double\n");
        for v in [0.0f64, 0., 0., 1., 0., 0., 0., 1., 0., 0., 0., 1.] {
            b.extend_from_slice(&v.to_be_bytes());
        }
        b.extend_from_slice(b"\nCELLS 1 5\n");
        for v in [4i32, 0, 2, 1, 3] {
            b.extend_from_slice(&v.to_be_bytes());
        }
        b.extend_from_slice(b"\nCELL_TYPES 1\n");
        b.extend_from_slice(&10i32.to_be_bytes());
        b.extend_from_slice(b"\nPOINT_DATA 4\nFIELD FieldData 1\nPressure 1 4 float\n");
        for v in [0.25f32, 0.5, 0.75, 1.0] {
            b.extend_from_slice(&v.to_be_bytes());
        }
        b.push(b'\n');
        let tmp = tempfile::tempdir().unwrap();
        let p = write(tmp.path(), "bin.vtk", &b);
        let m = read_vtk_legacy(&p).unwrap();
        assert_eq!(m.tets.len(), 1);
        assert_eq!(m.stats.reoriented, 1);
        assert_eq!(m.scalars, vec![0.25, 0.5, 0.75, 1.0]);
        // Every truncation is an error naming the file, never a panic.
        for cut in [10, 60, 100, 130, 200, 240, b.len() - 5] {
            let p = write(tmp.path(), "cut.vtk", &b[..cut]);
            let e = format!("{:#}", read_vtk_legacy(&p).unwrap_err());
            assert!(e.contains(&p.display().to_string()), "cut {cut}: {e}");
        }
    }

    #[test]
    fn errors_name_file_and_problem() {
        let tmp = tempfile::tempdir().unwrap();
        let cases = [
            (ASCII.replace("4 1 3 2 4", "4 1 3 2 7"), "out of range"),
            (ASCII.replace("10\n10\n", "10\n12\n"), "hexahedron"),
            (ASCII.replace("CELL_TYPES 2", "CELL_TYPES 3"), "count mismatch"),
            (ASCII.replace("CELLS 2 10", "CELLS 2 11"), "count mismatch: CELLS needs 11 values, found 10 before 'CELL_TYPES'"),
            (ASCII.replace("POINT_DATA 5", "POINT_DATA 6"), "count mismatch"),
            (ASCII.replace("VECTORS", "VECTROS"), "bad keyword"),
            (ASCII.replace("DATASET UNSTRUCTURED_GRID", "DATASET POLYDATA"), "UNSTRUCTURED_GRID"),
            (ASCII.replace("SCALARS temp double", "SCALARS temp double 3")
                .replace("0.5 1.5 2.5 3.5 4.5", &"0 ".repeat(15))
                .replace("SCALARS other float", "NORMALS other float")
                .replace("LOOKUP_TABLE default\n9 9 9 9 9", &"0 ".repeat(15)), "no point scalars"),
            (ASCII.replace("1 1 1", "1 nan 1"), "non-finite"),
            (ASCII.replace("0 0 1  1 1 1", "0 0 1  1 x 1"), "value 'x' in POINTS (value 13 of 15) is not a number"),
            (ASCII[..ASCII.len() - 10].to_string(), "truncated"),
            ("hello\n".to_string(), "not a VTK legacy file"),
        ];
        for (i, (text, what)) in cases.iter().enumerate() {
            let p = write(tmp.path(), &format!("bad{i}.vtk"), text.as_bytes());
            let e = format!("{:#}", read_vtk_legacy(&p).unwrap_err());
            assert!(e.contains(&p.display().to_string()), "{e}");
            assert!(e.contains(what), "case {i}: expected '{what}' in: {e}");
        }
    }
}
