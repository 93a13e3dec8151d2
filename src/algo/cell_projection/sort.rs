//! Per-frame visibility order. [`CentroidSort`]: cells back to front by
//! centroid distance from the eye (perspective) or along the view direction
//! (orthographic), with the LSD radix sort on 32-bit keys of `radix`.
//! [`Sorter`] runs the order a run asks for ([`SortKind`]): this one or
//! `mpvo`'s exact order. Both methods (VICP, balanced) draw the same order.
//!
//! Dependencies point one way: `sort` -> `mpvo` -> `radix`, `sort` -> `radix`.

use rayon::prelude::*;

use super::radix::{float_key, radix_sort_pairs};
use crate::scene::Camera;

/// Reusable buffers for the centroid sort of one mesh.
pub struct CentroidSort {
    centroids: Vec<[f32; 3]>,
    /// What the centroids are relative to (the eye is moved by it in f64).
    origin: [f64; 3],
    keys: Vec<u32>,
    scratch_keys: Vec<u32>,
    order: Vec<u32>,
    scratch_order: Vec<u32>,
}

impl CentroidSort {
    /// `centroids` relative to the same origin as the camera position passed
    /// to `sort` (world space here).
    pub fn new(centroids: Vec<[f32; 3]>) -> Self {
        Self::with_origin(centroids, [0.0; 3])
    }

    /// `centroids` relative to `origin` (`centroids_relative_f32`, the
    /// mesh's `render_origin`): 1e7 from the world origin, f32 world
    /// centroids are 1 unit apart and a unit mesh's order is lost.
    pub fn with_origin(centroids: Vec<[f32; 3]>, origin: [f64; 3]) -> Self {
        let n = centroids.len();
        CentroidSort {
            centroids,
            origin,
            keys: vec![0; n],
            scratch_keys: vec![0; n],
            order: (0..n as u32).collect(),
            scratch_order: vec![0; n],
        }
    }

    pub fn len(&self) -> usize {
        self.centroids.len()
    }

    pub fn host_bytes(&self, memory: &mut crate::algo::host_memory::HostMemory) {
        memory.vec("sort: f32 centroids", &self.centroids);
        memory.vec("sort: keys and scratch", &self.keys);
        memory.vec("sort: keys and scratch", &self.scratch_keys);
        memory.vec("sort: order and scratch", &self.order);
        memory.vec("sort: order and scratch", &self.scratch_order);
    }

    pub fn is_empty(&self) -> bool {
        self.centroids.is_empty()
    }

    /// The sort key of a centroid for `camera`: ascending key order is
    /// descending depth (farthest first).
    fn key_fn(&self, camera: &Camera) -> impl Fn(&[f32; 3]) -> u32 + Sync {
        let o = self.origin;
        let eye: [f32; 3] = std::array::from_fn(|k| (camera.eye[k] - o[k]) as f32);
        let fwd = camera.forward();
        let fwd = [fwd.x as f32, fwd.y as f32, fwd.z as f32];
        let perspective = camera.is_perspective();
        move |c: &[f32; 3]| {
            let d = [c[0] - eye[0], c[1] - eye[1], c[2] - eye[2]];
            let depth = if perspective {
                d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
            } else {
                d[0] * fwd[0] + d[1] * fwd[1] + d[2] * fwd[2]
            };
            !float_key(depth)
        }
    }

    /// Cell indices, farthest first.
    pub fn sort(&mut self, camera: &Camera) -> &[u32] {
        let key = self.key_fn(camera);
        self.keys.clear();
        self.keys.par_extend(self.centroids.par_iter().map(key));
        self.order.clear();
        self.order.extend(0..self.centroids.len() as u32);
        radix_sort_pairs(&mut self.keys, &mut self.order, &mut self.scratch_keys, &mut self.scratch_order);
        &self.order
    }

    /// The cells `cells` (ascending ids) only, farthest first: exactly
    /// [`Self::sort`]'s order with the other cells left out (same keys, and
    /// the radix sort is stable from ascending ids), for culling
    /// (`cull`) before sorting.
    pub fn sort_subset(&mut self, camera: &Camera, cells: &[u32]) -> &[u32] {
        let key = self.key_fn(camera);
        let centroids = &self.centroids;
        self.keys.clear();
        self.keys.par_extend(cells.par_iter().map(|&c| key(&centroids[c as usize])));
        self.order.clear();
        self.order.extend_from_slice(cells);
        radix_sort_pairs(&mut self.keys, &mut self.order, &mut self.scratch_keys, &mut self.scratch_order);
        &self.order
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Bounds;
    use crate::scene::Projection;

    #[test]
    fn farthest_first() {
        let cs = vec![[0.0, 0.0, 0.0], [0.0, 0.0, 5.0], [0.0, 0.0, -5.0], [1.0, 0.0, 0.0]];
        let b = Bounds { min: [-1.0; 3], max: [1.0; 3] };
        let mut cam = crate::scene::Camera::orbit(&b, 0.0, Projection::Perspective { fovy_deg: 30.0 });
        cam.eye = [0.0, 0.0, 20.0];
        cam.target = [0.0, 0.0, 0.0];
        let mut s = CentroidSort::new(cs);
        // distances from z = 20: 20, 15, 25, 20.02
        assert_eq!(s.sort(&cam), &[2, 3, 0, 1]);
        // A subset keeps the full order, and the full sort is whole again.
        assert_eq!(s.sort_subset(&cam, &[1, 2, 3]), &[2, 3, 1]);
        assert_eq!(s.sort(&cam), &[2, 3, 0, 1]);
    }
}

crate::choices! {
    /// Which visibility order a run draws in.
    #[derive(Default)]
    pub enum SortKind {
        /// Back to front by centroid distance (VTK's default): fast, not exact.
        #[default]
        Centroid = "centroid",
        /// MPVO from face adjacency (exact for connected convex meshes) with the
        /// MPVONC heuristic elsewhere; see `mpvo`.
        Mpvo = "mpvo",
    }
}

/// A per-frame sort of either kind, built once per mesh.
pub enum Sorter {
    Centroid(CentroidSort),
    Mpvo(Box<super::mpvo::MpvoSort>),
}

impl Sorter {
    pub fn new(kind: SortKind, mesh: &crate::mesh::TetMesh) -> Self {
        match kind {
            SortKind::Centroid => {
                let origin = super::render_origin(mesh);
                Sorter::Centroid(CentroidSort::with_origin(super::centroids_relative_f32(mesh, origin), origin))
            }
            SortKind::Mpvo => Sorter::Mpvo(Box::new(super::mpvo::MpvoSort::from_mesh(mesh))),
        }
    }

    pub fn host_bytes(&self, memory: &mut crate::algo::host_memory::HostMemory) {
        match self {
            Sorter::Centroid(s) => s.host_bytes(memory),
            Sorter::Mpvo(s) => s.host_bytes(memory),
        }
    }

    /// Cell indices, farthest first.
    pub fn sort(&mut self, camera: &Camera) -> &[u32] {
        match self {
            Sorter::Centroid(s) => s.sort(camera),
            Sorter::Mpvo(s) => s.sort(camera),
        }
    }
}
