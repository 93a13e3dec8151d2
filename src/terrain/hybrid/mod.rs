//! The hybrid model of HM / GPU HM (Paredes et al., GRAPP 2012; SPEC §4): a
//! regular height grid with power-of-two levels of detail and embedded TIN
//! patches, preprocessed per level into the GC classification (NC / CC /
//! PC), the PC list with each cell's chains of TIN-boundary (TB) vertices,
//! and the buffers of the paper's layout.
//!
//! Coordinates: topology works in grid units (a finest cell is 1×1, sample
//! (i, j) at (i, j)); vertices carry world positions (x·sx, y·sy, height).
//! The grid used is the largest corner of the data whose cell counts are
//! multiples of the coarsest cell (2^(levels-1)): at most that many minus
//! one columns and rows are left out (reported as `cropped`).
//!
//! TIN patches are polygons given in fractions of the domain (a corridor
//! along a polyline and a site polygon), so any grid gets them. Each
//! polygon's boundary gets a TB vertex at every crossing with the finest
//! grid's lines, so every TB edge lies inside one finest cell, hence inside
//! one cell of every level: a level-k cell is PC iff it holds a TB edge,
//! CC iff its centre is inside a patch, NC otherwise. The TIN is a
//! constrained Delaunay triangulation (`spade`) of the TB vertices (the
//! boundary edges as constraints, each checked with `try_add_constraint`)
//! and interior points at twice the grid's density (heights from the grid,
//! bilinear), keeping the faces inside the polygon.
//!
//! Geometry buffer (one vertex = x, y, z, 0 as f32; skirt vertices carry
//! their drop in w, see `skirt_depth`): TB vertices first, in
//! TB order (a vertex's offset is its TB index), then the TINs' interior
//! vertices, then the grid samples. NC cells are two triangles on the
//! diagonal (x0,y0)-(x1,y1); their indices are static, per level, grouped
//! by block (a coarsest cell), so a frame draws a block's NC cells with one
//! indexed draw of a range.
//!
//! PC tessellation: the part of a PC cell outside the TINs is bounded by
//! arcs of the cell border (with its corners) and the cell's TB chains
//! (each enters and leaves through the border); the loops are followed arc,
//! chain, arc, ... and each loop (a simple polygon) is ear-clipped. Every
//! vertex used is a grid corner or a TB vertex, shared with the neighbours
//! and the TIN, so the union of NC cells, PC tessellations and TINs covers
//! the domain once at every level (the coverage test checks it on the GPU).
//!
//! Parts: `patches` (patch shapes, placement and checks, the TB), `tin`
//! (one patch's triangulation), `levels` (GC classification, chains,
//! blocks, errors), `skirts`, `tessellate` (the PC tessellation) and
//! `geometry` (polygon tests, ear clipping); this file holds the types and
//! puts the model together.

mod geometry;
mod levels;
mod patches;
mod skirts;
mod tessellate;
mod tin;

use std::ops::Range;

use anyhow::{bail, Result};

use super::Heightmap;
pub use geometry::{cross_f32, ear_clip, inside, FLAT_AREA};
#[cfg(test)]
use geometry::{cross, signed_area};

/// Most levels built (cell sides 1, 2, 4, 8, 16 finest cells).
pub const MAX_LEVELS: usize = 5;

/// Cell classes of the GC list.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CellClass {
    /// Not covered: drawn as grid.
    Nc,
    /// Completely covered: the TIN is drawn there.
    Cc,
    /// Partially covered: tessellated against the TB.
    Pc,
}

/// A run of consecutive TB vertices inside one cell: `len` vertices from
/// TB index `start`, wrapping within the patch's TB range.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Chain {
    pub start: u32,
    pub len: u32,
    pub patch: u32,
}

/// One PC cell of a level.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PcCell {
    pub cell: [u32; 2],
    pub chains: Vec<Chain>,
}

/// One level of detail.
#[derive(Debug, Clone)]
pub struct Level {
    /// Cell side in finest cells (2^k).
    pub side: u32,
    /// Cells along x and y.
    pub cells: [u32; 2],
    /// GC list, `class[x + cells[0] * y]`.
    pub class: Vec<CellClass>,
    /// NC triangles' indices (6 per NC cell), grouped by block.
    pub nc_indices: Vec<u32>,
    /// Per block: its range of `nc_indices`.
    pub nc_by_block: Vec<Range<u32>>,
    /// PC cells, grouped by block.
    pub pc: Vec<PcCell>,
    /// Per block: its range of `pc`.
    pub pc_by_block: Vec<Range<u32>>,
    /// Per block: largest and summed squared height error of the level's
    /// grid triangles against the finest samples (world units).
    pub error_max: Vec<f64>,
    pub error_sse: Vec<f64>,
    /// Skirt triangles (see `HybridModel::skirt_depth`), grouped by block.
    pub skirt_indices: Vec<u32>,
    pub skirt_by_block: Vec<Range<u32>>,
}

/// A TIN patch: its polygon (grid units, counter-clockwise) and TB range.
#[derive(Debug, Clone)]
pub struct Patch {
    pub name: &'static str,
    pub polygon: Vec<[f64; 2]>,
    pub tb: Range<u32>,
}

/// The preprocessed hybrid model (see the module note).
#[derive(Debug, Clone)]
pub struct HybridModel {
    /// Finest cells used along x and y.
    pub domain: [u32; 2],
    /// Columns and rows of samples left out (see the module note).
    pub cropped: [u32; 2],
    pub spacing: [f64; 2],
    pub levels: Vec<Level>,
    /// Blocks (coarsest cells) along x and y; a block's side in finest cells.
    pub blocks: [u32; 2],
    pub block_side: u32,
    /// World positions (x, y, z, 0): TB, TIN interior, grid samples.
    pub vertices: Vec<[f32; 4]>,
    /// TB vertices' grid coordinates (the first `tb_count` vertices).
    pub tb_xy: Vec<[f64; 2]>,
    pub tin_interior: u32,
    /// Offset of grid sample (i, j): `grid_base + i + (domain[0] + 1) * j`.
    pub grid_base: u32,
    /// TIN triangles (indices into `vertices`).
    pub tin_indices: Vec<u32>,
    pub patches: Vec<Patch>,
    /// Finest samples in the domain and their heights' sum of squares about
    /// nothing (for RMS errors: `error_sse / samples`).
    pub samples: u64,
    /// Skirts: every block hangs a vertical strip this deep (height
    /// units: the largest grid error of any level, so it covers any gap)
    /// from its border at its level, so blocks of different levels leave
    /// no cracks at their T-junctions. Skirt vertices follow the grid's:
    /// a border sample's x, y and height with the drop in w (the one
    /// vertex kind whose w is not 0), so a skirt is placed `skirt_depth`
    /// lower but shaded as the ground at its border (see mesh.frag).
    pub skirt_depth: f64,
}

/// Bilinear height of the finest grid at grid coordinates p.
fn bilinear(map: &Heightmap, p: [f64; 2]) -> f64 {
    let (x, y) = (p[0].clamp(0.0, (map.nx - 1) as f64), p[1].clamp(0.0, (map.ny - 1) as f64));
    let (i, j) = ((x.floor() as usize).min(map.nx - 2), (y.floor() as usize).min(map.ny - 2));
    let (u, v) = (x - i as f64, y - j as f64);
    let h = |a, b| map.height(a, b) as f64;
    (1.0 - v) * ((1.0 - u) * h(i, j) + u * h(i + 1, j)) + v * ((1.0 - u) * h(i, j + 1) + u * h(i + 1, j + 1))
}

/// Levels to build for a grid of `cx` x `cy` finest cells: as many as keep
/// at least 4 coarsest cells per axis.
fn level_count(cx: usize, cy: usize) -> usize {
    let mut levels = MAX_LEVELS;
    while levels > 1 && (cx >> (levels - 1) < 4 || cy >> (levels - 1) < 4) {
        levels -= 1;
    }
    levels
}

/// A vertex of the geometry buffer: world x, y from grid coordinates, height z.
fn world_vertex(map: &Heightmap, p: [f64; 2], z: f64) -> [f32; 4] {
    [(p[0] * map.spacing[0]) as f32, (p[1] * map.spacing[1]) as f32, z as f32, 0.0]
}

impl HybridModel {
    /// Build the model of `map` with the default patches.
    pub fn build(map: &Heightmap) -> Result<Self> {
        let name = &map.name;
        let (cx, cy) = (map.nx - 1, map.ny - 1);
        let levels = level_count(cx, cy);
        if cx < 8 || cy < 8 {
            bail!("'{name}': a {}x{} grid is too small for a hybrid model (at least 9x9 samples)", map.nx, map.ny);
        }
        let block_side = 1u32 << (levels - 1);
        let blocks = [(cx / block_side as usize) as u32, (cy / block_side as usize) as u32];
        let domain = [blocks[0] * block_side, blocks[1] * block_side];
        let cropped = [cx as u32 - domain[0], cy as u32 - domain[1]];
        let (patches, tb_xy) = patches::place(map, domain)?;

        // Vertices: TB, then TIN interior points, then grid samples.
        let mut vertices: Vec<[f32; 4]> = tb_xy.iter().map(|&p| world_vertex(map, p, bilinear(map, p))).collect();
        let mut tin_indices = Vec::new();
        for patch in &patches {
            tin::triangulate(map, patch, &tb_xy, &mut vertices, &mut tin_indices)?;
        }
        let tin_interior = vertices.len() as u32 - tb_xy.len() as u32;
        let grid_base = vertices.len() as u32;
        for j in 0..=domain[1] as usize {
            for i in 0..=domain[0] as usize {
                vertices.push(world_vertex(map, [i as f64, j as f64], map.height(i, j) as f64));
            }
        }
        let mut model = HybridModel {
            domain,
            cropped,
            spacing: map.spacing,
            levels: Vec::new(),
            blocks,
            block_side,
            vertices,
            tb_xy,
            tin_interior,
            grid_base,
            tin_indices,
            patches,
            samples: 0,
            skirt_depth: 0.0,
        };
        // Levels whose cells could hold a whole patch are left out (a TIN
        // inside one cell would leave a hole in that cell's tessellation).
        for k in 0..levels {
            match model.build_level(map, 1 << k)? {
                Some(level) => model.levels.push(level),
                None if k > 0 => break,
                None => bail!("'{name}': a TIN patch lies inside one grid cell"),
            }
        }
        model.samples = model.domain.iter().map(|&d| d as u64).product::<u64>();
        model.add_skirts(map);
        Ok(model)
    }


    /// Geometry index of grid sample (i, j).
    pub fn grid_vertex(&self, i: u32, j: u32) -> u32 {
        self.grid_base + i + (self.domain[0] + 1) * j
    }

    fn patch_of_tb(&self, t: u32) -> usize {
        self.patches.iter().position(|p| p.tb.contains(&t)).unwrap_or(0)
    }

    /// Count of cells per class at `level`: (NC, CC, PC).
    pub fn counts(&self, level: usize) -> (usize, usize, usize) {
        let c = &self.levels[level].class;
        let n = |k| c.iter().filter(|&&x| x == k).count();
        (n(CellClass::Nc), n(CellClass::Cc), n(CellClass::Pc))
    }

    /// A TB vertex's chain successor/predecessor within its patch.
    fn tb_at(&self, chain: &Chain, k: u32) -> u32 {
        let p = &self.patches[chain.patch as usize].tb;
        p.start + (chain.start - p.start + k) % (p.end - p.start)
    }

    /// Grid coordinates of a geometry vertex (TB or grid sample).
    #[cfg(test)]
    fn xy(&self, v: u32) -> [f64; 2] {
        if (v as usize) < self.tb_xy.len() {
            self.tb_xy[v as usize]
        } else {
            let g = v - self.grid_base;
            let w = self.domain[0] + 1;
            [(g % w) as f64, (g / w) as f64]
        }
    }

    /// Which patch a TB vertex belongs to (diagnostics).
    pub fn patch_name(&self, t: u32) -> &'static str {
        self.patches[self.patch_of_tb(t)].name
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn jacksboro() -> Heightmap {
        crate::terrain::datasets::load_named("jacksboro", &crate::data_dir::data_dir()).unwrap()
    }

    /// Signed x-y area of a triangle list (grid units).
    fn area(m: &HybridModel, idx: &[u32]) -> f64 {
        idx.chunks(3).map(|t| 0.5 * cross(m.xy_any(t[0]), m.xy_any(t[1]), m.xy_any(t[2]))).sum()
    }

    impl HybridModel {
        fn xy_any(&self, v: u32) -> [f64; 2] {
            if v >= self.tb_xy.len() as u32 && v < self.grid_base {
                let p = self.vertices[v as usize];
                [p[0] as f64 / self.spacing[0], p[1] as f64 / self.spacing[1]]
            } else {
                self.xy(v)
            }
        }
    }

    #[test]
    fn classification_and_tessellation_tile_the_domain_at_every_level() {
        let map = jacksboro();
        let m = HybridModel::build(&map).unwrap();
        assert_eq!(m.levels.len(), 5);
        assert_eq!(m.domain, [400, 336]);
        let total = (m.domain[0] * m.domain[1]) as f64;
        let tin = area(&m, &m.tin_indices);
        let poly: f64 = m.patches.iter().map(|p| signed_area(&p.polygon)).sum();
        assert!((tin - poly).abs() < 1e-6 * poly, "TIN area {tin} vs polygons {poly}");
        for (k, level) in m.levels.iter().enumerate() {
            let (nc, cc, pc) = m.counts(k);
            assert!(pc > 0 && nc > 0, "level {k}: {nc} NC, {cc} CC, {pc} PC");
            let mut tris = Vec::new();
            for cell in &level.pc {
                tris.clear();
                m.tessellate(k, cell, &mut tris).unwrap();
                // Every triangle counter-clockwise (or flat: see `ear_clip`).
                for t in tris.chunks(3) {
                    assert!(cross(m.xy(t[0]), m.xy(t[1]), m.xy(t[2])) > -1e-9, "level {k} cell {:?}", cell.cell);
                }
                // Its area is the cell's minus the TINs' part of it.
                let s = level.side as f64;
                let (x0, y0) = (cell.cell[0] as f64 * s, cell.cell[1] as f64 * s);
                let mut covered = 0usize;
                let n = 64;
                for j in 0..n {
                    for i in 0..n {
                        let p = [x0 + (i as f64 + 0.5) * s / n as f64, y0 + (j as f64 + 0.5) * s / n as f64];
                        covered += m.patches.iter().any(|q| inside(&q.polygon, p)) as usize;
                    }
                }
                let outside = s * s * (1.0 - covered as f64 / (n * n) as f64);
                let a = area(&m, &tris);
                assert!((a - outside).abs() < 0.05 * s * s + 1e-9, "level {k} cell {:?}: area {a}, outside ~{outside}", cell.cell);
            }
            let ncs = (level.nc_indices.len() / 6) as f64 * (level.side * level.side) as f64;
            assert_eq!(ncs as usize, nc * (level.side * level.side) as usize);
            assert_eq!(nc + cc + pc, (level.cells[0] * level.cells[1]) as usize);
            let _ = total;
        }
    }

    #[test]
    fn ear_clip_handles_collinear_points_and_reflex_corners() {
        // An L with points along its edges.
        let pts: [[f32; 2]; 8] = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [2.0, 1.0], [1.0, 1.0], [1.0, 2.0], [0.0, 2.0], [0.0, 1.0]];
        let ids: Vec<u32> = (0..8).collect();
        let mut out = Vec::new();
        ear_clip(&pts, &ids, &mut out).unwrap();
        let a: f32 = out.chunks(3).map(|t| 0.5 * cross_f32(pts[t[0] as usize], pts[t[1] as usize], pts[t[2] as usize])).sum();
        assert!((a - 3.0).abs() < 1e-12, "{a}");
        assert!(ear_clip(&[[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]], &[0, 1, 2, 3], &mut out).is_err());
    }

    #[test]
    fn small_grids_are_refused_or_get_fewer_levels() {
        let flat = |n: usize| Heightmap::from_samples("flat", n, n, &vec![1.0; n * n], None, [1.0, 1.0]).unwrap();
        let e = HybridModel::build(&flat(5)).unwrap_err().to_string();
        assert!(e.contains("too small"), "{e}");
        let m = HybridModel::build(&flat(40)).unwrap();
        assert_eq!(m.levels.len(), 4);
    }
}

