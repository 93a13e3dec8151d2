//! Renumbering a loaded mesh for memory locality (issue 22 item 3): cells in
//! the Morton (Z-curve) order of their centroids, points in the order the
//! renumbered cells first use them. Refinement appends each level's new
//! points after the old ones and files come in whatever order their writer
//! chose, so cells close in space can be far apart in memory; every pass
//! that walks the cells and gathers their points (the sort's keys, packing,
//! culling, adjacency) then misses the cache on most gathers. After the
//! renumbering, neighbouring cells share cache lines and pages.
//!
//! The mesh stays the same mesh: each tet keeps its vertices in their order
//! (so its orientation), only the numbering of cells and points changes;
//! points no cell uses keep their relative order after the used ones. The
//! order depends on the mesh alone (ties in the code are broken by the old
//! cell index), so it is deterministic, and renumbering a renumbered mesh
//! changes nothing.

use rayon::prelude::*;

use super::TetMesh;

/// Bits per axis of the Morton code (3 × 21 = 63 bits).
const BITS: u32 = 21;

/// `x`'s low 21 bits spread to every third bit.
fn spread(x: u64) -> u64 {
    let mut x = x & 0x1f_ffff;
    x = (x | x << 32) & 0x001f_0000_0000_ffff;
    x = (x | x << 16) & 0x001f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

/// The Morton code of `p` on a 2^21 grid over `min .. min + extent`.
fn morton(p: [f64; 3], min: [f64; 3], extent: [f64; 3]) -> u64 {
    let max = f64::from((1u32 << BITS) - 1);
    let q = |k: usize| {
        let t = if extent[k] > 0.0 { (p[k] - min[k]) / extent[k] } else { 0.0 };
        // NaN (not in a validated mesh) maps to 0 through the clamp's `as`.
        (t.clamp(0.0, 1.0) * max) as u64
    };
    spread(q(0)) | spread(q(1)) << 1 | spread(q(2)) << 2
}

/// Renumber `mesh`'s cells and points for locality (see the module note).
pub fn spatial_order(mesh: &mut TetMesh) {
    let b = mesh.bounds();
    let extent: [f64; 3] = std::array::from_fn(|k| b.max[k] - b.min[k]);
    let mut keys: Vec<(u64, u32)> =
        mesh.tets.par_iter().enumerate().map(|(i, &t)| (morton(mesh.centroid(t), b.min, extent), i as u32)).collect();
    keys.par_sort_unstable();
    let mut tets: Vec<[u32; 4]> = keys.par_iter().map(|&(_, i)| mesh.tets[i as usize]).collect();
    drop(keys);
    // Points by first use in the new cell order, then the unused ones.
    const UNSEEN: u32 = u32::MAX;
    let mut new_id = vec![UNSEEN; mesh.points.len()];
    let mut next = 0u32;
    for t in &tets {
        for &v in t {
            let id = &mut new_id[v as usize];
            if *id == UNSEEN {
                *id = next;
                next += 1;
            }
        }
    }
    for id in new_id.iter_mut().filter(|id| **id == UNSEEN) {
        *id = next;
        next += 1;
    }
    tets.par_iter_mut().for_each(|t| *t = t.map(|v| new_id[v as usize]));
    let mut points = vec![[0f64; 3]; mesh.points.len()];
    let mut scalars = vec![0f64; mesh.scalars.len()];
    for (old, &new) in new_id.iter().enumerate() {
        points[new as usize] = mesh.points[old];
        scalars[new as usize] = mesh.scalars[old];
    }
    if mesh.stats.vertex_origin.len() == new_id.len() {
        let mut origin = vec![0u32; new_id.len()];
        for (old, &new) in new_id.iter().enumerate() {
            origin[new as usize] = mesh.stats.vertex_origin[old];
        }
        mesh.stats.vertex_origin = origin;
    }
    mesh.tets = tets;
    mesh.points = points;
    mesh.scalars = scalars;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A box of 6·n³ tets, cells and points numbered in a scrambled order.
    fn scrambled_box(n: u32) -> TetMesh {
        let mut m = super::super::refine::tests::cube();
        for _ in 0..n {
            m = super::super::refine::red_refine(&m).unwrap();
        }
        // Cells and points in a strided order (a stride coprime to the
        // count is a permutation): neighbours land far apart.
        let stride = |n: usize| (7919..).find(|s| gcd(*s, n) == 1).unwrap();
        let (nt, np) = (m.tets.len(), m.points.len());
        let (st, sp) = (stride(nt), stride(np));
        let tets = (0..nt).map(|i| m.tets[i * st % nt]).collect();
        // Old point j * sp % np becomes point j.
        let mut new_id = vec![0u32; np];
        for j in 0..np {
            new_id[j * sp % np] = j as u32;
        }
        m.tets = tets;
        m.tets.iter_mut().for_each(|t| *t = t.map(|v| new_id[v as usize]));
        m.points = (0..np).map(|j| m.points[j * sp % np]).collect();
        m.scalars = (0..np).map(|j| m.scalars[j * sp % np]).collect();
        m
    }

    fn gcd(a: usize, b: usize) -> usize {
        if b == 0 { a } else { gcd(b, a % b) }
    }

    fn sorted_cells(m: &TetMesh) -> Vec<[u64; 16]> {
        let mut cells: Vec<[u64; 16]> = m
            .tets
            .iter()
            .map(|&t| {
                let (p, s) = m.cell(t);
                let mut out = [0u64; 16];
                for i in 0..4 {
                    out[4 * i..4 * i + 3].copy_from_slice(&p[i].map(f64::to_bits));
                    out[4 * i + 3] = s[i].to_bits();
                }
                out
            })
            .collect();
        cells.sort_unstable();
        cells
    }

    #[test]
    fn same_cells_valid_and_idempotent() {
        for levels in [1, 2] {
            let before = scrambled_box(levels);
            let mut m = before.clone();
            spatial_order(&mut m);
            // The same cells, each with its vertices in the same order.
            assert_eq!(sorted_cells(&m), sorted_cells(&before));
            assert_eq!(m.points.len(), before.points.len());
            let mut checked = m.clone();
            checked.validate("reordered").unwrap();
            assert_eq!(checked.stats.reoriented, 0);
            assert_eq!(checked.tets, m.tets);
            // Points by first use: cell 0 uses 0..4.
            let mut first: Vec<u32> = m.tets[0].to_vec();
            first.sort_unstable();
            assert_eq!(first, [0, 1, 2, 3]);
            let mut again = m.clone();
            spatial_order(&mut again);
            assert_eq!(again.tets, m.tets);
            assert_eq!(again.points, m.points);
        }
    }

    #[test]
    fn neighbouring_cells_are_near_in_memory() {
        // The mean index distance between a cell's points, a locality
        // measure: far smaller after the renumbering.
        let spread_of = |m: &TetMesh| {
            let sum: u64 = m.tets.iter().map(|t| u64::from(t.iter().max().unwrap() - t.iter().min().unwrap())).sum();
            sum as f64 / m.tets.len() as f64
        };
        let before = scrambled_box(3);
        let mut m = before.clone();
        spatial_order(&mut m);
        assert!(spread_of(&m) * 4.0 < spread_of(&before), "{} vs {}", spread_of(&m), spread_of(&before));
    }

    #[test]
    fn morton_interleaves() {
        assert_eq!(spread(0b101), 0b1_000_001);
        let z = [0.0; 3];
        let e = [1.0; 3];
        assert_eq!(morton([0.0; 3], z, e), 0);
        assert_eq!(morton([1.0, 0.0, 0.0], z, e), spread((1 << BITS) - 1));
        assert_eq!(morton([0.0, 0.0, 1.0], z, e), spread((1 << BITS) - 1) << 2);
    }
}
