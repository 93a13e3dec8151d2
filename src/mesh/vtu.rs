//! VTK XML unstructured grids: `.vtu` files and `.pvtu` parallel files.
//!
//! `.vtu`: every `<Piece>` of the `<UnstructuredGrid>` (concatenated),
//! `Points` and `Cells` (`connectivity`, `offsets`, `types`) and one point
//! array. Arrays may be `ascii`, inline `binary` (base64) or `appended`
//! (raw or base64), uncompressed or `vtkZLibDataCompressor`, with UInt32 or
//! UInt64 headers and either byte order (the file layer is
//! `crate::vtk_xml`); any of Int8 to Int64, UInt8 to UInt64, Float32 and
//! Float64.
//!
//! `.pvtu`: the `<Piece Source="...">` files (paths relative to the
//! `.pvtu`) are read as above and concatenated; then points with
//! bit-identical coordinates are merged (`RawCells::weld`), so the cells of
//! neighbouring pieces share vertex indices, the quad-diagonal rule of
//! `cells` cuts their common faces alike and the face adjacency closes
//! across pieces. Ghost cells (a `vtkGhostType` cell array, non-zero
//! entries) are dropped from every piece: their owner piece holds them.
//!
//! The scalar: the point array named by the caller (`--scalar NAME`), else
//! the `PointData`'s active `Scalars`, else the first point array; arrays of
//! several components become their magnitude. Cell data is not converted: a
//! named array that exists only as cell data is refused with a message
//! saying so. Cells are split into tets by `cells`.

use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};

use super::cells::RawCells;
use super::TetMesh;
use crate::volume::decode::Endian;
use crate::vtk_xml::{array_payload, root_layout, split_appended, Layout};

/// Reads a `.vtu` or `.pvtu` file (by extension) into a tet mesh, with the
/// point array `array` as the scalar (`None`: see the module docs).
pub fn read_vtu(path: impl AsRef<Path>, array: Option<&str>) -> Result<TetMesh> {
    let path = path.as_ref();
    let name = path.display().to_string();
    let stem = stem_of(&name);
    let parallel = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("pvtu"));
    let raw = if parallel {
        let bytes = crate::fsio::read_input(path, "VTK XML parallel unstructured grid", crate::fsio::MAX_INPUT_BYTES)?;
        let mut raw = RawCells::default();
        for piece in pvtu_sources(&name, &bytes)? {
            let p = path.parent().unwrap_or(Path::new(".")).join(&piece);
            let pname = p.display().to_string();
            let bytes = crate::fsio::read_input(&p, "VTK XML unstructured grid (a piece of a .pvtu)", crate::fsio::MAX_INPUT_BYTES)
                .with_context(|| format!("{name}: piece '{piece}'"))?;
            raw.append(parse_vtu_raw(&pname, &bytes, array)?).map_err(|e| anyhow!("{name}: {e}"))?;
        }
        raw.weld();
        raw
    } else {
        let bytes = crate::fsio::read_input(path, "VTK XML unstructured grid", crate::fsio::MAX_INPUT_BYTES)?;
        parse_vtu_raw(&name, &bytes, array)?
    };
    raw.into_tet_mesh(&name, stem)
}

/// [`read_vtu`] of a `.vtu` already in memory (`name` starts every error).
pub fn parse_vtu_bytes(name: &str, bytes: &[u8], array: Option<&str>) -> Result<TetMesh> {
    parse_vtu_raw(name, bytes, array)?.into_tet_mesh(name, stem_of(name))
}

fn stem_of(name: &str) -> String {
    Path::new(name).file_stem().map_or_else(|| "vtu".to_string(), |s| s.to_string_lossy().into_owned())
}

/// The piece file names of a `.pvtu`.
fn pvtu_sources(name: &str, bytes: &[u8]) -> Result<Vec<String>> {
    let parts = split_appended(name, bytes)?;
    let doc = roxmltree::Document::parse(&parts.xml).map_err(|e| anyhow!("{name}: bad XML: {e}"))?;
    root_layout(name, doc.root_element(), "PUnstructuredGrid")?;
    let grid = doc
        .root_element()
        .children()
        .find(|n| n.has_tag_name("PUnstructuredGrid"))
        .ok_or_else(|| anyhow!("{name}: no <PUnstructuredGrid> element"))?;
    let sources: Vec<String> = grid
        .children()
        .filter(|n| n.has_tag_name("Piece"))
        .map(|n| n.attribute("Source").map(str::to_string).ok_or_else(|| anyhow!("{name}: a <Piece> has no Source")))
        .collect::<Result<_>>()?;
    if sources.is_empty() {
        bail!("{name}: no <Piece Source=...> elements");
    }
    Ok(sources)
}

/// A DataArray's value type.
#[derive(Debug, Clone, Copy, PartialEq)]
enum XType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl XType {
    fn parse(name: &str, what: &str, t: &str) -> Result<XType> {
        Ok(match t {
            "Int8" | "Char" => XType::I8,
            "UInt8" | "UChar" => XType::U8,
            "Int16" => XType::I16,
            "UInt16" => XType::U16,
            "Int32" => XType::I32,
            "UInt32" => XType::U32,
            "Int64" | "IdType" => XType::I64,
            "UInt64" => XType::U64,
            "Float32" => XType::F32,
            "Float64" => XType::F64,
            _ => bail!("{name}: {what} has unsupported type '{t}'; supported: Int8..Int64, UInt8..UInt64, Float32, Float64"),
        })
    }
    fn size(self) -> usize {
        match self {
            XType::I8 | XType::U8 => 1,
            XType::I16 | XType::U16 => 2,
            XType::I32 | XType::U32 | XType::F32 => 4,
            XType::I64 | XType::U64 | XType::F64 => 8,
        }
    }
    fn is_float(self) -> bool {
        matches!(self, XType::F32 | XType::F64)
    }
}

/// A value as read: integers exactly, floats as f64.
#[derive(Clone, Copy)]
enum Value {
    Int(i128),
    Float(f64),
}

fn decode(c: &[u8], t: XType, e: Endian) -> Value {
    macro_rules! w {
        ($ty:ty, $n:literal) => {{
            let a: [u8; $n] = std::array::from_fn(|i| c[i]);
            match e {
                Endian::Little => <$ty>::from_le_bytes(a),
                Endian::Big => <$ty>::from_be_bytes(a),
            }
        }};
    }
    match t {
        XType::I8 => Value::Int(c[0] as i8 as i128),
        XType::U8 => Value::Int(c[0] as i128),
        XType::I16 => Value::Int(w!(i16, 2) as i128),
        XType::U16 => Value::Int(w!(u16, 2) as i128),
        XType::I32 => Value::Int(w!(i32, 4) as i128),
        XType::U32 => Value::Int(w!(u32, 4) as i128),
        XType::I64 => Value::Int(w!(i64, 8) as i128),
        XType::U64 => Value::Int(w!(u64, 8) as i128),
        XType::F32 => Value::Float(w!(f32, 4) as f64),
        XType::F64 => Value::Float(w!(f64, 8)),
    }
}

/// One piece's file-level context.
struct Ctx<'d, 'a> {
    name: &'d str,
    doc: &'d roxmltree::Document<'d>,
    appended: Option<&'d (String, &'a [u8])>,
    layout: Layout,
}

impl Ctx<'_, '_> {
    /// Exactly `count` values of a DataArray, checked against its type.
    fn values(&self, what: &str, node: roxmltree::Node, count: usize) -> Result<Vec<Value>> {
        let name = self.name;
        let ty_name = node.attribute("type").ok_or_else(|| anyhow!("{name}: {what} has no type"))?;
        let ty = XType::parse(name, what, ty_name)?;
        let expected = count.checked_mul(ty.size()).ok_or_else(|| anyhow!("{name}: {what}: {count} values overflow the byte count"))?;
        if let Some(bytes) = array_payload(name, what, node, self.doc, self.appended, self.layout, expected)? {
            return Ok(bytes.chunks_exact(ty.size()).map(|c| decode(c, ty, self.layout.endian)).collect());
        }
        let text = node.text().unwrap_or("");
        // Each ASCII value takes at least two bytes with its separator.
        if count > text.len() / 2 + 1 {
            bail!("{name}: {what} needs {count} values, its text has only {} bytes", text.len());
        }
        let mut out = Vec::with_capacity(count);
        for (i, t) in text.split_ascii_whitespace().enumerate() {
            if i == count {
                bail!("{name}: {what} holds more than the {count} values it should");
            }
            let v = if ty.is_float() {
                let v: f64 = t.parse().map_err(|_| anyhow!("{name}: value '{t}' in {what} (value {i} of {count}) is not a number"))?;
                if ty == XType::F32 && v.is_finite() && v.abs() > f32::MAX as f64 {
                    bail!("{name}: value '{t}' in {what} is beyond the range of Float32");
                }
                Value::Float(v)
            } else {
                let v: i128 = t.parse().map_err(|_| anyhow!("{name}: value '{t}' in {what} (value {i} of {count}) is not an integer ({ty_name})"))?;
                let fits = match ty {
                    XType::I8 => i8::try_from(v).is_ok(),
                    XType::U8 => u8::try_from(v).is_ok(),
                    XType::I16 => i16::try_from(v).is_ok(),
                    XType::U16 => u16::try_from(v).is_ok(),
                    XType::I32 => i32::try_from(v).is_ok(),
                    XType::U32 => u32::try_from(v).is_ok(),
                    XType::I64 => i64::try_from(v).is_ok(),
                    _ => u64::try_from(v).is_ok(),
                };
                if !fits {
                    bail!("{name}: value {v} in {what} does not fit its type {ty_name}");
                }
                Value::Int(v)
            };
            out.push(v);
        }
        if out.len() != count {
            bail!("{name}: {what} needs {count} values, found {}", out.len());
        }
        Ok(out)
    }

    fn floats(&self, what: &str, node: roxmltree::Node, count: usize) -> Result<Vec<f64>> {
        Ok(self.values(what, node, count)?.into_iter().map(|v| match v {
            Value::Int(i) => i as f64,
            Value::Float(f) => f,
        }).collect())
    }

    /// Integer values in `0..=max`.
    fn ints(&self, what: &str, node: roxmltree::Node, count: usize, max: u64) -> Result<Vec<u64>> {
        let name = self.name;
        self.values(what, node, count)?
            .into_iter()
            .enumerate()
            .map(|(i, v)| match v {
                Value::Int(x) if x >= 0 && x as u128 <= max as u128 => Ok(x as u64),
                Value::Int(x) => bail!("{name}: {what} value {i} is {x}, outside 0..={max}"),
                Value::Float(_) => bail!("{name}: {what} must have an integer type"),
            })
            .collect()
    }
}

fn components(name: &str, node: roxmltree::Node) -> Result<usize> {
    let s = node.attribute("NumberOfComponents").unwrap_or("1");
    s.trim().parse::<usize>().ok().filter(|&k| (1..=64).contains(&k)).ok_or_else(|| {
        anyhow!("{name}: DataArray '{}' has a bad NumberOfComponents '{s}'", node.attribute("Name").unwrap_or("?"))
    })
}

fn count_attr(name: &str, node: roxmltree::Node, attr: &str) -> Result<usize> {
    let s = node.attribute(attr).ok_or_else(|| anyhow!("{name}: <Piece> has no {attr}"))?;
    s.trim()
        .parse::<usize>()
        .ok()
        .filter(|&n| n < u32::MAX as usize)
        .ok_or_else(|| anyhow!("{name}: bad {attr} '{s}' (a count below 2^32 is needed)"))
}

/// Parses one `.vtu`'s pieces into raw cells (not yet split).
fn parse_vtu_raw(name: &str, bytes: &[u8], array: Option<&str>) -> Result<RawCells> {
    let parts = split_appended(name, bytes)?;
    let doc = roxmltree::Document::parse(&parts.xml).map_err(|e| anyhow!("{name}: bad XML: {e}"))?;
    let layout = root_layout(name, doc.root_element(), "UnstructuredGrid")?;
    let ctx = Ctx { name, doc: &doc, appended: parts.appended.as_ref(), layout };
    let grid = doc
        .root_element()
        .children()
        .find(|n| n.has_tag_name("UnstructuredGrid"))
        .ok_or_else(|| anyhow!("{name}: no <UnstructuredGrid> element"))?;
    let pieces: Vec<_> = grid.children().filter(|n| n.has_tag_name("Piece")).collect();
    if pieces.is_empty() {
        bail!("{name}: <UnstructuredGrid> has no <Piece>");
    }
    let mut raw = RawCells::default();
    for (k, piece) in pieces.iter().enumerate() {
        let pname = if pieces.len() > 1 { format!("{name} (piece {k})") } else { name.to_string() };
        raw.append(parse_piece(&ctx, &pname, *piece, array)?).map_err(|e| anyhow!("{name}: {e}"))?;
    }
    Ok(raw)
}

fn child<'a, 'i>(name: &str, node: roxmltree::Node<'a, 'i>, tag: &str) -> Result<roxmltree::Node<'a, 'i>> {
    node.children().find(|n| n.has_tag_name(tag)).ok_or_else(|| anyhow!("{name}: the piece has no <{tag}>"))
}

fn arrays<'a, 'i>(node: Option<roxmltree::Node<'a, 'i>>) -> Vec<roxmltree::Node<'a, 'i>> {
    node.map_or_else(Vec::new, |n| n.children().filter(|c| c.has_tag_name("DataArray")).collect())
}

fn parse_piece(ctx: &Ctx, name: &str, piece: roxmltree::Node, array: Option<&str>) -> Result<RawCells> {
    let np = count_attr(name, piece, "NumberOfPoints")?;
    let nc = count_attr(name, piece, "NumberOfCells")?;

    let points_node = child(name, piece, "Points")?;
    let pa = arrays(Some(points_node));
    let pa = pa.first().ok_or_else(|| anyhow!("{name}: <Points> has no DataArray"))?;
    if components(name, *pa)? != 3 {
        bail!("{name}: the Points array has {} components, not 3", components(name, *pa)?);
    }
    let xyz = ctx.floats("the Points array", *pa, np.checked_mul(3).ok_or_else(|| anyhow!("{name}: too many points"))?)?;
    let points: Vec<[f64; 3]> = xyz.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();

    // ---- the scalar
    let pd = piece.children().find(|n| n.has_tag_name("PointData"));
    let cd = piece.children().find(|n| n.has_tag_name("CellData"));
    let (pd_arrays, cd_arrays) = (arrays(pd), arrays(cd));
    let list = |v: &[roxmltree::Node]| {
        let s: Vec<String> = v
            .iter()
            .map(|a| format!("'{}' ({} components)", a.attribute("Name").unwrap_or("?"), a.attribute("NumberOfComponents").unwrap_or("1")))
            .collect();
        if s.is_empty() { "none".to_string() } else { s.join(", ") }
    };
    let listing = || format!("point arrays: {}; cell arrays: {}", list(&pd_arrays), list(&cd_arrays));
    let chosen = match array.or(pd.and_then(|p| p.attribute("Scalars"))) {
        Some(want) => match pd_arrays.iter().find(|a| a.attribute("Name") == Some(want)) {
            Some(a) => *a,
            None if cd_arrays.iter().any(|a| a.attribute("Name") == Some(want)) => {
                bail!("{name}: {}; {}", super::vtk::cell_data_refusal(want), listing())
            }
            None => bail!("{name}: no point array named '{want}'; {}", listing()),
        },
        None => *pd_arrays.first().ok_or_else(|| anyhow!("{name}: no point data array to use as the scalar; {}", listing()))?,
    };
    let aname = chosen.attribute("Name").unwrap_or("(unnamed)");
    let k = components(name, chosen)?;
    let what = format!("point array '{aname}'");
    let vals = ctx.floats(&what, chosen, np.checked_mul(k).ok_or_else(|| anyhow!("{name}: {what} is too large"))?)?;
    let scalars: Vec<f64> = if k == 1 { vals } else { vals.chunks_exact(k).map(|c| c.iter().map(|x| x * x).sum::<f64>().sqrt()).collect() };

    // ---- cells
    let cells = child(name, piece, "Cells")?;
    let ca = arrays(Some(cells));
    let find = |n: &str| {
        ca.iter().find(|a| a.attribute("Name") == Some(n)).copied().ok_or_else(|| anyhow!("{name}: <Cells> has no '{n}' array"))
    };
    let types = ctx.ints("the cell types", find("types")?, nc, 255)?;
    let offsets = ctx.ints("the cell offsets", find("offsets")?, nc, u32::MAX as u64)?;
    let conn_len = offsets.last().copied().unwrap_or(0) as usize;
    if offsets.windows(2).any(|w| w[1] < w[0]) {
        bail!("{name}: the cell offsets do not rise");
    }
    let conn = ctx.ints("the cell connectivity", find("connectivity")?, conn_len, u32::MAX as u64 - 1)?;
    let mut types: Vec<u8> = types.into_iter().map(|t| t as u8).collect();
    let mut offsets: Vec<usize> = std::iter::once(0).chain(offsets.into_iter().map(|o| o as usize)).collect();
    let mut conn: Vec<u32> = conn.into_iter().map(|v| v as u32).collect();

    // Ghost cells belong to a neighbouring piece: drop them.
    if let Some(g) = cd_arrays.iter().find(|a| a.attribute("Name") == Some("vtkGhostType")) {
        let ghost = ctx.ints("the vtkGhostType cell array", *g, nc, 255)?;
        if ghost.iter().any(|&v| v != 0) {
            let (mut t2, mut o2, mut c2) = (Vec::new(), vec![0], Vec::new());
            for c in (0..nc).filter(|&c| ghost[c] == 0) {
                t2.push(types[c]);
                c2.extend_from_slice(&conn[offsets[c]..offsets[c + 1]]);
                o2.push(c2.len());
            }
            (types, offsets, conn) = (t2, o2, c2);
        }
    }
    Ok(RawCells { points, scalars, types, offsets, conn })
}
