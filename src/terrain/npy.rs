//! NumPy `.npy` arrays and `.npz` archives (a zip of `.npy` members) as
//! height grids. A `.npy` header is a Python dict literal giving `descr`
//! (byte order, kind, size), `fortran_order` and `shape`; integer (1-8
//! bytes, signed or not) and float (4, 8 bytes) arrays are read, any byte
//! order, C or Fortran order. A grid is a 2D array; an `.npz` with several
//! 2D arrays needs the one wanted named (`file.npz#name`), and its scalar
//! members (`dx`, `dy`, extents) are returned beside the grid.

use std::collections::BTreeMap;
use std::io::Read as _;

use anyhow::{bail, Context as _, Result};

use super::Heightmap;

/// Largest decompressed `.npz` member read (bytes): the largest grid
/// (`MAX_SAMPLES`) as float64.
pub const MAX_MEMBER_BYTES: u64 = super::MAX_SAMPLES as u64 * 8;

/// The element type of an array.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Int,
    Uint,
    Float,
}

/// A parsed `.npy` header.
#[derive(Debug, Clone, PartialEq)]
struct Header {
    kind: Kind,
    size: usize,
    big_endian: bool,
    fortran: bool,
    shape: Vec<usize>,
    /// Offset of the data.
    data_offset: usize,
}

/// A numeric array: its shape and its elements' bytes as the file stores
/// them (decoded one by one, [`Array::get`]: a grid is never also held as
/// f64, 8 bytes an element).
#[derive(Debug, Clone, PartialEq)]
pub struct Array<'a> {
    pub shape: Vec<usize>,
    header: Header,
    /// The whole `.npy` (header and data; borrowed from a file, owned when
    /// inflated from an `.npz`).
    bytes: std::borrow::Cow<'a, [u8]>,
}

impl Array<'_> {
    /// Elements.
    pub fn len(&self) -> usize {
        self.shape.iter().product()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Element `i` in C (row-major) order, as f64 (exact for every type
    /// but 64-bit integers beyond 2^53).
    pub fn get(&self, i: usize) -> f64 {
        let h = &self.header;
        let at = if h.fortran && self.shape.len() >= 2 {
            // C index -> multi-index -> column-major offset.
            let (mut rest, mut offset) = (i, 0);
            for d in (0..self.shape.len()).rev() {
                let stride: usize = self.shape[..d].iter().product();
                offset += (rest % self.shape[d]) * stride;
                rest /= self.shape[d];
            }
            offset
        } else {
            i
        };
        let chunk = &self.bytes[h.data_offset + at * h.size..h.data_offset + (at + 1) * h.size];
        let mut w = [0u8; 8];
        if h.big_endian {
            for (i, &b) in chunk.iter().rev().enumerate() {
                w[i] = b;
            }
        } else {
            w[..h.size].copy_from_slice(chunk);
        }
        match (h.kind, h.size) {
            (Kind::Float, 4) => f32::from_le_bytes([w[0], w[1], w[2], w[3]]) as f64,
            (Kind::Float, _) => f64::from_le_bytes(w),
            (Kind::Uint, _) => u64::from_le_bytes(w) as f64,
            (Kind::Int, s) => {
                // Sign-extend from s bytes.
                let shift = 64 - 8 * s as u32;
                ((u64::from_le_bytes(w) << shift) as i64 >> shift) as f64
            }
        }
    }
}

fn header(name: &str, b: &[u8]) -> Result<Header> {
    if b.len() < 10 || &b[..6] != b"\x93NUMPY" {
        bail!("{name}: not a NumPy .npy array (no \\x93NUMPY magic)");
    }
    let (len, start) = match b[6] {
        1 => (u16::from_le_bytes([b[8], b[9]]) as usize, 10usize),
        2 | 3 => {
            if b.len() < 12 {
                bail!("{name}: .npy header is truncated");
            }
            (u32::from_le_bytes([b[8], b[9], b[10], b[11]]) as usize, 12)
        }
        v => bail!("{name}: .npy format version {v} is not supported (1, 2 or 3)"),
    };
    let end = start.checked_add(len).filter(|&e| e <= b.len()).with_context(|| format!("{name}: .npy header is truncated"))?;
    let text = std::str::from_utf8(&b[start..end]).map_err(|_| anyhow::anyhow!("{name}: .npy header is not text"))?;
    // Each key once: with two, which one holds is a guess.
    for key in ["descr", "fortran_order", "shape"] {
        let n = text.matches(&format!("'{key}'")).count() + text.matches(&format!("\"{key}\"")).count();
        if n > 1 {
            bail!("{name}: .npy header gives '{key}' {n} times");
        }
    }
    let descr = dict_value(text, "descr").with_context(|| format!("{name}: .npy header has no 'descr'"))?;
    let descr = descr.trim().trim_matches(|c| c == '\'' || c == '"');
    let fortran = match dict_value(text, "fortran_order").map(str::trim) {
        Some("False") => false,
        Some("True") => true,
        _ => bail!("{name}: .npy header has no valid 'fortran_order'"),
    };
    let shape_text = dict_value(text, "shape").with_context(|| format!("{name}: .npy header has no 'shape'"))?;
    let shape_text = shape_text.trim();
    let inner = shape_text
        .strip_prefix('(')
        .and_then(|s| s.strip_suffix(')'))
        .with_context(|| format!("{name}: .npy shape '{}' is not a tuple", crate::fsio::clip_message(shape_text)))?;
    let shape = inner
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<usize>().map_err(|_| anyhow::anyhow!("{name}: .npy shape entry '{}' is not a size", crate::fsio::clip_message(s))))
        .collect::<Result<Vec<_>>>()?;
    let mut chars = descr.chars();
    let (order, rest) = match chars.next() {
        Some(c @ ('<' | '>' | '|' | '=')) => (c, chars.as_str()),
        _ => ('=', descr),
    };
    let (kind, size) = match (rest.get(..1), rest.get(1..).and_then(|s| s.parse::<usize>().ok())) {
        (Some("i"), Some(s @ (1 | 2 | 4 | 8))) => (Kind::Int, s),
        (Some("u"), Some(s @ (1 | 2 | 4 | 8))) => (Kind::Uint, s),
        (Some("f"), Some(s @ (4 | 8))) => (Kind::Float, s),
        _ => bail!(
            "{name}: .npy element type '{}' is not supported (integers of 1-8 bytes, float32, float64)",
            crate::fsio::clip_message(descr)
        ),
    };
    let big_endian = order == '>' || (order == '=' && cfg!(target_endian = "big"));
    Ok(Header { kind, size, big_endian, fortran, shape, data_offset: end })
}

/// The text after `'key':` up to the next top-level comma or closing brace.
fn dict_value<'a>(text: &'a str, key: &str) -> Option<&'a str> {
    let at = text.find(&format!("'{key}'")).or_else(|| text.find(&format!("\"{key}\"")))?;
    let rest = text[at + key.len() + 2..].trim_start().strip_prefix(':')?;
    let mut depth = 0i32;
    for (i, c) in rest.char_indices() {
        match c {
            '(' => depth += 1,
            ')' => depth -= 1,
            ',' | '}' if depth == 0 => return Some(&rest[..i]),
            _ => {}
        }
    }
    None
}

/// Refuse an array bigger than any grid volbench takes before its values
/// are made (each is an f64): `MAX_SAMPLES` elements, a grid as
/// `check_grid` says.
fn check_shape(name: &str, shape: &[usize]) -> Result<()> {
    let count = shape.iter().try_fold(1usize, |a, &d| a.checked_mul(d)).unwrap_or(usize::MAX);
    let max = super::MAX_SAMPLES;
    if count > max {
        bail!("{name}: .npy shape {shape:?} has {count} elements, more than the {max} of the largest grid (8192x8192)");
    }
    if let [ny, nx] = shape {
        super::check_grid(name, *nx, *ny)?;
    }
    Ok(())
}

/// Parse a whole `.npy` file: its header checked and its data's size
/// exactly the shape's.
pub fn parse_npy<'a>(name: &str, bytes: impl Into<std::borrow::Cow<'a, [u8]>>) -> Result<Array<'a>> {
    let bytes = bytes.into();
    let h = header(name, &bytes)?;
    let count = h.shape.iter().try_fold(1usize, |a, &d| a.checked_mul(d)).with_context(|| format!("{name}: .npy shape {:?} overflows", h.shape))?;
    let need = count.checked_mul(h.size).with_context(|| format!("{name}: .npy shape {:?} overflows", h.shape))?;
    check_shape(name, &h.shape)?;
    let data = &bytes[h.data_offset..];
    if data.len() != need {
        bail!(
            "{name}: .npy holds {} data bytes, shape {:?} of {}-byte elements needs exactly {need}{}",
            data.len(),
            h.shape,
            h.size,
            if data.len() > need { " (bytes after the data)" } else { "" }
        );
    }
    Ok(Array { shape: h.shape.clone(), header: h, bytes })
}

/// A 2D array as a height grid (rows along y).
fn grid_of(name: &str, a: &Array, spacing: [f64; 2]) -> Result<Heightmap> {
    let [ny, nx] = a.shape[..] else {
        bail!("{name}: a height grid must be a 2D array, this one has shape {:?}", a.shape);
    };
    Heightmap::from_fn(name, nx, ny, a.len(), |i| a.get(i), None, spacing)
}

/// A `.npy` file as a height grid (spacing 1).
pub fn parse_npy_heightmap(name: &str, bytes: &[u8]) -> Result<Heightmap> {
    grid_of(name, &parse_npy(name, bytes)?, [1.0, 1.0])
}

/// Every member of an `.npz` archive, by name without `.npy`.
pub fn parse_npz(name: &str, bytes: &[u8]) -> Result<BTreeMap<String, Array<'static>>> {
    let mut zip = zip::ZipArchive::new(std::io::Cursor::new(bytes)).map_err(|e| anyhow::anyhow!("{name}: not a readable .npz (zip) archive: {e}"))?;
    let mut out = BTreeMap::new();
    for i in 0..zip.len() {
        let mut f = zip.by_index(i).map_err(|e| anyhow::anyhow!("{name}: member {i} of the archive: {e}"))?;
        let member = f.name().map_err(|e| anyhow::anyhow!("{name}: member {i} of the archive has no readable name: {e}"))?.to_string();
        let Some(key) = member.strip_suffix(".npy") else { continue };
        let declared = f.size();
        if declared > MAX_MEMBER_BYTES {
            bail!("{name}: member '{}' declares {declared} bytes, more than the {MAX_MEMBER_BYTES} read", crate::fsio::clip_message(&member));
        }
        // The header first: a shape too big for any grid is refused before
        // the member is inflated.
        let mut data = Vec::with_capacity(declared.min(1 << 16) as usize);
        (&mut f)
            .take(declared.min(1 << 16))
            .read_to_end(&mut data)
            .map_err(|e| anyhow::anyhow!("{name}: member '{}': {e}", crate::fsio::clip_message(&member)))?;
        let label = format!("{name}[{}]", crate::fsio::clip_message(key));
        if let Ok(h) = header(&label, &data) {
            check_shape(&label, &h.shape)?;
        }
        data.reserve_exact((declared as usize).saturating_sub(data.len()));
        (&mut f)
            .take(declared + 1 - data.len() as u64)
            .read_to_end(&mut data)
            .map_err(|e| anyhow::anyhow!("{name}: member '{}': {e}", crate::fsio::clip_message(&member)))?;
        if data.len() as u64 != declared {
            bail!("{name}: member '{}' holds {} bytes, its directory entry says {declared}", crate::fsio::clip_message(&member), data.len());
        }
        let array = parse_npy(&label, data).map_err(|e| anyhow::anyhow!("{name}: {e:#}"))?;
        out.insert(key.to_string(), array);
    }
    Ok(out)
}

/// An `.npz` archive's grid (`array` names it; needed only when several
/// 2D arrays are present) and its scalar members.
pub fn parse_npz_grid(name: &str, bytes: &[u8], array: Option<&str>) -> Result<(Heightmap, BTreeMap<String, f64>)> {
    let members = parse_npz(name, bytes)?;
    let scalars: BTreeMap<String, f64> =
        members.iter().filter(|(_, a)| a.len() == 1 && a.shape.iter().all(|&d| d == 1)).map(|(k, a)| (k.clone(), a.get(0))).collect();
    let grids: Vec<&String> = members.iter().filter(|(_, a)| a.shape.len() == 2).map(|(k, _)| k).collect();
    let key = match array {
        Some(a) => {
            if !members.contains_key(a) {
                bail!("{name}: no array '{a}' in the archive (arrays: {})", members.keys().cloned().collect::<Vec<_>>().join(", "));
            }
            a.to_string()
        }
        None => match grids.as_slice() {
            [one] => (*one).clone(),
            [] => bail!("{name}: no 2D array in the archive (arrays: {})", members.keys().cloned().collect::<Vec<_>>().join(", ")),
            many => bail!(
                "{name}: several 2D arrays ({}); name the one to use as {name}#NAME",
                many.iter().map(|s| s.as_str()).collect::<Vec<_>>().join(", ")
            ),
        },
    };
    let spacing = match (scalars.get("dx"), scalars.get("dy")) {
        (Some(&dx), Some(&dy)) if dx.is_finite() && dy.is_finite() && dx != 0.0 && dy != 0.0 => [dx.abs(), dy.abs()],
        _ => [1.0, 1.0],
    };
    let label = format!("{name}[{key}]");
    let map = grid_of(&label, &members[&key], spacing).map_err(|e| anyhow::anyhow!("{e:#}"))?;
    Ok((map, scalars))
}

/// `parse_npz_grid` without the scalars.
pub fn parse_npz_heightmap(name: &str, bytes: &[u8], array: Option<&str>) -> Result<Heightmap> {
    Ok(parse_npz_grid(name, bytes, array)?.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn npy(descr: &str, fortran: bool, shape: &str, data: &[u8]) -> Vec<u8> {
        let mut h = format!("{{'descr': '{descr}', 'fortran_order': {}, 'shape': {shape}, }}", if fortran { "True" } else { "False" });
        while (h.len() + 11) % 64 != 0 {
            h.push(' ');
        }
        h.push('\n');
        let mut b = b"\x93NUMPY\x01\x00".to_vec();
        b.extend((h.len() as u16).to_le_bytes());
        b.extend(h.as_bytes());
        b.extend(data);
        b
    }

    #[test]
    fn reads_types_orders_and_layouts() {
        let d: Vec<u8> = [1i16, -2, 3, 4, 5, 6].iter().flat_map(|v| v.to_le_bytes()).collect();
        let m = parse_npy_heightmap("a.npy", &npy("<i2", false, "(2, 3)", &d)).unwrap();
        assert_eq!((m.nx, m.ny), (3, 2));
        assert_eq!(m.heights, vec![1.0, -2.0, 3.0, 4.0, 5.0, 6.0]);
        let d: Vec<u8> = [1.5f64, 2.5, 3.5, 4.5].iter().flat_map(|v| v.to_be_bytes()).collect();
        let m = parse_npy_heightmap("b.npy", &npy(">f8", true, "(2, 2)", &d)).unwrap();
        // Fortran order: columns first.
        assert_eq!(m.heights, vec![1.5, 3.5, 2.5, 4.5]);
        let d: Vec<u8> = [f32::NAN, 7.0, 9.0, 8.0].iter().flat_map(|v| v.to_le_bytes()).collect();
        let m = parse_npy_heightmap("c.npy", &npy("<f4", false, "(2, 2)", &d)).unwrap();
        assert_eq!(m.heights, vec![7.0, 7.0, 9.0, 8.0]);
        assert_eq!(m.nodata_filled, 1);
    }

    #[test]
    fn bad_arrays_are_errors_naming_the_file() {
        let cases: Vec<(Vec<u8>, &str)> = vec![
            (b"nope".to_vec(), "magic"),
            (npy("<c16", false, "(2, 2)", &[0; 64]), "element type"),
            (npy("<i2", false, "(2, 2)", &[0; 6]), "needs exactly 8"),
            (npy("<i2", false, "(2, 2)", &[0; 10]), "bytes after the data"),
            (npy("<i2", false, "(2, 2), 'descr': '<f8'", &[0; 8]), "'descr' 2 times"),
            (npy("<u1", false, "(20000, 20000)", &[]), "more than the"),
            (npy("<i2", false, "(4,)", &[0; 8]), "2D"),
            (npy("<i2", false, "(1, 4)", &[0; 8]), "at least 2x2"),
            (npy("<i8", false, "(4294967296, 4294967296)", &[0; 8]), "overflows"),
            (npy("<f4", false, "(2, 2)", &f32::NAN.to_le_bytes().repeat(4)), "no valid height"),
            (npy("<i2", false, "(2, x)", &[0; 8]), "not a size"),
        ];
        for (bytes, want) in cases {
            let e = format!("{:#}", parse_npy_heightmap("bad.npy", &bytes).unwrap_err());
            assert!(e.starts_with("bad.npy") && e.contains(want), "{e}");
        }
    }

    #[test]
    fn shipped_npz_reads() {
        let path = crate::data_dir::data_dir().join("terrain/jacksboro_fault_dem.npz");
        let bytes = std::fs::read(path).unwrap();
        let (m, s) = parse_npz_grid("j.npz", &bytes, None).unwrap();
        assert_eq!((m.nx, m.ny), (403, 344));
        assert_eq!(m.range(), (236.0, 1076.0));
        assert!((s["dx"] - 1.0 / 1200.0).abs() < 1e-12);
        let e = format!("{:#}", parse_npz_grid("j.npz", &bytes, Some("nosuch")).unwrap_err());
        assert!(e.contains("no array 'nosuch'") && e.contains("elevation"), "{e}");
        let e = format!("{:#}", parse_npz_grid("j.npz", &bytes, Some("dx")).unwrap_err());
        assert!(e.contains("2D"), "{e}");
        let e = format!("{:#}", parse_npz_grid("j.npz", &bytes[..1000], None).unwrap_err());
        assert!(e.starts_with("j.npz"), "{e}");
    }
}
