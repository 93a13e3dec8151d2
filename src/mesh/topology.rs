//! A ray walk's view of the mesh, built once per render: face adjacency and
//! which cells are solid. Both walks use it: the CPU reference's
//! (`reference::raycast`) and tet-raycast's (`algo::tet_raycast`), so they
//! agree on which faces are boundary and which cells are flat; it is mesh
//! structure, not integration (each walk integrates with its own code).
//!
//! Adjacency comes from the shared builder ([`FaceAdjacency`], matching by
//! vertex *index* triple: no welding, so an unmerged seam stays two
//! boundaries, see `reference`'s module docs; a mesh of constant cells,
//! whose tets have their own vertices, is matched through
//! `MeshStats::vertex_origin`, the file's points). The policies on top:
//! - Cells with a repeated vertex index carry no volume and no usable faces:
//!   they are left out entirely (their would-be neighbours pair with each
//!   other or become boundary) and counted.
//! - A triple held by three or more cells (a non-manifold, invalid mesh)
//!   leaves all of them as boundary faces and is counted.
//! - A cell is *solid* if it is positively oriented and not zero-volume by
//!   the one flatness test of volbench, [`tet_det`] (the test that gives the
//!   GPU paths and MPVO their `degenerate` cells), so the reference and the
//!   renderers agree on which cells are flat.

use rayon::prelude::*;

use crate::mesh::adjacency::FaceAdjacency;
use crate::mesh::geometry::tet_det;
use crate::mesh::TetMesh;

pub struct Topology {
    /// `neighbor[4·t + f]` = `4·t' + f'`: face `f` of tet `t` is face `f'` of
    /// tet `t'`; `NONE` on the boundary.
    pub neighbor: Vec<u32>,
    /// Boundary faces as `4·t + f`, ascending.
    pub boundary: Vec<u32>,
    /// Faces shared by three or more tets (invalid input), left as boundary.
    pub non_manifold_faces: usize,
    /// Tets left out because a vertex index repeats.
    pub collapsed_tets: usize,
    /// Per tet: positive volume beyond rounding, `det[p1−p0, p2−p0, p3−p0] >
    /// 0` and not zero-volume by [`tet_det`]. Flat cells (zero or negligible
    /// volume, or inverted) are `false`: the walk ignores their orientation.
    pub solid: Vec<bool>,
}

impl Topology {
    /// Expects indices in range and `4·tets < u32::MAX` (checked by the
    /// reference's input validation).
    pub fn build(mesh: &TetMesh) -> Topology {
        let repeats = |t: &[u32; 4]| (0..4).any(|a| (a + 1..4).any(|b| t[a] == t[b]));
        // A mesh of constant cells (`cell_data`) gives each tet its own
        // vertices: faces are matched through the points they copy.
        let origin = &mesh.stats.vertex_origin;
        let map = (!origin.is_empty() && origin.len() == mesh.points.len()).then_some(origin.as_slice());
        let adj = FaceAdjacency::build(&mesh.tets, map, |t| !repeats(t));
        let non_manifold_faces = adj.shared.iter().map(Vec::len).sum();
        let mut boundary = adj.boundary;
        if !adj.shared.is_empty() {
            boundary.extend(adj.shared.into_iter().flatten());
            boundary.sort_unstable();
        }
        let solid = (0..mesh.tets.len())
            .into_par_iter()
            .map(|c| {
                let (det, flat) = tet_det(mesh.tet_points(c));
                det > 0.0 && !flat
            })
            .collect();
        Topology {
            neighbor: adj.partner,
            boundary,
            non_manifold_faces,
            collapsed_tets: adj.excluded_cells,
            solid,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::adjacency::NONE;
    use crate::mesh::{MeshStats, TetGeometry};

    #[test]
    fn two_tets_share_one_face() {
        let mesh = TetMesh {
            name: "two".into(),
            points: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
                [1.0, 1.0, 1.0],
            ],
            scalars: vec![0.0; 5],
            tets: vec![[0, 1, 2, 3], [1, 2, 3, 4], [1, 1, 2, 3]],
            stats: Default::default(),
        };
        let t = Topology::build(&mesh);
        assert_eq!(t.neighbor[0], 4 + 3); // face 0 of tet 0 = (1,2,3) = face 3 of tet 1
        assert_eq!(t.neighbor[4 + 3], 0);
        assert!(t.neighbor[8..].iter().all(|&n| n == NONE));
        assert_eq!(t.boundary.len(), 6);
        assert_eq!(t.collapsed_tets, 1);
        assert_eq!(t.non_manifold_faces, 0);
        assert_eq!(t.solid, vec![true, true, false]); // tet 2 is collapsed
    }

    #[test]
    fn faces_of_three_cells_are_boundary() {
        // Three tets on the triangle (0,1,2): invalid input.
        let mesh = TetMesh {
            name: "fan".into(),
            points: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
                [0.0, 0.0, -1.0],
                [0.2, 0.2, 2.0],
            ],
            scalars: vec![0.0; 6],
            tets: vec![[0, 1, 2, 3], [0, 2, 1, 4], [0, 1, 2, 5]],
            stats: Default::default(),
        };
        let t = Topology::build(&mesh);
        assert_eq!(t.non_manifold_faces, 3);
        assert_eq!(t.boundary, (0..12).collect::<Vec<u32>>());
        assert!(t.neighbor.iter().all(|&n| n == NONE));
        assert_eq!(t.solid, vec![true, true, true]);
    }

    /// The reference and the GPU paths (via `TetGeometry`) agree on which
    /// cells are flat, including cells just either side of the threshold and
    /// inverted cells (which the reference never calls solid).
    #[test]
    fn solid_agrees_with_geometry() {
        let mut points = Vec::new();
        let mut tets = Vec::new();
        // Apex heights over a unit right triangle, each cell on its own
        // triangle (cells stacked on one face would overlap): |det| = h, and
        // the apex's three edges (0.424, 0.762, 0.762) have the smallest
        // product, 0.2461, so the cell is flat below 1e-10 · 0.2461.
        for (k, h) in [0.0, 1e-13, 1e-11, 2.4e-11, 2.5e-11, 1e-9, 1e-3, 1.0].into_iter().enumerate() {
            let x = 2.0 * k as f64;
            let first = points.len() as u32;
            points.extend([[x, 0.0, 0.0], [x + 1.0, 0.0, 0.0], [x, 1.0, 0.0], [x + 0.3, 0.3, h]]);
            tets.push([first, first + 1, first + 2, first + 3]);
        }
        let n = points.len();
        let mut mesh = TetMesh { name: "thin".into(), scalars: vec![0.0; n], points, tets, stats: MeshStats::default() };
        let inverted = {
            let mut m = TetMesh { name: "inv".into(), ..mesh.clone() };
            m.tets.iter_mut().for_each(|t| t.swap(2, 3));
            m
        };
        let solid = Topology::build(&inverted).solid;
        assert!(solid.iter().all(|&s| !s), "inverted cells are never solid");
        mesh.validate("thin").unwrap();
        let t = Topology::build(&mesh);
        let g = TetGeometry::compute(&mesh);
        let flat: Vec<bool> = g.cells.iter().map(|c| c.degenerate).collect();
        assert_eq!(flat, vec![true, true, true, true, false, false, false, false]);
        assert_eq!(t.solid, flat.iter().map(|f| !f).collect::<Vec<_>>());
        assert_eq!(mesh.stats.zero_volume, 4);
    }
}
