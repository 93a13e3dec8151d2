//! VTK legacy (`.vtk`) reader for `UNSTRUCTURED_GRID` files.
//!
//! Both ASCII and BINARY (big-endian) encodings, file versions up to 4.x
//! (`CELLS n size` with a count before each cell) and 5.x (`OFFSETS` /
//! `CONNECTIVITY`). Every section of the format is parsed (so unfamiliar but
//! legal content such as `FIELD` blocks, `METADATA`, vectors or cell data is
//! skipped correctly). Cells: every volumetric type (linear, quadratic,
//! Lagrange, polyhedra, whose `CELLS` entry is their face stream) is split
//! into tets conformingly by `tetrahedralize`; vertex, line and surface
//! cells are skipped and counted; other types are refused, named with their
//! counts. The scalar is the array the caller
//! names (a `SCALARS`, `VECTORS` or `FIELD` array, ...; several components
//! by magnitude): a point array of that name, else a cell array of that
//! name (shown as `--cell-data` says: `mesh::cell_data`). Without a name,
//! the first one-component `SCALARS` array of `POINT_DATA`; files that
//! store their point data only as a `FIELD` (such as VTK's own `post.vtk`,
//! whose point data is `FIELD FieldData 1` / `Pressure 1 2288 float`) fall
//! back to the first one-component field array of the right length; a file
//! with no point scalar at all uses the first one-component `SCALARS` or
//! `FIELD` array of `CELL_DATA` (not `vtkGhostType`), marked as a fallback
//! so the caller notes it.
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

mod connectivity;
mod values;

use crate::vtk_legacy::Lines as Reader;
use super::cell_data::{magnitudes, Association, ScalarChoice, ScalarInfo};
use super::cells::RawCells;
use super::TetMesh;
use anyhow::{anyhow, bail, Result};
use std::path::Path;
use values::{swapped_hint, DType};

/// VTK cell type of a linear tetrahedron.
pub const VTK_TETRA: i64 = super::cells::VTK_TETRA as i64;

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

#[derive(Clone, Copy, PartialEq, Default)]
enum Owner {
    #[default]
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
    read_vtk_legacy_with(path, ScalarChoice { array, ..Default::default() })
}

/// [`read_vtk_legacy`] with the scalar chosen and cell data treated as
/// `choice` says (`mesh::cell_data`).
pub fn read_vtk_legacy_with(path: impl AsRef<Path>, choice: ScalarChoice) -> Result<TetMesh> {
    let path = path.as_ref();
    let bytes = crate::fsio::read_input(path, "VTK file", crate::fsio::MAX_INPUT_BYTES)?;
    parse_vtk_bytes_with(&path.display().to_string(), &bytes, choice)
}

/// [`read_vtk_legacy`] on the bytes of a file already in memory. `name` (the
/// file path, or any label) is quoted in every error, and its file stem names
/// the mesh. Never panics on malformed input: every count is checked against
/// the bytes that remain before anything is allocated from it.
pub fn parse_vtk_bytes(name: &str, bytes: &[u8]) -> Result<TetMesh> {
    parse_vtk_bytes_array(name, bytes, None)
}

/// [`parse_vtk_bytes`] with the array `want` (point data first, then cell
/// data) as the scalar.
pub fn parse_vtk_bytes_array(name: &str, bytes: &[u8], want: Option<&str>) -> Result<TetMesh> {
    parse_vtk_bytes_with(name, bytes, ScalarChoice { array: want, ..Default::default() })
}

/// [`parse_vtk_bytes`] with the scalar chosen as `choice` says.
pub fn parse_vtk_bytes_with(name: &str, bytes: &[u8], choice: ScalarChoice) -> Result<TetMesh> {
    let mut r = Reader { name, b: bytes, pos: 0, binary: false };
    let (major, version) = read_header(&mut r, name, bytes)?;
    let mut s = Sections { want: choice.array, choice, major, version, ..Sections::default() };
    while !r.at_end() {
        let line = r.keyword_line("a section keyword")?;
        let kw = line[0].to_ascii_uppercase();
        match kw.as_str() {
            "METADATA" => r.skip_metadata()?,
            "FIELD" => s.field(&mut r, &line)?,
            "POINTS" => s.points(&mut r, &line)?,
            "CELLS" => s.cells(&mut r, &line)?,
            "CELL_TYPES" => s.cell_types(&mut r, &line)?,
            "POINT_DATA" | "CELL_DATA" => s.data_owner(&mut r, &line, &kw)?,
            "SCALARS" => s.scalars(&mut r, &line)?,
            "LOOKUP_TABLE" => {
                let size = r.count(line.get(2), "LOOKUP_TABLE size")?;
                let n = size.checked_mul(4).ok_or_else(|| r.err("LOOKUP_TABLE size overflows"))?;
                let dt = if r.binary { DType::U8 } else { DType::F64 };
                r.skip_values(n, dt, "LOOKUP_TABLE")?;
            }
            "COLOR_SCALARS" => {
                let n = s.tuples(&r, "COLOR_SCALARS")?;
                let k = r.count(line.get(2), "COLOR_SCALARS component count")?;
                let dt = if r.binary { DType::U8 } else { DType::F64 };
                r.skip_values(r.product(n, k, "COLOR_SCALARS")?, dt, "COLOR_SCALARS")?;
            }
            "VECTORS" | "NORMALS" | "TENSORS" | "TENSORS6" | "GLOBAL_IDS" | "PEDIGREE_IDS" => s.attribute(&mut r, &line, &kw)?,
            "TEXTURE_COORDINATES" => {
                let n = s.tuples(&r, &kw)?;
                let k = r.count(line.get(2), "TEXTURE_COORDINATES dimension")?;
                let dt = r.dtype(line.get(3), &kw)?;
                r.skip_values(r.product(n, k, &kw)?, dt, &kw)?;
            }
            _ => bail!(r.err(format!("bad keyword '{}'", line[0].escape_debug()))),
        }
    }
    s.into_mesh(&r, name)
}

/// The header: version line, title, encoding (sets `r.binary`), DATASET.
/// Returns the major version and the version as written.
fn read_header<'a>(r: &mut Reader<'a>, name: &str, bytes: &[u8]) -> Result<(u32, &'a str)> {
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
            "unsupported DATASET {}: a mesh is an UNSTRUCTURED_GRID (a volume a STRUCTURED_POINTS)",
            other.unwrap_or("(missing)")
        ))),
    }
    Ok((major, version))
}

/// What the sections read so far hold, and the state they are read in.
#[derive(Default)]
struct Sections<'a> {
    /// The array asked for, if any.
    want: Option<&'a str>,
    choice: ScalarChoice<'a>,
    major: u32,
    version: &'a str,
    points: Option<Vec<[f64; 3]>>,
    /// Offsets and connectivity (indices not yet checked).
    cells: Option<(Vec<usize>, Vec<i64>)>,
    n_cells: Option<usize>,
    types: Option<Vec<u8>>,
    /// Whose attributes follow (POINT_DATA / CELL_DATA), and how many tuples.
    owner: Owner,
    owner_count: usize,
    /// Point scalars read: (array name, components, one value per point).
    scalars: Option<(String, usize, Vec<f64>)>,
    field_scalars: Option<(String, usize, Vec<f64>)>,
    /// The cell array asked for, or the first one-component one (the
    /// fallback): (name, components, `components` values per cell).
    cell_array: Option<(String, usize, Vec<f64>)>,
    seen_point_arrays: Vec<String>,
    /// `vtkGhostType` arrays (cell data, point data), see `RawCells::drop_ghosts`.
    cell_ghost: Option<Vec<u8>>,
    point_ghost: Option<Vec<u8>>,
    seen_cell_arrays: Vec<String>,
}

impl Sections<'_> {
    fn n_points(&self) -> usize {
        self.points.as_ref().map_or(0, |p| p.len())
    }

    /// Tuples per attribute array of the current POINT_DATA / CELL_DATA.
    fn tuples(&self, r: &Reader, kw: &str) -> Result<usize> {
        if self.owner == Owner::None {
            Err(r.err(format!("{kw} outside POINT_DATA / CELL_DATA")))
        } else {
            Ok(self.owner_count)
        }
    }

    /// A `vtkGhostType` array of the current POINT_DATA / CELL_DATA (`n`
    /// one-component values of `dt`, each 0..=255), kept for
    /// `RawCells::drop_ghosts`.
    fn ghost(&mut self, r: &mut Reader, n: usize, ncomp: usize, dt: DType, what: &str) -> Result<()> {
        if ncomp != 1 {
            bail!(r.err(format!("{what} has {ncomp} components, not 1")));
        }
        let v = r.values_i64(n, dt, what)?;
        if let Some(i) = v.iter().position(|g| !(0..=255).contains(g)) {
            bail!(r.err(format!("{what} value {i} is {}, outside 0..=255", v[i])));
        }
        let v = Some(v.into_iter().map(|g| g as u8).collect());
        if self.owner == Owner::Cells {
            self.cell_ghost = v;
        } else {
            self.point_ghost = v;
        }
        Ok(())
    }

    fn field(&mut self, r: &mut Reader, line: &[&str]) -> Result<()> {
        let n_arrays = r.count(line.get(2), "FIELD array count")?;
        for _ in 0..n_arrays {
            let h = r.keyword_line("a FIELD array header")?;
            if h[0] == "NULL_ARRAY" {
                continue;
            }
            let ncomp = r.count(h.get(1), "FIELD array component count")?;
            let ntup = r.count(h.get(2), "FIELD array tuple count")?;
            let dt = r.dtype(h.get(3), &format!("FIELD array '{}'", h[0]))?;
            let n = ncomp.checked_mul(ntup).ok_or_else(|| r.err(format!("FIELD array '{}' size overflows", h[0])))?;
            let what = format!("FIELD array '{}'", h[0]);
            if h[0] == "vtkGhostType" && self.owner != Owner::None && self.want != Some("vtkGhostType") {
                if ntup != self.owner_count {
                    bail!(r.err(format!("{what} has {ntup} tuples, not the {} of its data", self.owner_count)));
                }
                self.ghost(r, ntup, ncomp, dt, &what)?;
                if r.peek_word().eq_ignore_ascii_case("METADATA") {
                    r.keyword_line("METADATA")?;
                    r.skip_metadata()?;
                }
                continue;
            }
            let named = self.want.is_some_and(|w| w == h[0]);
            if self.owner == Owner::Points
                && ntup == self.n_points()
                && (named || (self.want.is_none() && ncomp == 1 && self.field_scalars.is_none()))
            {
                let v = magnitudes(r.values_f64(n, dt, &what)?, ncomp, &r.err(&what).to_string(), "point")?;
                self.field_scalars = Some((h[0].to_string(), ncomp, v));
                if named {
                    self.scalars = self.field_scalars.clone();
                }
            } else if self.owner == Owner::Cells && ntup == self.owner_count && self.wants_cell_array(h[0], ncomp) {
                self.cell_array = Some((h[0].to_string(), ncomp, r.values_f64(n, dt, &what)?));
            } else {
                r.skip_values(n, dt, &what)?;
            }
            match self.owner {
                Owner::Points => self.seen_point_arrays.push(format!("FIELD {} ({ncomp} components)", h[0])),
                Owner::Cells => self.seen_cell_arrays.push(format!("FIELD {} ({ncomp} components)", h[0])),
                Owner::None => {}
            }
            if r.peek_word().eq_ignore_ascii_case("METADATA") {
                r.keyword_line("METADATA")?;
                r.skip_metadata()?;
            }
        }
        Ok(())
    }

    fn points(&mut self, r: &mut Reader, line: &[&str]) -> Result<()> {
        if self.points.is_some() {
            bail!(r.err("second POINTS section"));
        }
        let n = r.count(line.get(1), "POINTS count")?;
        let dt = r.dtype(line.get(2), "POINTS")?;
        let n3 = n.checked_mul(3).ok_or_else(|| r.err("POINTS count overflows"))?;
        let v = r.values_f64(n3, dt, "POINTS")?;
        self.points = Some(v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect());
        Ok(())
    }

    fn cells(&mut self, r: &mut Reader, line: &[&str]) -> Result<()> {
        if self.cells.is_some() {
            bail!(r.err("second CELLS section"));
        }
        if self.points.is_none() {
            bail!(r.err("CELLS before POINTS"));
        }
        let a = r.count(line.get(1), "CELLS count")?;
        let b = r.count(line.get(2), "CELLS size")?;
        let (offsets, conn) = if self.major >= 5 {
            connectivity::offsets_and_connectivity(r, a, b, self.version)?
        } else {
            connectivity::counted_cells(r, a, b, self.version)?
        };
        // Indices are checked once the types are known (a polyhedron's
        // entries are its face stream, counts among the indices).
        self.n_cells = Some(offsets.len().saturating_sub(1));
        self.cells = Some((offsets.iter().map(|&o| o as usize).collect(), conn));
        Ok(())
    }

    fn cell_types(&mut self, r: &mut Reader, line: &[&str]) -> Result<()> {
        let n = r.count(line.get(1), "CELL_TYPES count")?;
        let Some(nc) = self.n_cells else { bail!(r.err("CELL_TYPES before CELLS")) };
        if n != nc {
            bail!(r.err(format!("count mismatch: CELL_TYPES has {n} entries but CELLS has {nc} cells")));
        }
        let t = r.values_i64(n, DType::I32, "CELL_TYPES")?;
        // Types beyond a byte are no VTK cell; a byte-swapped 10..14 says why.
        if let Some(c) = t.iter().position(|&t| !(0..=255).contains(&t)) {
            let hint = (VTK_TETRA..=14).map(|k| swapped_hint(r.binary, t[c], k as i32)).find(|h| !h.is_empty());
            bail!(r.err(format!("unknown cell type {} at cell {c}{}", t[c], hint.unwrap_or(""))));
        }
        self.types = Some(t.iter().map(|&t| t as u8).collect());
        Ok(())
    }

    /// POINT_DATA or CELL_DATA (`kw`): the attributes that follow belong to it.
    fn data_owner(&mut self, r: &mut Reader, line: &[&str], kw: &str) -> Result<()> {
        let n = r.count(line.get(1), &format!("{kw} count"))?;
        let (o, expect, what) = if kw == "POINT_DATA" {
            (Owner::Points, self.points.as_ref().map(|p| p.len()), "POINTS")
        } else {
            (Owner::Cells, self.n_cells, "CELLS")
        };
        match expect {
            Some(e) if e == n => {}
            Some(e) => bail!(r.err(format!("count mismatch: {kw} {n} but {what} has {e}"))),
            None => bail!(r.err(format!("{kw} before {what}"))),
        }
        self.owner = o;
        self.owner_count = n;
        Ok(())
    }

    fn scalars(&mut self, r: &mut Reader, line: &[&str]) -> Result<()> {
        let n = self.tuples(r, "SCALARS")?;
        let name = line.get(1).copied().unwrap_or("?");
        let dt = r.dtype(line.get(2), &format!("SCALARS '{name}'"))?;
        let ncomp = match line.get(3) {
            Some(s) => s
                .parse::<usize>()
                .ok()
                .filter(|&k| (1..=4).contains(&k))
                .ok_or_else(|| r.err(format!("bad component count '{s}' for SCALARS '{name}'")))?,
            None => 1,
        };
        if r.peek_word().eq_ignore_ascii_case("LOOKUP_TABLE") {
            r.keyword_line("LOOKUP_TABLE")?;
        }
        let what = format!("SCALARS '{name}'");
        if name == "vtkGhostType" && self.want != Some(name) {
            return self.ghost(r, n, ncomp, dt, &what);
        }
        match self.owner {
            Owner::Points => self.seen_point_arrays.push(format!("SCALARS {name} ({ncomp} components)")),
            Owner::Cells => self.seen_cell_arrays.push(format!("SCALARS {name} ({ncomp} components)")),
            Owner::None => {}
        }
        let named = self.want == Some(name);
        if self.owner == Owner::Points && (named || (self.want.is_none() && ncomp == 1 && self.scalars.is_none())) {
            let v = r.values_f64(r.product(n, ncomp, &what)?, dt, &what)?;
            self.scalars = Some((name.to_string(), ncomp, magnitudes(v, ncomp, &r.err(&what).to_string(), "point")?));
        } else if self.owner == Owner::Cells && self.wants_cell_array(name, ncomp) {
            self.cell_array = Some((name.to_string(), ncomp, r.values_f64(r.product(n, ncomp, &what)?, dt, &what)?));
        } else {
            r.skip_values(r.product(n, ncomp, &what)?, dt, &what)?;
        }
        Ok(())
    }

    /// VECTORS, NORMALS, TENSORS, TENSORS6, GLOBAL_IDS, PEDIGREE_IDS (`kw`):
    /// read when it is the point array asked for, else skipped.
    fn attribute(&mut self, r: &mut Reader, line: &[&str], kw: &str) -> Result<()> {
        let n = self.tuples(r, kw)?;
        let k = match kw {
            "VECTORS" | "NORMALS" => 3,
            "TENSORS" => 9,
            "TENSORS6" => 6,
            _ => 1,
        };
        let dt = r.dtype(line.get(2), kw)?;
        let aname = line.get(1).copied().unwrap_or("?");
        match self.owner {
            Owner::Points => self.seen_point_arrays.push(format!("{kw} {aname} ({k} components)")),
            Owner::Cells => self.seen_cell_arrays.push(format!("{kw} {aname} ({k} components)")),
            Owner::None => {}
        }
        let what = format!("{kw} '{aname}'");
        if self.want == Some(aname) && self.owner == Owner::Points {
            let v = r.values_f64(r.product(n, k, kw)?, dt, kw)?;
            self.scalars = Some((aname.to_string(), k, magnitudes(v, k, &r.err(&what).to_string(), "point")?));
        } else if self.want == Some(aname) && self.owner == Owner::Cells {
            self.cell_array = Some((aname.to_string(), k, r.values_f64(r.product(n, k, kw)?, dt, kw)?));
        } else {
            r.skip_values(r.product(n, k, kw)?, dt, kw)?;
        }
        Ok(())
    }

    /// The mesh, once every section is read: the sections it needs and the
    /// scalar (the array asked for, else the first one-component one).
    fn into_mesh(self, r: &Reader, name: &str) -> Result<TetMesh> {
        let points = self.points.ok_or_else(|| r.err("no POINTS section"))?;
        let (offsets, conn) = self.cells.ok_or_else(|| r.err("no CELLS section"))?;
        let types = self.types.ok_or_else(|| r.err("no CELL_TYPES section"))?;
        let list = |v: &[String]| if v.is_empty() { "none".to_string() } else { v.join(", ") };
        let seen = format!("point arrays: {}; cell arrays: {}", list(&self.seen_point_arrays), list(&self.seen_cell_arrays));
        let stem = Path::new(name).file_stem().map_or_else(|| "vtk".to_string(), |s| s.to_string_lossy().into_owned());
        let (offsets, conn, faces) = connectivity::cells_and_faces(r, &types, &offsets, &conn, points.len())?;
        let mut raw = RawCells { points, types, offsets, conn, faces, ..Default::default() };
        let fallback = self.want.is_none();
        if let Some((array, components, scalars)) = self.scalars.or(self.field_scalars) {
            raw.scalars = scalars;
            raw.scalar = Some(ScalarInfo { array, association: Association::Point, components, cell_data: None, fallback: false });
        } else if let Some((array, components, values)) = self.cell_array {
            raw.cell_values = values;
            let cell_data = Some(self.choice.cell_data);
            raw.scalar = Some(ScalarInfo { array, association: Association::Cell, components, cell_data, fallback });
        } else if let Some(w) = self.want {
            bail!(r.err(format!("no point or cell array named '{w}'; {seen}")));
        } else {
            bail!(r.err(format!(
                "no point scalars and no cell scalar: need a one-component SCALARS (or FIELD) array in POINT_DATA \
                 or CELL_DATA; found {seen}"
            )));
        }
        let mut counts = super::MeshStats::default();
        for (g, n, what) in [(&self.cell_ghost, raw.types.len(), "CELL_DATA"), (&self.point_ghost, raw.points.len(), "POINT_DATA")] {
            if g.as_ref().is_some_and(|g| g.len() != n) {
                bail!(r.err(format!("the {what} vtkGhostType array does not have one value per entry")));
            }
        }
        raw.drop_ghosts(self.cell_ghost.as_deref(), self.point_ghost.as_deref(), &mut counts);
        let mut mesh = raw.into_tet_mesh(name, stem)?;
        mesh.stats.add_read_counts(&counts);
        Ok(mesh)
    }

    /// Whether the cell array `name` (`ncomp` components) of the current
    /// CELL_DATA is read: the one asked for, or without a name the first
    /// one-component one (not the ghost marker).
    fn wants_cell_array(&self, name: &str, ncomp: usize) -> bool {
        match self.want {
            Some(w) => w == name,
            None => ncomp == 1 && self.cell_array.is_none() && name != "vtkGhostType",
        }
    }
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
        let s = m.stats.scalar.as_ref().unwrap();
        assert_eq!((s.array.as_str(), s.association, s.cell_data), ("temp", super::super::cell_data::Association::Point, None));
        // The cell array by name, constant per cell: each tet its own vertices.
        let c = parse_vtk_bytes_array("two.vtk", ASCII.as_bytes(), Some("cellid")).unwrap();
        assert_eq!(c.points.len(), 8);
        assert_eq!(c.scalars, vec![0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0]);
        assert_eq!(c.stats.vertex_origin, vec![0, 1, 2, 3, 1, 3, 4, 2]);
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
                .replace("LOOKUP_TABLE default\n9 9 9 9 9", &"0 ".repeat(15))
                .replace("CELL_DATA 2\nSCALARS cellid int 1\nLOOKUP_TABLE default\n0 1\n", ""), "no point scalars and no cell scalar"),
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
