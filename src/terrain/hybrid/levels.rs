//! One level of detail of the hybrid model: the GC classification (a cell
//! is PC iff a TB edge lies in it, CC iff its centre is inside a patch), the
//! PC cells' TB chains, NC indices and PC cells grouped by block, and the
//! grid's height error per block.

use anyhow::Result;

use super::geometry::inside;
use super::{CellClass, Chain, Heightmap, HybridModel, Level, PcCell};

impl HybridModel {
    /// Level `side` (finest cells per cell side): GC classification, PC
    /// chains, NC indices and PC cells grouped by block, per-block grid
    /// error. `None` when a patch lies inside one cell of it.
    pub(super) fn build_level(&self, map: &Heightmap, side: u32) -> Result<Option<Level>> {
        let cells = [self.domain[0] / side, self.domain[1] / side];
        let (class, edge_cell) = self.classify(cells, side);
        let Some(chains) = self.chains(&edge_cell, class.len()) else {
            return Ok(None);
        };
        // Blocks: NC indices and PC cells grouped by block.
        let per = self.block_side / side;
        let nblocks = self.blocks[0] as usize * self.blocks[1] as usize;
        let (mut nc_indices, mut nc_by_block, mut pc, mut pc_by_block) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let (mut error_max, mut error_sse) = (vec![0.0; nblocks], vec![0.0; nblocks]);
        for by in 0..self.blocks[1] {
            for bx in 0..self.blocks[0] {
                let (n0, p0) = (nc_indices.len() as u32, pc.len() as u32);
                let b = (bx + self.blocks[0] * by) as usize;
                for y in by * per..(by + 1) * per {
                    for x in bx * per..(bx + 1) * per {
                        let c = (x + cells[0] * y) as usize;
                        let (x0, y0, x1, y1) = (x * side, y * side, (x + 1) * side, (y + 1) * side);
                        match class[c] {
                            CellClass::Nc => {
                                let v = |i, j| self.grid_vertex(i, j);
                                nc_indices.extend([v(x0, y0), v(x1, y0), v(x1, y1), v(x0, y0), v(x1, y1), v(x0, y1)]);
                            }
                            CellClass::Pc => pc.push(PcCell { cell: [x, y], chains: chains[c].clone() }),
                            CellClass::Cc => {}
                        }
                        let (m, s) = cell_error(map, [x0, y0], side);
                        error_max[b] = f64::max(error_max[b], m);
                        error_sse[b] += s;
                    }
                }
                nc_by_block.push(n0..nc_indices.len() as u32);
                pc_by_block.push(p0..pc.len() as u32);
            }
        }
        Ok(Some(Level {
            side,
            cells,
            class,
            nc_indices,
            nc_by_block,
            pc,
            pc_by_block,
            error_max,
            error_sse,
            skirt_indices: Vec::new(),
            skirt_by_block: Vec::new(),
        }))
    }

    /// The GC list of a level of `cells` cells of `side`, and per patch the
    /// cell of each of its TB edges.
    fn classify(&self, cells: [u32; 2], side: u32) -> (Vec<CellClass>, Vec<Vec<usize>>) {
        let ncells = cells[0] as usize * cells[1] as usize;
        let cell_of = |p: [f64; 2]| -> usize {
            let x = ((p[0] / side as f64).floor() as u32).min(cells[0] - 1);
            let y = ((p[1] / side as f64).floor() as u32).min(cells[1] - 1);
            (x + cells[0] * y) as usize
        };
        // TB edges per cell (by the edge's midpoint: the edge lies in one cell).
        let mut edge_cell: Vec<Vec<usize>> = Vec::new();
        let mut has_edge = vec![false; ncells];
        for patch in &self.patches {
            let n = (patch.tb.end - patch.tb.start) as usize;
            let cellv: Vec<usize> = (0..n)
                .map(|i| {
                    let a = self.tb_xy[patch.tb.start as usize + i];
                    let b = self.tb_xy[patch.tb.start as usize + (i + 1) % n];
                    cell_of([0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])])
                })
                .collect();
            for &c in &cellv {
                has_edge[c] = true;
            }
            edge_cell.push(cellv);
        }
        let mut class = vec![CellClass::Nc; ncells];
        for y in 0..cells[1] {
            for x in 0..cells[0] {
                let c = (x + cells[0] * y) as usize;
                let centre = [(x as f64 + 0.5) * side as f64, (y as f64 + 0.5) * side as f64];
                class[c] = if has_edge[c] {
                    CellClass::Pc
                } else if self.patches.iter().any(|p| inside(&p.polygon, centre)) {
                    CellClass::Cc
                } else {
                    CellClass::Nc
                };
            }
        }
        (class, edge_cell)
    }

    /// Per cell, its TB chains: maximal runs of a patch's TB edges in it.
    /// `None` when a patch's whole TB lies in one cell.
    fn chains(&self, edge_cell: &[Vec<usize>], ncells: usize) -> Option<Vec<Vec<Chain>>> {
        let mut chains: Vec<Vec<Chain>> = vec![Vec::new(); ncells];
        for (pi, patch) in self.patches.iter().enumerate() {
            let ec = &edge_cell[pi];
            let n = ec.len();
            // Start at an edge whose predecessor lies in another cell.
            let first = (0..n).find(|&i| ec[(i + n - 1) % n] != ec[i])?;
            let mut i = 0;
            while i < n {
                let e0 = (first + i) % n;
                let mut len = 1;
                while len < n && ec[(e0 + len) % n] == ec[e0] {
                    len += 1;
                }
                chains[ec[e0]].push(Chain { start: patch.tb.start + e0 as u32, len: len as u32 + 1, patch: pi as u32 });
                i += len;
            }
        }
        Some(chains)
    }
}

/// Largest and summed squared error of a level cell's two triangles
/// against the finest samples it holds (its lower-left closed corner, open
/// upper and right edges, so each sample counts once; the domain's last row
/// and column are exact at every level: they are grid samples of all).
fn cell_error(map: &Heightmap, [x0, y0]: [u32; 2], side: u32) -> (f64, f64) {
    if side == 1 {
        return (0.0, 0.0);
    }
    let h = |i: u32, j: u32| map.height(i as usize, j as usize) as f64;
    let (z00, z10, z01, z11) = (h(x0, y0), h(x0 + side, y0), h(x0, y0 + side), h(x0 + side, y0 + side));
    let (mut mx, mut sse) = (0.0f64, 0.0);
    for j in 0..side {
        for i in 0..side {
            let (u, v) = (i as f64 / side as f64, j as f64 / side as f64);
            let z = if u >= v { z00 + u * (z10 - z00) + v * (z11 - z10) } else { z00 + v * (z01 - z00) + u * (z11 - z01) };
            let e = z - h(x0 + i, y0 + j);
            mx = mx.max(e.abs());
            sse += e * e;
        }
    }
    (mx, sse)
}
