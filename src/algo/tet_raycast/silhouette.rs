//! The boundary's silhouette edges per frame, for adaptive refinement's
//! structural test (`algo::adaptive`): a block is not filled by
//! interpolation when a silhouette edge projects into it, since rays on its
//! two sides may cross different numbers of boundary faces (or none).
//!
//! A silhouette edge is a boundary edge whose faces face different ways
//! ([`Faces::side`]: towards the eye, away, or edge-on), one with an
//! edge-on face or a flat cell's face, or one with other than two boundary
//! faces (an open or non-manifold boundary): a superset of the contour
//! edges of the boundary surface, hidden ones included.

use super::tiles::{Faces, View};

/// An edge's second face when it has only one ([`BoundaryEdges`]).
const LONE: u32 = u32::MAX;
/// An edge's second face when it has three or more.
const MANY: u32 = u32::MAX - 1;

/// The boundary's edges (pairs of boundary points) and their faces (in the
/// order of [`Faces`]), built once.
#[derive(Debug, Default)]
pub struct BoundaryEdges {
    pub ends: Vec<[u32; 2]>,
    pub faces: Vec<[u32; 2]>,
}

impl BoundaryEdges {
    pub fn new(faces: &Faces) -> Self {
        let mut all: Vec<([u32; 2], u32)> = Vec::with_capacity(faces.corners.len() * 3);
        for (i, c) in faces.corners.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (c[k], c[(k + 1) % 3]);
                all.push(([a.min(b), a.max(b)], i as u32));
            }
        }
        all.sort_unstable();
        let mut edges = BoundaryEdges::default();
        let mut i = 0;
        while i < all.len() {
            let mut j = i + 1;
            while j < all.len() && all[j].0 == all[i].0 {
                j += 1;
            }
            let second = match j - i {
                1 => LONE,
                2 => all[i + 1].1,
                _ => MANY,
            };
            edges.ends.push(all[i].0);
            edges.faces.push([all[i].1, second]);
            i = j;
        }
        edges
    }

    /// The frame's silhouette edges as segments between their ends' pixel
    /// coordinates `px` (the boundary points projected, every one in front
    /// of the eye); `shader_points`, `shader_eye` as for [`Faces::side`].
    pub fn silhouettes<'a>(
        &'a self,
        faces: &'a Faces,
        px: &'a [[f64; 2]],
        shader_points: &'a [[f32; 3]],
        shader_eye: [f64; 3],
        view: &'a View,
    ) -> impl Iterator<Item = ([f64; 2], [f64; 2])> + 'a {
        let sides: Vec<i8> = (0..faces.corners.len()).map(|i| faces.side(i, shader_points, shader_eye, view)).collect();
        self.ends.iter().zip(&self.faces).filter_map(move |(e, f)| {
            let on = f[1] >= MANY || {
                let (a, b) = (sides[f[0] as usize], sides[f[1] as usize]);
                a != b || a == 0
            };
            on.then(|| (px[e[0] as usize], px[e[1] as usize]))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_silhouette_of_a_tetrahedron_seen_face_on() {
        // One positively oriented tet's four faces (FACE_VERTS order, outward
        // counter-clockwise), seen from above its apex: the three side
        // faces face the eye, the base (z = 0) faces away.
        let points: Vec<[f32; 3]> = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.2, 0.2, 1.0]];
        // Faces of tet (0, 1, 2, 3) with FACE_VERTS: (1,2,3), (0,3,2), (0,1,3), (0,2,1).
        let faces = Faces { corners: vec![[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]], solid: vec![true; 4] };
        let edges = BoundaryEdges::new(&faces);
        assert_eq!(edges.ends.len(), 6);
        assert!(edges.faces.iter().all(|f| f[1] < MANY));
        let view = View { eye: [0.3, 0.3, 10.0], forward: [0.0, 0.0, -1.0], right: [1.0, 0.0, 0.0], up: [0.0, 1.0, 0.0], perspective: true, size: [64, 64] };
        let px: Vec<[f64; 2]> = (0..4).map(|i| [i as f64, 0.0]).collect();
        let sil: Vec<_> = edges.silhouettes(&faces, &px, &points, view.eye, &view).collect();
        // The silhouette is the outline: the base's three edges (the apex
        // projects inside it), not the apex's.
        assert_eq!(sil.len(), 3, "{sil:?}");
        // A flat cell: every edge.
        let flat = Faces { corners: faces.corners.clone(), solid: vec![false; 4] };
        assert_eq!(edges.silhouettes(&flat, &px, &points, view.eye, &view).count(), 6);
        // An open surface (one triangle): its three edges.
        let one = Faces { corners: vec![[0, 1, 2]], solid: vec![true] };
        let e1 = BoundaryEdges::new(&one);
        assert_eq!(e1.silhouettes(&one, &px, &points, view.eye, &view).count(), 3);
    }
}
