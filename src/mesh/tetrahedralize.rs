//! Every cell of an unstructured file into tetrahedra: the driver behind
//! `RawCells::into_tet_mesh`. Linear cells go through `cells`' conforming
//! split with `repair`'s fallbacks, higher-order cells through
//! `higher_order`, polyhedra and prisms through `polyhedron`; points those
//! add (face, body and cell centroids) are appended to the points with
//! their interpolated scalars, and a face-centre point is shared by the two
//! cells of its face. Errors name the file's cell, its type and the reason;
//! validation errors that name tets also name the file cell each came from.

use anyhow::{anyhow, bail, Result};

use super::cells::{cell_type_name, RawCells};
use super::tet_builder::Tetrahedralizer;
use super::{higher_order, polyhedron, repair, HigherOrder, TetMesh};

/// How a cell type is treated when a volume mesh is read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CellKind {
    /// A linear 3-D cell with this many vertices: split into tets.
    Solid(usize),
    /// A 0-, 1- or 2-D cell (vertex, line, triangle, quad, their
    /// quadratic, Lagrange and Bezier forms, an empty cell): it has no
    /// volume, so it contributes nothing to a volume rendering; skipped and
    /// counted (`MeshStats::skipped_lower_dim`).
    LowerDim,
    /// A quadratic, Lagrange or Bezier 3-D cell (`higher_order`).
    HigherOrder,
    /// A polyhedron (42) or a pentagonal / hexagonal prism (`polyhedron`).
    Polyhedron,
    /// Anything else (convex point set, parametric and generic higher-order
    /// cells, unknown numbers): refused.
    Unsupported,
}

pub fn cell_kind(t: i64) -> CellKind {
    match t {
        10 => CellKind::Solid(4),
        11 | 12 => CellKind::Solid(8),
        13 => CellKind::Solid(6),
        14 => CellKind::Solid(5),
        15 | 16 | 42 => CellKind::Polyhedron,
        0..=9 | 21..=23 | 28 | 30 | 34..=36 | 51..=54 | 68..=70 | 75..=77 => CellKind::LowerDim,
        t if (0..=255).contains(&t) && higher_order::is_higher_order(t as u8) => CellKind::HigherOrder,
        _ => CellKind::Unsupported,
    }
}

impl RawCells {
    /// Splits every cell into tets (`tetrahedralize`): linear 3-D cells by
    /// [`CellSplitter`]'s rule with `repair`'s fallbacks, higher-order cells
    /// as `higher_order`'s mode (process-wide, `--higher-order`) says,
    /// polyhedra and prisms by `polyhedron`; lower-dimensional cells skipped
    /// and counted, anything else refused with an error naming each
    /// unsupported type and its count. `source` starts every error; the
    /// mesh is validated. A cell scalar (`cell_values`) is first averaged to
    /// the points (`average`, on the file's cells), or after the split given
    /// to each tet from its file cell (`constant`: each tet then has its own
    /// vertices); see `cell_data`.
    pub fn into_tet_mesh(self, source: &str, name: String) -> anyhow::Result<TetMesh> {
        self.into_tet_mesh_with(source, name, higher_order::mode())
    }

    /// [`RawCells::into_tet_mesh`] with higher-order cells read as `mode` says.
    pub fn into_tet_mesh_with(mut self, source: &str, name: String, mode: HigherOrder) -> anyhow::Result<TetMesh> {
        use super::cell_data::{self, CellData};
        let n = self.types.len();
        if self.offsets.len() != n + 1 {
            anyhow::bail!("{source}: {} cell offsets for {n} cells", self.offsets.len());
        }
        let np = self.points.len();
        // Cell data: averaged to the points here, on the file's cells; kept
        // per cell (its magnitude) for the constant treatment after the split.
        let info = self.scalar.clone();
        let mut cell_value: Option<Vec<f64>> = None;
        if let Some(info) = info.as_ref().filter(|i| i.association == cell_data::Association::Cell) {
            let k = info.components.max(1);
            if self.cell_values.len() != n * k {
                anyhow::bail!("{source}: cell array '{}' has {} values for {n} cells of {k} components", info.array, self.cell_values.len());
            }
            let what = format!("{source}: cell array '{}'", info.array);
            match info.cell_data.unwrap_or_default() {
                CellData::Average => {
                    let v = cell_data::average_to_points(np, &self.offsets, &self.conn, &self.cell_values, k, source)?;
                    self.scalars = cell_data::magnitudes(v, k, &format!("{what} averaged to the points"), "point")?;
                }
                CellData::Constant => {
                    let v = cell_data::magnitudes(std::mem::take(&mut self.cell_values), k, &what, "cell")?;
                    if let Some(c) = v.iter().position(|x| !x.is_finite()) {
                        anyhow::bail!("{what}: cell {c} has a non-finite value {}", v[c]);
                    }
                    if let Some(c) = v.iter().position(|x| x.abs() > super::geometry::MAX_ABS_VALUE) {
                        anyhow::bail!(
                            "{what}: cell {c} has a value beyond the f32 range (|s| > {:e}): {}; the renderers compute in f32",
                            super::geometry::MAX_ABS_VALUE,
                            v[c]
                        );
                    }
                    // Placeholder point scalars while splitting and validating.
                    self.scalars = vec![0.0; np];
                    cell_value = Some(v);
                }
            }
        }
        let (mut mesh, cell_of) = tetrahedralize(self, source, name, mode)?;
        mesh.stats.scalar = info;
        if let Some(v) = cell_value {
            let per_tet: Vec<f64> = cell_of.iter().map(|&c| v[c as usize]).collect();
            cell_data::constant_per_cell(&mut mesh, &per_tet, source)?;
        }
        Ok(mesh)
    }
}

/// `RawCells::into_tet_mesh`'s work (see there and the module docs): the
/// validated mesh and, for each of its tets, the file cell it comes from.
/// The cell scalar (`cell_values`) is the caller's.
pub(crate) fn tetrahedralize(raw: RawCells, source: &str, name: String, mode: HigherOrder) -> Result<(TetMesh, Vec<u32>)> {
    let RawCells { points, scalars, types, offsets, conn, faces, .. } = raw;
    let n = types.len();
    if offsets.len() != n + 1 {
        bail!("{source}: {} cell offsets for {n} cells", offsets.len());
    }
    let mut unsupported: std::collections::BTreeMap<u8, usize> = Default::default();
    for &t in &types {
        if cell_kind(t as i64) == CellKind::Unsupported {
            *unsupported.entry(t).or_default() += 1;
        }
    }
    if !unsupported.is_empty() {
        let list: Vec<String> =
            unsupported.iter().map(|(t, c)| format!("{c} cells of type {t} ({})", cell_type_name(*t as i64))).collect();
        bail!("{source}: unsupported cells: {}; {}", list.join(", "), READ_CELLS);
    }
    let np = points.len();
    let cell = |c: usize| -> Result<&[u32]> {
        let (a, b) = (offsets[c], offsets[c + 1]);
        conn.get(a..b).ok_or_else(|| anyhow!("{source}: cell {c}: offsets {a}..{b} outside the connectivity"))
    };
    let mut tz = Tetrahedralizer::new(points, scalars, mode);
    // Face-centre nodes of the cells that have them, for their serendipity neighbours.
    for (c, &t) in types.iter().enumerate() {
        if higher_order::is_higher_order(t) {
            let v = cell(c)?;
            if higher_order::check_node_count(t, v.len()).is_ok() && v.iter().all(|&i| (i as usize) < np) {
                higher_order::register_face_nodes(&mut tz, t, v);
            }
        }
    }
    let mut cell_of: Vec<u32> = Vec::new();
    let mut poly = 0usize;
    let mut skipped = 0;
    for (c, &t) in types.iter().enumerate() {
        let v = cell(c)?;
        let named = |e: anyhow::Error| anyhow!("{source}: cell {c} ({}, type {t}) {e}", cell_type_name(t as i64));
        if let Some(&bad) = v.iter().find(|&&i| i as usize >= np) {
            return Err(named(anyhow!("has point index {bad} out of range (the file has {np} points)")));
        }
        let before = tz.stats.repairs;
        match cell_kind(t as i64) {
            CellKind::Solid(k) => {
                if v.len() != k {
                    bail!("{source}: cell {c} is a {} (type {t}) but has {} vertices, not {k}", cell_type_name(t as i64), v.len());
                }
                repair::split_linear(&mut tz, t, v).map_err(named)?;
            }
            CellKind::HigherOrder => {
                higher_order::check_node_count(t, v.len()).map_err(named)?;
                higher_order::split(&mut tz, t, v).map_err(named)?;
                tz.stats.higher_order_cells += 1;
            }
            CellKind::Polyhedron => {
                if t == polyhedron::VTK_POLYHEDRON {
                    let k = faces.cells.get(poly).filter(|e| e.0 == c).map(|_| poly);
                    let Some(k) = k else {
                        return Err(named(anyhow!("has no faces (a polyhedron needs the file's face arrays)")));
                    };
                    poly += 1;
                    polyhedron::split(&mut tz, &faces.faces_of(k), Some(v)).map_err(named)?;
                } else {
                    let want = if t == polyhedron::VTK_PENTAGONAL_PRISM { 10 } else { 12 };
                    if v.len() != want {
                        return Err(named(anyhow!("has {} vertices, not {want}", v.len())));
                    }
                    let faces = polyhedron::prism_faces(v);
                    let refs: Vec<&[u32]> = faces.iter().map(|f| f.as_slice()).collect();
                    polyhedron::split(&mut tz, &refs, Some(v)).map_err(named)?;
                }
            }
            CellKind::LowerDim => skipped += 1,
            CellKind::Unsupported => return Err(named(anyhow!("is not a cell type volbench reads"))),
        }
        // Count each file cell once per kind of repair (a higher-order
        // cell's sub-cells are repaired one by one).
        let r = &mut tz.stats.repairs;
        r.reoriented_cells = r.reoriented_cells.min(before.reoriented_cells + 1);
        r.resplit_cells = r.resplit_cells.min(before.resplit_cells + 1);
        r.centroid_split_cells = r.centroid_split_cells.min(before.centroid_split_cells + 1);
        r.degenerate_cells = r.degenerate_cells.min(before.degenerate_cells + 1);
        cell_of.resize(tz.tets.len(), c as u32);
    }
    if poly != faces.cells.len() {
        bail!("{source}: the face arrays describe {} polyhedra but {poly} cells are of type 42", faces.cells.len());
    }
    let mut stats = tz.stats;
    stats.skipped_lower_dim = skipped;
    if stats.higher_order_cells > 0 {
        stats.higher_order = Some(mode);
    }
    let mut mesh = TetMesh { name, points: tz.points, scalars: tz.scalars, tets: tz.tets, stats };
    if mesh.tets.is_empty() && skipped > 0 && mesh.stats.repairs.degenerate_cells == 0 {
        bail!("{source}: no 3-D cells: all {skipped} cells are vertices, lines or surface cells");
    }
    mesh.validate(source).map_err(|e| name_cells(e, &cell_of, &types))?;
    Ok((mesh, cell_of))
}

/// What the readers read, for the refusal of other cell types.
pub const READ_CELLS: &str = "volbench reads the linear cells tetra (10), voxel (11), hexahedron (12), wedge (13), pyramid (14), \
     pentagonal and hexagonal prisms (15, 16) and polyhedra (42); the quadratic tetra, hexahedron, wedge and pyramid \
     (24-27), triquadratic hexahedron (29), quadratic-linear and biquadratic-quadratic wedges (31, 32), \
     biquadratic-quadratic hexahedron (33) and Lagrange tetra, hexahedron and wedge (71-73) subdivided through every \
     node; the triquadratic pyramid (37), Lagrange pyramid (74) and Bezier cells (78-81) by their corners \
     (--higher-order corners); and skips 0- to 2-D cells (see docs/formats.md)";

/// Adds to a validation error that names tets which file cell each came from.
fn name_cells(e: anyhow::Error, cell_of: &[u32], types: &[u8]) -> anyhow::Error {
    let text = format!("{e:#}");
    let mut named = Vec::new();
    let bytes = text.as_bytes();
    let mut i = 0;
    while let Some(at) = text[i..].find("tet") {
        let mut j = i + at + 3;
        if bytes.get(j) == Some(&b's') {
            j += 1;
        }
        // "tet N", "tets N and M", "tets [N, M]"
        let rest = &text[j..];
        let mut k = 0;
        let mut nums = Vec::new();
        let rb = rest.as_bytes();
        while k < rb.len() && (rb[k] == b' ' || rb[k] == b'[' || rb[k] == b',' || rb[k].is_ascii_digit() || rest[k..].starts_with("and ")) {
            if rest[k..].starts_with("and ") {
                k += 4;
                continue;
            }
            if rb[k].is_ascii_digit() {
                let s = k;
                while k < rb.len() && rb[k].is_ascii_digit() {
                    k += 1;
                }
                if let Ok(x) = rest[s..k].parse::<usize>() {
                    nums.push(x);
                }
                continue;
            }
            k += 1;
        }
        for t in nums {
            if let Some(&c) = cell_of.get(t) {
                let ty = types[c as usize];
                let s = format!("tet {t} is from cell {c} ({}, type {ty})", cell_type_name(ty as i64));
                if !named.contains(&s) {
                    named.push(s);
                }
            }
        }
        i = j;
    }
    if named.is_empty() {
        e
    } else {
        anyhow!("{text} [{}]", named.join("; "))
    }
}

#[cfg(test)]
#[path = "tetrahedralize_tests.rs"]
mod tests;
