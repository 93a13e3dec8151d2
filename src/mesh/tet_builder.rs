//! The sink the splitters write to: the mesh being built from a file's
//! cells (its points plus the ones splitting adds, with their interpolated
//! scalars, the tets, and what was counted). Below the splitters
//! (`repair`, `higher_order`, `polyhedron`) and the driver that feeds them
//! (`tetrahedralize`).

use std::collections::HashMap;

use anyhow::{anyhow, Result};

use super::{HigherOrder, MeshStats};

/// The mesh being built: the file's points plus the added ones, the tets,
/// and what was counted.
pub(crate) struct Tetrahedralizer {
    pub points: Vec<[f64; 3]>,
    pub scalars: Vec<f64>,
    pub tets: Vec<[u32; 4]>,
    pub stats: MeshStats,
    pub mode: HigherOrder,
    /// Added (or registered) face-centre points by the face's sorted ids.
    face_points: HashMap<Vec<u32>, u32>,
}

impl Tetrahedralizer {
    pub fn new(points: Vec<[f64; 3]>, scalars: Vec<f64>, mode: HigherOrder) -> Tetrahedralizer {
        Tetrahedralizer { points, scalars, tets: Vec::new(), stats: MeshStats::default(), mode, face_points: HashMap::new() }
    }

    /// Appends a point; its index.
    pub fn add_point(&mut self, p: [f64; 3], s: f64) -> Result<u32> {
        let i = u32::try_from(self.points.len()).ok().filter(|&i| i < u32::MAX).ok_or_else(|| anyhow!("too many points for 32-bit indices"))?;
        self.points.push(p);
        self.scalars.push(s);
        self.stats.added_points += 1;
        Ok(i)
    }

    /// The point and value `sum w_i x_i` of the points `terms` name.
    pub fn combine(&self, terms: &[(u32, f64)]) -> ([f64; 3], f64) {
        let mut p = [0.0; 3];
        let mut s = 0.0;
        for &(v, w) in terms {
            let q = self.points[v as usize];
            for (pa, qa) in p.iter_mut().zip(q) {
                *pa += w * qa;
            }
            s += w * self.scalars[v as usize];
        }
        (p, s)
    }

    /// The centre point of the face `key` (its sorted point ids): the one
    /// already made for the cell on the other side, else a new one at the
    /// combination `terms`.
    pub fn face_point(&mut self, key: Vec<u32>, terms: &[(u32, f64)]) -> Result<u32> {
        if let Some(&i) = self.face_points.get(&key) {
            return Ok(i);
        }
        let (p, s) = self.combine(terms);
        let i = self.add_point(p, s)?;
        self.face_points.insert(key, i);
        Ok(i)
    }

    /// A face-centre node the file has (the first cell to name it wins).
    pub fn register_face_point(&mut self, key: Vec<u32>, node: u32) {
        self.face_points.entry(key).or_insert(node);
    }
}
