//! Face adjacency of a tetrahedral mesh: the one builder behind the CPU
//! reference's ray walk (`reference/topology.rs`) and the MPVO visibility
//! sort (`algo/cell_projection/mpvo.rs`).
//!
//! Faces are matched by their sorted vertex triple: a parallel sort of all
//! `4·n` face slots (`4·c + f`, face `f` opposite vertex `f` of cell `c`)
//! keyed by that triple, then one scan over runs of equal keys. A triple held
//! by exactly two cells links them ([`FaceAdjacency::partner`]); a triple held
//! by one cell is a boundary face; a triple held by three or more cells is
//! reported as a group ([`FaceAdjacency::shared`]) and linked to nothing,
//! because what such a group means is the caller's decision (the reference
//! treats it as invalid input and leaves every holder on the boundary; MPVO
//! pairs the two solid holders when the others are flat cells welded onto
//! them).
//!
//! Two more choices are parameters rather than policy:
//! - *Which vertex ids are compared.* Either the mesh's indices, or a
//!   [`weld_coincident`] map that merges points with bit-identical
//!   coordinates, so two grid blocks whose boundary points coincide without
//!   sharing indices are joined ([`FaceAdjacency::welded_pairs`] counts what
//!   only the map matched).
//! - *Which cells take part.* Cells the caller leaves out (the reference
//!   drops cells with a repeated vertex index: they have no usable faces)
//!   hold no faces at all; their would-be neighbours pair with each other or
//!   become boundary.
//!
//! Whether a cell is flat (zero volume) is not decided here: that is
//! [`super::geometry::tet_det`]'s job, and only the callers' policies need it.

use rayon::prelude::*;

/// `partner` value of a face slot without a partner (boundary, shared by
/// three or more cells, or of a left-out cell).
pub const NONE: u32 = u32::MAX;

/// Local vertex indices of face `f` (the face opposite vertex `f`), ordered
/// counter-clockwise seen from outside a positively oriented tet, i.e. the
/// normal `(v1 − v0) × (v2 − v0)` points out of the tet. (Matching only uses
/// the vertex set; the order is for callers that need the orientation.)
pub const FACE_VERTS: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

/// Face adjacency by vertex triple (see the module docs).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct FaceAdjacency {
    /// `partner[4·c + f] = 4·c' + f'`: face `f` of cell `c` is face `f'` of
    /// cell `c'` (their triples are held by exactly these two cells); `NONE`
    /// otherwise.
    pub partner: Vec<u32>,
    /// Slots of faces held by one cell only, ascending.
    pub boundary: Vec<u32>,
    /// Faces held by three or more cells: per triple, the slots of its
    /// holders (ascending), in ascending order of the triple. Their `partner`
    /// is `NONE`; callers decide.
    pub shared: Vec<Vec<u32>>,
    /// Pairs (counted once) whose triples are equal only through the vertex
    /// map; 0 without a map.
    pub welded_pairs: usize,
    /// Cells left out by the caller's filter.
    pub excluded_cells: usize,
}

impl FaceAdjacency {
    /// Matches the faces of `tets`. `vertex_map` (indexed by vertex index,
    /// e.g. from [`weld_coincident`]) gives the ids compared, the indices
    /// themselves if `None`. Only cells for which `include(cell)` is true
    /// take part.
    ///
    /// Expects indices in range (a validated mesh; with a map, `vertex_map`
    /// covers every index) and `4·tets.len() < NONE` (the slots are `u32`).
    /// Validation guarantees the first; the reference checks the second
    /// before building, and it is asserted here (as MPVO always did).
    pub fn build(
        tets: &[[u32; 4]],
        vertex_map: Option<&[u32]>,
        include: impl Fn(&[u32; 4]) -> bool + Sync,
    ) -> FaceAdjacency {
        let n = tets.len();
        assert!(4 * n < NONE as usize, "too many cells for 32-bit face slots");
        let id = |v: u32| vertex_map.map_or(v, |m| m[v as usize]);
        // (first two ids, third id, slot): sorting the tuples sorts by triple
        // and, within a triple, by slot, so the result is deterministic.
        // Made by an indexed parallel map, which writes the vector in place
        // (a filtered one is gathered in pieces and copied: twice the 16
        // bytes per face at the peak), then the excluded cells' faces removed.
        let mut faces: Vec<(u64, u32, u32)> = (0..4 * n)
            .into_par_iter()
            .map(|slot| {
                let k = sorted_triple(&tets[slot / 4], slot % 4, id);
                (((k[0] as u64) << 32) | k[1] as u64, k[2], slot as u32)
            })
            .collect();
        let kept: Vec<bool> = tets.par_iter().map(&include).collect();
        if kept.contains(&false) {
            faces.retain(|&(_, _, slot)| kept[slot as usize / 4]);
        }
        drop(kept);
        faces.par_sort_unstable();

        let mut adj = FaceAdjacency {
            partner: vec![NONE; 4 * n],
            excluded_cells: n - faces.len() / 4,
            ..Default::default()
        };
        let original = |slot: u32| sorted_triple(&tets[slot as usize / 4], slot as usize % 4, |v| v);
        let mut i = 0;
        while i < faces.len() {
            let key = (faces[i].0, faces[i].1);
            let mut j = i + 1;
            while j < faces.len() && (faces[j].0, faces[j].1) == key {
                j += 1;
            }
            match j - i {
                1 => adj.boundary.push(faces[i].2),
                2 => {
                    let (a, b) = (faces[i].2, faces[i + 1].2);
                    adj.partner[a as usize] = b;
                    adj.partner[b as usize] = a;
                    if vertex_map.is_some() && original(a) != original(b) {
                        adj.welded_pairs += 1;
                    }
                }
                _ => adj.shared.push(faces[i..j].iter().map(|f| f.2).collect()),
            }
            i = j;
        }
        adj.boundary.sort_unstable();
        adj
    }

    /// Number of faces held by exactly two cells (each pair counted once).
    pub fn interior_faces(&self) -> usize {
        self.partner.iter().filter(|&&p| p != NONE).count() / 2
    }
}

/// The ids of face `f` of `t` under `id`, ascending.
#[inline]
fn sorted_triple(t: &[u32; 4], f: usize, id: impl Fn(u32) -> u32) -> [u32; 3] {
    let mut k = FACE_VERTS[f].map(|l| id(t[l]));
    k.sort_unstable();
    k
}

/// Canonical vertex id per point: the smallest index among the points at
/// bit-identical coordinates (`-0.0` and `0.0` are one position), for
/// [`FaceAdjacency::build`]'s `vertex_map`.
pub fn weld_coincident(points: &[[f64; 3]]) -> Vec<u32> {
    let np = points.len();
    assert!(np <= u32::MAX as usize, "too many points for 32-bit ids");
    let mut by_pos: Vec<u32> = (0..np as u32).collect();
    // `+ 0.0` turns -0.0 into 0.0.
    let bits = |i: u32| points[i as usize].map(|x| (x + 0.0).to_bits());
    by_pos.par_sort_unstable_by_key(|&i| (bits(i), i));
    let mut weld: Vec<u32> = (0..np as u32).collect();
    let mut i = 0;
    while i < np {
        let mut j = i + 1;
        while j < np && bits(by_pos[j]) == bits(by_pos[i]) {
            weld[by_pos[j] as usize] = by_pos[i];
            j += 1;
        }
        i = j;
    }
    weld
}

#[cfg(test)]
mod tests {
    use super::super::geometry::{cross, dot, sub};
    use super::*;

    #[test]
    fn face_orders_point_outwards() {
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.2, 0.3, 1.0]];
        assert!(dot(cross(sub(p[1], p[0]), sub(p[2], p[0])), sub(p[3], p[0])) > 0.0);
        for (f, fv) in FACE_VERTS.iter().enumerate() {
            assert!(!fv.contains(&f));
            let n = cross(sub(p[fv[1]], p[fv[0]]), sub(p[fv[2]], p[fv[0]]));
            assert!(dot(n, sub(p[f], p[fv[0]])) < 0.0, "face {f}");
        }
    }

    #[test]
    fn pairs_boundary_and_excluded_cells() {
        // Tets 0 and 1 share (1,2,3); tet 2 repeats a vertex and is left out
        // (else it would take (1,2,3) too).
        let tets = [[0, 1, 2, 3], [1, 2, 3, 4], [1, 1, 2, 3]];
        let repeats = |t: &[u32; 4]| (0..4).any(|a| (a + 1..4).any(|b| t[a] == t[b]));
        let adj = FaceAdjacency::build(&tets, None, |t| !repeats(t));
        assert_eq!(adj.partner[0], 4 + 3); // face 0 of tet 0 = face 3 of tet 1
        assert_eq!(adj.partner[4 + 3], 0);
        assert_eq!(adj.boundary, vec![1, 2, 3, 4, 5, 6]);
        assert!(adj.shared.is_empty());
        assert_eq!((adj.excluded_cells, adj.welded_pairs, adj.interior_faces()), (1, 0, 1));
        assert!(adj.partner[8..].iter().all(|&p| p == NONE));
        // Without the filter tet 2 holds (1,2,3) twice (faces 0 and 1), so
        // four slots share it; its faces (1,1,3) and (1,1,2) are boundary.
        let all = FaceAdjacency::build(&tets, None, |_| true);
        assert_eq!(all.shared, vec![vec![0, 7, 8, 9]]);
        assert_eq!(all.boundary, vec![1, 2, 3, 4, 5, 6, 10, 11]);
        assert_eq!((all.excluded_cells, all.interior_faces()), (0, 0));
        assert!(all.partner.iter().all(|&p| p == NONE));
    }

    #[test]
    fn welding_joins_coincident_points() {
        // Two tets on either side of the triangle (1,0,0), (0,1,0), (0,0,1),
        // which the second tet stores as points 5, 6, 7 (one with -0.0).
        let points = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
            [1.0, -0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let weld = weld_coincident(&points);
        assert_eq!(weld, vec![0, 1, 2, 3, 4, 1, 2, 3]);
        let tets = [[0, 1, 2, 3], [4, 5, 6, 7]];
        let plain = FaceAdjacency::build(&tets, None, |_| true);
        assert_eq!((plain.interior_faces(), plain.boundary.len()), (0, 8));
        let welded = FaceAdjacency::build(&tets, Some(&weld), |_| true);
        assert_eq!((welded.interior_faces(), welded.welded_pairs), (1, 1));
        assert_eq!((welded.partner[0], welded.partner[4]), (4, 0));
        assert_eq!(welded.boundary, vec![1, 2, 3, 5, 6, 7]);
        // Faces equal by index are not counted as welded.
        let same = FaceAdjacency::build(&[[0, 1, 2, 3], [4, 1, 2, 3]], Some(&weld), |_| true);
        assert_eq!((same.interior_faces(), same.welded_pairs), (1, 0));
    }
}
