//! Per-frame visibility order: cells back to front by centroid distance from
//! the eye (perspective) or along the view direction (orthographic), with an
//! LSD radix sort on 32-bit keys. Both methods draw the same order.

use rayon::prelude::*;

use crate::scene::Camera;

/// Order-preserving map from f32 to u32 (ascending floats -> ascending keys).
#[inline]
pub(crate) fn float_key(x: f32) -> u32 {
    let b = x.to_bits();
    if b & 0x8000_0000 != 0 {
        !b
    } else {
        b | 0x8000_0000
    }
}

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

    pub fn is_empty(&self) -> bool {
        self.centroids.is_empty()
    }

    /// Cell indices, farthest first.
    pub fn sort(&mut self, camera: &Camera) -> &[u32] {
        let o = self.origin;
        let eye: [f32; 3] = std::array::from_fn(|k| (camera.eye[k] - o[k]) as f32);
        let fwd = camera.forward();
        let fwd = [fwd.x as f32, fwd.y as f32, fwd.z as f32];
        let perspective = camera.is_perspective();
        // Farthest first: invert the key of the depth so ascending key order
        // is descending depth.
        self.keys.par_iter_mut().zip(self.centroids.par_iter()).for_each(|(k, c)| {
            let d = [c[0] - eye[0], c[1] - eye[1], c[2] - eye[2]];
            let depth = if perspective {
                d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
            } else {
                d[0] * fwd[0] + d[1] * fwd[1] + d[2] * fwd[2]
            };
            *k = !float_key(depth);
        });
        for (i, o) in self.order.iter_mut().enumerate() {
            *o = i as u32;
        }
        radix_sort_pairs(&mut self.keys, &mut self.order, &mut self.scratch_keys, &mut self.scratch_order);
        &self.order
    }
}

/// Stable LSD radix sort of (key, value) pairs by key, 8 bits per pass;
/// passes whose digit is the same for every key are skipped.
pub fn radix_sort_pairs(keys: &mut Vec<u32>, values: &mut Vec<u32>, tmp_k: &mut Vec<u32>, tmp_v: &mut Vec<u32>) {
    let n = keys.len();
    debug_assert_eq!(values.len(), n);
    tmp_k.resize(n, 0);
    tmp_v.resize(n, 0);
    // All four histograms in one read of the keys.
    let mut hist = [[0usize; 256]; 4];
    for &k in keys.iter() {
        for (p, h) in hist.iter_mut().enumerate() {
            h[((k >> (8 * p)) & 0xff) as usize] += 1;
        }
    }
    for (p, h) in hist.iter().enumerate() {
        if h.iter().any(|&c| c == n) {
            continue; // every key has the same digit: this pass would not move anything
        }
        let mut offsets = [0usize; 256];
        let mut sum = 0;
        for (o, &c) in offsets.iter_mut().zip(h.iter()) {
            *o = sum;
            sum += c;
        }
        let shift = 8 * p;
        for i in 0..n {
            let k = keys[i];
            let d = ((k >> shift) & 0xff) as usize;
            let dst = offsets[d];
            offsets[d] += 1;
            tmp_k[dst] = k;
            tmp_v[dst] = values[i];
        }
        std::mem::swap(keys, tmp_k);
        std::mem::swap(values, tmp_v);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Bounds;
    use crate::scene::Projection;

    #[test]
    fn float_keys_are_monotonic() {
        let xs = [-1e30f32, -2.0, -1.0, -0.0, 0.0, 1e-30, 1.0, 3.5, 1e30];
        for w in xs.windows(2) {
            assert!(float_key(w[0]) <= float_key(w[1]), "{} {}", w[0], w[1]);
        }
    }

    #[test]
    fn radix_matches_std_sort() {
        let mut state = 12345u64;
        let mut keys: Vec<u32> = (0..10_000)
            .map(|_| {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (state >> 33) as u32
            })
            .collect();
        let mut expected: Vec<(u32, u32)> = keys.iter().copied().zip(0..).collect();
        expected.sort_by_key(|&(k, _)| k); // stable, like LSD radix
        let mut values: Vec<u32> = (0..keys.len() as u32).collect();
        radix_sort_pairs(&mut keys, &mut values, &mut Vec::new(), &mut Vec::new());
        let got: Vec<(u32, u32)> = keys.into_iter().zip(values).collect();
        assert_eq!(got, expected);
    }

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
    }
}

/// Which visibility order a run draws in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, clap::ValueEnum, Default)]
#[serde(rename_all = "lowercase")]
pub enum SortKind {
    /// Back to front by centroid distance (VTK's default): fast, not exact.
    #[default]
    Centroid,
    /// MPVO from face adjacency (exact for connected convex meshes) with the
    /// MPVONC heuristic elsewhere; see `mpvo`.
    Mpvo,
}

impl SortKind {
    pub fn name(self) -> &'static str {
        match self {
            SortKind::Centroid => "centroid",
            SortKind::Mpvo => "mpvo",
        }
    }
}

/// A per-frame sort of either kind, built once per mesh.
pub enum Sorter {
    Centroid(CentroidSort),
    Mpvo(Box<super::mpvo::MpvoSort>),
}

impl Sorter {
    pub fn new(kind: SortKind, mesh: &crate::mesh::TetMesh, geometry: &crate::mesh::TetGeometry) -> Self {
        match kind {
            SortKind::Centroid => {
                let origin = super::render_origin(mesh);
                Sorter::Centroid(CentroidSort::with_origin(super::centroids_relative_f32(geometry, origin), origin))
            }
            SortKind::Mpvo => Sorter::Mpvo(Box::new(super::mpvo::MpvoSort::new(mesh, geometry))),
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
