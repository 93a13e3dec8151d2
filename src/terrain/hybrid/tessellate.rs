//! The PC tessellation: the part of a PC cell outside the TINs, as
//! triangles over grid corners and TB vertices (transcribed line by line
//! in `shaders/terrain/tessellate.glsl`).

use anyhow::{bail, Context as _, Result};

use super::geometry::ear_clip;
use super::{HybridModel, PcCell};

impl HybridModel {
    /// Triangles (geometry indices, counter-clockwise in x-y) covering the
    /// part of PC cell `pc` of `level` outside the TINs, appended to `out`.
    ///
    /// This is the one tessellation of the project: `shaders/terrain/
    /// tessellate.glsl` is a line-by-line transcription that the GPU
    /// methods run, so all three produce the same triangles in the same
    /// order. That is why it computes in f32 (what a GPU computes in), in
    /// cell-local coordinates (TB position minus the cell's corner, both
    /// f32; exact for the coordinate on a grid line, and small numbers
    /// elsewhere), with each product written so no fused multiply-add can
    /// change a rounding (the shader marks them `precise`).
    ///
    /// Which border arcs lie outside the TINs needs no point-in-polygon
    /// test: a TB runs counter-clockwise around its patch (the TIN on its
    /// left), so the arc that leaves a chain's entry point counter-clockwise
    /// along the cell border is outside, and the arc that leaves its exit
    /// point is inside.
    pub fn tessellate(&self, level: usize, pc: &PcCell, out: &mut Vec<u32>) -> Result<()> {
        let side = self.levels[level].side;
        let s = side as f32;
        let origin = [(pc.cell[0] * side) as f32, (pc.cell[1] * side) as f32];
        let local = |t: u32| {
            let p = self.tb_xy[t as usize];
            [p[0] as f32 - origin[0], p[1] as f32 - origin[1]]
        };
        // Position along the border, counter-clockwise from the corner.
        let u_of = |p: [f32; 2]| -> f32 {
            if p[1] == 0.0 {
                p[0]
            } else if p[0] == s {
                s + p[1]
            } else if p[1] == s {
                2.0 * s + (s - p[0])
            } else {
                3.0 * s + (s - p[1])
            }
        };
        let corner_ids = [
            self.grid_vertex(pc.cell[0] * side, pc.cell[1] * side),
            self.grid_vertex((pc.cell[0] + 1) * side, pc.cell[1] * side),
            self.grid_vertex((pc.cell[0] + 1) * side, (pc.cell[1] + 1) * side),
            self.grid_vertex(pc.cell[0] * side, (pc.cell[1] + 1) * side),
        ];
        let corner_xy = [[0.0, 0.0], [s, 0.0], [s, s], [0.0, s]];
        // Chain ends on the border: (u, chain, is its start), sorted by u
        // (insertion sort, as the shader does; the u are distinct).
        let mut ends: Vec<(f32, usize, bool)> = Vec::new();
        for (ci, ch) in pc.chains.iter().enumerate() {
            for (k, is_start) in [(0, true), (ch.len - 1, false)] {
                let e = (u_of(local(self.tb_at(ch, k))), ci, is_start);
                let mut at = ends.len();
                while at > 0 && ends[at - 1].0 > e.0 {
                    at -= 1;
                }
                ends.insert(at, e);
            }
        }
        let m = ends.len();
        let mut visited = vec![false; m];
        let (mut ring, mut pts) = (Vec::new(), Vec::new());
        for start in 0..m {
            if visited[start] || !ends[start].2 {
                continue;
            }
            ring.clear();
            pts.clear();
            let mut i = start;
            loop {
                visited[i] = true;
                // Arc from end i (a chain's entry) to end i+1: end i, then
                // the corners strictly between.
                let ch = &pc.chains[ends[i].1];
                let first = self.tb_at(ch, 0);
                ring.push(first);
                pts.push(local(first));
                let (ua, mut ub) = (ends[i].0, ends[(i + 1) % m].0);
                if ub <= ua {
                    ub += 4.0 * s;
                }
                for round in 0..2 {
                    for c in 0..4 {
                        let cu = c as f32 * s + round as f32 * 4.0 * s;
                        if cu > ua && cu < ub {
                            ring.push(corner_ids[c]);
                            pts.push(corner_xy[c]);
                        }
                    }
                }
                // End i+1 is a chain's exit: that chain backwards to just
                // after its entry, which is the next arc's first vertex.
                let j = (i + 1) % m;
                if ends[j].2 {
                    bail!("PC cell {:?} at level {level}: two chain entries follow each other on the border", pc.cell);
                }
                let ch = &pc.chains[ends[j].1];
                for k in (1..ch.len).rev() {
                    let t = self.tb_at(ch, k);
                    ring.push(t);
                    pts.push(local(t));
                }
                i = ends.iter().position(|e| e.1 == ends[j].1 && e.2).context("chain entry missing")?;
                if i == start {
                    break;
                }
                if visited[i] {
                    bail!("PC cell {:?} at level {level}: the border walk does not close", pc.cell);
                }
            }
            ear_clip(&pts, &ring, out).with_context(|| format!("tessellating PC cell {:?} at level {level}", pc.cell))?;
        }
        Ok(())
    }
}
