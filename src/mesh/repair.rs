//! Linear cells that the plain min-index split (`cells`) would fold over,
//! and collapsed cells: how a tetra, voxel, hexahedron, wedge or pyramid is
//! split when it is non-convex, twisted, inside out or degenerate.
//!
//! For each cell the conforming triangulations are tried in turn: every
//! triangulation of its reference cell on its own vertices that cuts its
//! quad faces along the diagonals the min-index rule gives (so neighbours
//! still share their faces' cuts), fewest tets first (`cells::
//! conforming_triangulations`). The cell's orientation is the sign of its
//! net volume under the first one; a triangulation *folds* when one of its
//! tets with volume has the opposite sign. The first triangulation that does
//! not fold is used:
//!
//! - the first one: the plain split (a cell given inside out, every tet
//!   negative, is kept and its tets reoriented by `TetMesh::validate`:
//!   counted in `Repairs::reoriented_cells`);
//! - another one: `Repairs::resplit_cells` (a non-convex or twisted cell);
//! - none: the cell is split around an added point at its vertices' mean
//!   (scalar: the mean of theirs), each face cut along the same diagonals
//!   and coned to that point (`Repairs::centroid_split_cells`). If that folds
//!   too (the cell is not star-shaped from its centroid: it crosses itself)
//!   the cell is refused, named by the caller.
//!
//! Collapsed cells (a point id repeated, as VTK's degenerate hexahedra,
//! wedges and pyramids are written) are split the same way and the tets
//! that repeat an id are dropped: what remains is the split of the
//! degenerate form (a hexahedron with a collapsed edge is a wedge, with a
//! collapsed face a pyramid or a wedge; a wedge with a collapsed vertical
//! edge a pyramid; a pyramid with a collapsed base edge a tetra), and a
//! quad face with a collapsed edge becomes the triangle its neighbour sees.
//! Counted in `Repairs::degenerate_cells`; a cell collapsed to no volume at
//! all adds no tets. A tetra with a repeated point is refused (it is no
//! degenerate form of anything with volume).

use anyhow::{bail, Result};

use super::cells::{as_hex_order, conforming_triangulations, quad_diagonal, reference_of, VTK_TETRA};
use super::geometry::tet_det;
use super::tet_builder::Tetrahedralizer;

fn repeats(t: &[u32]) -> bool {
    (0..t.len()).any(|a| (a + 1..t.len()).any(|b| t[a] == t[b]))
}

/// Signs of the tets with volume: (positive, negative, net volume).
fn signs(points: &[[f64; 3]], tets: &[[u32; 4]]) -> (usize, usize, f64) {
    let (mut pos, mut neg, mut net) = (0, 0, 0.0);
    for t in tets {
        let (det, flat) = tet_det(t.map(|v| points[v as usize]));
        net += det;
        if !flat {
            if det > 0.0 {
                pos += 1;
            } else {
                neg += 1;
            }
        }
    }
    (pos, neg, net)
}

/// Splits one linear cell (`cell_type` 10 to 14, vertex count and indices
/// already checked) into `t`, repairing it as the module docs say.
pub(crate) fn split_linear(t: &mut Tetrahedralizer, cell_type: u8, v: &[u32]) -> Result<()> {
    let degenerate = repeats(v);
    if cell_type == VTK_TETRA {
        return add_tetra(t, v, degenerate);
    }
    let (ct, h) = as_hex_order(cell_type, v);
    let cands = conforming_triangulations(ct, &h);
    let Some(first) = cands.first() else {
        bail!("no triangulation of this cell cuts its quad faces as its neighbours do");
    };
    if degenerate {
        t.stats.repairs.degenerate_cells += 1;
    }
    let plain = on_vertices(first, &h);
    let (pos, neg, net) = signs(&t.points, &plain);
    if pos == 0 || neg == 0 {
        // No fold (or nothing with volume: flat cells are kept and counted
        // by validation, collapsed ones may add nothing).
        if neg > 0 {
            t.stats.repairs.reoriented_cells += 1;
        }
        t.tets.extend(plain);
        return Ok(());
    }
    let positive = net > 0.0;
    for local in cands.iter().skip(1) {
        let tets = on_vertices(local, &h);
        if unfolded(&tets, &t.points, positive) {
            t.stats.repairs.resplit_cells += 1;
            add_repaired(t, tets, positive);
            return Ok(());
        }
    }
    let tets = split_around_centroid(t, ct, &h)?;
    if unfolded(&tets, &t.points, positive) {
        t.stats.repairs.centroid_split_cells += 1;
        add_repaired(t, tets, positive);
        return Ok(());
    }
    bail!(
        "the cell folds over: none of its {} triangulations that cut its faces as its neighbours do, nor a \
         split around its centroid, gives tetrahedra of one orientation (the cell crosses itself)",
        cands.len()
    )
}

/// A tetra as it is (reoriented when inside out); one with a repeated
/// point (`degenerate`) is refused.
fn add_tetra(t: &mut Tetrahedralizer, v: &[u32], degenerate: bool) -> Result<()> {
    if degenerate {
        // VTK's degenerate forms are of hexahedra, wedges and pyramids;
        // a tetra with a repeated point is a triangle or less.
        bail!("repeats a vertex index {v:?}: a tetra with a repeated point has no volume");
    }
    let tet = [v[0], v[1], v[2], v[3]];
    if tet_det(tet.map(|i| t.points[i as usize])).0 < 0.0 {
        t.stats.repairs.reoriented_cells += 1;
    }
    t.tets.push(tet);
    Ok(())
}

/// A local triangulation on the cell's vertices `h`, the tets a collapsed
/// cell's repeated ids flatten left out.
fn on_vertices(local: &[[usize; 4]], h: &[u32]) -> Vec<[u32; 4]> {
    local.iter().map(|l| l.map(|i| h[i])).filter(|g| !repeats(g)).collect()
}

/// Whether `tets` all have the orientation of the cell (`positive`: its
/// net volume's sign), and some volume.
fn unfolded(tets: &[[u32; 4]], points: &[[f64; 3]], positive: bool) -> bool {
    let (p, n, _) = signs(points, tets);
    if positive { n == 0 && p > 0 } else { p == 0 && n > 0 }
}

/// Adds a repaired cell's tets, counting it reoriented when inside out.
fn add_repaired(t: &mut Tetrahedralizer, tets: Vec<[u32; 4]>, positive: bool) {
    if !positive {
        t.stats.repairs.reoriented_cells += 1;
    }
    t.tets.extend(tets);
}

/// The split of a pyramid, wedge or hexahedron (`ct`, vertices `h` in
/// hexahedron order) around a point added at its centroid, keeping every
/// face's cut: its faces' triangles coned to the centroid.
fn split_around_centroid(t: &mut Tetrahedralizer, ct: u8, h: &[u32]) -> Result<Vec<[u32; 4]>> {
    let Some((coords, faces)) = reference_of(ct) else {
        bail!("no split for this cell type");
    };
    let (centre, value) = centroid(t, h);
    let oriented = face_triangles_outward(coords, faces, h);
    let c = t.add_point(centre, value)?;
    Ok(oriented.iter().map(|f| [f[0], f[1], f[2], c]).filter(|g| !repeats(g)).collect())
}

/// The mean position and value of the cell's distinct vertices.
fn centroid(t: &Tetrahedralizer, h: &[u32]) -> ([f64; 3], f64) {
    let mut distinct: Vec<u32> = h.to_vec();
    distinct.sort_unstable();
    distinct.dedup();
    let k = distinct.len() as f64;
    let centre: [f64; 3] = std::array::from_fn(|a| distinct.iter().map(|&i| t.points[i as usize][a]).sum::<f64>() / k);
    let value = distinct.iter().map(|&i| t.scalars[i as usize]).sum::<f64>() / k;
    (centre, value)
}

/// The reference cell's faces (`coords`, `faces`) as triangles, quads cut
/// as the min-index rule cuts them for the global ids `h`, each ordered to
/// face away from the reference centroid; as global ids.
fn face_triangles_outward(coords: &[[i64; 3]], faces: &[&[usize]], h: &[u32]) -> Vec<[u32; 3]> {
    // The reference centroid, scaled by the vertex count to stay integral.
    let n = coords.len() as i64;
    let rc: [i64; 3] = std::array::from_fn(|a| coords.iter().map(|c| c[a]).sum::<i64>());
    let mut local_tris: Vec<[usize; 3]> = Vec::new();
    for f in faces {
        if f.len() == 4 {
            if quad_diagonal(f, h) == 0 {
                local_tris.extend([[f[0], f[1], f[2]], [f[0], f[2], f[3]]]);
            } else {
                local_tris.extend([[f[0], f[1], f[3]], [f[1], f[2], f[3]]]);
            }
        } else {
            local_tris.push([f[0], f[1], f[2]]);
        }
    }
    let scaled = |i: usize| coords[i].map(|x| x * n);
    let mut oriented = Vec::new();
    for tri in local_tris {
        let d = det_i([scaled(tri[0]), scaled(tri[1]), scaled(tri[2]), rc]);
        let (a, b) = if d > 0 { (tri[0], tri[1]) } else { (tri[1], tri[0]) };
        oriented.push([h[a], h[b], h[tri[2]]]);
    }
    oriented
}

fn det_i(p: [[i64; 3]; 4]) -> i64 {
    let s = |a: [i64; 3], b: [i64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let (a, b, c) = (s(p[1], p[0]), s(p[2], p[0]), s(p[3], p[0]));
    a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])
}
