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
//! saying so. Cells are split into tets by `tetrahedralize` (polyhedra:
//! VTK 9.4+'s `face_connectivity` / `face_offsets` / `polyhedron_to_faces` /
//! `polyhedron_offsets` arrays or the older `faces` / `faceoffsets`).

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
    let mut faces = if types.contains(&super::polyhedron::VTK_POLYHEDRON) {
        poly_faces(ctx, name, &ca, &types, np)?
    } else {
        Default::default()
    };

    // Ghost cells belong to a neighbouring piece: drop them.
    if let Some(g) = cd_arrays.iter().find(|a| a.attribute("Name") == Some("vtkGhostType")) {
        let ghost = ctx.ints("the vtkGhostType cell array", *g, nc, 255)?;
        if ghost.iter().any(|&v| v != 0) {
            faces.retain_cells(&ghost.iter().map(|&g| g == 0).collect::<Vec<bool>>());
            let (mut t2, mut o2, mut c2) = (Vec::new(), vec![0], Vec::new());
            for c in (0..nc).filter(|&c| ghost[c] == 0) {
                t2.push(types[c]);
                c2.extend_from_slice(&conn[offsets[c]..offsets[c + 1]]);
                o2.push(c2.len());
            }
            (types, offsets, conn) = (t2, o2, c2);
        }
    }
    Ok(RawCells { points, scalars, types, offsets, conn, faces })
}

/// The faces of a piece's polyhedra (type 42), from VTK 9.4+'s
/// `face_connectivity` / `face_offsets` / `polyhedron_to_faces` /
/// `polyhedron_offsets` arrays or the older `faces` / `faceoffsets` (each
/// polyhedron's face stream, `faceoffsets` its end, -1 for other cells).
fn poly_faces(ctx: &Ctx, name: &str, ca: &[roxmltree::Node], types: &[u8], np: usize) -> Result<super::polyhedron::PolyFaces> {
    use super::polyhedron::{parse_face_stream, PolyFaces, VTK_POLYHEDRON};
    let nc = types.len();
    let find = |n: &str| ca.iter().find(|a| a.attribute("Name") == Some(n)).copied();
    let signed = |what: &str, node: roxmltree::Node, count: usize| -> Result<Vec<i64>> {
        ctx.values(what, node, count)?
            .into_iter()
            .enumerate()
            .map(|(i, v)| match v {
                Value::Int(x) if (-1..=u32::MAX as i128).contains(&x) => Ok(x as i64),
                Value::Int(x) => bail!("{name}: {what} value {i} is {x}, outside -1..={}", u32::MAX),
                Value::Float(_) => bail!("{name}: {what} must have an integer type"),
            })
            .collect()
    };
    let rising = |what: &str, v: &[i64], from: i64| -> Result<()> {
        let mut last = from;
        for (i, &x) in v.iter().enumerate() {
            if x < last {
                bail!("{name}: {what} value {i} is {x}, below the previous offset {last}: offsets must rise");
            }
            last = x;
        }
        Ok(())
    };
    let mut out = PolyFaces::default();
    if let (Some(fc), Some(fo), Some(pf), Some(po)) =
        (find("face_connectivity"), find("face_offsets"), find("polyhedron_to_faces"), find("polyhedron_offsets"))
    {
        let poff = ctx.ints("the polyhedron_offsets array", po, nc, u32::MAX as u64)?;
        let poff: Vec<i64> = poff.into_iter().map(|x| x as i64).collect();
        rising("the polyhedron_offsets array", &poff, 0)?;
        let n_refs = poff.last().copied().unwrap_or(0) as usize;
        let p2f = ctx.ints("the polyhedron_to_faces array", pf, n_refs, u32::MAX as u64 - 1)?;
        // The faces are those the polyhedra name.
        let n_faces = p2f.iter().max().map_or(0, |&m| m as usize + 1);
        let foff = ctx.ints("the face_offsets array", fo, n_faces, u32::MAX as u64)?;
        let foff: Vec<i64> = foff.into_iter().map(|x| x as i64).collect();
        rising("the face_offsets array", &foff, 0)?;
        let fconn = ctx.ints("the face_connectivity array", fc, foff.last().copied().unwrap_or(0) as usize, np.saturating_sub(1) as u64)
            .map_err(|e| anyhow!("{e:#} (a face names a point the piece does not have)"))?;
        let face = |f: usize| -> Vec<u32> {
            let a = if f == 0 { 0 } else { foff[f - 1] as usize };
            fconn[a..foff[f] as usize].iter().map(|&v| v as u32).collect()
        };
        for c in 0..nc {
            let a = if c == 0 { 0 } else { poff[c - 1] as usize };
            let b = poff[c] as usize;
            if types[c] == VTK_POLYHEDRON {
                let fs: Vec<Vec<u32>> = p2f[a..b].iter().map(|&f| face(f as usize)).collect();
                out.push_cell(c, &fs);
            } else if b > a {
                bail!("{name}: cell {c} is not a polyhedron but polyhedron_offsets gives it {} faces", b - a);
            }
        }
    } else if let (Some(f), Some(fo)) = (find("faces"), find("faceoffsets")) {
        let foff = signed("the faceoffsets array", fo, nc)?;
        let n = foff.iter().copied().max().unwrap_or(0).max(0) as usize;
        let stream = signed("the faces array", f, n)?;
        let mut start = 0usize;
        for c in 0..nc {
            let end = foff[c];
            if types[c] != VTK_POLYHEDRON {
                if end != -1 {
                    bail!("{name}: cell {c} is not a polyhedron but its faceoffsets entry is {end}, not -1");
                }
                continue;
            }
            if end < start as i64 {
                bail!("{name}: cell {c}: its faceoffsets entry {end} is before the end of the previous face stream ({start})");
            }
            let fs = parse_face_stream(&stream[start..end as usize], np)
                .map_err(|e| anyhow!("{name}: cell {c} (polyhedron, type 42): {e}"))?;
            out.push_cell(c, &fs);
            start = end as usize;
        }
    } else {
        bail!(
            "{name}: the piece has polyhedron cells (type 42) but <Cells> has neither the face_connectivity, \
             face_offsets, polyhedron_to_faces and polyhedron_offsets arrays nor the older faces and faceoffsets"
        );
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::adjacency::FaceAdjacency;
    use crate::mesh::TetGeometry;
    use base64::Engine;
    use std::io::Write;

    /// A 2x2x1 block: a hexahedron, a voxel, two wedges and a pyramid over a
    /// hex-sized hole... kept exactly space-filling: cells 0..3 fill four
    /// unit cubes of a 2x2x1 grid (the fourth as two wedges), plus a
    /// pyramid on top of the first cube (apex above it).
    struct Grid {
        points: Vec<[f64; 3]>,
        scalar: Vec<f64>,
        velocity: Vec<[f64; 3]>,
        cells: Vec<(u8, Vec<u32>)>,
    }

    fn grid() -> Grid {
        let mut points = Vec::new();
        for k in 0..2 {
            for j in 0..3 {
                for i in 0..3 {
                    points.push([i as f64, j as f64, k as f64]);
                }
            }
        }
        points.push([0.5, 0.5, 2.0]); // pyramid apex, point 18
        let p = |i: u32, j: u32, k: u32| i + 3 * j + 9 * k;
        let hex = |i: u32, j: u32| {
            vec![p(i, j, 0), p(i + 1, j, 0), p(i + 1, j + 1, 0), p(i, j + 1, 0), p(i, j, 1), p(i + 1, j, 1), p(i + 1, j + 1, 1), p(i, j + 1, 1)]
        };
        let h0 = hex(0, 0);
        let h1 = hex(1, 0);
        let h2 = hex(0, 1);
        let h3 = hex(1, 1);
        let mut cells = vec![
            (12u8, h0.clone()),
            (11u8, vec![h1[0], h1[1], h1[3], h1[2], h1[4], h1[5], h1[7], h1[6]]),
            (12u8, h2),
        ];
        // h3's bottom/top faces are cut 0-2 / 4-6 by the rule (their smallest index is corner 0 / 4).
        cells.push((13, vec![h3[0], h3[1], h3[2], h3[4], h3[5], h3[6]]));
        cells.push((13, vec![h3[0], h3[2], h3[3], h3[4], h3[6], h3[7]]));
        cells.push((14, vec![h0[4], h0[5], h0[6], h0[7], 18]));
        cells.push((5, vec![0, 1, 2])); // a triangle: skipped
        let scalar = points.iter().map(|q| q[0] + 2.0 * q[1] + 3.0 * q[2]).collect();
        let velocity = points.iter().map(|q| [q[0], 0.0, q[2]]).collect();
        Grid { points, scalar, velocity, cells }
    }

    #[derive(Clone, Copy, Debug)]
    enum Format {
        Ascii,
        Binary,
        Appended,
        AppendedBase64,
    }

    /// Encodes an array's bytes as VTK does: a header of `word`-byte words
    /// (`[n]`, or zlib blocks `[blocks, block, last, sizes...]`) and the data.
    fn stream(data: &[u8], zlib: bool, word: usize, big: bool, block: usize) -> Vec<u8> {
        let w = |v: usize| -> Vec<u8> {
            match (word, big) {
                (4, false) => (v as u32).to_le_bytes().to_vec(),
                (4, true) => (v as u32).to_be_bytes().to_vec(),
                (_, false) => (v as u64).to_le_bytes().to_vec(),
                (_, true) => (v as u64).to_be_bytes().to_vec(),
            }
        };
        if !zlib {
            return [w(data.len()), data.to_vec()].concat();
        }
        let chunks: Vec<&[u8]> = data.chunks(block).collect();
        let comp: Vec<Vec<u8>> = chunks
            .iter()
            .map(|c| {
                let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
                e.write_all(c).unwrap();
                e.finish().unwrap()
            })
            .collect();
        let last = data.len() % block;
        let mut out = [w(chunks.len()), w(block), w(last)].concat();
        for c in &comp {
            out.extend(w(c.len()));
        }
        for c in comp {
            out.extend(c);
        }
        out
    }

    fn write_vtu(g: &Grid, f: Format, zlib: bool, word: usize, big: bool) -> Vec<u8> {
        let b64 = |b: &[u8]| base64::engine::general_purpose::STANDARD.encode(b);
        let mut appended: Vec<u8> = Vec::new();
        let mut body = String::new();
        let mut array = |name: &str, ty: &str, comps: usize, text: String, bytes: Vec<u8>| {
            let s = stream(&bytes, zlib, word, big, 40);
            let (fmt, inner) = match f {
                Format::Ascii => ("ascii".to_string(), text),
                Format::Binary => ("binary".to_string(), b64(&s)),
                Format::Appended | Format::AppendedBase64 => {
                    let off = appended.len();
                    appended.extend(if matches!(f, Format::Appended) { s } else { b64(&s).into_bytes() });
                    (format!("appended\" offset=\"{off}"), String::new())
                }
            };
            format!("<DataArray type=\"{ty}\" Name=\"{name}\" NumberOfComponents=\"{comps}\" format=\"{fmt}\">{inner}</DataArray>\n")
        };
        let f64s = |v: &[f64]| -> (String, Vec<u8>) {
            let t = v.iter().map(|x| format!("{x}")).collect::<Vec<_>>().join(" ");
            let b = v.iter().flat_map(|x| if big { x.to_be_bytes() } else { x.to_le_bytes() }).collect();
            (t, b)
        };
        let i64s = |v: &[i64]| -> (String, Vec<u8>) {
            let t = v.iter().map(|x| x.to_string()).collect::<Vec<_>>().join(" ");
            let b = v.iter().flat_map(|x| if big { x.to_be_bytes() } else { x.to_le_bytes() }).collect();
            (t, b)
        };
        let np = g.points.len();
        let nc = g.cells.len();
        body.push_str(&format!("<Piece NumberOfPoints=\"{np}\" NumberOfCells=\"{nc}\">\n<PointData Scalars=\"temp\">\n"));
        let (t, b) = f64s(&g.scalar);
        body.push_str(&array("temp", "Float64", 1, t, b));
        let (t, b) = f64s(&g.velocity.concat());
        body.push_str(&array("velocity", "Float64", 3, t, b));
        body.push_str("</PointData>\n<CellData>\n");
        let ids: Vec<i64> = (0..nc as i64).collect();
        let (t, b) = i64s(&ids);
        body.push_str(&array("cellid", "Int64", 1, t, b));
        body.push_str("</CellData>\n<Points>\n");
        let (t, b) = f64s(&g.points.concat());
        body.push_str(&array("Points", "Float64", 3, t, b));
        body.push_str("</Points>\n<Cells>\n");
        let conn: Vec<i64> = g.cells.iter().flat_map(|c| c.1.iter().map(|&v| v as i64)).collect();
        let offsets: Vec<i64> = g.cells.iter().scan(0, |o, c| { *o += c.1.len() as i64; Some(*o) }).collect();
        let (t, b) = i64s(&conn);
        body.push_str(&array("connectivity", "Int64", 1, t, b));
        let (t, b) = i64s(&offsets);
        body.push_str(&array("offsets", "Int64", 1, t, b));
        let types: Vec<u8> = g.cells.iter().map(|c| c.0).collect();
        let t = types.iter().map(|x| x.to_string()).collect::<Vec<_>>().join(" ");
        body.push_str(&array("types", "UInt8", 1, t, types.clone()));
        body.push_str("</Cells>\n</Piece>\n");
        let order = if big { "BigEndian" } else { "LittleEndian" };
        let header = if word == 8 { "UInt64" } else { "UInt32" };
        let comp = if zlib { " compressor=\"vtkZLibDataCompressor\"" } else { "" };
        let mut out = format!(
            "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"{order}\" header_type=\"{header}\"{comp}>\n<UnstructuredGrid>\n{body}</UnstructuredGrid>\n"
        )
        .into_bytes();
        if !appended.is_empty() {
            let enc = if matches!(f, Format::Appended) { "raw" } else { "base64" };
            out.extend(format!("<AppendedData encoding=\"{enc}\">\n_").into_bytes());
            out.extend(appended);
            out.extend(b"\n</AppendedData>\n");
        }
        out.extend(b"</VTKFile>\n");
        out
    }

    fn check_mesh(m: &TetMesh, what: &str) {
        // 2 hexes x 5 or 6, a voxel, 2 wedges x 3, a pyramid x 2; the triangle skipped.
        assert_eq!(m.stats.skipped_lower_dim, 1, "{what}");
        assert_eq!(m.stats.reoriented, 0, "{what}");
        let vol = TetGeometry::compute(m).total_volume();
        assert!((vol - (4.0 + 1.0 / 3.0)).abs() < 1e-12, "{what}: volume {vol}");
        let adj = FaceAdjacency::build(&m.tets, None, |_| true);
        // Surface: 2x2 bottom, 3 top quads + 4 pyramid sides, 8 side quads: 2 triangles per quad.
        assert_eq!(adj.boundary.len(), 2 * (4 + 3 + 8) + 4, "{what}: cracks");
        assert_eq!(m.scalars.len(), m.points.len());
    }

    #[test]
    fn every_encoding_reads_the_same_mesh() {
        let g = grid();
        let reference = parse_vtu_bytes("g.vtu", &write_vtu(&g, Format::Ascii, false, 4, false), None).unwrap();
        check_mesh(&reference, "ascii");
        assert_eq!(reference.scalars, g.scalar);
        for f in [Format::Ascii, Format::Binary, Format::Appended, Format::AppendedBase64] {
            for zlib in [false, true] {
                for word in [4, 8] {
                    for big in [false, true] {
                        let what = format!("{f:?} zlib {zlib} header {word} big-endian {big}");
                        let bytes = write_vtu(&g, f, zlib, word, big);
                        let m = parse_vtu_bytes("g.vtu", &bytes, None).unwrap_or_else(|e| panic!("{what}: {e:#}"));
                        assert_eq!(m.tets, reference.tets, "{what}");
                        assert_eq!(m.points, reference.points, "{what}");
                        assert_eq!(m.scalars, reference.scalars, "{what}");
                        // Every truncation is an error naming the file, never a panic.
                        for cut in (0..bytes.len()).step_by(97) {
                            if let Err(e) = parse_vtu_bytes("cut.vtu", &bytes[..cut], None) {
                                assert!(format!("{e:#}").starts_with("cut.vtu"), "{what}: {e:#}");
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn scalar_choice_and_refusals() {
        let g = grid();
        let bytes = write_vtu(&g, Format::Binary, true, 8, false);
        let m = parse_vtu_bytes("g.vtu", &bytes, Some("velocity")).unwrap();
        let want: Vec<f64> = g.velocity.iter().map(|v| (v[0] * v[0] + v[2] * v[2]).sqrt()).collect();
        assert_eq!(m.scalars, want);
        let e = format!("{:#}", parse_vtu_bytes("g.vtu", &bytes, Some("cellid")).unwrap_err());
        assert!(e.contains("'cellid' is cell data") && e.contains("Cell Data to Point Data"), "{e}");
        let e = format!("{:#}", parse_vtu_bytes("g.vtu", &bytes, Some("nope")).unwrap_err());
        assert!(e.contains("no point array named 'nope'") && e.contains("'temp' (1 components)"), "{e}");
        // Unsupported cells are named with their counts.
        let mut q = grid();
        q.cells.push((41, (0..10).collect()));
        q.cells.push((41, (0..10).collect()));
        q.cells.push((55, (0..4).collect()));
        let e = format!("{:#}", parse_vtu_bytes("q.vtu", &write_vtu(&q, Format::Ascii, false, 4, false), None).unwrap_err());
        assert!(e.contains("2 cells of type 41 (convex point set)") && e.contains("1 cells of type 55 (parametric tetra region)"), "{e}");
        assert!(e.contains("polyhedra (42)") && e.contains("Lagrange tetra, hexahedron and wedge (71-73)"), "{e}");
        // A polyhedron without the face arrays.
        let mut q = grid();
        q.cells.push((42, (0..4).collect()));
        let e = format!("{:#}", parse_vtu_bytes("q.vtu", &write_vtu(&q, Format::Ascii, false, 4, false), None).unwrap_err());
        assert!(e.contains("polyhedron cells (type 42) but <Cells> has neither"), "{e}");
        // A hexahedron with 7 vertices.
        let mut h = grid();
        h.cells[0].1.pop();
        let e = format!("{:#}", parse_vtu_bytes("h.vtu", &write_vtu(&h, Format::Ascii, false, 4, false), None).unwrap_err());
        assert!(e.contains("cell 0 is a hexahedron (type 12) but has 7 vertices"), "{e}");
        let bad = String::from_utf8(write_vtu(&g, Format::Ascii, false, 4, false)).unwrap().replace("UnstructuredGrid\" version", "ImageData\" version");
        let e = format!("{:#}", parse_vtu_bytes("i.vtu", bad.as_bytes(), None).unwrap_err());
        assert!(e.contains("is not UnstructuredGrid"), "{e}");
    }

    /// Two pieces, each with its own copy of every point: merged, the shared
    /// points weld and the faces between the pieces close.
    #[test]
    fn pvtu_pieces_weld() {
        let g = grid();
        let tmp = tempfile::tempdir().unwrap();
        let (a, b) = g.cells.split_at(3);
        for (i, cells) in [a, b].iter().enumerate() {
            let piece = Grid { points: g.points.clone(), scalar: g.scalar.clone(), velocity: g.velocity.clone(), cells: cells.to_vec() };
            std::fs::write(tmp.path().join(format!("p_{i}.vtu")), write_vtu(&piece, Format::Appended, true, 4, false)).unwrap();
        }
        let pvtu = "<?xml version=\"1.0\"?>\n<VTKFile type=\"PUnstructuredGrid\" version=\"1.0\">\n<PUnstructuredGrid GhostLevel=\"0\">\n\
                    <PPointData Scalars=\"temp\"><PDataArray type=\"Float64\" Name=\"temp\"/></PPointData>\n\
                    <PPoints><PDataArray type=\"Float64\" NumberOfComponents=\"3\"/></PPoints>\n\
                    <Piece Source=\"p_0.vtu\"/>\n<Piece Source=\"p_1.vtu\"/>\n</PUnstructuredGrid>\n</VTKFile>\n";
        let p = tmp.path().join("all.pvtu");
        std::fs::write(&p, pvtu).unwrap();
        let m = read_vtu(&p, None).unwrap();
        assert_eq!(m.name, "all");
        assert_eq!(m.points.len(), g.points.len());
        check_mesh(&m, "pvtu");
        std::fs::remove_file(tmp.path().join("p_1.vtu")).unwrap();
        let e = format!("{:#}", read_vtu(&p, None).unwrap_err());
        assert!(e.contains("all.pvtu") && e.contains("p_1.vtu"), "{e}");
    }

    /// The legacy reader splits the same cells the same way.
    #[test]
    fn legacy_file_with_mixed_cells() {
        let g = grid();
        let mut s = format!("# vtk DataFile Version 3.0\nmixed\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS {} double\n", g.points.len());
        for p in &g.points {
            s += &format!("{} {} {}\n", p[0], p[1], p[2]);
        }
        let size: usize = g.cells.iter().map(|c| c.1.len() + 1).sum();
        s += &format!("CELLS {} {size}\n", g.cells.len());
        for c in &g.cells {
            s += &format!("{} {}\n", c.1.len(), c.1.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(" "));
        }
        s += &format!("CELL_TYPES {}\n", g.cells.len());
        for c in &g.cells {
            s += &format!("{}\n", c.0);
        }
        s += &format!("POINT_DATA {}\nSCALARS temp double 1\nLOOKUP_TABLE default\n", g.points.len());
        for v in &g.scalar {
            s += &format!("{v}\n");
        }
        s += "VECTORS velocity double\n";
        for v in &g.velocity {
            s += &format!("{} {} {}\n", v[0], v[1], v[2]);
        }
        let m = crate::mesh::vtk::parse_vtk_bytes("m.vtk", s.as_bytes()).unwrap();
        check_mesh(&m, "legacy");
        let x = parse_vtu_bytes("g.vtu", &write_vtu(&g, Format::Ascii, false, 4, false), None).unwrap();
        assert_eq!(m.tets, x.tets);
        let v = crate::mesh::vtk::parse_vtk_bytes_array("m.vtk", s.as_bytes(), Some("velocity")).unwrap();
        assert_eq!(v.scalars[4], 1.0);
        let e = format!("{:#}", crate::mesh::vtk::parse_vtk_bytes_array("m.vtk", s.as_bytes(), Some("nope")).unwrap_err());
        assert!(e.contains("no point array named 'nope'"), "{e}");
    }

    /// Files VTK 9.7's vtkXMLUnstructuredGridWriter wrote (the fuzz seeds): a
    /// hexahedron, two wedges and a pyramid in four encodings read alike and
    /// close (VTK's own vtkDataSetTriangleFilter made 14 tets of them too).
    #[test]
    fn vtk_written_files() {
        let files: [(&str, &[u8]); 4] = [
            ("ascii", include_bytes!("../../fuzz/seeds/vtu/mixed_ascii.vtu")),
            ("binary zlib", include_bytes!("../../fuzz/seeds/vtu/mixed_binary_zlib.vtu")),
            ("appended raw UInt64 big-endian", include_bytes!("../../fuzz/seeds/vtu/mixed_appended_raw_u64_be.vtu")),
            ("appended zlib UInt64", include_bytes!("../../fuzz/seeds/vtu/mixed_appended_zlib_u64.vtu")),
        ];
        let first = parse_vtu_bytes("a.vtu", files[0].1, None).unwrap();
        for (what, bytes) in files {
            let m = parse_vtu_bytes("m.vtu", bytes, None).unwrap_or_else(|e| panic!("{what}: {e:#}"));
            assert_eq!(m.tets, first.tets, "{what}");
            assert_eq!(m.scalars, (0..13).map(|i| i as f64 * 0.5).collect::<Vec<_>>(), "{what}");
            assert_eq!(m.tets.len(), 14, "{what}");
            assert_eq!(m.stats.reoriented, 0, "{what}");
            let vol = TetGeometry::compute(&m).total_volume();
            assert!((vol - 7.0 / 3.0).abs() < 1e-12, "{what}: {vol}");
            let adj = FaceAdjacency::build(&m.tets, None, |_| true);
            assert_eq!(adj.boundary.len(), 22, "{what}: cracks");
        }
    }
}
