//! Skirts: vertical strips hung from every block's border at its level,
//! so that blocks of different levels leave no cracks at their
//! T-junctions (see `HybridModel::skirt_depth`).

use super::geometry::inside;
use super::{CellClass, Heightmap, HybridModel};

impl HybridModel {
    /// Skirt vertices (a copy of every grid sample and TB vertex on a block
    /// border, with the drop) and each level's skirt triangles per block.
    pub(super) fn add_skirts(&mut self, map: &Heightmap) {
        let depth = self.levels.iter().flat_map(|l| l.error_max.iter().copied()).fold(0.0, f64::max).max(1e-3 * map.range().1.abs().max(1.0));
        self.skirt_depth = depth;
        let (w, h, b) = (self.domain[0] + 1, self.domain[1] + 1, self.block_side);
        let mut skirt = vec![u32::MAX; w as usize * h as usize];
        for j in 0..h {
            for i in 0..w {
                if i % b == 0 || j % b == 0 {
                    let v = self.vertices[self.grid_vertex(i, j) as usize];
                    skirt[(i + w * j) as usize] = self.vertices.len() as u32;
                    // The sample's own height, and the drop in w: the vertex
                    // stage lowers it; shading sees the border's height.
                    self.vertices.push([v[0], v[1], v[2], depth as f32]);
                }
            }
        }
        // TB vertices on block borders hang skirts too (PC cells' edges).
        let mut tb_skirt = vec![u32::MAX; self.tb_xy.len()];
        for (t, p) in self.tb_xy.iter().enumerate() {
            let on = |c: f64| c.fract() == 0.0 && (c as u32).is_multiple_of(b);
            if on(p[0]) || on(p[1]) {
                let v = self.vertices[t];
                tb_skirt[t] = self.vertices.len() as u32;
                self.vertices.push([v[0], v[1], v[2], depth as f32]);
            }
        }
        for k in 0..self.levels.len() {
            let side = self.levels[k].side;
            let (mut idx, mut ranges) = (Vec::new(), Vec::new());
            for by in 0..self.blocks[1] {
                for bx in 0..self.blocks[0] {
                    let start = idx.len() as u32;
                    let (x0, y0, x1, y1) = (bx * b, by * b, (bx + 1) * b, (by + 1) * b);
                    // Border edges with the block's cell inside them: NC
                    // cells' whole edges, PC cells' parts outside the TINs
                    // (a skirt under a TIN could show through it).
                    let mut border = Vec::new();
                    for t in (0..b).step_by(side as usize) {
                        border.push(([x0 + t, y0], [x0 + t + side, y0], [x0 + t, y0]));
                        border.push(([x0 + t, y1], [x0 + t + side, y1], [x0 + t, y1 - side]));
                        border.push(([x0, y0 + t], [x0, y0 + t + side], [x0, y0 + t]));
                        border.push(([x1, y0 + t], [x1, y0 + t + side], [x1 - side, y0 + t]));
                    }
                    let level = &self.levels[k];
                    let block = (bx + self.blocks[0] * by) as usize;
                    for ([ax, ay], [cx, cy], [ix, iy]) in border {
                        let (a, c) = (self.grid_vertex(ax, ay), self.grid_vertex(cx, cy));
                        let (sa, sc) = (skirt[(ax + w * ay) as usize], skirt[(cx + w * cy) as usize]);
                        match level.class[(ix / side + level.cells[0] * (iy / side)) as usize] {
                            CellClass::Nc => idx.extend([a, c, sc, a, sc, sa]),
                            CellClass::Cc => {}
                            CellClass::Pc => {
                                // The parts of the edge outside the TINs, split
                                // where TB chains cross it.
                                let r = &level.pc_by_block[block];
                                let Some(pc) = level.pc[r.start as usize..r.end as usize].iter().find(|p| p.cell == [ix / side, iy / side]) else {
                                    continue;
                                };
                                let horizontal = ay == cy;
                                let along = |p: [f64; 2]| if horizontal { p[0] } else { p[1] };
                                let mut stops: Vec<(f64, u32, u32)> = vec![(along([ax as f64, ay as f64]), a, sa)];
                                for ch in &pc.chains {
                                    for t in [self.tb_at(ch, 0), self.tb_at(ch, ch.len - 1)] {
                                        let p = self.tb_xy[t as usize];
                                        let on = if horizontal { p[1] == ay as f64 } else { p[0] == ax as f64 };
                                        if on && tb_skirt[t as usize] != u32::MAX {
                                            stops.push((along(p), t, tb_skirt[t as usize]));
                                        }
                                    }
                                }
                                stops.push((along([cx as f64, cy as f64]), c, sc));
                                stops.sort_by(|p, q| p.0.total_cmp(&q.0));
                                for pair in stops.windows(2) {
                                    let (p, q) = (pair[0], pair[1]);
                                    let mid = 0.5 * (p.0 + q.0);
                                    let m = if horizontal { [mid, ay as f64] } else { [ax as f64, mid] };
                                    if !self.patches.iter().any(|poly| inside(&poly.polygon, m)) {
                                        idx.extend([p.1, q.1, q.2, p.1, q.2, p.2]);
                                    }
                                }
                            }
                        }
                    }
                    ranges.push(start..idx.len() as u32);
                }
            }
            self.levels[k].skirt_indices = idx;
            self.levels[k].skirt_by_block = ranges;
        }
    }
}
