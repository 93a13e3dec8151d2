//! VTK legacy (`.vtk`) reader for `DATASET STRUCTURED_POINTS` volumes.
//!
//! ASCII and BINARY (big-endian) files: `DIMENSIONS`, `SPACING` (or its old
//! name `ASPECT_RATIO`), `ORIGIN`, then `POINT_DATA` with a one-component
//! `SCALARS` array (its `LOOKUP_TABLE` line optional) of type unsigned_char,
//! short, unsigned_short or float (char and int convert, see `decode`). The
//! first such array is the volume (BINARY samples that look little-endian,
//! `bytes::byte_order`, are refused as such); other attribute arrays, `FIELD` blocks,
//! lookup tables, `CELL_DATA` and `METADATA` are parsed and skipped, so a
//! file is read to its end and a malformed tail is still an error. ASCII
//! values outside the declared type's range are errors.
//!
//! The line and token layer (`crate::vtk_legacy`) is shared with the
//! unstructured-grid reader `mesh::vtk`; errors name the file, the problem
//! and the byte offset.

use anyhow::{bail, Result};
use std::path::Path;

use crate::vtk_legacy::Lines as Reader;
use super::decode::{decode_binary, parse_ascii, RawType, Tokens};
use crate::bytes::Endian;
use super::{check_dims, from_steps, stem_of, Samples, Volume};

/// Reads a VTK legacy `STRUCTURED_POINTS` file.
pub fn read_structured_points(path: impl AsRef<Path>) -> Result<Volume> {
    let path = path.as_ref();
    let bytes = crate::fsio::read_input(path, "VTK legacy file", crate::fsio::MAX_INPUT_BYTES)?;
    parse_structured_points_bytes(&path.display().to_string(), &bytes)
}

/// The sample type of a `SCALARS` array that can become a volume.
fn volume_type(t: &str) -> Option<RawType> {
    Some(match t.to_ascii_lowercase().as_str() {
        "unsigned_char" => RawType::U8,
        "char" => RawType::I8,
        "short" => RawType::I16,
        "unsigned_short" => RawType::U16,
        "int" => RawType::I32,
        "float" => RawType::F32,
        _ => return None,
    })
}

/// Bytes per value of any legacy data type (to skip arrays that are not read).
fn type_size(t: &str) -> Option<usize> {
    Some(match t.to_ascii_lowercase().as_str() {
        "unsigned_char" | "char" => 1,
        "unsigned_short" | "short" => 2,
        "unsigned_int" | "int" | "float" | "vtkidtype" => 4,
        "unsigned_long" | "long" | "double" | "vtktypeint64" | "vtktypeuint64" => 8,
        _ => return None,
    })
}

#[derive(Clone, Copy, PartialEq, Default)]
enum Owner {
    #[default]
    None,
    Points,
    Cells,
}

impl<'a> Reader<'a> {
    /// Whether the next word is `kw`, without moving (binary data may start
    /// with a byte that looks like whitespace).
    fn next_is(&self, kw: &str) -> bool {
        let rest = &self.b[self.pos..];
        let start = rest.iter().position(|c| !c.is_ascii_whitespace()).unwrap_or(rest.len());
        let rest = &rest[start..];
        rest.len() >= kw.len()
            && rest[..kw.len()].eq_ignore_ascii_case(kw.as_bytes())
            && rest.get(kw.len()).is_none_or(|c| c.is_ascii_whitespace())
    }

    fn numbers3(&self, line: &[&str], what: &str) -> Result<[f64; 3]> {
        if line.len() != 4 {
            return Err(self.err(format!("{what} needs 3 numbers, found {}", line.len() - 1)));
        }
        let mut v = [0.0; 3];
        for a in 0..3 {
            v[a] = line[a + 1].parse().map_err(|_| self.err(format!("bad number '{}' in {what}", line[a + 1])))?;
        }
        Ok(v)
    }

    /// Skips `n` values (binary: of `size` bytes; ASCII: tokens).
    fn skip_sized(&mut self, n: usize, size: usize, what: &str) -> Result<()> {
        if self.binary {
            self.binary_bytes(n, size, what)?;
        } else {
            let mut t = Tokens::new(&self.b[self.pos..]);
            for i in 0..n {
                if t.next_token().is_none() {
                    self.pos += t.pos();
                    return Err(self.err(format!("truncated file: {what} has {i} of {n} values")));
                }
            }
            self.pos += t.pos();
        }
        Ok(())
    }

    /// `n` values of a typed array (skipped by its type's size).
    fn skip_typed(&mut self, n: usize, type_name: Option<&&str>, what: &str) -> Result<()> {
        let t = type_name.ok_or_else(|| self.err(format!("missing data type for {what}")))?;
        let size = type_size(t).ok_or_else(|| self.err(format!("unsupported data type '{t}' for {what}")))?;
        self.skip_sized(n, size, what)
    }

}

/// Parses a VTK legacy `STRUCTURED_POINTS` file from its bytes. `name` starts
/// every error and its stem names the volume. Never panics on malformed
/// input: counts are checked against the bytes that remain before anything is
/// allocated from them.
pub fn parse_structured_points_bytes(name: &str, bytes: &[u8]) -> Result<Volume> {
    let mut r = Reader { name, b: bytes, pos: 0, binary: false };
    header(&mut r)?;
    let mut g = Sections::default();
    while !r.at_end() {
        let line = r.keyword_line("a section keyword")?;
        g.section(&mut r, &line)?;
    }
    let dims = g.dims.ok_or_else(|| r.err("no DIMENSIONS line"))?;
    let samples = g.scalars.ok_or_else(|| {
        r.err(format!(
            "no point scalars: need POINT_DATA with a one-component SCALARS array; found {}",
            if g.seen.is_empty() { "none".to_string() } else { g.seen.join(", ") }
        ))
    })?;
    let sp = g.spacing.unwrap_or([1.0; 3]);
    let steps = [[sp[0], 0.0, 0.0], [0.0, sp[1], 0.0], [0.0, 0.0, sp[2]]];
    from_steps(name, stem_of(name), dims, steps, g.origin.unwrap_or([0.0; 3]), samples)
}

/// The version line, the title, ASCII or BINARY and `DATASET STRUCTURED_POINTS`.
fn header(r: &mut Reader) -> Result<()> {
    let first = r.raw_line("the '# vtk DataFile Version' line")?;
    if !first.starts_with("# vtk DataFile Version") {
        bail!("{}: not a VTK legacy file (the first line is not '# vtk DataFile Version x.y')", r.name);
    }
    r.raw_line("the title line")?;
    let enc = r.keyword_line("ASCII or BINARY")?;
    match enc[0].to_ascii_uppercase().as_str() {
        "ASCII" => r.binary = false,
        "BINARY" => r.binary = true,
        other => bail!(r.err(format!("expected ASCII or BINARY, found '{}'", other.escape_debug()))),
    }
    let ds = r.keyword_line("DATASET")?;
    if !ds[0].eq_ignore_ascii_case("DATASET") {
        bail!(r.err(format!("expected DATASET, found '{}'", ds.join(" ").escape_debug())));
    }
    match ds.get(1).map(|s| s.to_ascii_uppercase()).as_deref() {
        Some("STRUCTURED_POINTS") => Ok(()),
        other => bail!(r.err(format!(
            "unsupported DATASET {}: only STRUCTURED_POINTS is a regular-grid volume",
            other.unwrap_or("(missing)")
        ))),
    }
}

/// What the sections after the header have given so far.
#[derive(Default)]
struct Sections {
    dims: Option<[usize; 3]>,
    spacing: Option<[f64; 3]>,
    origin: Option<[f64; 3]>,
    /// The data the attribute arrays belong to, and its count.
    owner: Owner,
    owner_count: usize,
    /// The first one-component point SCALARS.
    scalars: Option<Samples>,
    /// Every point SCALARS seen (for the error when none is usable).
    seen: Vec<String>,
}

impl Sections {
    /// One section, from its keyword line `line`.
    fn section(&mut self, r: &mut Reader, line: &[&str]) -> Result<()> {
        let kw = line[0].to_ascii_uppercase();
        match kw.as_str() {
            "DIMENSIONS" => {
                if self.dims.is_some() {
                    bail!(r.err("second DIMENSIONS line"));
                }
                if line.len() != 4 {
                    bail!(r.err(format!("DIMENSIONS needs 3 numbers, found {}", line.len() - 1)));
                }
                let mut d = [0u64; 3];
                for a in 0..3 {
                    d[a] = line[a + 1].parse().map_err(|_| r.err(format!("bad DIMENSIONS value '{}'", line[a + 1])))?;
                }
                self.dims = Some(check_dims(r.name, d)?);
            }
            "SPACING" | "ASPECT_RATIO" => {
                if self.spacing.is_some() {
                    bail!(r.err("second SPACING line"));
                }
                self.spacing = Some(r.numbers3(line, &kw)?);
            }
            "ORIGIN" => {
                if self.origin.is_some() {
                    bail!(r.err("second ORIGIN line"));
                }
                self.origin = Some(r.numbers3(line, "ORIGIN")?);
            }
            "METADATA" => r.skip_metadata()?,
            "FIELD" => skip_field(r, line)?,
            "POINT_DATA" => {
                let n = r.count(line.get(1), "POINT_DATA count")?;
                let d = self.dims.ok_or_else(|| r.err("POINT_DATA before DIMENSIONS"))?;
                let points = d[0] * d[1] * d[2];
                if n != points {
                    bail!(r.err(format!(
                        "count mismatch: POINT_DATA {n} but DIMENSIONS {} {} {} make {points} points",
                        d[0], d[1], d[2]
                    )));
                }
                self.owner = Owner::Points;
                self.owner_count = n;
            }
            "CELL_DATA" => {
                self.owner = Owner::Cells;
                self.owner_count = r.count(line.get(1), "CELL_DATA count")?;
            }
            "SCALARS" => self.scalars_section(r, line, &kw)?,
            "LOOKUP_TABLE" => {
                let size = r.count(line.get(2), "LOOKUP_TABLE size")?;
                let n = r.product(size, 4, "LOOKUP_TABLE")?;
                r.skip_sized(n, 1, "LOOKUP_TABLE")?;
            }
            "COLOR_SCALARS" => {
                let n = self.need_owner(r, &kw)?;
                let k = r.count(line.get(2), "COLOR_SCALARS component count")?;
                r.skip_sized(r.product(n, k, "COLOR_SCALARS")?, 1, "COLOR_SCALARS")?;
            }
            "VECTORS" | "NORMALS" | "TENSORS" | "TENSORS6" | "GLOBAL_IDS" | "PEDIGREE_IDS" => {
                let n = self.need_owner(r, &kw)?;
                let k = match kw.as_str() {
                    "VECTORS" | "NORMALS" => 3,
                    "TENSORS" => 9,
                    "TENSORS6" => 6,
                    _ => 1,
                };
                let total = r.product(n, k, &kw)?;
                r.skip_typed(total, line.get(2), &kw)?;
            }
            "TEXTURE_COORDINATES" => {
                let n = self.need_owner(r, &kw)?;
                let k = r.count(line.get(2), "TEXTURE_COORDINATES dimension")?;
                let total = r.product(n, k, &kw)?;
                r.skip_typed(total, line.get(3), &kw)?;
            }
            _ => bail!(r.err(format!("bad keyword '{}'", line[0].escape_debug()))),
        }
        Ok(())
    }

    /// The count of the data an attribute array `kw` belongs to.
    fn need_owner(&self, r: &Reader, kw: &str) -> Result<usize> {
        if self.owner == Owner::None {
            Err(r.err(format!("{kw} outside POINT_DATA / CELL_DATA")))
        } else {
            Ok(self.owner_count)
        }
    }

    /// A SCALARS array: the volume's samples if it is the first
    /// one-component point array, else skipped.
    fn scalars_section(&mut self, r: &mut Reader, line: &[&str], kw: &str) -> Result<()> {
        let n = self.need_owner(r, kw)?;
        let aname = line.get(1).copied().unwrap_or("?");
        let what = format!("SCALARS '{aname}'");
        let tname = *line.get(2).ok_or_else(|| r.err(format!("missing data type for {what}")))?;
        let comps = match line.get(3) {
            Some(s) => s
                .parse::<usize>()
                .ok()
                .filter(|k| (1..=4).contains(k))
                .ok_or_else(|| r.err(format!("bad component count '{s}' for {what}")))?,
            None => 1,
        };
        if r.next_is("LOOKUP_TABLE") {
            r.keyword_line("LOOKUP_TABLE")?;
        }
        if self.owner == Owner::Points {
            self.seen.push(format!("{what} ({tname}, {comps} components)"));
        }
        if self.owner == Owner::Points && comps == 1 && self.scalars.is_none() {
            let ty = volume_type(tname).ok_or_else(|| {
                r.err(format!(
                    "unsupported type '{tname}' for {what}; supported: unsigned_char, short, \
                     unsigned_short, float, char, int"
                ))
            })?;
            self.scalars = Some(if r.binary { binary_samples(r, ty, n, &what)? } else { ascii_samples(r, ty, tname, n, &what)? });
        } else {
            let k = r.product(n, comps, &what)?;
            r.skip_typed(k, Some(&tname), &what)?;
        }
        Ok(())
    }
}

/// A FIELD block: its arrays skipped.
fn skip_field(r: &mut Reader, line: &[&str]) -> Result<()> {
    let arrays = r.count(line.get(2), "FIELD array count")?;
    for _ in 0..arrays {
        let h = r.keyword_line("a FIELD array header")?;
        if h[0] == "NULL_ARRAY" {
            continue;
        }
        let what = format!("FIELD array '{}'", h[0]);
        let comps = r.count(h.get(1), "FIELD array component count")?;
        let tuples = r.count(h.get(2), "FIELD array tuple count")?;
        let n = r.product(comps, tuples, &what)?;
        r.skip_typed(n, h.get(3), &what)?;
        if r.next_is("METADATA") {
            r.keyword_line("METADATA")?;
            r.skip_metadata()?;
        }
    }
    Ok(())
}

/// `n` BINARY samples of `ty`: big-endian, as the format says; little-endian
/// samples are named as such, as the mesh reader does.
fn binary_samples(r: &mut Reader, ty: RawType, n: usize, what: &str) -> Result<Samples> {
    let data = r.binary_bytes(n, ty.size(), what)?;
    use crate::bytes::byte_order::{looks_little_endian, looks_little_endian_int};
    let evidence = match ty {
        RawType::F32 => looks_little_endian(data, 4),
        RawType::F64 => looks_little_endian(data, 8),
        RawType::I16 | RawType::I32 => looks_little_endian_int(data, ty.size(), true),
        RawType::U16 | RawType::U32 => looks_little_endian_int(data, ty.size(), false),
        RawType::I8 | RawType::U8 => None,
    };
    if let Some(e) = evidence {
        r.pos -= data.len();
        bail!(r.err(format!("{what}: {e}")));
    }
    decode_binary(r.name, data.into(), ty, Endian::Big, n)
}

/// `n` ASCII samples of `ty` (`tname` as the file names it).
fn ascii_samples(r: &mut Reader, ty: RawType, tname: &str, n: usize, what: &str) -> Result<Samples> {
    let mut t = Tokens::new(&r.b[r.pos..]);
    let s = parse_ascii(r.name, what, &mut t, ty, tname, n, r.pos)?;
    r.pos += t.pos();
    Ok(s)
}
