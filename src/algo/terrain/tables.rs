//! The PC cells as the GPU methods read them (GPU HM's layout, Paredes et
//! al. §3.1): the TB vertices' grid coordinates (f32, a vertex's offset is
//! its TB index, as in the geometry buffer), the chain list (per chain: its
//! first TB index, length, and its patch's TB range, for wrapping) and, per
//! level, one 4 × u32 entry per PC cell:
//!
//! - x: cell column | cell row << 16
//! - y: first chain | chain count << 24
//! - z: cell side in finest cells | part << 8 (see `hm-gpu`)
//! - w: the cell's triangle count
//!
//! Both GPU methods run `shaders/terrain/tessellate.glsl`, the transcription
//! of `HybridModel::tessellate`, on these; its fixed array sizes
//! (`MAX_CHAINS`, `MAX_RING`) are checked here for every cell, so a cell
//! the shader could not hold is an error at set-up, not a wrong image.

use anyhow::{bail, Result};

use crate::terrain::hybrid::HybridModel;

/// Chains per PC cell the shader holds (`MAX_CHAINS` in tessellate.glsl).
pub const MAX_CHAINS: usize = 8;
/// Ring vertices per loop the shader holds (`MAX_RING` in tessellate.glsl).
pub const MAX_RING: usize = 256;

pub struct PcTables {
    pub tb_xy: Vec<[f32; 2]>,
    pub chains: Vec<[u32; 4]>,
    /// Per level, per PC cell (in `Level::pc` order): its entry (part 0).
    pub cells: Vec<Vec<[u32; 4]>>,
    /// The largest ring of any cell (vertices), for the record.
    pub max_ring: usize,
}

impl PcTables {
    pub fn build(model: &HybridModel) -> Result<Self> {
        let tb_xy = model.tb_xy.iter().map(|p| [p[0] as f32, p[1] as f32]).collect();
        let (mut chains, mut cells, mut max_ring) = (Vec::new(), Vec::new(), 0usize);
        let mut tris = Vec::new();
        for (k, level) in model.levels.iter().enumerate() {
            let mut entries = Vec::with_capacity(level.pc.len());
            for pc in &level.pc {
                if pc.chains.len() > MAX_CHAINS {
                    bail!("level {k}, PC cell {:?}: {} TB chains, the GPU tessellator holds {MAX_CHAINS}", pc.cell, pc.chains.len());
                }
                // A loop's ring holds at most every chain vertex and 4 corners.
                let ring = pc.chains.iter().map(|c| c.len as usize).sum::<usize>() + 4;
                if ring > MAX_RING {
                    bail!("level {k}, PC cell {:?}: up to {ring} ring vertices, the GPU tessellator holds {MAX_RING}", pc.cell);
                }
                max_ring = max_ring.max(ring);
                if pc.cell[0] >= 1 << 16 || pc.cell[1] >= 1 << 16 || chains.len() >= 1 << 24 {
                    bail!("level {k}: cell {:?} or chain {} beyond the GPU entry's fields", pc.cell, chains.len());
                }
                tris.clear();
                model.tessellate(k, pc, &mut tris)?;
                let first = chains.len() as u32;
                for c in &pc.chains {
                    let p = &model.patches[c.patch as usize].tb;
                    chains.push([c.start, c.len, p.start, p.end - p.start]);
                }
                entries.push([
                    pc.cell[0] | pc.cell[1] << 16,
                    first | (pc.chains.len() as u32) << 24,
                    level.side,
                    (tris.len() / 3) as u32,
                ]);
            }
            cells.push(entries);
        }
        Ok(PcTables { tb_xy, chains, cells, max_ring })
    }

    /// The most of `count(level, cell index)` any frame can sum: per block,
    /// its level with the largest sum over the block's PC cells.
    pub fn frame_capacity(&self, model: &HybridModel, count: impl Fn(usize, usize) -> u64) -> u64 {
        let blocks = model.blocks[0] as usize * model.blocks[1] as usize;
        (0..blocks)
            .map(|b| {
                (0..model.levels.len())
                    .map(|k| {
                        let r = &model.levels[k].pc_by_block[b];
                        (r.start as usize..r.end as usize).map(|i| count(k, i)).sum::<u64>()
                    })
                    .max()
                    .unwrap_or(0)
            })
            .sum()
    }
}

/// The triangles of an index list (3 per triangle), sorted, as the
/// fingerprint the agreement of the methods is checked on: (triangles,
/// FNV-1a 64 of the sorted triples). Triangles keep their vertex order
/// (every method emits the shared tessellation's order).
pub fn triangle_digest(indices: &[u32]) -> (u64, String) {
    let mut t: Vec<[u32; 3]> = indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    t.sort_unstable();
    let bytes: Vec<u8> = t.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
    (t.len() as u64, format!("{:016x}", crate::vk::fnv1a64(&bytes)))
}
