//! Red refinement (Bey): every tet split into 8 at its edge midpoints, the
//! scalar at a midpoint the mean of its edge's ends (a linear field stays
//! exact). An edge shared by several tets gets one midpoint, so the refined
//! mesh is conforming wherever the input is. The scaling study
//! (`harness::scale`) refines a mesh level by level with it.

use std::collections::HashMap;

use anyhow::{ensure, Context as _, Result};

use super::TetMesh;

/// Host bytes a refinement of `mesh` holds at its peak: the input, the
/// output (8x the tets, points plus one per edge, at most 6 per tet) and
/// the edge table. An estimate from above, checked before allocating.
pub fn refined_bytes(mesh: &TetMesh) -> u128 {
    refined_bytes_of(mesh.points.len() as u128, mesh.tets.len() as u128)
}

/// [`refined_bytes`] of a mesh of `p` points and `t` tets.
pub fn refined_bytes_of(p: u128, t: u128) -> u128 {
    let edges = 6 * t;
    let point = 24 + 8;
    let input = p * point + t * 16;
    let output = (p + edges) * point + 8 * t * 16;
    // Hash map entry ((u32, u32) -> u32) with its control byte, at the
    // load factor hashbrown keeps (7/8), doubled for the resize peak.
    let table = edges * 13 * 8 / 7 * 2;
    input + output + table
}

/// A mesh's sizes as red refinement changes them, so the sizes of every
/// level are known before any is made: each edge gets a point and becomes
/// 2, each face gets 3 new edges and becomes 4, each tet gets 1 new edge
/// (its inner octahedron's diagonal) and 8 inner faces, and becomes 8.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RefineCounts {
    pub points: u128,
    /// Distinct edges.
    pub edges: u128,
    /// Distinct faces.
    pub faces: u128,
    pub tets: u128,
}

impl RefineCounts {
    /// Counted from `mesh` (its distinct edges and faces, sorted).
    pub fn of(mesh: &TetMesh) -> Self {
        let mut edges: Vec<u64> = Vec::with_capacity(mesh.tets.len() * 6);
        for t in &mesh.tets {
            for (a, b) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
                let (x, y) = (t[a].min(t[b]), t[a].max(t[b]));
                edges.push(u64::from(x) << 32 | u64::from(y));
            }
        }
        edges.sort_unstable();
        edges.dedup();
        let edge_count = edges.len() as u128;
        drop(edges);
        let mut faces: Vec<[u32; 3]> = Vec::with_capacity(mesh.tets.len() * 4);
        for t in &mesh.tets {
            for skip in 0..4 {
                let mut f = [0u32; 3];
                let mut k = 0;
                for (i, &v) in t.iter().enumerate() {
                    if i != skip {
                        f[k] = v;
                        k += 1;
                    }
                }
                f.sort_unstable();
                faces.push(f);
            }
        }
        faces.sort_unstable();
        faces.dedup();
        RefineCounts { points: mesh.points.len() as u128, edges: edge_count, faces: faces.len() as u128, tets: mesh.tets.len() as u128 }
    }

    /// The counts after one red refinement.
    pub fn refined(self) -> Self {
        let RefineCounts { points, edges, faces, tets } = self;
        RefineCounts { points: points + edges, edges: 2 * edges + 3 * faces + tets, faces: 4 * faces + 8 * tets, tets: 8 * tets }
    }
}

/// `mesh` red-refined once: 8 times the tets; its name gets `-r1` (`-r2`
/// ...) appended. Errors when the point count would overflow the 32-bit
/// indices. Every child tet keeps the positive orientation.
pub fn red_refine(mesh: &TetMesh) -> Result<TetMesh> {
    let tets = mesh.tets.len().checked_mul(8).context("too many tets to refine")?;
    let mut points = mesh.points.clone();
    let mut scalars = mesh.scalars.clone();
    let mut midpoint: HashMap<(u32, u32), u32> = HashMap::with_capacity(mesh.tets.len() * 2);
    let mut out = Vec::with_capacity(tets);
    for t in &mesh.tets {
        let mut mid = |a: u32, b: u32| -> Result<u32> {
            let key = (a.min(b), a.max(b));
            if let Some(&m) = midpoint.get(&key) {
                return Ok(m);
            }
            let m = u32::try_from(points.len()).ok().filter(|&m| m < u32::MAX).context("refined mesh has more points than 32-bit indices hold")?;
            let (pa, pb) = (mesh.points[a as usize], mesh.points[b as usize]);
            points.push([0.5 * (pa[0] + pb[0]), 0.5 * (pa[1] + pb[1]), 0.5 * (pa[2] + pb[2])]);
            scalars.push(0.5 * (mesh.scalars[a as usize] + mesh.scalars[b as usize]));
            midpoint.insert(key, m);
            Ok(m)
        };
        let [v0, v1, v2, v3] = *t;
        let (m01, m02, m03) = (mid(v0, v1)?, mid(v0, v2)?, mid(v0, v3)?);
        let (m12, m13, m23) = (mid(v1, v2)?, mid(v1, v3)?, mid(v2, v3)?);
        // The corners keep the parent's orientation (each is the parent
        // scaled by 1/2 about a vertex); the inner octahedron is cut along
        // m02-m13, and its four tets are listed positively oriented for a
        // positive parent (checked by the tests).
        out.extend_from_slice(&[
            [v0, m01, m02, m03],
            [m01, v1, m12, m13],
            [m02, m12, v2, m23],
            [m03, m13, m23, v3],
            [m01, m02, m03, m13],
            [m01, m12, m02, m13],
            [m02, m03, m13, m23],
            [m02, m13, m12, m23],
        ]);
    }
    let level = mesh.name.rsplit_once("-r").and_then(|(base, n)| Some((base, n.parse::<u32>().ok()?)));
    let name = match level {
        Some((base, n)) => format!("{base}-r{}", n + 1),
        None => format!("{}-r1", mesh.name),
    };
    let mut refined = TetMesh { name, points, scalars, tets: out, stats: Default::default() };
    refined.validate(&refined.name.clone())?;
    ensure!(refined.stats.reoriented == 0, "red refinement produced {} inverted tets", refined.stats.reoriented);
    Ok(refined)
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::mesh::adjacency::FaceAdjacency;
    use crate::mesh::TetGeometry;

    /// A box split into 6 tets around its main diagonal (conforming), the
    /// scalar linear.
    pub(in crate::mesh) fn cube() -> TetMesh {
        let mut points = Vec::new();
        for z in 0..2 {
            for y in 0..2 {
                for x in 0..2 {
                    points.push([x as f64, y as f64 * 1.5, z as f64 * 0.75]);
                }
            }
        }
        let f = |p: &[f64; 3]| 0.3 + 2.0 * p[0] - 0.7 * p[1] + 1.1 * p[2];
        let scalars = points.iter().map(f).collect();
        let tets = vec![[0, 1, 3, 7], [0, 3, 2, 7], [0, 2, 6, 7], [0, 6, 4, 7], [0, 4, 5, 7], [0, 5, 1, 7]];
        let mut m = TetMesh { name: "cube".into(), points, scalars, tets, stats: Default::default() };
        m.validate("cube").unwrap();
        m
    }

    /// Boundary faces; every other face pairs with exactly one neighbour.
    fn boundary_faces(m: &TetMesh) -> usize {
        let adj = FaceAdjacency::build(&m.tets, None, |_| true);
        assert!(adj.shared.is_empty());
        assert_eq!(adj.interior_faces() * 2 + adj.boundary.len(), 4 * m.tets.len());
        adj.boundary.len()
    }

    #[test]
    fn refinement_is_conforming_volume_preserving_and_linear() {
        let mut m = cube();
        let volume = TetGeometry::compute(&m).total_volume();
        let boundary = boundary_faces(&m);
        for level in 1..=2 {
            let r = red_refine(&m).unwrap();
            assert_eq!(r.tets.len(), m.tets.len() * 8);
            assert_eq!(r.name, format!("cube-r{level}"));
            assert_eq!(r.stats.reoriented, 0);
            // Volume: every child positive, the sum the parent's.
            let g = TetGeometry::compute(&r);
            assert!((g.total_volume() - volume).abs() < 1e-12 * volume, "{} vs {volume}", g.total_volume());
            // Conforming: the faces inside pair up; the boundary faces are
            // the old ones each split into 4.
            assert_eq!(boundary_faces(&r), boundary * 4usize.pow(level));
            let f = |p: &[f64; 3]| 0.3 + 2.0 * p[0] - 0.7 * p[1] + 1.1 * p[2];
            for (p, s) in r.points.iter().zip(&r.scalars) {
                assert!((f(p) - s).abs() < 1e-12, "{p:?}: {s} vs {}", f(p));
            }
            m = r;
        }
        // One midpoint per edge: 8 corners + 12 box edges + 6 face
        // diagonals + 1 body diagonal = 27 points.
        assert_eq!(red_refine(&cube()).unwrap().points.len(), 27);
    }

    #[test]
    fn counts_of_every_level_are_known_before_refining() {
        let mut m = cube();
        let mut counts = RefineCounts::of(&m);
        // 8 corners; 12 box edges + 6 face diagonals + 1 body diagonal; 6 tets' 24 faces, 12 on the boundary.
        assert_eq!(counts, RefineCounts { points: 8, edges: 19, faces: 18, tets: 6 });
        for _ in 1..=2 {
            m = red_refine(&m).unwrap();
            counts = counts.refined();
            assert_eq!(RefineCounts::of(&m), counts);
        }
        assert_eq!(counts.tets, 6 * 64);
        assert_eq!(refined_bytes(&m), refined_bytes_of(counts.points, counts.tets));
    }

    #[test]
    fn estimate_bounds_the_real_sizes() {
        let m = cube();
        let r = red_refine(&m).unwrap();
        let real = (r.points.len() * 32 + r.tets.len() * 16) as u128;
        assert!(refined_bytes(&m) > real);
    }
}
