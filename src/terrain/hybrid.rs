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

use std::collections::{HashMap, HashSet};
use std::ops::Range;

use anyhow::{bail, Context as _, Result};
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation as _};

use super::Heightmap;

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

/// A patch shape in domain fractions.
struct PatchSpec {
    name: &'static str,
    polygon: Vec<[f64; 2]>,
}

/// The corridor along the fault (a band around a polyline running
/// south-west to north-east, as the Jacksboro fault does across the
/// model) and an L-shaped site to the north-west of it.
fn default_patches() -> Vec<PatchSpec> {
    let line = [[0.08, 0.22], [0.5, 0.47], [0.92, 0.8]];
    let half_width = 0.045;
    vec![PatchSpec { name: "fault corridor", polygon: band(&line, half_width) }, PatchSpec { name: "site", polygon: site() }]
}

/// A band of `half` around a polyline (mitred joints).
fn band(line: &[[f64; 2]], half: f64) -> Vec<[f64; 2]> {
    let n = line.len();
    let normal = |a: [f64; 2], b: [f64; 2]| {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let l = (dx * dx + dy * dy).sqrt();
        [-dy / l, dx / l]
    };
    let offsets: Vec<[f64; 2]> = (0..n)
        .map(|i| {
            let a = if i > 0 { normal(line[i - 1], line[i]) } else { normal(line[0], line[1]) };
            let b = if i + 1 < n { normal(line[i], line[i + 1]) } else { a };
            let m = [a[0] + b[0], a[1] + b[1]];
            let dot = (m[0] * a[0] + m[1] * a[1]).max(1e-3);
            [m[0] / dot * half, m[1] / dot * half]
        })
        .collect();
    let mut poly: Vec<[f64; 2]> = (0..n).map(|i| [line[i][0] - offsets[i][0], line[i][1] - offsets[i][1]]).collect();
    poly.extend((0..n).rev().map(|i| [line[i][0] + offsets[i][0], line[i][1] + offsets[i][1]]));
    poly
}

fn site() -> Vec<[f64; 2]> {
    let shape = [[0.0, 0.0], [1.0, 0.0], [1.0, 0.45], [0.5, 0.45], [0.5, 1.0], [0.0, 1.0]];
    let (c, size, angle) = ([0.2, 0.72], 0.16, 20f64.to_radians());
    shape
        .iter()
        .map(|p| {
            let (x, y) = ((p[0] - 0.5) * size, (p[1] - 0.5) * size);
            [c[0] + x * angle.cos() - y * angle.sin(), c[1] + x * angle.sin() + y * angle.cos()]
        })
        .collect()
}

fn signed_area(p: &[[f64; 2]]) -> f64 {
    (0..p.len()).map(|i| {
        let (a, b) = (p[i], p[(i + 1) % p.len()]);
        a[0] * b[1] - b[0] * a[1]
    }).sum::<f64>() * 0.5
}

/// Even-odd point-in-polygon test.
pub fn inside(poly: &[[f64; 2]], p: [f64; 2]) -> bool {
    let mut c = false;
    let n = poly.len();
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + n - 1) % n]);
        if (a[1] > p[1]) != (b[1] > p[1]) && p[0] < (b[0] - a[0]) * (p[1] - a[1]) / (b[1] - a[1]) + a[0] {
            c = !c;
        }
    }
    c
}

fn cross(o: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
}

/// Whether segments ab and cd cross or touch.
fn segments_meet(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> bool {
    let (d1, d2) = (cross(a, b, c), cross(a, b, d));
    let (d3, d4) = (cross(c, d, a), cross(c, d, b));
    d1.signum() != d2.signum() && d3.signum() != d4.signum() || [d1, d2, d3, d4].contains(&0.0)
}

/// Distance from p to segment ab.
fn segment_distance(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let l2 = dx * dx + dy * dy;
    let t = if l2 > 0.0 { (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2).clamp(0.0, 1.0) } else { 0.0 };
    let (qx, qy) = (a[0] + t * dx - p[0], a[1] + t * dy - p[1]);
    (qx * qx + qy * qy).sqrt()
}

/// How close (grid units) a TB crossing may come to a grid vertex, and a
/// patch vertex to a grid line: closer is refused (the model needs every
/// TB vertex on exactly one grid line).
const LATTICE_EPS: f64 = 1e-6;

/// The TB of a polygon: its vertices plus every crossing with the lines
/// x = i and y = j, in order. Crossing coordinates on a line are exact.
fn boundary(name: &str, poly: &[[f64; 2]]) -> Result<Vec<[f64; 2]>> {
    let mut out = Vec::new();
    let n = poly.len();
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        for c in a {
            if (c - c.round()).abs() < LATTICE_EPS {
                bail!("patch '{name}': vertex {a:?} lies on a grid line");
            }
        }
        out.push(a);
        let mut hits: Vec<(f64, [f64; 2])> = Vec::new();
        for axis in 0..2 {
            let (lo, hi) = (a[axis].min(b[axis]), a[axis].max(b[axis]));
            let mut k = lo.ceil();
            while k < hi {
                let t = (k - a[axis]) / (b[axis] - a[axis]);
                let other = a[1 - axis] + t * (b[1 - axis] - a[1 - axis]);
                if (other - other.round()).abs() < LATTICE_EPS {
                    bail!("patch '{name}': edge {a:?}-{b:?} passes through grid vertex near ({k}, {other})");
                }
                let mut p = [0.0; 2];
                p[axis] = k;
                p[1 - axis] = other;
                hits.push((t, p));
                k += 1.0;
            }
        }
        hits.sort_by(|x, y| x.0.total_cmp(&y.0));
        out.extend(hits.into_iter().map(|h| h.1));
    }
    Ok(out)
}

/// Bilinear height of the finest grid at grid coordinates p.
fn bilinear(map: &Heightmap, p: [f64; 2]) -> f64 {
    let (x, y) = (p[0].clamp(0.0, (map.nx - 1) as f64), p[1].clamp(0.0, (map.ny - 1) as f64));
    let (i, j) = ((x.floor() as usize).min(map.nx - 2), (y.floor() as usize).min(map.ny - 2));
    let (u, v) = (x - i as f64, y - j as f64);
    let h = |a, b| map.height(a, b) as f64;
    (1.0 - v) * ((1.0 - u) * h(i, j) + u * h(i + 1, j)) + v * ((1.0 - u) * h(i, j + 1) + u * h(i + 1, j + 1))
}

impl HybridModel {
    /// Build the model of `map` with the default patches.
    pub fn build(map: &Heightmap) -> Result<Self> {
        let name = &map.name;
        let (cx, cy) = (map.nx - 1, map.ny - 1);
        // As many levels as keep at least 4 coarsest cells per axis.
        let mut levels = MAX_LEVELS;
        while levels > 1 && (cx >> (levels - 1) < 4 || cy >> (levels - 1) < 4) {
            levels -= 1;
        }
        if cx < 8 || cy < 8 {
            bail!("'{name}': a {}x{} grid is too small for a hybrid model (at least 9x9 samples)", map.nx, map.ny);
        }
        let block_side = 1u32 << (levels - 1);
        let blocks = [(cx / block_side as usize) as u32, (cy / block_side as usize) as u32];
        let domain = [blocks[0] * block_side, blocks[1] * block_side];
        let cropped = [cx as u32 - domain[0], cy as u32 - domain[1]];
        let (dw, dh) = (domain[0] as f64, domain[1] as f64);

        // Patches in grid units, nudged off the lattice, counter-clockwise.
        let mut patches = Vec::new();
        let mut tb_xy: Vec<[f64; 2]> = Vec::new();
        let specs = if map.patches.is_empty() {
            default_patches()
        } else {
            map.patches.iter().map(|p| PatchSpec { name: "given patch", polygon: p.clone() }).collect()
        };
        for spec in specs {
            if spec.polygon.len() < 3 || spec.polygon.iter().flatten().any(|c| !c.is_finite()) {
                bail!("'{name}': TIN patch '{}' needs at least 3 finite vertices", spec.name);
            }
            // Arbitrary sub-sample offsets (they only keep patch corners off
            // grid lines), not 1/pi and e/10.
            #[allow(clippy::approx_constant)]
            let mut poly: Vec<[f64; 2]> = spec.polygon.iter().map(|p| [p[0] * dw + 0.3183, p[1] * dh + 0.2718]).collect();
            if signed_area(&poly) < 0.0 {
                poly.reverse();
            }
            let tb = boundary(spec.name, &poly).with_context(|| format!("'{name}': building the TIN boundary"))?;
            let start = tb_xy.len() as u32;
            tb_xy.extend(tb);
            patches.push(Patch { name: spec.name, polygon: poly, tb: start..tb_xy.len() as u32 });
        }
        // Patches must be simple, disjoint and inside the domain.
        let edges: Vec<(usize, [f64; 2], [f64; 2])> = patches
            .iter()
            .enumerate()
            .flat_map(|(pi, p)| (0..p.polygon.len()).map(move |i| (pi, p.polygon[i], p.polygon[(i + 1) % p.polygon.len()])))
            .collect();
        for (i, e) in edges.iter().enumerate() {
            for f in &edges[i + 1..] {
                let adjacent = e.0 == f.0 && (e.2 == f.1 || f.2 == e.1);
                if !adjacent && segments_meet(e.1, e.2, f.1, f.2) {
                    bail!("'{name}': TIN patch edges cross ({:?}-{:?} and {:?}-{:?})", e.1, e.2, f.1, f.2);
                }
            }
            if !(e.1[0] > 0.0 && e.1[1] > 0.0 && e.1[0] < dw && e.1[1] < dh) {
                bail!("'{name}': TIN patch vertex {:?} is outside the grid", e.1);
            }
        }
        for (i, p) in patches.iter().enumerate() {
            for q in &patches[i + 1..] {
                if inside(&q.polygon, p.polygon[0]) || inside(&p.polygon, q.polygon[0]) {
                    bail!("'{name}': TIN patches '{}' and '{}' overlap", p.name, q.name);
                }
            }
        }

        // Vertices: TB, then TIN interior points, then grid samples.
        let world = |p: [f64; 2], z: f64| [(p[0] * map.spacing[0]) as f32, (p[1] * map.spacing[1]) as f32, z as f32, 0.0];
        let mut vertices: Vec<[f32; 4]> = tb_xy.iter().map(|&p| world(p, bilinear(map, p))).collect();
        let mut tin_indices = Vec::new();
        for patch in &patches {
            let tb: Vec<u32> = (patch.tb.start..patch.tb.end).collect();
            let mut interior = Vec::new();
            let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
            for p in &patch.polygon {
                for a in 0..2 {
                    lo[a] = lo[a].min(p[a]);
                    hi[a] = hi[a].max(p[a]);
                }
            }
            // Twice the grid's density; not within 0.2 cells of the TB. The
            // TB's edges (each inside one grid cell: `boundary` cuts them at
            // every grid line) are listed by the cells within 0.2 of them, so
            // a candidate tests only its own cell's edges: time proportional
            // to the patch's area, not to area times perimeter (a 16384²
            // grid took hours).
            let n = tb.len();
            let cell = |x: f64, y: f64| (x.floor() as i64, y.floor() as i64);
            let mut near: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
            for i in 0..n {
                let (a, b) = (tb_xy[tb[i] as usize], tb_xy[tb[(i + 1) % n] as usize]);
                let (c0, c1) = (cell(a[0].min(b[0]) - 0.2, a[1].min(b[1]) - 0.2), cell(a[0].max(b[0]) + 0.2, a[1].max(b[1]) + 0.2));
                for cx in c0.0..=c1.0 {
                    for cy in c0.1..=c1.1 {
                        near.entry((cx, cy)).or_default().push(i);
                    }
                }
            }
            let mut y = (lo[1] * 2.0).ceil() * 0.5;
            while y < hi[1] {
                let mut x = (lo[0] * 2.0).ceil() * 0.5;
                while x < hi[0] {
                    let p = [x, y];
                    let edges = near.get(&cell(x, y)).map_or(&[][..], Vec::as_slice);
                    if inside(&patch.polygon, p)
                        && edges.iter().all(|&i| segment_distance(p, tb_xy[tb[i] as usize], tb_xy[tb[(i + 1) % n] as usize]) > 0.2)
                    {
                        interior.push(p);
                    }
                    x += 0.5;
                }
                y += 0.5;
            }
            let mut cdt: ConstrainedDelaunayTriangulation<Point2<f64>> = ConstrainedDelaunayTriangulation::new();
            // Our vertex index per spade vertex index.
            let mut ours: Vec<u32> = Vec::new();
            let mut handles = Vec::new();
            let mut insert = |cdt: &mut ConstrainedDelaunayTriangulation<Point2<f64>>, p: [f64; 2], index: u32| -> Result<_> {
                let h = cdt.insert(Point2::new(p[0], p[1])).map_err(|e| anyhow::anyhow!("'{name}': TIN vertex {p:?}: {e:?}"))?;
                if h.index() < ours.len() {
                    bail!("'{name}': patch '{}': two TIN vertices at {p:?}", patch.name);
                }
                ours.push(index);
                Ok(h)
            };
            for &t in &tb {
                handles.push(insert(&mut cdt, tb_xy[t as usize], t)?);
            }
            let first_interior = vertices.len() as u32;
            for (k, &p) in interior.iter().enumerate() {
                insert(&mut cdt, p, first_interior + k as u32)?;
                vertices.push(world(p, bilinear(map, p)));
            }
            for i in 0..handles.len() {
                let (a, b) = (handles[i], handles[(i + 1) % handles.len()]);
                let made = cdt.try_add_constraint(a, b);
                if made.is_empty() || !cdt.exists_constraint(a, b) {
                    bail!("'{name}': patch '{}': TB edge {i} could not be a constraint edge (crossing or split)", patch.name);
                }
            }
            // Inside faces: those left of a TB edge (the TB runs counter-
            // clockwise), then everything reachable without crossing a
            // constraint. (A centroid test against the polygon misjudges the
            // slivers between a TB chain and the straight edge it follows.)
            let n = handles.len();
            let forward: HashSet<(usize, usize)> = (0..n).map(|i| (handles[i].index(), handles[(i + 1) % n].index())).collect();
            let mut inside_faces: HashSet<usize> = HashSet::new();
            let mut stack = Vec::new();
            for face in cdt.inner_faces() {
                if face.adjacent_edges().iter().any(|e| forward.contains(&(e.from().fix().index(), e.to().fix().index())))
                    && inside_faces.insert(face.fix().index())
                {
                    stack.push(face.fix());
                }
            }
            while let Some(f) = stack.pop() {
                for e in cdt.face(f).adjacent_edges() {
                    if e.is_constraint_edge() {
                        continue;
                    }
                    if let Some(g) = e.rev().face().fix().as_inner() {
                        if inside_faces.insert(g.index()) {
                            stack.push(g);
                        }
                    }
                }
            }
            for face in cdt.inner_faces() {
                if inside_faces.contains(&face.fix().index()) {
                    tin_indices.extend(face.vertices().map(|h| ours[h.fix().index()]));
                }
            }
        }
        let tin_interior = vertices.len() as u32 - tb_xy.len() as u32;
        let grid_base = vertices.len() as u32;
        for j in 0..=domain[1] as usize {
            for i in 0..=domain[0] as usize {
                vertices.push(world([i as f64, j as f64], map.height(i, j) as f64));
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

    fn build_level(&self, map: &Heightmap, side: u32) -> Result<Option<Level>> {
        let cells = [self.domain[0] / side, self.domain[1] / side];
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
        // Chains: maximal runs of a patch's TB edges in one cell.
        let mut chains: Vec<Vec<Chain>> = vec![Vec::new(); ncells];
        for (pi, patch) in self.patches.iter().enumerate() {
            let ec = &edge_cell[pi];
            let n = ec.len();
            // Start at an edge whose predecessor lies in another cell.
            let Some(first) = (0..n).find(|&i| ec[(i + n - 1) % n] != ec[i]) else {
                return Ok(None);
            };
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

    /// Skirt vertices (a copy of every grid sample and TB vertex on a block
    /// border, with the drop) and each level's skirt triangles per block.
    fn add_skirts(&mut self, map: &Heightmap) {
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

/// Twice the area (cell-local units²) below which a ring vertex counts as
/// collinear with its neighbours when no ear is left (f32 rounding of
/// coordinates up to 16 is ~1e-6; see `ear_clip`).
pub const FLAT_AREA: f32 = 1e-4;

/// Twice the signed area of triangle o, a, b in f32, evaluated in this
/// order (the shader's `cross2` is the same expression, `precise`).
pub fn cross_f32(o: [f32; 2], a: [f32; 2], b: [f32; 2]) -> f32 {
    let p = (a[0] - o[0]) * (b[1] - o[1]);
    let q = (a[1] - o[1]) * (b[0] - o[0]);
    p - q
}

/// Ear clipping of a simple counter-clockwise ring (cell-local positions
/// `pts`, geometry indices `ids`), in f32 (see `HybridModel::tessellate`):
/// the first convex vertex, in ring order, whose triangle holds no other
/// ring vertex is clipped, again and again. When nothing else can be
/// clipped, the first (nearly) collinear vertex is clipped as a flat
/// triangle (every ring edge stays an edge: dropping it would leave a
/// T-junction against the TIN or the neighbour, which the rasterizer's
/// snapping turns into gaps or overlaps).
pub fn ear_clip(pts: &[[f32; 2]], ids: &[u32], out: &mut Vec<u32>) -> Result<()> {
    let mut ring: Vec<usize> = (0..pts.len()).collect();
    while ring.len() > 3 {
        let n = ring.len();
        let mut clip = None;
        for k in 0..n {
            let (a, b, c) = (ring[(k + n - 1) % n], ring[k], ring[(k + 1) % n]);
            if cross_f32(pts[a], pts[b], pts[c]) <= 0.0 {
                continue;
            }
            let blocked = ring.iter().any(|&o| {
                o != a && o != b && o != c && {
                    let p = pts[o];
                    cross_f32(pts[a], pts[b], p) >= 0.0 && cross_f32(pts[b], pts[c], p) >= 0.0 && cross_f32(pts[c], pts[a], p) >= 0.0
                }
            });
            if !blocked {
                clip = Some(k);
                break;
            }
        }
        if clip.is_none() {
            clip = (0..n).find(|&k| cross_f32(pts[ring[(k + n - 1) % n]], pts[ring[k]], pts[ring[(k + 1) % n]]).abs() <= FLAT_AREA);
        }
        let Some(k) = clip else { bail!("no ear in a ring of {n} vertices (not simple or not counter-clockwise)") };
        out.extend([ids[ring[(k + n - 1) % n]], ids[ring[k]], ids[ring[(k + 1) % n]]]);
        ring.remove(k);
    }
    if ring.len() == 3 {
        out.extend(ring.iter().map(|&r| ids[r]));
    }
    Ok(())
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

