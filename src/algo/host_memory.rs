//! Where a method's host memory goes: the bytes each structure it keeps
//! between frames holds (a `Vec`'s capacity times its element size), named,
//! reported in the result's `details.host_memory` with the total and the
//! bytes per cell (issue 22 item 3, docs/scaling.md). The figures are counted
//! from the structures, not sampled, so they are exact and load-independent;
//! the process's peak RSS (which also holds the loader's transients and, on
//! lavapipe, every device allocation) is measured beside them by the harness.

use serde_json::json;

/// Named byte counts of the structures one method keeps.
#[derive(Debug, Clone, Default)]
pub struct HostMemory {
    parts: Vec<(&'static str, u64)>,
    /// Names whose size has a bound independent of the mesh (a buffer of
    /// at most so many bytes): the rest is the per-cell part.
    bounded: Vec<&'static str>,
}

/// Bytes a `Vec` holds (its capacity, not its length: what is allocated).
pub fn vec_bytes<T>(v: &Vec<T>) -> u64 {
    (v.capacity() * std::mem::size_of::<T>()) as u64
}

impl HostMemory {
    /// Count `bytes` under `name` (added to what the name already has).
    pub fn add(&mut self, name: &'static str, bytes: u64) {
        match self.parts.iter_mut().find(|(n, _)| *n == name) {
            Some((_, b)) => *b += bytes,
            None => self.parts.push((name, bytes)),
        }
    }

    /// Count `bytes` under `name`, a structure whose size is bounded
    /// whatever the mesh size (left out of the per-cell part).
    pub fn bounded(&mut self, name: &'static str, bytes: u64) {
        self.add(name, bytes);
        if !self.bounded.contains(&name) {
            self.bounded.push(name);
        }
    }

    /// Bytes of the structures that grow with the mesh (all but the
    /// `bounded` ones).
    pub fn per_cell_part(&self) -> u64 {
        self.parts.iter().filter(|(n, _)| !self.bounded.contains(n)).map(|(_, b)| b).sum()
    }

    /// Count a vector under `name`.
    pub fn vec<T>(&mut self, name: &'static str, v: &Vec<T>) {
        self.add(name, vec_bytes(v));
    }

    /// The loaded mesh, which the run holds for the method (counted in
    /// every method's breakdown).
    pub fn scene_mesh(&mut self, mesh: &crate::mesh::TetMesh) {
        self.vec("mesh: points (f64)", &mesh.points);
        self.vec("mesh: scalars (f64)", &mesh.scalars);
        self.vec("mesh: tets (u32)", &mesh.tets);
    }

    /// Everything in `other`, added under its names.
    pub fn extend(&mut self, other: &HostMemory) {
        for &(n, b) in &other.parts {
            if other.bounded.contains(&n) {
                self.bounded(n, b);
            } else {
                self.add(n, b);
            }
        }
    }

    pub fn total(&self) -> u64 {
        self.parts.iter().map(|(_, b)| b).sum()
    }

    pub fn get(&self, name: &str) -> Option<u64> {
        self.parts.iter().find(|(n, _)| *n == name).map(|(_, b)| *b)
    }

    /// `{ by_structure: {name: bytes}, bytes_per_cell: {name: b/cell},
    /// total_bytes, total_bytes_per_cell, bounded: [names],
    /// per_cell_part_bytes_per_cell }` (the last: the total without the
    /// bounded structures, per cell).
    pub fn to_json(&self, cells: usize) -> serde_json::Value {
        let per = |b: u64| b as f64 / cells.max(1) as f64;
        let round = |x: f64| (x * 100.0).round() / 100.0;
        let by: serde_json::Map<String, serde_json::Value> = self.parts.iter().map(|(n, b)| (n.to_string(), json!(b))).collect();
        let per_cell: serde_json::Map<String, serde_json::Value> =
            self.parts.iter().map(|(n, b)| (n.to_string(), json!(round(per(*b))))).collect();
        json!({
            "by_structure": by,
            "bytes_per_cell": per_cell,
            "total_bytes": self.total(),
            "total_bytes_per_cell": round(per(self.total())),
            "bounded": self.bounded,
            "per_cell_part_bytes_per_cell": round(per(self.per_cell_part())),
        })
    }
}

/// The process's peak resident set (VmHWM of /proc/self/status), bytes;
/// `None` where /proc is not available.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    vm_hwm_kb(&status).map(|kb| kb * 1024)
}

/// The VmHWM line of a /proc/<pid>/status text, in kB.
pub fn vm_hwm_kb(status: &str) -> Option<u64> {
    status.lines().find(|l| l.starts_with("VmHWM:"))?.split_whitespace().nth(1)?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_capacity_by_name() {
        let mut m = HostMemory::default();
        let v: Vec<[f32; 3]> = Vec::with_capacity(10);
        m.vec("centroids", &v);
        m.add("keys", 8);
        m.add("keys", 8);
        assert_eq!(m.get("centroids"), Some(120));
        assert_eq!(m.get("keys"), Some(16));
        assert_eq!(m.total(), 136);
        m.bounded("ring", 64);
        assert_eq!((m.total(), m.per_cell_part()), (200, 136));
        let j = m.to_json(4);
        assert_eq!(j["total_bytes"], 200);
        assert_eq!(j["bytes_per_cell"]["keys"], 4.0);
        assert_eq!(j["per_cell_part_bytes_per_cell"], 34.0);
        assert_eq!(j["bounded"][0], "ring");
        assert_eq!(vm_hwm_kb("Name:\tx\nVmHWM:\t  1234 kB\n"), Some(1234));
        assert!(peak_rss_bytes().unwrap_or(1) > 0);
    }
}
