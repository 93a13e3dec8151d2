//! VTK XML unstructured grids: `.vtu` files and `.pvtu` parallel files.
//!
//! `.vtu`: every `<Piece>` of the `<UnstructuredGrid>` (concatenated),
//! `Points` and `Cells` (`connectivity`, `offsets`, `types`) and one point
//! array. Arrays may be `ascii`, inline `binary` (base64) or `appended`
//! (raw or base64), uncompressed or compressed by `vtkZLibDataCompressor`,
//! `vtkLZ4DataCompressor` or `vtkLZMADataCompressor`, with UInt32 or
//! UInt64 headers and either byte order (the file layer is
//! `crate::vtk_xml`); any of Int8 to Int64, UInt8 to UInt64, Float32 and
//! Float64.
//!
//! Memory: each array is opened first (its header, block sizes and bytes
//! present checked, and its data bytes charged to [`MAX_DECODED_BYTES`]),
//! then decoded value by value straight into its final vector (f64 points
//! and scalars, u32 connectivity, u8 types; a vector's magnitude summed as
//! it is read), a block or 64 KiB at a time, ASCII token by token: no
//! intermediate array of values, never the whole inflated array, and
//! nothing reserved beyond what the data present can hold.
//!
//! `.pvtu`: the `<Piece Source="...">` files (paths relative to the
//! `.pvtu`) are read as above and concatenated; then points with
//! bit-identical coordinates are merged (`RawCells::weld`), so the cells of
//! neighbouring pieces share vertex indices, the quad-diagonal rule of
//! `cells` cuts their common faces alike and the face adjacency closes
//! across pieces (`MeshStats::seam_points_merged`; copies whose scalars
//! differ keep the first piece's value, are counted in
//! `seam_scalar_mismatches` and noted). Before any piece is read, each must
//! be a distinct file (canonical paths compared: a piece listed twice is
//! refused) and all together within `fsio::MAX_INPUT_BYTES`.
//!
//! Ghosts (`vtkGhostType`, `RawCells::drop_ghosts`): cells marked
//! `DUPLICATECELL`, `REFINEDCELL` or `HIDDENCELL`, and cells using a point
//! marked `HIDDENPOINT`, are skipped as VTK's geometry filter does, and
//! counted (`ghost_cells`, `hidden_cells`, `ghost_points`).
//!
//! The scalar, chosen once per file: the array named by the caller
//! (`--scalar NAME`: a point array of that name, else a cell array), else
//! the `PointData`'s active `Scalars`, else the first point array, else (no
//! point data: noted by the caller) the `CellData`'s active `Scalars`, else
//! its first numeric one-component array that is not `vtkGhostType`, else
//! its first numeric array. Arrays of several
//! components become their magnitude; cell data is shown as `--cell-data`
//! says (`mesh::cell_data`). A `.pvtu` chooses among the arrays its
//! `PPointData` / `PCellData` declare (by the same rules), and every piece
//! must hold that array, with the same association and component count:
//! pieces are never mixed. A `.pvtu` that declares no arrays, and a `.vtu`
//! of several pieces, take the first piece's choice for all. Cells are split
//! into tets by `tetrahedralize` (polyhedra: VTK 9.4+'s `face_connectivity` /
//! `face_offsets` / `polyhedron_to_faces` / `polyhedron_offsets` arrays or
//! the older `faces` / `faceoffsets`).

use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};

use super::cell_data::{Association, ScalarChoice, ScalarInfo};
use super::cells::{PolyFaces, RawCells};
use super::{MeshStats, TetMesh};
use crate::bytes::Endian;
use crate::vtk_xml::{array_payload, root_layout, split_appended, visit, Appended, Layout, Payload};

/// Reads a `.vtu` or `.pvtu` file (by extension) into a tet mesh, with the
/// point array `array` as the scalar (`None`: see the module docs).
pub fn read_vtu(path: impl AsRef<Path>, array: Option<&str>) -> Result<TetMesh> {
    read_vtu_with(path, ScalarChoice { array, ..Default::default() })
}

/// [`read_vtu`] with the scalar chosen and cell data treated as `choice`
/// says (`mesh::cell_data`).
pub fn read_vtu_with(path: impl AsRef<Path>, choice: ScalarChoice) -> Result<TetMesh> {
    use crate::fsio::{check_input, read_input, MAX_INPUT_BYTES};
    let path = path.as_ref();
    let name = path.display().to_string();
    let stem = stem_of(&name);
    let parallel = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("pvtu"));
    let budget = Budget::new(MAX_DECODED_BYTES);
    let mut counts = MeshStats::default();
    let raw = if parallel {
        let bytes = read_input(path, "VTK XML parallel unstructured grid", MAX_INPUT_BYTES)?;
        let (sources, mut pick) = pvtu_sources(&name, &bytes, choice)?;
        drop(bytes);
        // Every piece once, and all of them together within the input cap,
        // checked from their metadata before any is read.
        let dir = path.parent().unwrap_or(Path::new("."));
        let what = "VTK XML unstructured grid (a piece of a .pvtu)";
        let mut seen: std::collections::HashMap<std::path::PathBuf, &str> = Default::default();
        let mut total = 0u64;
        for piece in &sources {
            let p = dir.join(piece);
            let len = check_input(&p, what, MAX_INPUT_BYTES).with_context(|| format!("{name}: piece '{piece}'"))?;
            let canonical = std::fs::canonicalize(&p).with_context(|| format!("{name}: piece '{piece}'"))?;
            if let Some(first) = seen.get(&canonical) {
                bail!(
                    "{name}: piece '{piece}' is the same file as piece '{first}' ({}); a .pvtu lists each piece once",
                    canonical.display()
                );
            }
            seen.insert(canonical, piece);
            total += len;
            if total > MAX_INPUT_BYTES {
                bail!("{name}: its pieces up to '{piece}' hold {total} bytes, more than the {MAX_INPUT_BYTES} bytes volbench reads for one mesh");
            }
        }
        let mut raw = RawCells::default();
        for piece in &sources {
            let p = dir.join(piece);
            let bytes = read_input(&p, what, MAX_INPUT_BYTES).with_context(|| format!("{name}: piece '{piece}'"))?;
            let part = parse_vtu_raw(&p.display().to_string(), &bytes, choice, pick.as_ref(), &budget, &mut counts)?;
            drop(bytes);
            pick = pick.or_else(|| part.scalar.clone());
            raw.append(part).map_err(|e| anyhow!("{name}: {e}"))?;
        }
        let (merged, mismatches) = raw.weld();
        counts.seam_points_merged = merged;
        counts.seam_scalar_mismatches = mismatches;
        if mismatches > 0 {
            crate::progress!(
                "{name}: note: {mismatches} of the {merged} points repeated on the pieces' seams have different scalars in \
                 different pieces; each keeps its first piece's value"
            );
        }
        raw
    } else {
        let bytes = read_input(path, "VTK XML unstructured grid", MAX_INPUT_BYTES)?;
        parse_vtu_raw(&name, &bytes, choice, None, &budget, &mut counts)?
    };
    let mut mesh = raw.into_tet_mesh(&name, stem)?;
    mesh.stats.add_read_counts(&counts);
    Ok(mesh)
}

/// [`read_vtu`] of a `.vtu` already in memory (`name` starts every error).
pub fn parse_vtu_bytes(name: &str, bytes: &[u8], array: Option<&str>) -> Result<TetMesh> {
    parse_vtu_bytes_with(name, bytes, ScalarChoice { array, ..Default::default() })
}

/// [`parse_vtu_bytes`] with the scalar chosen as `choice` says.
pub fn parse_vtu_bytes_with(name: &str, bytes: &[u8], choice: ScalarChoice) -> Result<TetMesh> {
    let mut counts = MeshStats::default();
    let raw = parse_vtu_raw(name, bytes, choice, None, &Budget::new(MAX_DECODED_BYTES), &mut counts)?;
    let mut mesh = raw.into_tet_mesh(name, stem_of(name))?;
    mesh.stats.add_read_counts(&counts);
    Ok(mesh)
}

fn stem_of(name: &str) -> String {
    Path::new(name).file_stem().map_or_else(|| "vtu".to_string(), |s| s.to_string_lossy().into_owned())
}

/// The piece file names of a `.pvtu`, and the scalar chosen among the
/// arrays it declares (`None` when it declares none: the first piece
/// decides).
fn pvtu_sources(name: &str, bytes: &[u8], choice: ScalarChoice) -> Result<(Vec<String>, Option<ScalarInfo>)> {
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
    let ppd = grid.children().find(|n| n.has_tag_name("PPointData"));
    let pcd = grid.children().find(|n| n.has_tag_name("PCellData"));
    let (pd, cd) = (tagged(ppd, "PDataArray"), tagged(pcd, "PDataArray"));
    if pd.is_empty() && cd.is_empty() {
        return Ok((sources, None));
    }
    let pick = choose(name, (ppd, &pd), (pcd, &cd), choice, "the .pvtu declares")?;
    Ok((sources, Some(pick)))
}

/// The scalar among a piece's (or a `.pvtu`'s declared) point and cell
/// arrays, by the rules of the module docs. `what` says whose arrays they
/// are, in the error.
fn choose(
    name: &str,
    (pd, pd_arrays): (Option<roxmltree::Node>, &[roxmltree::Node]),
    (cd, cd_arrays): (Option<roxmltree::Node>, &[roxmltree::Node]),
    choice: ScalarChoice,
    what: &str,
) -> Result<ScalarInfo> {
    let info = |a: &roxmltree::Node, association, fallback| -> Result<ScalarInfo> {
        Ok(ScalarInfo {
            array: a.attribute("Name").unwrap_or("(unnamed)").to_string(),
            association,
            components: components(name, *a)?,
            cell_data: (association == Association::Cell).then_some(choice.cell_data),
            fallback,
        })
    };
    match choice.array.or(pd.and_then(|p| p.attribute("Scalars"))) {
        Some(want) => match (named(pd_arrays, want), named(cd_arrays, want)) {
            (Some(a), _) => info(&a, Association::Point, false),
            (None, Some(a)) => info(&a, Association::Cell, false),
            (None, None) => bail!("{name}: {what} no point or cell array named '{want}'; {}", listing(pd_arrays, cd_arrays)),
        },
        None => {
            if let Some(a) = pd_arrays.first() {
                return info(a, Association::Point, false);
            }
            let numeric = |a: &&roxmltree::Node| {
                a.attribute("Name") != Some("vtkGhostType") && a.attribute("type").is_some_and(|t| XType::parse(name, "", t).is_ok())
            };
            let active = cd.and_then(|c| c.attribute("Scalars")).and_then(|w| named(cd_arrays, w));
            let one = |a: &&roxmltree::Node| numeric(a) && components(name, **a).is_ok_and(|k| k == 1);
            match active.or_else(|| cd_arrays.iter().find(one).or_else(|| cd_arrays.iter().find(numeric)).copied()) {
                Some(a) => info(&a, Association::Cell, true),
                None => bail!("{name}: {what} no point or numeric cell array to use as the scalar; {}", listing(pd_arrays, cd_arrays)),
            }
        }
    }
}

/// The array named `want` among `v`.
fn named<'a, 'i>(v: &[roxmltree::Node<'a, 'i>], want: &str) -> Option<roxmltree::Node<'a, 'i>> {
    v.iter().find(|a| a.attribute("Name") == Some(want)).copied()
}

/// "point arrays: 'a' (1 components), ...; cell arrays: ...".
fn listing(pd: &[roxmltree::Node], cd: &[roxmltree::Node]) -> String {
    let list = |v: &[roxmltree::Node]| {
        let s: Vec<String> = v
            .iter()
            .map(|a| format!("'{}' ({} components)", a.attribute("Name").unwrap_or("?"), a.attribute("NumberOfComponents").unwrap_or("1")))
            .collect();
        if s.is_empty() { "none".to_string() } else { s.join(", ") }
    };
    format!("point arrays: {}; cell arrays: {}", list(pd), list(cd))
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

/// A value as decoded: integers exactly, floats as f64. Values are handed
/// on one at a time as they are decoded, never stored in this form.
#[derive(Clone, Copy)]
enum Value {
    Int(i128),
    Float(f64),
}

fn decode(c: &[u8], t: XType, e: Endian) -> Value {
    match t {
        XType::I8 => Value::Int(c[0] as i8 as i128),
        XType::U8 => Value::Int(c[0] as i128),
        XType::I16 => Value::Int(e.read::<i16>(c) as i128),
        XType::U16 => Value::Int(e.read::<u16>(c) as i128),
        XType::I32 => Value::Int(e.read::<i32>(c) as i128),
        XType::U32 => Value::Int(e.read::<u32>(c) as i128),
        XType::I64 => Value::Int(e.read::<i64>(c) as i128),
        XType::U64 => Value::Int(e.read::<u64>(c) as i128),
        XType::F32 => Value::Float(e.read::<f32>(c) as f64),
        XType::F64 => Value::Float(e.read::<f64>(c)),
    }
}

impl Value {
    fn float(self) -> f64 {
        match self {
            Value::Int(i) => i as f64,
            Value::Float(f) => f,
        }
    }

    /// This integer value, in `0..=max`.
    fn int_in(self, name: &str, what: &str, i: usize, max: u64) -> Result<u64> {
        match self {
            Value::Int(x) if x >= 0 && x as u128 <= max as u128 => Ok(x as u64),
            Value::Int(x) => bail!("{name}: {what} value {i} is {x}, outside 0..={max}"),
            Value::Float(_) => bail!("{name}: {what} must have an integer type"),
        }
    }
}

/// Data bytes (count × the type's size, as the file stores them) one mesh
/// read may decode, over all its arrays and pieces: the input cap again,
/// so a compressed file cannot promise more than an uncompressed one may
/// hold. Charged from the declared counts before an array is allocated or
/// inflated.
pub const MAX_DECODED_BYTES: u64 = crate::fsio::MAX_INPUT_BYTES;

/// What is left of [`MAX_DECODED_BYTES`] for one read (shared by a
/// `.pvtu`'s pieces).
struct Budget(std::cell::Cell<u64>);

impl Budget {
    fn new(bytes: u64) -> Budget {
        Budget(std::cell::Cell::new(bytes))
    }
}

/// One piece's file-level context.
struct Ctx<'d, 'a> {
    name: &'d str,
    appended: Option<&'d Appended<'a>>,
    layout: Layout,
    budget: &'d Budget,
}

/// A `DataArray` opened for decoding: its header checked and its bytes
/// charged to the budget; nothing of its size allocated yet.
struct Array<'x> {
    name: &'x str,
    what: &'x str,
    ty: XType,
    ty_name: &'x str,
    endian: Endian,
    count: usize,
    body: Body<'x>,
}

enum Body<'x> {
    Ascii(&'x str),
    Binary(Payload<'x>),
}

impl<'d, 'a: 'd> Ctx<'d, 'a> {
    /// Opens a DataArray of exactly `count` values: its type, its header
    /// (binary: sizes and blocks checked, see `vtk_xml::Payload::open`) and
    /// its bytes against the budget, before anything is allocated.
    fn open<'x>(&'x self, what: &'x str, node: roxmltree::Node<'x, '_>, count: usize) -> Result<Array<'x>>
    where
        'd: 'x,
    {
        let name = self.name;
        let ty_name = node.attribute("type").ok_or_else(|| anyhow!("{name}: {what} has no type"))?;
        let ty = XType::parse(name, what, ty_name)?;
        let expected = count.checked_mul(ty.size()).ok_or_else(|| anyhow!("{name}: {what}: {count} values overflow the byte count"))?;
        let left = self.budget.0.get();
        if expected as u64 > left {
            bail!(
                "{name}: {what} declares {count} values ({expected} bytes); with the arrays before it that is more than the \
                 {MAX_DECODED_BYTES} bytes of data one mesh may hold"
            );
        }
        let body = match array_payload(name, what, node, self.appended, self.layout, expected)? {
            Some(p) => Body::Binary(p),
            None => {
                let text = node.text().unwrap_or("");
                // Each ASCII value takes at least two bytes with its separator.
                if count > text.len() / 2 + 1 {
                    bail!("{name}: {what} needs {count} values, its text has only {} bytes", text.len());
                }
                Body::Ascii(text)
            }
        };
        self.budget.0.set(left - expected as u64);
        Ok(Array { name, what, ty, ty_name, endian: self.layout.endian, count, body })
    }
}

impl Array<'_> {
    /// Hands every value, in order, to `f` (index, value): binary data a
    /// block or 64 KiB at a time, ASCII token by token (each checked
    /// against the declared type). Exactly `count` values, or an error.
    fn each(self, mut f: impl FnMut(usize, Value) -> Result<()>) -> Result<()> {
        let Array { name, what, ty, ty_name, endian, count, body } = self;
        match body {
            Body::Binary(payload) => {
                let size = ty.size();
                let (mut carry, mut have, mut i) = ([0u8; 8], 0usize, 0usize);
                payload.for_each_chunk(name, what, &mut |mut c: &[u8]| {
                    if have > 0 {
                        let k = (size - have).min(c.len());
                        carry[have..have + k].copy_from_slice(&c[..k]);
                        have += k;
                        c = &c[k..];
                        if have < size {
                            return Ok(());
                        }
                        f(i, decode(&carry[..size], ty, endian))?;
                        i += 1;
                        have = 0;
                    }
                    let mut it = c.chunks_exact(size);
                    for v in &mut it {
                        f(i, decode(v, ty, endian))?;
                        i += 1;
                    }
                    let r = it.remainder();
                    carry[..r.len()].copy_from_slice(r);
                    have = r.len();
                    Ok(())
                })?;
                if i != count {
                    bail!("{name}: {what} decodes to {i} values, {count} expected");
                }
            }
            Body::Ascii(text) => {
                let mut n = 0;
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
                        let v: i128 = t
                            .parse()
                            .map_err(|_| anyhow!("{name}: value '{t}' in {what} (value {i} of {count}) is not an integer ({ty_name})"))?;
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
                    f(i, v)?;
                    n += 1;
                }
                if n != count {
                    bail!("{name}: {what} needs {count} values, found {n}");
                }
            }
        }
        Ok(())
    }

    /// Values `f` may be handed, at most, as far as the data present can
    /// tell: reserve this many, not the declared count, for ASCII (bounded
    /// by its text); binary data's count was checked against its header
    /// and the bytes present (see `open`).
    fn capacity(&self) -> usize {
        match &self.body {
            Body::Ascii(text) => self.count.min(text.len() / 2 + 1),
            Body::Binary(p) => p.len() / self.ty.size(),
        }
    }

    /// Integer values in `0..=max`, into a vector of `T`.
    fn ints<T: TryFrom<u64>>(self, max: u64) -> Result<Vec<T>> {
        let (name, what) = (self.name, self.what);
        let mut out = Vec::with_capacity(self.capacity());
        self.each(|i, v| {
            let x = v.int_in(name, what, i, max)?;
            out.push(T::try_from(x).map_err(|_| anyhow!("{name}: {what} value {i} is {x}, too large"))?);
            Ok(())
        })?;
        Ok(out)
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

/// Parses one `.vtu`'s pieces into raw cells (not yet split), with the
/// scalar `pick` when it is decided (by a `.pvtu`), else chosen by the
/// first piece for all; ghost counts are added to `counts`.
fn parse_vtu_raw(
    name: &str,
    bytes: &[u8],
    choice: ScalarChoice,
    pick: Option<&ScalarInfo>,
    budget: &Budget,
    counts: &mut MeshStats,
) -> Result<RawCells> {
    let parts = split_appended(name, bytes)?;
    let doc = roxmltree::Document::parse(&parts.xml).map_err(|e| anyhow!("{name}: bad XML: {e}"))?;
    let layout = root_layout(name, doc.root_element(), "UnstructuredGrid")?;
    let appended = Appended::new(&doc, parts.appended.as_ref());
    let ctx = Ctx { name, appended: appended.as_ref(), layout, budget };
    let grid = doc
        .root_element()
        .children()
        .find(|n| n.has_tag_name("UnstructuredGrid"))
        .ok_or_else(|| anyhow!("{name}: no <UnstructuredGrid> element"))?;
    let pieces: Vec<_> = grid.children().inspect(|_| visit()).filter(|n| n.has_tag_name("Piece")).collect();
    if pieces.is_empty() {
        bail!("{name}: <UnstructuredGrid> has no <Piece>");
    }
    let mut raw = RawCells::default();
    let mut pick = pick.cloned();
    for (k, piece) in pieces.iter().enumerate() {
        let pname = if pieces.len() > 1 { format!("{name} (piece {k})") } else { name.to_string() };
        let part = parse_piece(&ctx, &pname, *piece, choice, pick.as_ref(), counts)?;
        pick = pick.or_else(|| part.scalar.clone());
        raw.append(part).map_err(|e| anyhow!("{name}: {e}"))?;
    }
    Ok(raw)
}

fn child<'a, 'i>(name: &str, node: roxmltree::Node<'a, 'i>, tag: &str) -> Result<roxmltree::Node<'a, 'i>> {
    node.children().inspect(|_| visit()).find(|n| n.has_tag_name(tag)).ok_or_else(|| anyhow!("{name}: the piece has no <{tag}>"))
}

fn arrays<'a, 'i>(node: Option<roxmltree::Node<'a, 'i>>) -> Vec<roxmltree::Node<'a, 'i>> {
    tagged(node, "DataArray")
}

/// The children of `node` with the tag `tag`.
fn tagged<'a, 'i>(node: Option<roxmltree::Node<'a, 'i>>, tag: &str) -> Vec<roxmltree::Node<'a, 'i>> {
    node.map_or_else(Vec::new, |n| n.children().inspect(|_| visit()).filter(|c| c.has_tag_name(tag)).collect())
}

/// One `<Piece>`: its points, its scalar (`pick`, the array the first
/// piece chose, else as `choice` says), its cells and their polyhedra's
/// faces, ghosts dropped (counted in `counts`).
fn parse_piece(
    ctx: &Ctx,
    name: &str,
    piece: roxmltree::Node,
    choice: ScalarChoice,
    pick: Option<&ScalarInfo>,
    counts: &mut MeshStats,
) -> Result<RawCells> {
    let np = count_attr(name, piece, "NumberOfPoints")?;
    let nc = count_attr(name, piece, "NumberOfCells")?;
    let ctx = Ctx { name, ..*ctx };
    let points = read_points(&ctx, piece, np)?;

    // ---- the scalar
    let pd = piece.children().find(|n| n.has_tag_name("PointData"));
    let cd = piece.children().find(|n| n.has_tag_name("CellData"));
    let (pd_arrays, cd_arrays) = (arrays(pd), arrays(cd));
    let info = match pick {
        None => choose(name, (pd, &pd_arrays), (cd, &cd_arrays), choice, "the piece has")?,
        Some(p) => picked_scalar(name, p, &pd_arrays, &cd_arrays)?,
    };
    let (scalars, cell_values) = read_scalar(&ctx, &info, &pd_arrays, &cd_arrays, np, nc)?;

    let mut raw = read_cells(&ctx, piece, nc, np)?;
    raw.points = points;
    raw.scalars = scalars;
    raw.cell_values = cell_values;
    raw.scalar = Some(info);

    // Ghosts (`vtkGhostType`): cells VTK does not draw are dropped.
    let cell_ghost = ghost_array(&ctx, &cd_arrays, "the vtkGhostType cell array", nc)?;
    let point_ghost = ghost_array(&ctx, &pd_arrays, "the vtkGhostType point array", np)?;
    raw.drop_ghosts(cell_ghost.as_deref(), point_ghost.as_deref(), counts);
    Ok(raw)
}

/// The piece's `np` points (its `<Points>` array of 3 components).
fn read_points(ctx: &Ctx, piece: roxmltree::Node, np: usize) -> Result<Vec<[f64; 3]>> {
    let name = ctx.name;
    let points_node = child(name, piece, "Points")?;
    let pa = arrays(Some(points_node));
    let pa = pa.first().ok_or_else(|| anyhow!("{name}: <Points> has no DataArray"))?;
    if components(name, *pa)? != 3 {
        bail!("{name}: the Points array has {} components, not 3", components(name, *pa)?);
    }
    let xyz = ctx.open("the Points array", *pa, np.checked_mul(3).ok_or_else(|| anyhow!("{name}: too many points"))?)?;
    let mut points: Vec<[f64; 3]> = Vec::with_capacity(xyz.capacity() / 3);
    let mut p = [0.0; 3];
    xyz.each(|i, v| {
        p[i % 3] = v.float();
        if i % 3 == 2 {
            points.push(p);
        }
        Ok(())
    })?;
    Ok(points)
}

/// The scalar `p` the file's first piece chose, found in this piece (an
/// error unless it has the array, with as many components).
fn picked_scalar(name: &str, p: &ScalarInfo, pd_arrays: &[roxmltree::Node], cd_arrays: &[roxmltree::Node]) -> Result<ScalarInfo> {
    let (list, whose) = match p.association {
        Association::Point => (pd_arrays, "point"),
        Association::Cell => (cd_arrays, "cell"),
    };
    let Some(a) = list.iter().find(|a| a.attribute("Name") == Some(p.array.as_str())) else {
        bail!(
            "{name}: the piece has no {whose} array '{}', the scalar chosen for the whole file; {}",
            p.array,
            listing(pd_arrays, cd_arrays)
        );
    };
    let k = components(name, *a)?;
    if k != p.components {
        bail!("{name}: the piece's {whose} array '{}' has {k} components, the file's scalar {}", p.array, p.components);
    }
    Ok(ScalarInfo { fallback: p.fallback, ..p.clone() })
}

/// The values of the scalar `info`, as (point scalars, cell values).
/// Point data: one value per point (a vector's magnitude, taken tuple by
/// tuple as it is decoded); cell data: every component, kept for the
/// treatment (`--cell-data`).
fn read_scalar(
    ctx: &Ctx,
    info: &ScalarInfo,
    pd_arrays: &[roxmltree::Node],
    cd_arrays: &[roxmltree::Node],
    np: usize,
    nc: usize,
) -> Result<(Vec<f64>, Vec<f64>)> {
    let name = ctx.name;
    let chosen = match info.association {
        Association::Point => pd_arrays.iter(),
        Association::Cell => cd_arrays.iter(),
    }
    .find(|a| a.attribute("Name").unwrap_or("(unnamed)") == info.array)
    .copied()
    .ok_or_else(|| anyhow!("{name}: {} array '{}' not found", info.association.name(), info.array))?;
    let k = info.components;
    let what = format!("{} array '{}'", info.association.name(), info.array);
    let tuples = if info.association == Association::Point { np } else { nc };
    let vals = ctx.open(&what, chosen, tuples.checked_mul(k).ok_or_else(|| anyhow!("{name}: {what} is too large"))?)?;
    let point = info.association == Association::Point;
    let mut values: Vec<f64> = Vec::with_capacity(if point { vals.capacity() / k } else { vals.capacity() });
    let mut tuple: Vec<f64> = Vec::with_capacity(k);
    let whose = format!("{name}: {what}");
    vals.each(|i, v| {
        if !point || k == 1 {
            values.push(v.float());
            return Ok(());
        }
        tuple.push(v.float());
        if i % k == k - 1 {
            values.push(super::cell_data::tuple_magnitude(&tuple, i / k, &whose, "point")?);
            tuple.clear();
        }
        Ok(())
    })?;
    Ok(if point { (values, Vec::new()) } else { (Vec::new(), values) })
}

/// The piece's `nc` cells (`<Cells>`: types, offsets, connectivity, and
/// the faces of its polyhedra), in a [`RawCells`] without points or
/// scalar.
fn read_cells(ctx: &Ctx, piece: roxmltree::Node, nc: usize, np: usize) -> Result<RawCells> {
    let name = ctx.name;
    let cells = child(name, piece, "Cells")?;
    let ca = arrays(Some(cells));
    let find = |n: &str| {
        ca.iter().find(|a| a.attribute("Name") == Some(n)).copied().ok_or_else(|| anyhow!("{name}: <Cells> has no '{n}' array"))
    };
    let types: Vec<u8> = ctx.open("the cell types", find("types")?, nc)?.ints(255)?;
    let offsets = read_offsets(ctx, find("offsets")?, nc)?;
    let conn_len = offsets.last().copied().unwrap_or(0);
    let conn: Vec<u32> = ctx.open("the cell connectivity", find("connectivity")?, conn_len)?.ints(u32::MAX as u64 - 1)?;
    let faces = if types.contains(&super::polyhedron::VTK_POLYHEDRON) {
        poly_faces(ctx, name, &ca, &types, np)?
    } else {
        Default::default()
    };
    Ok(RawCells { types, offsets, conn, faces, ..Default::default() })
}

/// The `nc` cell offsets (the `offsets` array `node`), checked to rise,
/// after a leading 0.
fn read_offsets(ctx: &Ctx, node: roxmltree::Node, nc: usize) -> Result<Vec<usize>> {
    let name = ctx.name;
    let what = "the cell offsets";
    let offs = ctx.open(what, node, nc)?;
    let mut offsets: Vec<usize> = Vec::with_capacity(offs.capacity() + 1);
    offsets.push(0);
    offs.each(|i, v| {
        let o = v.int_in(name, what, i, u32::MAX as u64)? as usize;
        if offsets.last().is_some_and(|&last| o < last) {
            bail!("{name}: the cell offsets do not rise (offset {i} is {o})");
        }
        offsets.push(o);
        Ok(())
    })?;
    Ok(offsets)
}

/// The `vtkGhostType` array among `list`, `n` values, if there is one.
fn ghost_array(ctx: &Ctx, list: &[roxmltree::Node], what: &str, n: usize) -> Result<Option<Vec<u8>>> {
    match list.iter().find(|a| a.attribute("Name") == Some("vtkGhostType")) {
        Some(g) => Ok(Some(ctx.open(what, *g, n)?.ints(255)?)),
        None => Ok(None),
    }
}

/// The faces of a piece's polyhedra (type 42), from VTK 9.4+'s
/// `face_connectivity` / `face_offsets` / `polyhedron_to_faces` /
/// `polyhedron_offsets` arrays or the older `faces` / `faceoffsets` (each
/// polyhedron's face stream, `faceoffsets` its end, -1 for other cells).
fn poly_faces(ctx: &Ctx, name: &str, ca: &[roxmltree::Node], types: &[u8], np: usize) -> Result<PolyFaces> {
    use super::polyhedron::{parse_face_stream, VTK_POLYHEDRON};
    let nc = types.len();
    let find = |n: &str| ca.iter().find(|a| a.attribute("Name") == Some(n)).copied();
    let signed = |what: &str, node: roxmltree::Node, count: usize| -> Result<Vec<i64>> {
        let values = ctx.open(what, node, count)?;
        let mut out = Vec::with_capacity(values.capacity());
        values.each(|i, v| {
            out.push(match v {
                Value::Int(x) if (-1..=u32::MAX as i128).contains(&x) => x as i64,
                Value::Int(x) => bail!("{name}: {what} value {i} is {x}, outside -1..={}", u32::MAX),
                Value::Float(_) => bail!("{name}: {what} must have an integer type"),
            });
            Ok(())
        })?;
        Ok(out)
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
        let poff = ctx.open("the polyhedron_offsets array", po, nc)?.ints::<u64>(u32::MAX as u64)?;
        let poff: Vec<i64> = poff.into_iter().map(|x| x as i64).collect();
        rising("the polyhedron_offsets array", &poff, 0)?;
        let n_refs = poff.last().copied().unwrap_or(0) as usize;
        let p2f = ctx.open("the polyhedron_to_faces array", pf, n_refs)?.ints::<u64>(u32::MAX as u64 - 1)?;
        // The faces are those the polyhedra name.
        let n_faces = p2f.iter().max().map_or(0, |&m| m as usize + 1);
        let foff = ctx.open("the face_offsets array", fo, n_faces)?.ints::<u64>(u32::MAX as u64)?;
        let foff: Vec<i64> = foff.into_iter().map(|x| x as i64).collect();
        rising("the face_offsets array", &foff, 0)?;
        let fconn = ctx
            .open("the face_connectivity array", fc, foff.last().copied().unwrap_or(0) as usize)?
            .ints::<u64>(np.saturating_sub(1) as u64)
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
        let c = parse_vtu_bytes("g.vtu", &bytes, Some("cellid")).unwrap();
        let s = c.stats.scalar.as_ref().unwrap();
        assert_eq!((s.array.as_str(), s.association, s.fallback), ("cellid", Association::Cell, false));
        assert_eq!(c.points.len(), 4 * c.tets.len());
        let e = format!("{:#}", parse_vtu_bytes("g.vtu", &bytes, Some("nope")).unwrap_err());
        assert!(e.contains("no point or cell array named 'nope'") && e.contains("'temp' (1 components)") && e.contains("'cellid'"), "{e}");
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

    /// Issue 35 item 12: the scalar is chosen once per file, from the
    /// arrays a `.pvtu` declares (else by its first piece), and a piece
    /// without it (or with another component count) is refused: pieces'
    /// fields are never mixed.
    #[test]
    fn pvtu_scalars_are_declared_and_never_mixed() {
        let g = grid();
        let tmp = tempfile::tempdir().unwrap();
        let (a, b) = g.cells.split_at(3);
        let piece = |cells: &[(u8, Vec<u32>)]| {
            let p = Grid { points: g.points.clone(), scalar: g.scalar.clone(), velocity: g.velocity.clone(), cells: cells.to_vec() };
            String::from_utf8(write_vtu(&p, Format::Ascii, false, 4, false)).unwrap()
        };
        let (p0, p1) = (piece(a), piece(b));
        let pressure = p1.replace("Scalars=\"temp\"", "Scalars=\"pressure\"").replace("Name=\"temp\"", "Name=\"pressure\"");
        let flat = p1.replace("Name=\"velocity\" NumberOfComponents=\"3\"", "Name=\"velocity\" NumberOfComponents=\"1\"");
        let write = |second: &str, declared: &str| {
            std::fs::write(tmp.path().join("p_0.vtu"), &p0).unwrap();
            std::fs::write(tmp.path().join("p_1.vtu"), second).unwrap();
            let pvtu = format!(
                "<?xml version=\"1.0\"?>\n<VTKFile type=\"PUnstructuredGrid\" version=\"1.0\">\n<PUnstructuredGrid GhostLevel=\"0\">\n{declared}\n\
                 <PPoints><PDataArray type=\"Float64\" NumberOfComponents=\"3\"/></PPoints>\n\
                 <Piece Source=\"p_0.vtu\"/>\n<Piece Source=\"p_1.vtu\"/>\n</PUnstructuredGrid>\n</VTKFile>\n"
            );
            let p = tmp.path().join("all.pvtu");
            std::fs::write(&p, pvtu).unwrap();
            p
        };
        let temp = "<PPointData Scalars=\"temp\"><PDataArray type=\"Float64\" Name=\"temp\"/>\
                    <PDataArray type=\"Float64\" Name=\"velocity\" NumberOfComponents=\"3\"/></PPointData>\
                    <PCellData><PDataArray type=\"Int64\" Name=\"cellid\"/></PCellData>";
        let err = |p: &std::path::Path, array: Option<&str>| format!("{:#}", read_vtu(p, array).unwrap_err());
        // Declared 'temp', or nothing declared (the first piece's 'temp'):
        // the piece calling its field 'pressure' is refused, naming both.
        for declared in [temp, ""] {
            let p = write(&pressure, declared);
            let e = err(&p, None);
            assert!(e.contains("p_1.vtu") && e.contains("no point array 'temp'") && e.contains("'pressure'"), "{declared}: {e}");
        }
        let p = write(&pressure, temp);
        let e = err(&p, Some("pressure"));
        assert!(e.contains("all.pvtu: the .pvtu declares no point or cell array named 'pressure'") && e.contains("'cellid'"), "{e}");
        // Another component count.
        let p = write(&flat, temp);
        let e = err(&p, Some("velocity"));
        assert!(e.contains("p_1.vtu") && e.contains("'velocity' has 1 components, the file's scalar 3"), "{e}");
        // Alike pieces: the declared active scalar, a declared vector, a declared cell array.
        let p = write(&p1, temp);
        let m = read_vtu(&p, None).unwrap();
        assert_eq!(m.stats.scalar.as_ref().map(|s| (s.array.as_str(), s.association)), Some(("temp", Association::Point)));
        check_mesh(&m, "declared temp");
        let v = read_vtu(&p, Some("velocity")).unwrap();
        assert_eq!(v.points, m.points);
        assert_eq!(v.scalars[4], 1.0);
        let c = read_vtu(&p, Some("cellid")).unwrap();
        let s = c.stats.scalar.as_ref().unwrap();
        assert_eq!((s.array.as_str(), s.association, s.cell_data), ("cellid", Association::Cell, Some(super::super::cell_data::CellData::Constant)));
        assert_eq!(c.points.len(), 4 * c.tets.len());
        assert_eq!(c.tets.len(), m.tets.len());
        // Only cell data declared: the cell array, as the fallback.
        let p = write(&p1, "<PCellData><PDataArray type=\"Int64\" Name=\"cellid\"/></PCellData>");
        let c = read_vtu(&p, None).unwrap();
        assert!(c.stats.scalar.as_ref().is_some_and(|s| s.fallback && s.association == Association::Cell));
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
        assert!(e.contains("no point or cell array named 'nope'"), "{e}");
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

    /// The mixed mesh VTK 9.7.2 wrote with each compressor, header type and
    /// data mode (`tests/fixtures/vtk_xml/make.py`) reads as the ASCII seed.
    #[test]
    fn vtk_written_compressed_files() {
        macro_rules! fixtures {
            ($($c:literal),*) => {
                [$(
                    ($c, &include_bytes!(concat!("../../tests/fixtures/vtk_xml/mixed_", $c, ".vtu"))[..]),
                )*]
            };
        }
        let files = fixtures!(
            "zlib_u32_raw", "zlib_u32_base64", "zlib_u32_binary", "zlib_u64_raw", "zlib_u64_base64", "zlib_u64_binary",
            "lz4_u32_raw", "lz4_u32_base64", "lz4_u32_binary", "lz4_u64_raw", "lz4_u64_base64", "lz4_u64_binary",
            "lzma_u32_raw", "lzma_u32_base64", "lzma_u32_binary", "lzma_u64_raw", "lzma_u64_base64", "lzma_u64_binary"
        );
        let first = parse_vtu_bytes("a.vtu", include_bytes!("../../fuzz/seeds/vtu/mixed_ascii.vtu"), None).unwrap();
        for (what, bytes) in files {
            let m = parse_vtu_bytes("m.vtu", bytes, None).unwrap_or_else(|e| panic!("{what}: {e:#}"));
            assert_eq!(m.tets, first.tets, "{what}");
            assert_eq!(m.points, first.points, "{what}");
            assert_eq!(m.scalars, first.scalars, "{what}");
            // Truncated anywhere: an error naming the file, never a panic.
            for cut in (0..bytes.len()).step_by(53) {
                if let Err(e) = parse_vtu_bytes("cut.vtu", &bytes[..cut], None) {
                    assert!(format!("{e:#}").starts_with("cut.vtu"), "{what}: {e:#}");
                }
            }
        }
    }

    /// A strip of 7 hexahedra with cell ghosts 0, 1, 2, 4, 8, 16, 32 and a
    /// hidden and a duplicate point: VTK's vtkGeometryFilter keeps the cells
    /// marked 0, 2, 4 and 16 and drops those using the hidden point.
    fn ghost_strip(point_ghost: bool) -> (String, String) {
        let mut pts = Vec::new();
        for k in 0..2 {
            for j in 0..2 {
                for i in 0..8 {
                    pts.push(format!("{i} {j} {k}"));
                }
            }
        }
        let p = |i: usize, j: usize, k: usize| i + 8 * j + 16 * k;
        let cells: Vec<String> = (0..7)
            .map(|i| {
                let h = [p(i, 0, 0), p(i + 1, 0, 0), p(i + 1, 1, 0), p(i, 1, 0), p(i, 0, 1), p(i + 1, 0, 1), p(i + 1, 1, 1), p(i, 1, 1)];
                h.map(|v| v.to_string()).join(" ")
            })
            .collect();
        let scalar: Vec<String> = (0..32).map(|i| i.to_string()).collect();
        // Point 7 (x = 7, the last cell's) hidden, point 3 duplicate.
        let pg: Vec<&str> = (0..32).map(|i| if !point_ghost { "0" } else if i == 7 { "2" } else if i == 3 { "1" } else { "0" }).collect();
        let pg_xml = format!("<DataArray type=\"UInt8\" Name=\"vtkGhostType\" format=\"ascii\">{}</DataArray>", pg.join(" "));
        let xml = format!(
            "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid><Piece NumberOfPoints=\"32\" NumberOfCells=\"7\">\
             <PointData Scalars=\"s\"><DataArray type=\"Float64\" Name=\"s\" format=\"ascii\">{}</DataArray>{}</PointData>\
             <CellData><DataArray type=\"UInt8\" Name=\"vtkGhostType\" format=\"ascii\">0 1 2 4 8 16 32</DataArray></CellData>\
             <Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">{}</DataArray></Points>\
             <Cells><DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">{}</DataArray>\
             <DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">{}</DataArray>\
             <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">{}</DataArray></Cells></Piece></UnstructuredGrid></VTKFile>",
            scalar.join(" "),
            if point_ghost { pg_xml.as_str() } else { "" },
            pts.join(" "),
            cells.join(" "),
            (1..=7).map(|c| (8 * c).to_string()).collect::<Vec<_>>().join(" "),
            ["12"; 7].join(" ")
        );
        let mut legacy = format!("# vtk DataFile Version 3.0\nghosts\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 32 double\n{}\n", pts.join("\n"));
        legacy += &format!("CELLS 7 63\n{}\nCELL_TYPES 7\n{}\n", cells.iter().map(|c| format!("8 {c}")).collect::<Vec<_>>().join("\n"), ["12"; 7].join("\n"));
        legacy += "CELL_DATA 7\nFIELD FieldData 1\nvtkGhostType 1 7 unsigned_char\n0 1 2 4 8 16 32\n";
        legacy += &format!("POINT_DATA 32\nSCALARS s double 1\nLOOKUP_TABLE default\n{}\n", scalar.join(" "));
        if point_ghost {
            legacy += &format!("SCALARS vtkGhostType unsigned_char 1\nLOOKUP_TABLE default\n{}\n", pg.join(" "));
        }
        (xml, legacy)
    }

    #[test]
    fn ghost_cells_and_points_are_skipped_as_vtk_does() {
        for point_ghost in [false, true] {
            let (xml, legacy) = ghost_strip(point_ghost);
            for (what, m) in [
                ("vtu", parse_vtu_bytes("g.vtu", xml.as_bytes(), None).unwrap()),
                ("legacy", crate::mesh::vtk::parse_vtk_bytes("g.vtk", legacy.as_bytes()).unwrap()),
            ] {
                let what = format!("{what}, point ghosts {point_ghost}");
                // Kept: cells 0, 2, 4, 5 (ghost 0, 2, 4, 16); with point ghosts the last
                // kept cell (5, x 5..6) stays, cell 6 (x 6..7, hidden point 7) was hidden anyway.
                assert_eq!(m.stats.ghost_cells, 1, "{what}");
                assert_eq!(m.stats.hidden_cells, 2, "{what}");
                assert_eq!(m.stats.ghost_points, if point_ghost { 2 } else { 0 }, "{what}");
                assert_eq!(m.scalars, (0..32).map(f64::from).collect::<Vec<_>>(), "{what}");
                let vol = TetGeometry::compute(&m).total_volume();
                assert!((vol - 4.0).abs() < 1e-12, "{what}: volume {vol}");
            }
        }
        // A hidden point used by a drawn cell hides it: point 0 belongs to cell 0 only.
        let (xml, _) = ghost_strip(true);
        let xml = xml.replacen(">0 0 0 1 0 0 0 2 ", ">2 0 0 1 0 0 0 2 ", 1);
        let m = parse_vtu_bytes("g.vtu", xml.as_bytes(), None).unwrap();
        assert_eq!((m.stats.ghost_cells, m.stats.hidden_cells, m.stats.ghost_points), (1, 3, 3));
        // A ghost array of the wrong length is an error naming it.
        let bad = ghost_strip(false).0.replace(">0 1 2 4 8 16 32<", ">0 1 2<");
        let e = format!("{:#}", parse_vtu_bytes("g.vtu", bad.as_bytes(), None).unwrap_err());
        assert!(e.contains("the vtkGhostType cell array needs 7 values"), "{e}");
    }

    /// VTK's own partition (vtkExtractUnstructuredGridPiece, 3 pieces, ghost
    /// level 1, LZ4, `tests/fixtures/vtk_xml/make.py`): each piece holds all
    /// 24 hexahedra, 16 of them ghosts, and all 60 points.
    #[test]
    fn vtk_partitioned_pvtu_reads_as_one_mesh() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/vtk_xml");
        let m = read_vtu(dir.join("seam.pvtu"), None).unwrap();
        assert_eq!(m.points.len(), 60);
        assert_eq!(m.stats.ghost_cells, 48);
        assert_eq!(m.stats.seam_points_merged, 120);
        assert_eq!(m.stats.seam_scalar_mismatches, 0);
        assert_eq!(m.stats.ghost_points, 120);
        assert!(m.tets.len() >= 5 * 24, "{}", m.tets.len());
        let vol = TetGeometry::compute(&m).total_volume();
        assert!((vol - 24.0).abs() < 1e-9, "volume {vol}");
        // The faces between pieces close: only the block's surface is boundary.
        let adj = FaceAdjacency::build(&m.tets, None, |_| true);
        assert_eq!(adj.boundary.len(), 2 * 2 * (4 * 3 + 4 * 2 + 3 * 2));
        for (p, s) in m.points.iter().zip(&m.scalars) {
            assert_eq!(*s, p[0] + 10.0 * p[1] + 100.0 * p[2]);
        }
    }

    /// Many one-tet pieces in one `.vtu`: the nodes stepped over grow
    /// linearly with the pieces (each array's end was found by a scan of
    /// the whole document: quadratic).
    #[test]
    fn many_pieces_read_in_linear_steps() {
        let file = |n: usize| {
            let mut s = String::from("<VTKFile type=\"UnstructuredGrid\" header_type=\"UInt32\"><UnstructuredGrid>");
            let mut data: Vec<u8> = Vec::new();
            let mut arr = |ty: &str, name: &str, comps: usize, bytes: Vec<u8>| {
                let off = data.len();
                data.extend((bytes.len() as u32).to_le_bytes());
                data.extend(bytes);
                format!("<DataArray type=\"{ty}\" Name=\"{name}\" NumberOfComponents=\"{comps}\" format=\"appended\" offset=\"{off}\"/>")
            };
            for i in 0..n {
                let x = i as f64 * 2.0;
                let pts: Vec<u8> = [x, 0., 0., x + 1., 0., 0., x, 1., 0., x, 0., 1.].iter().flat_map(|v: &f64| v.to_le_bytes()).collect();
                let sc: Vec<u8> = [1.0f64, 2., 3., 4.].iter().flat_map(|v| v.to_le_bytes()).collect();
                s += "<Piece NumberOfPoints=\"4\" NumberOfCells=\"1\"><PointData>";
                s += &arr("Float64", "s", 1, sc);
                s += "</PointData><Points>";
                s += &arr("Float64", "Points", 3, pts);
                s += "</Points><Cells>";
                s += &arr("Int32", "connectivity", 1, [0i32, 1, 2, 3].iter().flat_map(|v| v.to_le_bytes()).collect());
                s += &arr("Int32", "offsets", 1, 4i32.to_le_bytes().to_vec());
                s += &arr("UInt8", "types", 1, vec![10]);
                s += "</Cells></Piece>";
            }
            s += "</UnstructuredGrid><AppendedData encoding=\"raw\">_";
            let mut out = s.into_bytes();
            out.extend(data);
            out.extend(b"</AppendedData></VTKFile>");
            out
        };
        let steps = |n: usize| {
            let bytes = file(n);
            crate::vtk_xml::NODE_VISITS.with(|c| c.set(0));
            let m = parse_vtu_bytes("many.vtu", &bytes, None).unwrap();
            assert_eq!(m.tets.len(), n);
            crate::vtk_xml::NODE_VISITS.with(|c| c.get())
        };
        let (small, large) = (steps(500), steps(2000));
        assert!(large <= 4 * small + 100 && large >= 4 * small - 100, "500 pieces: {small} steps, 2000: {large}");
    }

    /// A `.pvtu` listing a piece twice (by the same name or another path to
    /// the same file) is refused before any piece is read; seam points with
    /// different scalars are counted, the first piece's value kept.
    #[test]
    fn pvtu_repeats_and_seam_scalar_mismatches() {
        let g = grid();
        let tmp = tempfile::tempdir().unwrap();
        let (a, b) = g.cells.split_at(3);
        for (i, cells) in [a, b].iter().enumerate() {
            // Piece 1's scalar differs at point 4 (on the seam).
            let mut scalar = g.scalar.clone();
            if i == 1 {
                scalar[4] += 1.0;
            }
            let piece = Grid { points: g.points.clone(), scalar, velocity: g.velocity.clone(), cells: cells.to_vec() };
            std::fs::write(tmp.path().join(format!("p_{i}.vtu")), write_vtu(&piece, Format::Binary, false, 8, false)).unwrap();
        }
        let pvtu = |sources: &[&str]| {
            let pieces: String = sources.iter().map(|s| format!("<Piece Source=\"{s}\"/>\n")).collect();
            format!("<VTKFile type=\"PUnstructuredGrid\"><PUnstructuredGrid GhostLevel=\"0\">{pieces}</PUnstructuredGrid></VTKFile>\n")
        };
        let p = tmp.path().join("all.pvtu");
        std::fs::write(&p, pvtu(&["p_0.vtu", "p_1.vtu"])).unwrap();
        let m = read_vtu(&p, None).unwrap();
        assert_eq!(m.points.len(), g.points.len());
        assert_eq!(m.stats.seam_points_merged, g.points.len());
        assert_eq!(m.stats.seam_scalar_mismatches, 1);
        assert_eq!(m.scalars, g.scalar);
        std::fs::create_dir(tmp.path().join("sub")).unwrap();
        std::os::unix::fs::symlink(tmp.path().join("p_1.vtu"), tmp.path().join("sub/link.vtu")).unwrap();
        for (sources, first) in [(vec!["p_0.vtu", "p_1.vtu", "p_0.vtu"], "p_0.vtu"), (vec!["p_1.vtu", "./sub/../sub/link.vtu"], "p_1.vtu")] {
            std::fs::write(&p, pvtu(&sources)).unwrap();
            let e = format!("{:#}", read_vtu(&p, None).unwrap_err());
            assert!(e.contains("all.pvtu") && e.contains(&format!("is the same file as piece '{first}'")), "{e}");
        }
        // Pieces over the input cap together (sparse files: sizes from the metadata,
        // nothing read): 2 x 0.6 GiB and 3 x 0.4 GiB, refused at the last piece.
        for (n, size) in [(2usize, 0.6f64), (3, 0.4)] {
            let names: Vec<String> = (0..n).map(|i| format!("big_{n}_{i}.vtu")).collect();
            for f in &names {
                std::fs::File::create(tmp.path().join(f)).unwrap().set_len((size * (1u64 << 30) as f64) as u64).unwrap();
            }
            std::fs::write(&p, pvtu(&names.iter().map(|s| s.as_str()).collect::<Vec<_>>())).unwrap();
            let e = format!("{:#}", read_vtu(&p, None).unwrap_err());
            let last = &names[n - 1];
            assert!(e.contains(&format!("its pieces up to '{last}' hold")) && e.contains("more than the 1073741824 bytes"), "{e}");
        }
    }
}
