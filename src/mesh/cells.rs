//! Linear VTK cells (tetra, voxel, hexahedron, wedge, pyramid) split into
//! tetrahedra *conformingly*: two cells that share a quadrilateral face cut
//! it along the same diagonal, so the result has no cracks and its face
//! adjacency closes. Both the legacy (`vtk`) and the XML (`vtu`) readers go
//! through [`CellSplitter`].
//!
//! The rule (Dompierre, Labbé, Vallet, Camarero, "How to subdivide pyramids,
//! prisms and hexahedra into tetrahedra", 8th International Meshing
//! Roundtable, 1999): a quad face is cut along the diagonal through its
//! vertex with the smallest global index. Both neighbours see the same four
//! indices, so they pick the same diagonal whatever else they do.
//!
//! Each cell type then needs a triangulation of its reference cell that
//! induces exactly the required diagonals. Those are not hand-written: for
//! each type every triangulation of its reference cell that uses only its
//! vertices is enumerated once (a search over vertex 4-sets, pairwise
//! interior-disjoint by exact integer separating-axis tests, volumes summing
//! to the cell's, every inner triangle shared by exactly two tets), and each
//! is filed under the diagonals it puts on the quad faces. The counts are
//! the known ones (tested): pyramid 2, wedge 6, hexahedron 74 (2 with 5
//! tets, 72 with 6).
//! - Pyramids and wedges: every diagonal choice the rule can produce has a
//!   triangulation (2 and 3 tets).
//! - Hexahedra: of the 64 ways to cut the 6 faces, 2 have a 5-tet
//!   triangulation, 44 a 6-tet one and 18 none on the hex's own vertices
//!   (those would need a Steiner point). The min-index rule never produces
//!   one of the 18: its global-minimum corner has all three of its faces cut
//!   through it, and the exhaustive check over all 8! = 40,320 orders of a
//!   hex's corner indices (`min_index_rule_always_fits`) finds 42 reachable
//!   cuts, each with a triangulation. So no point is ever added; a hex with
//!   5-tet cuts gets 5 tets, every other 6.
//!
//! Tets are emitted positively oriented when the cell itself is (its
//! reference triangulation is oriented on the reference cell), so a
//! well-formed cell adds nothing to `MeshStats::reoriented`.
//!
//! The other cells (higher-order, polyhedra, and linear cells that fold
//! over or are collapsed) are split by `higher_order`, `polyhedron` and
//! `repair`, driven per file cell by `tetrahedralize`, all on top of this
//! rule ([`conforming_triangulations`] gives `repair` every triangulation
//! that keeps a cell's face diagonals).

use std::collections::HashMap;
use std::sync::OnceLock;

/// VTK cell type numbers of the linear 3-D cells.
pub const VTK_TETRA: u8 = 10;
pub const VTK_VOXEL: u8 = 11;
pub const VTK_HEXAHEDRON: u8 = 12;
pub const VTK_WEDGE: u8 = 13;
pub const VTK_PYRAMID: u8 = 14;

/// The VTK name of a cell type, for messages.
pub fn cell_type_name(t: i64) -> &'static str {
    match t {
        1 => "vertex",
        2 => "poly-vertex",
        3 => "line",
        4 => "poly-line",
        5 => "triangle",
        6 => "triangle strip",
        7 => "polygon",
        8 => "pixel",
        9 => "quad",
        10 => "tetra",
        11 => "voxel",
        12 => "hexahedron",
        13 => "wedge",
        14 => "pyramid",
        15 => "pentagonal prism",
        16 => "hexagonal prism",
        21 => "quadratic edge",
        22 => "quadratic triangle",
        23 => "quadratic quad",
        24 => "quadratic tetra",
        25 => "quadratic hexahedron",
        26 => "quadratic wedge",
        27 => "quadratic pyramid",
        28 => "biquadratic quad",
        29 => "triquadratic hexahedron",
        30 => "quadratic-linear quad",
        31 => "quadratic-linear wedge",
        32 => "biquadratic-quadratic wedge",
        33 => "biquadratic-quadratic hexahedron",
        34 => "biquadratic triangle",
        35 => "cubic line",
        36 => "quadratic polygon",
        37 => "triquadratic pyramid",
        41 => "convex point set",
        42 => "polyhedron",
        51 => "parametric curve",
        52 => "parametric surface",
        53 => "parametric tri surface",
        54 => "parametric quad surface",
        55 => "parametric tetra region",
        56 => "parametric hex region",
        60 => "higher-order edge",
        61 => "higher-order triangle",
        62 => "higher-order quad",
        63 => "higher-order polygon",
        64 => "higher-order tetrahedron",
        65 => "higher-order wedge",
        66 => "higher-order pyramid",
        67 => "higher-order hexahedron",
        68 => "Lagrange curve",
        69 => "Lagrange triangle",
        70 => "Lagrange quadrilateral",
        71 => "Lagrange tetrahedron",
        72 => "Lagrange hexahedron",
        73 => "Lagrange wedge",
        74 => "Lagrange pyramid",
        75 => "Bezier curve",
        76 => "Bezier triangle",
        77 => "Bezier quadrilateral",
        78 => "Bezier tetrahedron",
        79 => "Bezier hexahedron",
        80 => "Bezier wedge",
        81 => "Bezier pyramid",
        0 => "empty cell",
        _ => "unknown",
    }
}

/// A reference cell: integer vertex coordinates (convex, in VTK's vertex
/// order) and its faces (quads in cyclic order).
struct Reference {
    coords: &'static [[i64; 3]],
    faces: &'static [&'static [usize]],
}

const PYRAMID_REF: Reference = Reference {
    coords: &[[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0], [1, 1, 2]],
    faces: &[&[0, 1, 2, 3], &[0, 1, 4], &[1, 2, 4], &[2, 3, 4], &[3, 0, 4]],
};
const WEDGE_REF: Reference = Reference {
    coords: &[[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [0, 1, 1]],
    faces: &[&[0, 1, 2], &[3, 4, 5], &[0, 1, 4, 3], &[1, 2, 5, 4], &[2, 0, 3, 5]],
};
const HEX_REF: Reference = Reference {
    coords: &[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
    faces: &[&[0, 1, 2, 3], &[4, 5, 6, 7], &[0, 1, 5, 4], &[1, 2, 6, 5], &[2, 3, 7, 6], &[3, 0, 4, 7]],
};

fn sub(a: [i64; 3], b: [i64; 3]) -> [i64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: [i64; 3], b: [i64; 3]) -> [i64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn dot(a: [i64; 3], b: [i64; 3]) -> i64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn det(p: [[i64; 3]; 4]) -> i64 {
    dot(sub(p[1], p[0]), cross(sub(p[2], p[0]), sub(p[3], p[0])))
}

/// Whether two tets' interiors are disjoint: some axis (a face normal of
/// either, or a cross product of an edge of each) separates their
/// projections. Exact in integers; complete for convex polytopes.
fn interiors_disjoint(a: [[i64; 3]; 4], b: [[i64; 3]; 4]) -> bool {
    let edges = |t: [[i64; 3]; 4]| {
        let mut e = Vec::with_capacity(6);
        for i in 0..4 {
            for j in i + 1..4 {
                e.push(sub(t[j], t[i]));
            }
        }
        e
    };
    let (ea, eb) = (edges(a), edges(b));
    let mut axes = Vec::new();
    for t in [&ea, &eb] {
        for i in 0..6 {
            for j in i + 1..6 {
                axes.push(cross(t[i], t[j]));
            }
        }
    }
    for x in &ea {
        for y in &eb {
            axes.push(cross(*x, *y));
        }
    }
    axes.iter().filter(|n| **n != [0, 0, 0]).any(|&n| {
        let pa = a.map(|p| dot(p, n));
        let pb = b.map(|p| dot(p, n));
        let (amin, amax) = (pa.iter().min().copied().unwrap_or(0), pa.iter().max().copied().unwrap_or(0));
        let (bmin, bmax) = (pb.iter().min().copied().unwrap_or(0), pb.iter().max().copied().unwrap_or(0));
        amax <= bmin || bmax <= amin
    })
}

/// Every triangulation of a reference cell on its own vertices, each as
/// positively oriented local tets.
fn triangulations(r: &Reference) -> Vec<Vec<[usize; 4]>> {
    let n = r.coords.len();
    let pos = |t: [usize; 4]| t.map(|i| r.coords[i]);
    let mut tets = Vec::new();
    for a in 0..n {
        for b in a + 1..n {
            for c in b + 1..n {
                for d in c + 1..n {
                    let t = [a, b, c, d];
                    let v = det(pos(t));
                    if v > 0 {
                        tets.push((t, v));
                    } else if v < 0 {
                        tets.push(([a, b, d, c], -v));
                    }
                }
            }
        }
    }
    // Cell volume x6 by coning the faces from vertex 0 (convex cell).
    let total: i64 = r
        .faces
        .iter()
        .filter(|f| !f.contains(&0))
        .map(|f| (1..f.len() - 1).map(|k| det(pos([0, f[0], f[k], f[k + 1]])).abs()).sum::<i64>())
        .sum();
    let on_boundary = |tri: [usize; 3]| r.faces.iter().any(|f| tri.iter().all(|v| f.contains(v)));
    let mut out = Vec::new();
    let mut chosen: Vec<usize> = Vec::new();
    fn search(
        start: usize,
        left: i64,
        tets: &[([usize; 4], i64)],
        pos: &dyn Fn([usize; 4]) -> [[i64; 3]; 4],
        chosen: &mut Vec<usize>,
        out: &mut Vec<Vec<usize>>,
    ) {
        if left == 0 {
            out.push(chosen.clone());
            return;
        }
        for i in start..tets.len() {
            let (t, v) = tets[i];
            if v > left || !chosen.iter().all(|&c| interiors_disjoint(pos(tets[c].0), pos(t))) {
                continue;
            }
            chosen.push(i);
            search(i + 1, left - v, tets, pos, chosen, out);
            chosen.pop();
        }
    }
    let mut found = Vec::new();
    search(0, total, &tets, &pos, &mut chosen, &mut found);
    for set in found {
        let ts: Vec<[usize; 4]> = set.iter().map(|&i| tets[i].0).collect();
        // Face to face: every triangle not on the cell's boundary is held by exactly two tets.
        let mut count: HashMap<[usize; 3], usize> = HashMap::new();
        for t in &ts {
            for f in 0..4 {
                let mut tri = [t[(f + 1) % 4], t[(f + 2) % 4], t[(f + 3) % 4]];
                tri.sort_unstable();
                *count.entry(tri).or_default() += 1;
            }
        }
        if count.iter().all(|(tri, &c)| if on_boundary(*tri) { c == 1 } else { c == 2 }) {
            out.push(ts);
        }
    }
    out
}

/// Which diagonal of each quad face a triangulation uses, as a bit per quad
/// (bit set: the diagonal through the face's vertices 1 and 3, clear: 0 and 2).
fn signature(r: &Reference, tets: &[[usize; 4]]) -> u32 {
    let mut sig = 0;
    for (q, f) in r.faces.iter().filter(|f| f.len() == 4).enumerate() {
        let uses_13 = tets.iter().any(|t| t.contains(&f[1]) && t.contains(&f[3]) && t.iter().filter(|v| f.contains(v)).count() == 3);
        if uses_13 {
            sig |= 1 << q;
        }
    }
    sig
}

/// The required signature of a cell from its global vertex indices: each quad
/// is cut through its smallest-index vertex.
fn required_signature(r: &Reference, global: &[u32]) -> u32 {
    let mut sig = 0;
    for (q, f) in r.faces.iter().filter(|f| f.len() == 4).enumerate() {
        let min_at = (0..4).min_by_key(|&k| global[f[k]]).unwrap_or(0);
        if min_at % 2 == 1 {
            sig |= 1 << q;
        }
    }
    sig
}

/// Per cell type: signature -> the triangulation with fewest tets, and every
/// triangulation with that signature (fewest tets first; `repair` tries the
/// others when the first folds over).
struct Table {
    by_signature: HashMap<u32, Vec<[usize; 4]>>,
    all_by_signature: HashMap<u32, Vec<Vec<[usize; 4]>>>,
}

fn table(r: &Reference) -> Table {
    let all = triangulations(r);
    let mut by_signature: HashMap<u32, Vec<[usize; 4]>> = HashMap::new();
    let mut all_by_signature: HashMap<u32, Vec<Vec<[usize; 4]>>> = HashMap::new();
    for t in &all {
        let s = signature(r, t);
        let e = by_signature.entry(s).or_insert_with(|| t.clone());
        if t.len() < e.len() {
            *e = t.clone();
        }
        all_by_signature.entry(s).or_default().push(t.clone());
    }
    for v in all_by_signature.values_mut() {
        v.sort_by_key(|t| t.len());
    }
    Table { by_signature, all_by_signature }
}

/// A linear cell in hexahedron order (a voxel's corners reordered), for
/// the per-cell code outside this module.
pub(crate) fn as_hex_order(cell_type: u8, v: &[u32]) -> (u8, Vec<u32>) {
    if cell_type == VTK_VOXEL {
        (VTK_HEXAHEDRON, vec![v[0], v[1], v[3], v[2], v[4], v[5], v[7], v[6]])
    } else {
        (cell_type, v.to_vec())
    }
}

/// A reference cell: its integer vertex coordinates and faces.
pub(crate) type ReferenceCell = (&'static [[i64; 3]], &'static [&'static [usize]]);

/// The reference cell of a pyramid, wedge or hexahedron (`repair`'s
/// centroid split cones its faces).
pub(crate) fn reference_of(cell_type: u8) -> Option<ReferenceCell> {
    let r = match cell_type {
        VTK_PYRAMID => &PYRAMID_REF,
        VTK_WEDGE => &WEDGE_REF,
        VTK_HEXAHEDRON => &HEX_REF,
        _ => return None,
    };
    Some((r.coords, r.faces))
}

/// Every triangulation of a pyramid, wedge or hexahedron (hexahedron
/// order) on its own vertices that cuts its quad faces as the min-index
/// rule requires for the global indices `v`, fewest tets first. The first
/// is the one [`CellSplitter::add`] uses; all keep the neighbours conforming.
///
/// A quad face with a repeated id (a collapsed cell) has no diagonal to
/// agree on: either cut leaves the same non-degenerate triangle, so its
/// bit is free and every triangulation matching the other quads is a
/// candidate.
pub(crate) fn conforming_triangulations(cell_type: u8, v: &[u32]) -> Vec<&'static Vec<[usize; 4]>> {
    let (r, t) = match cell_type {
        VTK_PYRAMID => (&PYRAMID_REF, &tables()[0]),
        VTK_WEDGE => (&WEDGE_REF, &tables()[1]),
        VTK_HEXAHEDRON => (&HEX_REF, &tables()[2]),
        _ => return Vec::new(),
    };
    let want = required_signature(r, v);
    let mut free = 0u32;
    for (q, f) in r.faces.iter().filter(|f| f.len() == 4).enumerate() {
        if (0..4).any(|a| (a + 1..4).any(|b| v[f[a]] == v[f[b]])) {
            free |= 1 << q;
        }
    }
    if free == 0 {
        return t.all_by_signature.get(&want).map_or_else(Vec::new, |list| list.iter().collect());
    }
    let mut out: Vec<&'static Vec<[usize; 4]>> = t
        .all_by_signature
        .iter()
        .filter(|(sig, _)| (**sig & !free) == (want & !free))
        .flat_map(|(_, list)| list.iter())
        .collect();
    // Deterministic: the rule's own signature first, then fewest tets.
    out.sort_by_key(|x| (signature(r, x) != want, x.len(), (*x).clone()));
    out
}

/// The local vertex pair of the diagonal the min-index rule cuts a quad
/// face (local vertices `f`, global indices `v`) along.
pub(crate) fn quad_diagonal(f: &[usize], v: &[u32]) -> usize {
    (0..4).min_by_key(|&k| v[f[k]]).unwrap_or(0) % 2
}

fn tables() -> &'static [Table; 3] {
    static T: OnceLock<[Table; 3]> = OnceLock::new();
    T.get_or_init(|| [table(&PYRAMID_REF), table(&WEDGE_REF), table(&HEX_REF)])
}

/// Splits cells into tets by the min-index rule (module docs).
#[derive(Default)]
pub struct CellSplitter {
    pub tets: Vec<[u32; 4]>,
}

impl CellSplitter {

    /// Adds one cell of a solid type (`cell_kind(t) == Solid(v.len())`,
    /// indices in range: the readers check both first).
    pub fn add(&mut self, cell_type: u8, v: &[u32]) -> anyhow::Result<()> {
        let (r, table) = match cell_type {
            VTK_TETRA => {
                self.tets.push([v[0], v[1], v[2], v[3]]);
                return Ok(());
            }
            VTK_VOXEL => {
                // Voxel corners are in grid order; as a hexahedron: 0 1 3 2 4 5 7 6.
                let h = [v[0], v[1], v[3], v[2], v[4], v[5], v[7], v[6]];
                return self.add(VTK_HEXAHEDRON, &h);
            }
            VTK_PYRAMID => (&PYRAMID_REF, &tables()[0]),
            VTK_WEDGE => (&WEDGE_REF, &tables()[1]),
            VTK_HEXAHEDRON => (&HEX_REF, &tables()[2]),
            t => anyhow::bail!("cell type {t} ({}) cannot be split into tetrahedra", cell_type_name(t as i64)),
        };
        let sig = required_signature(r, v);
        if let Some(local) = table.by_signature.get(&sig) {
            self.tets.extend(local.iter().map(|t| t.map(|i| v[i])));
            return Ok(());
        }
        // Unreachable under the min-index rule (see the module docs and
        // `min_index_rule_always_fits`); an error rather than a panic.
        anyhow::bail!("no triangulation of a {} with the cut diagonals {sig:#b}", cell_type_name(cell_type as i64))
    }
}

/// Cells as an unstructured file holds them (VTK's layout: a type per cell,
/// offsets into one connectivity array), before splitting. Indices are
/// checked against the points when the cells are split.
#[derive(Debug, Clone, Default)]
pub struct RawCells {
    pub points: Vec<[f64; 3]>,
    /// One per point when the scalar is point data; empty when it is cell
    /// data (`cell_values`), until [`RawCells::into_tet_mesh`] applies the
    /// treatment.
    pub scalars: Vec<f64>,
    pub types: Vec<u8>,
    /// `types.len() + 1` rising offsets into `conn`, from 0.
    pub offsets: Vec<usize>,
    /// For polyhedra (type 42), whose `conn` holds their points, their faces.
    pub faces: PolyFaces,
    pub conn: Vec<u32>,
    /// The scalar as cell data: `scalar.components` values per cell (a
    /// vector's components, kept until the treatment: `average` averages
    /// them one by one as VTK does, then takes the magnitude). Empty for
    /// point data.
    pub cell_values: Vec<f64>,
    /// What the scalar is (`cell_data`); its `cell_data` field is the
    /// treatment [`RawCells::into_tet_mesh`] applies to cell data.
    pub scalar: Option<super::cell_data::ScalarInfo>,
}

impl RawCells {
    /// Appends another piece, its indices shifted past this one's points.
    pub fn append(&mut self, other: RawCells) -> anyhow::Result<()> {
        if self.offsets.is_empty() {
            self.offsets.push(0);
        }
        let base = u32::try_from(self.points.len()).map_err(|_| anyhow::anyhow!("too many points for 32-bit indices"))?;
        base.checked_add(u32::try_from(other.points.len()).unwrap_or(u32::MAX))
            .ok_or_else(|| anyhow::anyhow!("too many points for 32-bit indices"))?;
        match (&self.scalar, &other.scalar) {
            (Some(a), Some(b)) if (&a.array, a.association, a.components) != (&b.array, b.association, b.components) => {
                anyhow::bail!(
                    "pieces with different scalars: {} array '{}' ({} components) and {} array '{}' ({} components)",
                    a.association.name(),
                    a.array,
                    a.components,
                    b.association.name(),
                    b.array,
                    b.components
                );
            }
            (None, Some(_)) if self.types.is_empty() => self.scalar = other.scalar.clone(),
            _ => {}
        }
        let at = self.conn.len();
        self.faces.append(other.faces, self.types.len(), base);
        self.points.extend(other.points);
        self.scalars.extend(other.scalars);
        self.cell_values.extend(other.cell_values);
        self.types.extend(other.types);
        self.offsets.extend(other.offsets.iter().skip(1).map(|o| o + at));
        self.conn.extend(other.conn.iter().map(|v| v + base));
        Ok(())
    }

    /// Merges points with bit-identical coordinates (pieces of a parallel
    /// file repeat their shared boundary points) and renumbers the cells;
    /// returns how many points were merged away and how many of those had
    /// a scalar different from their first copy's (which is kept).
    pub fn weld(&mut self) -> (usize, usize) {
        let map = super::adjacency::weld_coincident(&self.points);
        let mut new_index = vec![u32::MAX; self.points.len()];
        let (mut points, mut scalars) = (Vec::new(), Vec::new());
        let mut mismatches = 0;
        for (i, &rep) in map.iter().enumerate() {
            let rep = rep as usize;
            if rep == i {
                new_index[i] = points.len() as u32;
                points.push(self.points[i]);
                if let Some(&s) = self.scalars.get(i) {
                    scalars.push(s);
                }
            } else if self.scalars.get(i).map(|s| s.to_bits()) != self.scalars.get(rep).map(|s| s.to_bits()) {
                mismatches += 1;
            }
        }
        let merged = self.points.len() - points.len();
        for v in self.conn.iter_mut().chain(self.faces.conn.iter_mut()) {
            if let Some(&rep) = map.get(*v as usize) {
                *v = new_index[rep as usize];
            }
        }
        self.points = points;
        self.scalars = scalars;
        (merged, mismatches)
    }

    /// Keeps the cells `keep` says yes to (by index), in order; the points
    /// stay as they are.
    pub fn retain_cells(&mut self, mut keep: impl FnMut(usize) -> bool) {
        let n = self.types.len();
        let kept: Vec<bool> = (0..n).map(&mut keep).collect();
        self.faces.retain_cells(&kept);
        // Cell data goes with its cell: `k` values per cell (none for point data).
        let k = if self.cell_values.is_empty() || n == 0 { 0 } else { self.cell_values.len() / n };
        let (mut t, mut c) = (0usize, 0usize);
        for (i, _) in kept.iter().enumerate().filter(|(_, &keep_it)| keep_it) {
            let (a, b) = (self.offsets[i], self.offsets[i + 1]);
            self.cell_values.copy_within(i * k..(i + 1) * k, t * k);
            self.types[t] = self.types[i];
            self.conn.copy_within(a..b, c);
            c += b - a;
            t += 1;
            self.offsets[t] = c;
        }
        self.types.truncate(t);
        self.offsets.truncate(t + 1);
        self.conn.truncate(c);
        self.cell_values.truncate(t * k);
    }

    /// Skips the cells VTK does not draw, by the `vtkGhostType` arrays
    /// (`cell_ghost`: one per cell, `point_ghost`: one per point; both
    /// checked for length by the caller, indices against the points when
    /// split): a cell marked `DUPLICATECELL` (1, owned by a neighbouring
    /// piece), `REFINEDCELL` (8, covered by finer cells) or `HIDDENCELL`
    /// (32), or using a point marked `HIDDENPOINT` (2), as
    /// `vtkGeometryFilter` and `vtkRemoveGhosts` do. The other bits
    /// (`HIGHCONNECTIVITYCELL` 2, `LOWCONNECTIVITYCELL` 4, `EXTERIORCELL`
    /// 16) mark cells that are drawn. `DUPLICATEPOINT` (1) points stay.
    /// The counts go to `stats` (`ghost_cells`, `hidden_cells`,
    /// `ghost_points`).
    pub fn drop_ghosts(&mut self, cell_ghost: Option<&[u8]>, point_ghost: Option<&[u8]>, stats: &mut super::MeshStats) {
        const DUPLICATECELL: u8 = 1;
        const REFINEDCELL: u8 = 8;
        const HIDDENCELL: u8 = 32;
        const HIDDENPOINT: u8 = 2;
        if let Some(pg) = point_ghost {
            stats.ghost_points += pg.iter().filter(|&&g| g & 3 != 0).count();
        }
        let hidden_point = |v: u32| point_ghost.and_then(|pg| pg.get(v as usize)).is_some_and(|&g| g & HIDDENPOINT != 0);
        let (mut dup, mut hidden) = (0, 0);
        let kept: Vec<bool> = (0..self.types.len())
            .map(|c| {
                let g = cell_ghost.and_then(|cg| cg.get(c)).copied().unwrap_or(0);
                let uses_hidden = || {
                    point_ghost.is_some()
                        && self.offsets.get(c..c + 2).and_then(|o| self.conn.get(o[0]..o[1])).is_some_and(|v| v.iter().any(|&p| hidden_point(p)))
                };
                if g & DUPLICATECELL != 0 {
                    dup += 1;
                    false
                } else if g & (HIDDENCELL | REFINEDCELL) != 0 || uses_hidden() {
                    hidden += 1;
                    false
                } else {
                    true
                }
            })
            .collect();
        if dup + hidden > 0 {
            self.retain_cells(|c| kept[c]);
        }
        stats.ghost_cells += dup;
        stats.hidden_cells += hidden;
    }
}

/// The polyhedra of a [`RawCells`]: for each, its cell index
/// and its faces.
#[derive(Debug, Clone, Default)]
pub struct PolyFaces {
    /// (cell index, first face, end face), cells rising.
    pub cells: Vec<(usize, usize, usize)>,
    /// `faces + 1` rising offsets into `conn`, from 0 (empty: no faces).
    pub offsets: Vec<usize>,
    pub conn: Vec<u32>,
}

impl PolyFaces {
    /// Adds the faces of cell `cell` (after every cell added so far).
    pub fn push_cell(&mut self, cell: usize, faces: &[Vec<u32>]) {
        if self.offsets.is_empty() {
            self.offsets.push(0);
        }
        let first = self.offsets.len() - 1;
        for f in faces {
            self.conn.extend_from_slice(f);
            self.offsets.push(self.conn.len());
        }
        self.cells.push((cell, first, first + faces.len()));
    }

    /// Appends another piece's polyhedra, whose cells follow `cell_base`
    /// cells and whose points follow `point_base` points.
    pub fn append(&mut self, other: PolyFaces, cell_base: usize, point_base: u32) {
        for k in 0..other.cells.len() {
            let faces = other.faces_of(k).into_iter().map(|f| f.iter().map(|v| v + point_base).collect()).collect::<Vec<Vec<u32>>>();
            self.push_cell(other.cells[k].0 + cell_base, &faces);
        }
    }

    /// The faces of the `k`-th polyhedron.
    pub fn faces_of(&self, k: usize) -> Vec<&[u32]> {
        let (_, a, b) = self.cells[k];
        (a..b).map(|f| &self.conn[self.offsets[f]..self.offsets[f + 1]]).collect()
    }

    /// Keeps the polyhedra of the cells `keep` says, renumbering the cells
    /// (ghost cells dropped).
    pub fn retain_cells(&mut self, keep: &[bool]) {
        if self.cells.is_empty() {
            return;
        }
        let mut new_index = Vec::with_capacity(keep.len());
        let mut n = 0;
        for &k in keep {
            new_index.push(n);
            n += k as usize;
        }
        let old = std::mem::take(self);
        for k in 0..old.cells.len() {
            let c = old.cells[k].0;
            if keep.get(c).copied().unwrap_or(false) {
                let faces: Vec<Vec<u32>> = old.faces_of(k).into_iter().map(|f| f.to_vec()).collect();
                self.push_cell(new_index[c], &faces);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::adjacency::FaceAdjacency;
    use crate::mesh::{MeshStats, TetGeometry, TetMesh};

    const TET_REF: Reference = Reference { coords: &[[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], faces: &[&[0, 1, 2], &[0, 1, 3], &[1, 2, 3], &[0, 2, 3]] };

    #[test]
    fn triangulation_counts_are_the_known_ones() {
        let t = tables();
        assert_eq!(triangulations(&TET_REF).len(), 1);
        assert_eq!(triangulations(&PYRAMID_REF).len(), 2, "pyramid");
        assert_eq!(triangulations(&WEDGE_REF).len(), 6, "wedge");
        assert_eq!(triangulations(&HEX_REF).len(), 74, "hexahedron");
        assert_eq!(t[0].by_signature.len(), 2);
        assert_eq!(t[1].by_signature.len(), 6);
        // Hex: 2 five-tet signatures, 44 six-tet ones; 18 of 64 need a centre point.
        assert_eq!(t[2].by_signature.values().filter(|v| v.len() == 5).count(), 2);
        assert_eq!(t[2].by_signature.values().filter(|v| v.len() == 6).count(), 44);
    }

    #[test]
    fn min_index_rule_always_fits() {
        // Every ordering of the global indices: the rule's signature has a triangulation.
        fn perms(n: usize) -> Vec<Vec<u32>> {
            if n == 0 {
                return vec![vec![]];
            }
            let mut out = Vec::new();
            for p in perms(n - 1) {
                for at in 0..=p.len() {
                    let mut q = p.clone();
                    q.insert(at, (n - 1) as u32);
                    out.push(q);
                }
            }
            out
        }
        let hex: std::collections::HashSet<u32> = perms(8).iter().map(|p| required_signature(&HEX_REF, p)).collect();
        assert_eq!(hex.len(), 42, "cuts the rule reaches on a hex");
        for (r, t) in [(&PYRAMID_REF, &tables()[0]), (&WEDGE_REF, &tables()[1]), (&HEX_REF, &tables()[2])] {
            for p in perms(r.coords.len()) {
                assert!(t.by_signature.contains_key(&required_signature(r, &p)), "{p:?}");
            }
        }
    }

    /// A structured block of `n³` unit cells, each randomly a hexahedron, a
    /// voxel, two wedges or six pyramids on an extra centre point. Global
    /// indices are shuffled so the cuts vary from face to face.
    type Block = (Vec<[f64; 3]>, Vec<(u8, Vec<u32>)>);

    fn mixed_block(n: usize, seed: u64, warp: bool) -> Block {
        let mut rng = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        let mut next = move || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            rng
        };
        let np = (n + 1).pow(3);
        let mut perm: Vec<u32> = (0..np as u32).collect();
        for i in (1..np).rev() {
            perm.swap(i, (next() % (i as u64 + 1)) as usize);
        }
        let mut points = vec![[0.0; 3]; np];
        let at = |i: usize, j: usize, k: usize| perm[i + (n + 1) * (j + (n + 1) * k)];
        for k in 0..=n {
            for j in 0..=n {
                for i in 0..=n {
                    let (x, y, z) = (i as f64, j as f64, k as f64);
                    points[at(i, j, k) as usize] =
                        if warp { [x + 0.1 * (y * 1.3).sin(), y + 0.1 * (z + x).cos(), z + 0.05 * x * y] } else { [x, y, z] };
                }
            }
        }
        let mut cells = Vec::new();
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let c = |di, dj, dk| at(i + di, j + dj, k + dk);
                    let hex = vec![c(0, 0, 0), c(1, 0, 0), c(1, 1, 0), c(0, 1, 0), c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1)];
                    match next() % 4 {
                        0 => cells.push((VTK_HEXAHEDRON, hex)),
                        1 => cells.push((VTK_VOXEL, vec![hex[0], hex[1], hex[3], hex[2], hex[4], hex[5], hex[7], hex[6]])),
                        2 => {
                            // Two wedges through a vertical diagonal plane, when the rule
                            // cuts the bottom and top faces along parallel diagonals
                            // (their triangles lie on those faces); else a hex.
                            let through = |q: [usize; 4]| (0..4).min_by_key(|&k| hex[q[k]]).unwrap_or(0) % 2;
                            match (through([0, 1, 2, 3]), through([4, 5, 6, 7])) {
                                (0, 0) => {
                                    cells.push((VTK_WEDGE, vec![hex[0], hex[1], hex[2], hex[4], hex[5], hex[6]]));
                                    cells.push((VTK_WEDGE, vec![hex[0], hex[2], hex[3], hex[4], hex[6], hex[7]]));
                                }
                                (1, 1) => {
                                    cells.push((VTK_WEDGE, vec![hex[1], hex[2], hex[3], hex[5], hex[6], hex[7]]));
                                    cells.push((VTK_WEDGE, vec![hex[1], hex[3], hex[0], hex[5], hex[7], hex[4]]));
                                }
                                _ => cells.push((VTK_HEXAHEDRON, hex)),
                            }
                        }
                        _ => {
                            // Six pyramids on a centre point.
                            let ci = points.len() as u32;
                            let ctr: [f64; 3] = std::array::from_fn(|a| hex.iter().map(|&v| points[v as usize][a]).sum::<f64>() / 8.0);
                            points.push(ctr);
                            let p = |v: u32| points[v as usize];
                            for f in HEX_REF.faces {
                                // Base counter-clockwise seen from the apex (inside).
                                let mut b: Vec<u32> = f.iter().map(|&l| hex[l]).collect();
                                if crate::mesh::geometry::tet_det([p(b[0]), p(b[1]), p(b[2]), ctr]).0 < 0.0 {
                                    b.reverse();
                                }
                                cells.push((VTK_PYRAMID, vec![b[0], b[1], b[2], b[3], ci]));
                            }
                        }
                    }
                }
            }
        }
        (points, cells)
    }

    fn split(points: Vec<[f64; 3]>, cells: &[(u8, Vec<u32>)]) -> TetMesh {
        let n = points.len();
        let mut s = CellSplitter::default();
        for (t, v) in cells {
            s.add(*t, v).unwrap();
        }
        let mut m = TetMesh { name: "m".into(), points, scalars: vec![0.0; n], tets: s.tets, stats: MeshStats::default() };
        m.validate("m").unwrap();
        m
    }

    fn check_block(n: usize, seed: u64, warp: bool) {
        let (points, cells) = mixed_block(n, seed, warp);
        let m = split(points, &cells);
        assert_eq!(m.stats.reoriented, 0, "seed {seed}: the splits are positively oriented");
        assert_eq!(m.stats.zero_volume, 0);
        let adj = FaceAdjacency::build(&m.tets, None, |_| true);
        assert!(adj.shared.is_empty());
        // Every boundary face lies on the block's surface: no interior cracks.
        let on_surface = |f: [u32; 3]| {
            (0..3).any(|a| {
                let c: Vec<f64> = f.iter().map(|&v| m.points[v as usize][a]).collect();
                !warp && (c.iter().all(|&x| x == 0.0) || c.iter().all(|&x| x == n as f64))
            })
        };
        for &slot in &adj.boundary {
            let (c, f) = (slot as usize / 4, slot as usize % 4);
            let t = m.tets[c];
            let face = crate::mesh::adjacency::FACE_VERTS[f].map(|i| t[i]);
            if !warp {
                assert!(on_surface(face), "seed {seed}: interior boundary face {face:?}");
            }
        }
        // Two triangles per surface quad.
        assert_eq!(adj.boundary.len(), 2 * 6 * n * n, "seed {seed}");
        let vol = TetGeometry::compute(&m).total_volume();
        if !warp {
            assert!((vol - (n * n * n) as f64).abs() < 1e-9 * vol, "seed {seed}: volume {vol}");
        }
    }

    #[test]
    fn mixed_blocks_close_and_keep_their_volume() {
        for seed in 0..40 {
            check_block(3, seed, false);
        }
        // Warped cells at another size: still conforming.
        for seed in 0..5 {
            check_block(5, seed, true);
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
        #[test]
        fn random_mixed_meshes_are_conforming(seed in 0u64..u64::MAX, n in 1usize..5) {
            check_block(n, seed, false);
        }
    }

    #[test]
    fn names() {
        assert_eq!(cell_type_name(25), "quadratic hexahedron");
    }
}
