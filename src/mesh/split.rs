//! Structured (curvilinear) hexahedral grid → conforming tetrahedral mesh.
//!
//! Each hexahedron is cut into 5 tets (4 corner tets + 1 central tet). The two
//! mirror-image variants of that split put opposite diagonals on every face,
//! so they alternate with the parity of `i + j + k`: neighbouring hexes then
//! cut their shared face along the same diagonal and the result is conforming
//! (no cracks, no T-junctions). This is how the Blunt Fin (187,395 tets) and
//! Oxygen Post (513,375 tets) meshes of the cell-projection literature were
//! made. Collapsed grid points are kept as-is; the tets they flatten are
//! counted as zero-volume by [`TetMesh::validate`].

use super::{MeshStats, TetMesh};
use anyhow::{bail, Result};
use rayon::prelude::*;

/// Corner `c` of a hex is at offset `(c & 1, (c >> 1) & 1, (c >> 2) & 1)` in
/// `(i, j, k)`. Split used when `i + j + k` is even: corner tets at 000, 110,
/// 101, 011 plus the central tet 100-010-001-111. Every tet is positively
/// oriented on a right-handed unit cube.
pub const PATTERN_EVEN: [[usize; 4]; 5] = [
    [0, 1, 2, 4],
    [3, 2, 1, 7],
    [5, 1, 4, 7],
    [6, 4, 2, 7],
    [1, 2, 4, 7],
];

/// The mirror image of [`PATTERN_EVEN`] (x → 1 − x, two vertices swapped to
/// keep positive orientation), used when `i + j + k` is odd: corner tets at
/// 100, 010, 001, 111 plus the central tet 000-110-101-011.
pub const PATTERN_ODD: [[usize; 4]; 5] = [
    [1, 3, 0, 5],
    [2, 0, 3, 6],
    [4, 5, 0, 6],
    [7, 3, 5, 6],
    [0, 5, 3, 6],
];

/// Tet connectivity of the 5-tet split of an `nx×ny×nz` point grid (point
/// `(i,j,k)` has index `i + nx*(j + ny*k)`), cells in `i`-fastest order, 5 tets
/// per cell. Errors if a dimension is < 2 or the indices would not fit u32.
pub fn hex_grid_tet_indices(dims: [usize; 3]) -> Result<Vec<[u32; 4]>> {
    let [nx, ny, nz] = dims;
    if nx < 2 || ny < 2 || nz < 2 {
        bail!("grid dimensions {dims:?} have no hexahedral cells (each must be >= 2)");
    }
    let n_points = nx
        .checked_mul(ny)
        .and_then(|v| v.checked_mul(nz))
        .filter(|&n| n <= u32::MAX as usize);
    let n_tets = ((nx - 1) * (ny - 1)).checked_mul(nz - 1).and_then(|c| c.checked_mul(5));
    let (Some(_), Some(n_tets)) = (n_points, n_tets) else {
        bail!("grid dimensions {dims:?} are too large for 32-bit indices");
    };
    let mut tets = vec![[0u32; 4]; n_tets];
    let cells_per_slab = (nx - 1) * (ny - 1);
    tets.par_chunks_mut(5 * cells_per_slab).enumerate().for_each(|(k, slab)| {
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let corner = |c: usize| {
                    ((i + (c & 1)) + nx * ((j + ((c >> 1) & 1)) + ny * (k + ((c >> 2) & 1)))) as u32
                };
                let pattern = if (i + j + k) % 2 == 0 { &PATTERN_EVEN } else { &PATTERN_ODD };
                let base = 5 * (i + (nx - 1) * j);
                for (t, local) in pattern.iter().enumerate() {
                    slab[base + t] = local.map(corner);
                }
            }
        }
    });
    Ok(tets)
}

/// Splits every hexahedral cell of a structured grid into 5 tets (alternating
/// mirrored patterns, conforming) and validates/orients the result.
/// `points` and `scalars` are in grid order (`i` fastest).
pub fn hex_grid_to_tets(
    name: &str,
    dims: [usize; 3],
    points: Vec<[f64; 3]>,
    scalars: Vec<f64>,
) -> Result<TetMesh> {
    let n = dims.iter().try_fold(1usize, |acc, &d| acc.checked_mul(d));
    if n != Some(points.len()) {
        bail!(
            "{name}: grid dimensions {dims:?} do not match the {} points given",
            points.len()
        );
    }
    if scalars.len() != points.len() {
        bail!("{name}: {} points but {} scalars", points.len(), scalars.len());
    }
    let tets = hex_grid_tet_indices(dims).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    let mut mesh = TetMesh {
        name: name.to_string(),
        points,
        scalars,
        tets,
        stats: MeshStats::default(),
    };
    mesh.validate(name)?;
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::super::geometry::{tet_det, TetGeometry};
    use super::*;
    use std::collections::HashMap;

    fn corner_pos(c: usize) -> [f64; 3] {
        [(c & 1) as f64, ((c >> 1) & 1) as f64, ((c >> 2) & 1) as f64]
    }

    #[test]
    fn patterns_are_positive_and_fill_the_cube() {
        for pattern in [&PATTERN_EVEN, &PATTERN_ODD] {
            let mut vol = 0.0;
            for t in pattern {
                let (det, zero) = tet_det(t.map(corner_pos));
                assert!(det > 0.0 && !zero, "{t:?}");
                vol += det / 6.0;
            }
            assert!((vol - 1.0).abs() < 1e-15);
        }
    }

    fn grid(dims: [usize; 3], warp: bool) -> Vec<[f64; 3]> {
        let mut pts = Vec::new();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let (x, y, z) = (i as f64, j as f64, k as f64);
                    pts.push(if warp {
                        [x + 0.1 * (y * 1.3).sin(), y + 0.1 * (z + x).cos(), z + 0.05 * x * y]
                    } else {
                        [x, y, z]
                    });
                }
            }
        }
        pts
    }

    /// Face-matching check: every triangle appears once (boundary) or twice
    /// (interior, shared by two tets), with no hanging faces, and the number of
    /// boundary triangles is exactly two per boundary quad.
    #[test]
    fn split_is_conforming() {
        for dims in [[2, 2, 2], [3, 4, 5], [5, 3, 4], [4, 4, 4]] {
            let n = dims[0] * dims[1] * dims[2];
            let pts = grid(dims, true);
            let m = hex_grid_to_tets("g", dims, pts, vec![0.0; n]).unwrap();
            let [nx, ny, nz] = dims;
            let cells = (nx - 1) * (ny - 1) * (nz - 1);
            assert_eq!(m.tets.len(), 5 * cells);
            assert_eq!(m.stats.reoriented, 0);
            assert_eq!(m.stats.zero_volume, 0);
            let mut faces: HashMap<[u32; 3], usize> = HashMap::new();
            for t in &m.tets {
                for i in 0..4 {
                    let mut f = [t[(i + 1) % 4], t[(i + 2) % 4], t[(i + 3) % 4]];
                    f.sort();
                    *faces.entry(f).or_default() += 1;
                }
            }
            assert!(faces.values().all(|&c| c == 1 || c == 2), "a face used > 2 times");
            let boundary = faces.values().filter(|&&c| c == 1).count();
            let quads = 2 * ((nx - 1) * (ny - 1) + (ny - 1) * (nz - 1) + (nx - 1) * (nz - 1));
            assert_eq!(boundary, 2 * quads, "dims {dims:?}: cracks between hexes");
            // Euler-style count: 4 faces per tet = boundary + 2 * interior.
            let interior = faces.values().filter(|&&c| c == 2).count();
            assert_eq!(4 * m.tets.len(), boundary + 2 * interior);
        }
    }

    #[test]
    fn volume_is_preserved_and_left_handed_grids_reorient() {
        let dims = [4, 3, 5];
        let n = 60;
        let pts = grid(dims, false);
        let m = hex_grid_to_tets("g", dims, pts.clone(), vec![0.0; n]).unwrap();
        let g = TetGeometry::compute(&m);
        assert!((g.total_volume() - 3.0 * 2.0 * 4.0).abs() < 1e-12);
        // Mirror the grid: every tet is inverted and must be reoriented.
        let mirrored = pts.iter().map(|p| [-p[0], p[1], p[2]]).collect();
        let m = hex_grid_to_tets("g", dims, mirrored, vec![0.0; n]).unwrap();
        assert_eq!(m.stats.reoriented, m.tets.len());
        assert!((TetGeometry::compute(&m).total_volume() - 24.0).abs() < 1e-12);
    }

    #[test]
    fn bad_inputs() {
        assert!(hex_grid_to_tets("g", [1, 2, 2], vec![[0.0; 3]; 4], vec![0.0; 4]).is_err());
        let e = hex_grid_to_tets("g", [2, 2, 2], vec![[0.0; 3]; 7], vec![0.0; 7]).unwrap_err();
        assert!(e.to_string().contains("do not match"));
        assert!(hex_grid_to_tets("g", [2, 2, 2], grid([2, 2, 2], false), vec![0.0; 7]).is_err());
    }
}
