//! Exact visibility order from face adjacency: Williams' MPVO (Meshed
//! Polyhedra Visibility Ordering, 1992) with a depth-driven form of his
//! MPVONC heuristic for non-convex meshes.
//!
//! **Once per mesh** ([`MpvoSort::new`]):
//! - *Face adjacency* from the shared builder
//!   ([`crate::mesh::adjacency::FaceAdjacency`]: faces matched by sorted
//!   vertex triple), after *welding* vertices with bit-identical coordinates
//!   (`weld_coincident`: two grid blocks whose boundary points coincide
//!   without sharing indices are joined; `welded_faces` counts what only the
//!   weld matched). A triple held by two cells is an interior face, by one a
//!   boundary face. MPVO's policy for triples with three or more holders
//!   (they happen when the weld merges a collapsed grid point, the blunt
//!   fin's): if exactly two holders are solid they are paired (the flat ones
//!   draw nothing), otherwise all stay boundary faces (`flat_shared_faces`,
//!   or `non_manifold_faces` if three or more are solid: invalid input).
//!   Solid/flat is `TetGeometry`'s `degenerate` flag, i.e. the one flatness
//!   test of `mesh::geometry::tet_det` that the CPU reference uses too.
//! - *One plane per interior face*, from [`TetGeometry`] (unit outward normal
//!   `n`, offset `a`) of the solid cell (the lower face slot if both are
//!   solid); the other side stores its exact negation, so the two cells agree
//!   bit for bit on which side of the face the eye lies. A face between two
//!   degenerate (zero-volume) cells has no trustworthy plane and carries no
//!   constraint (`unconstrained_faces`); a face between a degenerate and a
//!   solid cell uses the solid cell's plane (a solid cell's faces always have
//!   positive area). So flat cells add only constraints that are true of
//!   their solid neighbours' faces.
//! - *Seam links*: a structured grid's seam whose two sides cut each quad
//!   along different diagonals (the oxygen post's O-grid seam: the 5-tet
//!   split's parity does not match across it) shares no face, yet the cells
//!   on either side overlap face to face. Boundary faces of solid cells that
//!   share a welded edge, lie in one plane with opposite normals and overlap
//!   are linked: each linked cell pair is one more constraint, decided by the
//!   same side test on one of the two faces' plane (`seam_links`).
//!
//! **Per frame** ([`MpvoSort::sort`]):
//! 1. In parallel over cells, for each interior face of cell `c` with plane
//!    `(n, a)` (outward from `c`), the side test `s = n·eye + a` (eye and plane relative to the mesh's render origin)
//!    (perspective) or `s = −n·v` (orthographic, `v` the view direction: the
//!    eye is at `−∞·v`). `s > 0`: the eye is outside `c` across that face, so
//!    the neighbour lies between `c` and the eye and `c` is drawn first.
//!    `s < 0`: the neighbour is behind `c` and is drawn first. `s = 0` (face
//!    seen exactly edge-on): no constraint. The result is a 4+4-bit mask per
//!    cell (faces whose neighbour is behind / in front) and, in the same pass,
//!    the cell's depth key (squared centroid distance from the eye, or
//!    centroid depth along `v`). Seam links are tested the same way.
//! 2. The centroid order (the same keys as `sort::CentroidSort`, the LSD
//!    radix sort of `radix`), as a rank per cell.
//! 3. Kahn's topological sort of the "behind" DAG, back to front: a cell
//!    becomes *ready* once every neighbour behind it has been emitted; the
//!    initial ready cells are those with nothing behind them (for a convex
//!    mesh: cells whose boundary faces face away from the eye).
//!    **Tie-break among ready cells (our MPVONC):** the farthest ready cell
//!    by centroid is always emitted next (the ready set is a priority queue
//!    on centroid rank: a bitset with summary levels, O(1)-ish per
//!    operation). Williams' MPVONC sorts only the initial sources (cells with
//!    a back-facing boundary face) by distance before his depth-first
//!    traversal; ordering every ready cell by depth subsumes that: where
//!    faces and links say nothing (separate parts, across a concavity) the
//!    order falls back to centroid order, and where they speak they are
//!    always obeyed. For a convex, acyclic mesh any topological order is an
//!    exact visibility order, so the tie-break costs nothing there.
//! 4. **Cycles.** If no cell is ready while cells remain, the "behind"
//!    relation restricted to them has a cycle (possible for non-Delaunay
//!    meshes, for overlapping cells, or by rounding with the eye almost in a
//!    face's plane). The farthest remaining cell (centroid) is then emitted
//!    regardless of its unmet predecessors and the sort goes on; each forced
//!    emission counts as one `cycles_broken` in [`MpvoFrameStats`]. Every
//!    cell is emitted exactly once, so the output is always a permutation,
//!    and the loop ends after exactly `n` emissions.
//!
//! The order is reported farthest first, the convention of
//! `sort::CentroidSort` (this module does not depend on `sort`: `sort::Sorter`
//! wraps this one). [`MpvoSort::check_order`] (and
//! [`MpvoSort::count_out_of_order`]) count the face and link constraints that
//! any given order, e.g. the centroid order, violates, with the same tests.
//!
//! **Cost** (release, 2 shared cores; `tests/mpvo.rs`, ignored test): oxygen
//! post (513,375 tets) build ≈ 0.1 s, per frame 21–31 ms (medians over 14
//! views), of which step 1 ≈ 3 ms (parallel, streams 32 bytes of plane per
//! cell face), step 2 ≈ 4 ms and step 3 ≈ 15 ms (sequential; its cost is the
//! random access to neighbours' records as the front of ready cells sweeps
//! the mesh, kept to one 24-byte record per cell); blunt fin (187,395 tets)
//! 6–8 ms. The centroid sort alone takes 2.5 and 1 ms.

use rayon::prelude::*;
use serde::Serialize;

use super::radix::{float_key, radix_sort_pairs};
use crate::mesh::adjacency::{weld_coincident, FaceAdjacency, FACE_VERTS, NONE};
use crate::mesh::{TetGeometry, TetMesh};
use crate::scene::Camera;

/// `remaining` value of a cell already emitted.
const EMITTED: u8 = u8::MAX;

/// What was found while building the adjacency (once per mesh).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct MpvoBuildStats {
    pub cells: usize,
    /// Faces shared by exactly two cells.
    pub interior_faces: usize,
    /// Faces of one cell only (including non-manifold ones).
    pub boundary_faces: usize,
    /// Cell faces whose (welded) vertex triple is shared by three or more
    /// solid cells (invalid input); all are left as boundary faces. (When
    /// exactly two holders of a triple are solid, those two are paired:
    /// welding a collapsed grid point makes flat cells share their triple.)
    pub non_manifold_faces: usize,
    /// Cell faces whose triple is held by three or more cells, at most one of
    /// them solid (flat cells at collapsed points): boundary faces.
    pub flat_shared_faces: usize,
    /// Interior faces found only because coincident vertices were welded
    /// (seams of O-grids and similar).
    pub welded_faces: usize,
    /// Interior faces between two degenerate cells: no plane, no constraint.
    pub unconstrained_faces: usize,
    /// Degenerate (zero-volume) cells of the geometry.
    pub degenerate_cells: usize,
    /// Pairs of solid cells whose boundary faces share an edge, lie in one
    /// plane facing opposite ways and overlap: a non-conforming seam (the
    /// oxygen post's O-grid seam, whose two sides split each quad along
    /// different diagonals). Each pair is one constraint, like a shared face.
    pub seam_links: usize,
}

/// What happened in the last [`MpvoSort::sort`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct MpvoFrameStats {
    /// Interior faces and seam links with a strict side decision (the edges
    /// of the "behind" graph).
    pub constraints: usize,
    /// Interior faces and seam links whose plane the eye lies exactly in (no
    /// constraint).
    pub edge_on_faces: usize,
    /// Cells ready at the start (nothing behind them).
    pub sources: usize,
    /// Times the ready set was empty with cells left, so that the farthest
    /// remaining cell was emitted before all cells behind it.
    pub cycles_broken: usize,
    /// Largest size of the ready set.
    pub max_ready: usize,
}

/// How well an order respects the visibility constraints (interior faces
/// and seam links) for one camera.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct OrderCheck {
    /// Constraints with a strict side decision for this camera.
    pub constraints: usize,
    /// Of those, the ones whose "behind" cell is drawn after its "in front"
    /// cell.
    pub violated: usize,
    /// Cells drawn before at least one neighbour that lies behind them.
    pub cells_out_of_order: usize,
}

/// MPVO visibility sort of one mesh: adjacency built once, order per frame.
pub struct MpvoSort {
    /// Per cell: neighbours, this frame's side mask, rank and count of
    /// unemitted cells behind it, together so that the topological sort
    /// touches one record per cell.
    nodes: Vec<Node>,
    /// `planes[4c+f]`: the plane of that face, outward from `c`, exactly the
    /// negation of the neighbour's; zero when the face carries no constraint.
    /// Relative to `origin` (`TetPrecomputed::plane_relative`), as are the
    /// links' planes: far from the world origin a world-space offset has
    /// lost the digits the eye-side test needs.
    planes: Vec<[f64; 4]>,
    /// `render_origin` of the mesh.
    origin: [f64; 3],
    /// Constraints across non-conforming seams (see module docs), and per
    /// cell the links it takes part in (CSR: `link_list[link_start[c] ..
    /// link_start[c + 1]]`, only for cells with `Node::linked`).
    links: Vec<Link>,
    link_start: Vec<u32>,
    link_list: Vec<u32>,
    /// Per frame, per link: the side test (`s > 0`: `a` first, `s < 0`: `b`
    /// first, 0: no constraint).
    link_sides: Vec<i8>,
    centroids: Vec<[f64; 3]>,
    build: MpvoBuildStats,
    // Per-frame buffers.
    /// Depth keys, ascending = farthest first (radix-sorted in place).
    keys: Vec<u32>,
    scratch_keys: Vec<u32>,
    /// Cells farthest first by centroid (`Node::rank` is the inverse).
    by_depth: Vec<u32>,
    scratch_cells: Vec<u32>,
    ready: RankSet,
    order: Vec<u32>,
    position: Vec<u32>,
    frame: MpvoFrameStats,
}

/// One cell's adjacency and per-frame sort state.
#[derive(Debug, Clone, Copy)]
struct Node {
    /// The cell across face `f`, or `NONE`.
    nb: [u32; 4],
    /// Rank in this frame's centroid order (0 = farthest).
    rank: u32,
    /// Low nibble: faces whose neighbour is behind (drawn before); high
    /// nibble: faces whose neighbour is in front (drawn after).
    mask: u8,
    /// Neighbours behind not yet emitted; `EMITTED` once emitted.
    remaining: u8,
    /// Takes part in seam links.
    linked: bool,
}

/// A constraint between two cells whose boundary faces overlap in one plane
/// without being the same triangle (a seam cut along different diagonals on
/// its two sides): `plane` is `a`'s face, outward from `a`.
#[derive(Debug, Clone, Copy)]
struct Link {
    a: u32,
    b: u32,
    plane: [f64; 4],
}

impl MpvoSort {
    /// Builds adjacency and per-face planes. `geometry` must be
    /// `TetGeometry::compute(mesh)`.
    pub fn new(mesh: &TetMesh, geometry: &TetGeometry) -> MpvoSort {
        let n = mesh.tets.len();
        assert_eq!(geometry.cells.len(), n, "geometry does not belong to this mesh");

        // Faces keyed by sorted welded triple; MPVO's policy for triples
        // with three or more holders on top.
        let weld = weld_coincident(&mesh.points);
        let adj = FaceAdjacency::build(&mesh.tets, Some(&weld), |_| true);
        let mut build = MpvoBuildStats {
            cells: n,
            interior_faces: adj.interior_faces(),
            boundary_faces: adj.boundary.len(),
            welded_faces: adj.welded_pairs,
            ..Default::default()
        };
        let partner = resolve_shared_faces(adj, geometry, &mut build);
        let origin = super::render_origin(mesh);
        let links = seam_links(mesh, geometry, &weld, &partner, origin);
        build.seam_links = links.len();
        let (link_start, link_list) = links_per_cell(&links, n);
        let planes = face_planes(mesh, geometry, &partner, origin);
        let neighbor: Vec<u32> = partner.par_iter().map(|&p| if p == NONE { NONE } else { p / 4 }).collect();
        drop(partner);
        build.degenerate_cells = geometry.cells.iter().filter(|c| c.degenerate).count();
        build.unconstrained_faces = unconstrained_faces(&neighbor, &planes);
        let nodes = (0..n)
            .into_par_iter()
            .map(|c| Node {
                nb: std::array::from_fn(|f| neighbor[4 * c + f]),
                rank: 0,
                mask: 0,
                remaining: 0,
                linked: link_start[c + 1] > link_start[c],
            })
            .collect();
        MpvoSort {
            nodes,
            planes,
            origin,
            link_sides: vec![0; links.len()],
            links,
            link_start,
            link_list,
            // Relative to `origin`, like the planes and the eye.
            centroids: geometry.centroids.iter().map(|c| std::array::from_fn(|k| c[k] - origin[k])).collect(),
            build,
            keys: vec![0; n],
            scratch_keys: Vec::new(),
            by_depth: Vec::with_capacity(n),
            scratch_cells: Vec::new(),
            ready: RankSet::new(n),
            order: Vec::with_capacity(n),
            position: Vec::new(),
            frame: MpvoFrameStats::default(),
        }
    }

    pub fn host_bytes(&self, memory: &mut crate::algo::host_memory::HostMemory) {
        memory.vec("sort: mpvo nodes (adjacency, per-frame state)", &self.nodes);
        memory.vec("sort: mpvo face planes (f64)", &self.planes);
        memory.vec("sort: mpvo seam links", &self.links);
        memory.vec("sort: mpvo seam links", &self.link_start);
        memory.vec("sort: mpvo seam links", &self.link_list);
        memory.vec("sort: mpvo seam links", &self.link_sides);
        memory.vec("sort: mpvo f64 centroids", &self.centroids);
        memory.vec("sort: keys and scratch", &self.keys);
        memory.vec("sort: keys and scratch", &self.scratch_keys);
        memory.vec("sort: order and scratch", &self.by_depth);
        memory.vec("sort: order and scratch", &self.scratch_cells);
        memory.vec("sort: order and scratch", &self.order);
        memory.vec("sort: order and scratch", &self.position);
        for level in &self.ready.levels {
            memory.vec("sort: mpvo ready set", level);
        }
    }

    /// Convenience: computes the geometry itself.
    pub fn from_mesh(mesh: &TetMesh) -> MpvoSort {
        MpvoSort::new(mesh, &TetGeometry::compute(mesh))
    }

    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    pub fn build_stats(&self) -> MpvoBuildStats {
        self.build
    }

    /// Statistics of the last [`MpvoSort::sort`].
    pub fn frame_stats(&self) -> MpvoFrameStats {
        self.frame
    }

    /// The cell across face `f` (opposite vertex `f`) of cell `c`, if any.
    pub fn neighbor(&self, c: usize, f: usize) -> Option<u32> {
        let d = self.nodes[c].nb[f];
        (d != NONE).then_some(d)
    }

    /// Step 1: side tests and depth keys; returns (constraints, edge-on
    /// faces), seam links included.
    fn classify(&mut self, camera: &Camera) -> (usize, usize) {
        let eye: [f64; 3] = std::array::from_fn(|k| camera.eye[k] - self.origin[k]);
        let f = camera.forward();
        let v = [f.x, f.y, f.z];
        let perspective = camera.is_perspective();
        let side = |p: &[f64; 4]| {
            if perspective {
                p[0] * eye[0] + p[1] * eye[1] + p[2] * eye[2] + p[3]
            } else {
                -(p[0] * v[0] + p[1] * v[1] + p[2] * v[2])
            }
        };
        let (link_constraints, link_edge_on) = self
            .link_sides
            .par_iter_mut()
            .zip(self.links.par_iter())
            .map(|(out, l)| {
                let s = side(&l.plane);
                *out = if s > 0.0 {
                    1
                } else if s < 0.0 {
                    -1
                } else {
                    0
                };
                ((*out != 0) as usize, (*out == 0) as usize)
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
        let planes = &self.planes;
        let centroids = &self.centroids;
        let (constraints, edge_on) = self
            .nodes
            .par_iter_mut()
            .zip(self.keys.par_iter_mut())
            .enumerate()
            .with_min_len(4096)
            .map(|(c, (node, key))| {
                let mut m = 0u8;
                let mut edge_on = 0usize;
                for face in 0..4 {
                    let slot = 4 * c + face;
                    if node.nb[face] == NONE {
                        continue;
                    }
                    let p = &planes[slot];
                    let s = side(p);
                    if s < 0.0 {
                        m |= 1 << face;
                    } else if s > 0.0 {
                        m |= 0x10 << face;
                    } else if *p != [0.0; 4] {
                        edge_on += 1;
                    }
                }
                node.mask = m;
                let q = &centroids[c];
                let d = [q[0] - eye[0], q[1] - eye[1], q[2] - eye[2]];
                let depth = if perspective {
                    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
                } else {
                    d[0] * v[0] + d[1] * v[1] + d[2] * v[2]
                };
                // Farthest first: ascending key = descending depth.
                *key = !float_key(depth as f32);
                ((m & 0xf).count_ones() as usize, edge_on)
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
        // Each edge-on face was seen from both sides.
        (constraints + link_constraints, edge_on / 2 + link_edge_on)
    }

    fn link_view(&self) -> LinkView<'_> {
        LinkView { links: &self.links, sides: &self.link_sides, start: &self.link_start, list: &self.link_list }
    }

    /// Cell indices back to front (farthest first) for this camera.
    pub fn sort(&mut self, camera: &Camera) -> &[u32] {
        let (constraints, edge_on) = self.classify(camera);
        // The centroid order (the ready set's priority and the cycle
        // breaker's choice), as ranks.
        self.by_depth.clear();
        self.by_depth.extend(0..self.len() as u32);
        radix_sort_pairs(&mut self.keys, &mut self.by_depth, &mut self.scratch_keys, &mut self.scratch_cells);
        for (r, &c) in self.by_depth.iter().enumerate() {
            self.nodes[c as usize].rank = r as u32;
        }
        let links =
            LinkView { links: &self.links, sides: &self.link_sides, start: &self.link_start, list: &self.link_list };
        let (sources, cycles_broken, max_ready) =
            topological_order(&mut self.nodes, &self.by_depth, &links, &mut self.ready, &mut self.order);
        self.frame = MpvoFrameStats { constraints, edge_on_faces: edge_on, sources, cycles_broken, max_ready };
        &self.order
    }

    /// Checks `order` (cell indices, farthest first; must be a permutation of
    /// the cells, else this panics) against the constraints for `camera`.
    pub fn check_order(&mut self, order: &[u32], camera: &Camera) -> OrderCheck {
        let n = self.len();
        assert_eq!(order.len(), n, "order has {} cells, mesh has {n}", order.len());
        let (constraints, _) = self.classify(camera);
        self.position.clear();
        self.position.resize(n, u32::MAX);
        for (i, &c) in order.iter().enumerate() {
            let p = &mut self.position[c as usize];
            assert!(*p == u32::MAX, "cell {c} appears twice in the order");
            *p = i as u32;
        }
        let (nodes, position, links) = (&self.nodes, &self.position, self.link_view());
        let (violated, cells) = (0..n)
            .into_par_iter()
            .with_min_len(4096)
            .map(|c| {
                let node = &nodes[c];
                let mut v = 0;
                for face in 0..4 {
                    if node.mask & (1 << face) != 0 && position[node.nb[face] as usize] > position[c] {
                        v += 1;
                    }
                }
                if node.linked {
                    links.each(c, |other, before| {
                        if before && position[other] > position[c] {
                            v += 1;
                        }
                    });
                }
                (v, (v > 0) as usize)
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
        OrderCheck { constraints, violated, cells_out_of_order: cells }
    }

    /// How many face (and seam link) constraints `order` (farthest first)
    /// violates for `camera` (see [`MpvoSort::check_order`]).
    pub fn count_out_of_order(&mut self, order: &[u32], camera: &Camera) -> usize {
        self.check_order(order, camera).violated
    }
}

/// Step 2: Kahn's algorithm; the ready set holds centroid-order ranks and
/// yields the farthest ready cell; when it is empty with cells left, the
/// farthest remaining cell is forced (a broken cycle). Reads `nb`, `mask`
/// and `rank` of the nodes (`by_depth[rank] == cell`), uses `remaining`.
/// Returns (sources, cycles broken, largest ready set).
fn topological_order(
    nodes: &mut [Node],
    by_depth: &[u32],
    links: &LinkView,
    ready: &mut RankSet,
    order: &mut Vec<u32>,
) -> (usize, usize, usize) {
    let n = nodes.len();
    ready.reset(n);
    for (c, node) in nodes.iter_mut().enumerate() {
        let mut r = (node.mask & 0xf).count_ones() as u8;
        if node.linked {
            links.each(c, |_, before| r += before as u8);
        }
        node.remaining = r;
        if r == 0 {
            ready.insert(node.rank);
        }
    }
    let sources = ready.len();
    let mut max_ready = sources;
    order.clear();
    let mut cursor = 0usize; // ranks below it are all emitted
    let mut cycles = 0;
    while order.len() < n {
        let c = match ready.pop_min() {
            Some(r) => by_depth[r as usize] as usize,
            None => {
                // A cycle: force the farthest remaining cell.
                while nodes[by_depth[cursor] as usize].remaining == EMITTED {
                    cursor += 1;
                }
                cycles += 1;
                by_depth[cursor] as usize
            }
        };
        let node = &mut nodes[c];
        node.remaining = EMITTED;
        order.push(c as u32);
        let (mut succ, nb, linked) = (node.mask >> 4, node.nb, node.linked);
        if linked {
            links.each(c, |d, before| {
                let next = &mut nodes[d];
                if !before && next.remaining != EMITTED {
                    next.remaining -= 1;
                    if next.remaining == 0 {
                        ready.insert(next.rank);
                    }
                }
            });
        }
        if succ != 0 {
            while succ != 0 {
                let face = succ.trailing_zeros() as usize;
                succ &= succ - 1;
                let next = &mut nodes[nb[face] as usize];
                if next.remaining != EMITTED {
                    next.remaining -= 1;
                    if next.remaining == 0 {
                        ready.insert(next.rank);
                    }
                }
            }
            max_ready = max_ready.max(ready.len());
        }
    }
    (sources, cycles, max_ready)
}

/// The seam links of a mesh with this frame's side tests.
struct LinkView<'a> {
    links: &'a [Link],
    sides: &'a [i8],
    start: &'a [u32],
    list: &'a [u32],
}

impl LinkView<'_> {
    /// Calls `f(other, other_is_drawn_before_c)` for each link of cell `c`
    /// that constrains the order this frame.
    #[inline]
    fn each(&self, c: usize, mut f: impl FnMut(usize, bool)) {
        for &k in &self.list[self.start[c] as usize..self.start[c + 1] as usize] {
            let (l, s) = (&self.links[k as usize], self.sides[k as usize]);
            if s != 0 {
                // s > 0: `a` is drawn first.
                let c_is_a = l.a as usize == c;
                let other = if c_is_a { l.b } else { l.a };
                f(other as usize, (s > 0) != c_is_a);
            }
        }
    }
}

/// `partner[slot]`, the neighbour's face slot (`NONE` on the boundary),
/// after MPVO's policy for faces of three or more holders, which `build`
/// counts.
fn resolve_shared_faces(adj: FaceAdjacency, geometry: &TetGeometry, build: &mut MpvoBuildStats) -> Vec<u32> {
    let mut partner = adj.partner;
    for holders in &adj.shared {
        // Only possible through welding (degenerate cells at collapsed
        // points) or invalid input. If exactly two of the holders are
        // solid cells they are the real neighbours (the others are flat
        // and draw nothing).
        let m = holders.len();
        let solid: Vec<u32> = holders.iter().copied().filter(|&s| !geometry.cells[s as usize / 4].degenerate).collect();
        if let [a, b] = solid[..] {
            partner[a as usize] = b;
            partner[b as usize] = a;
            build.interior_faces += 1;
            build.welded_faces += 1;
            build.boundary_faces += m - 2;
        } else {
            if solid.len() > 2 {
                build.non_manifold_faces += m;
            } else {
                build.flat_shared_faces += m;
            }
            build.boundary_faces += m;
        }
    }
    partner
}

/// Per cell of `n`, the seam links it takes part in, as CSR: (start per
/// cell and one past the last, the links' indices).
fn links_per_cell(links: &[Link], n: usize) -> (Vec<u32>, Vec<u32>) {
    let mut link_start = vec![0u32; n + 1];
    for l in links {
        link_start[l.a as usize + 1] += 1;
        link_start[l.b as usize + 1] += 1;
    }
    for c in 0..n {
        link_start[c + 1] += link_start[c];
    }
    let mut fill = link_start.clone();
    let mut link_list = vec![0u32; 2 * links.len()];
    for (k, l) in links.iter().enumerate() {
        for c in [l.a, l.b] {
            link_list[fill[c as usize] as usize] = k as u32;
            fill[c as usize] += 1;
        }
    }
    (link_start, link_list)
}

/// One plane per interior face (relative to `origin`), the other side its
/// exact negation; zero on the boundary and between two flat cells.
fn face_planes(mesh: &TetMesh, geometry: &TetGeometry, partner: &[u32], origin: [f64; 3]) -> Vec<[f64; 4]> {
    let cells = &geometry.cells;
    (0..4 * mesh.tets.len())
        .into_par_iter()
        .map(|slot| {
            let other_slot = partner[slot];
            if other_slot == NONE {
                return [0.0; 4];
            }
            let (c, d) = (slot / 4, other_slot as usize / 4);
            let own = !cells[c].degenerate;
            let other = !cells[d].degenerate;
            // The owner: the solid side, the lower slot if both are solid.
            if own && (!other || slot < other_slot as usize) {
                cells[c].plane_relative(slot % 4, mesh.tet_points(c), origin)
            } else if other {
                cells[d].plane_relative(other_slot as usize % 4, mesh.tet_points(d), origin).map(|x| -x)
            } else {
                [0.0; 4]
            }
        })
        .collect()
}

/// Interior faces (counted once) whose plane is zero: they constrain nothing.
fn unconstrained_faces(neighbor: &[u32], planes: &[[f64; 4]]) -> usize {
    (0..neighbor.len() / 4)
        .into_par_iter()
        .map(|c| {
            (0..4)
                .filter(|&f| {
                    let d = neighbor[4 * c + f];
                    d != NONE && (c as u32) < d && planes[4 * c + f] == [0.0; 4]
                })
                .count()
        })
        .sum()
}

/// Finds the seam links (see `MpvoBuildStats::seam_links`): boundary faces
/// of solid cells that share a (welded) edge, face opposite ways (normals
/// within ~2.6° of antiparallel), are coplanar (the other face's third vertex
/// within 1e-3 edge lengths of the plane) and overlap (both third vertices
/// strictly on the same side of the shared edge). One link per cell pair,
/// with the plane of the lower-indexed cell's face.
fn seam_links(mesh: &TetMesh, geometry: &TetGeometry, weld: &[u32], partner: &[u32], origin: [f64; 3]) -> Vec<Link> {
    let cells = &geometry.cells;
    let face_ids = |slot: usize| {
        let t = mesh.tets[slot / 4];
        FACE_VERTS[slot % 4].map(|l| weld[t[l] as usize])
    };
    let mut edges: Vec<(u64, u32)> = (0..partner.len())
        .into_par_iter()
        .filter(|&slot| partner[slot] == NONE && !cells[slot / 4].degenerate)
        .flat_map_iter(|slot| {
            let v = face_ids(slot);
            [(v[0], v[1]), (v[1], v[2]), (v[2], v[0])]
                .into_iter()
                .filter(|(a, b)| a != b)
                .map(move |(a, b)| (((a.min(b) as u64) << 32) | a.max(b) as u64, slot as u32))
        })
        .collect();
    edges.par_sort_unstable();
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let cross =
        |a: [f64; 3], b: [f64; 3]| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let mut links = Vec::new();
    let mut i = 0;
    while i < edges.len() {
        let mut j = i + 1;
        while j < edges.len() && edges[j].0 == edges[i].0 {
            j += 1;
        }
        let (u, v) = ((edges[i].0 >> 32) as u32, edges[i].0 as u32);
        let (pu, pv) = (mesh.points[u as usize], mesh.points[v as usize]);
        let e = sub(pv, pu);
        let elen = dot(e, e).sqrt();
        for x in i..j {
            for y in x + 1..j {
                let (f, g) = (edges[x].1 as usize, edges[y].1 as usize);
                let (cf, cg) = (f / 4, g / 4);
                if cf == cg {
                    continue;
                }
                let pf = cells[cf].planes[f % 4];
                let pg = cells[cg].planes[g % 4];
                let (nf, ng) = ([pf[0], pf[1], pf[2]], [pg[0], pg[1], pg[2]]);
                if dot(nf, ng) > -0.999 {
                    continue;
                }
                let third = |slot: usize| {
                    let w =
                        face_ids(slot).into_iter().find(|&w| w != u && w != v).expect("a triangle has a third vertex");
                    mesh.points[w as usize]
                };
                let (wf, wg) = (third(f), third(g));
                if dot(nf, sub(wg, pu)).abs() > 1e-3 * elen {
                    continue;
                }
                let sf = dot(nf, cross(e, sub(wf, pu)));
                let sg = dot(nf, cross(e, sub(wg, pu)));
                if sf * sg > 0.0 {
                    let (a, b, c, face) = if cf < cg { (cf, cg, cf, f) } else { (cg, cf, cg, g) };
                    let plane = cells[c].plane_relative(face % 4, mesh.tet_points(c), origin);
                    links.push(Link { a: a as u32, b: b as u32, plane });
                }
            }
        }
        i = j;
    }
    links.sort_by_key(|l| (l.a, l.b));
    links.dedup_by_key(|l| (l.a, l.b));
    // Bound the per-cell count (it must fit `Node::remaining`): only
    // pathological input gets anywhere near it.
    let mut per_cell = vec![0u16; mesh.tets.len()];
    for l in &links {
        per_cell[l.a as usize] += 1;
        per_cell[l.b as usize] += 1;
    }
    links.retain(|l| per_cell[l.a as usize] <= MAX_LINKS && per_cell[l.b as usize] <= MAX_LINKS);
    links
}

/// Cells with more seam links than this (pathological input) keep none.
const MAX_LINKS: u16 = 32;

/// A set of integers in `0..n` with O(log64 n) insert and remove-minimum:
/// a bitset with one summary level per factor of 64 (bit `i` of a word at
/// level `l + 1` says whether word `i` of level `l` is non-zero). For the
/// oxygen post's 513,375 cells that is 8,022 + 126 + 2 + 1 words.
struct RankSet {
    levels: Vec<Vec<u64>>,
    len: usize,
}

impl RankSet {
    fn new(n: usize) -> RankSet {
        let mut s = RankSet { levels: Vec::new(), len: 0 };
        s.reset(n);
        s
    }

    /// Empties the set and sizes it for `0..n`.
    fn reset(&mut self, n: usize) {
        let mut sizes = Vec::new();
        let mut words = n.div_ceil(64).max(1);
        loop {
            sizes.push(words);
            if words == 1 {
                break;
            }
            words = words.div_ceil(64);
        }
        self.levels.resize_with(sizes.len(), Vec::new);
        for (level, &size) in self.levels.iter_mut().zip(&sizes) {
            level.clear();
            level.resize(size, 0);
        }
        self.len = 0;
    }

    fn len(&self) -> usize {
        self.len
    }

    #[inline]
    fn insert(&mut self, x: u32) {
        let mut i = x as usize;
        for level in self.levels.iter_mut() {
            let (w, b) = (i / 64, i % 64);
            let was = level[w];
            level[w] = was | (1 << b);
            if was != 0 {
                break; // the summaries above already say "non-empty"
            }
            i = w;
        }
        self.len += 1;
    }

    #[inline]
    fn pop_min(&mut self) -> Option<u32> {
        let top = self.levels.len() - 1;
        if self.levels[top][0] == 0 {
            return None;
        }
        let mut i = 0usize;
        for level in self.levels.iter().rev() {
            i = i * 64 + level[i].trailing_zeros() as usize;
        }
        let x = i;
        for level in self.levels.iter_mut() {
            let (w, b) = (i / 64, i % 64);
            level[w] &= !(1 << b);
            if level[w] != 0 {
                break;
            }
            i = w;
        }
        self.len -= 1;
        Some(x as u32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(neighbor: &[u32], masks: &[u8], by_depth: &[u32]) -> (Vec<u32>, usize, usize) {
        let mut nodes: Vec<Node> = (0..masks.len())
            .map(|c| Node {
                nb: std::array::from_fn(|f| neighbor[4 * c + f]),
                rank: 0,
                mask: masks[c],
                remaining: 0,
                linked: false,
            })
            .collect();
        for (r, &c) in by_depth.iter().enumerate() {
            nodes[c as usize].rank = r as u32;
        }
        let (mut ready, mut order) = (RankSet::new(0), Vec::new());
        let start = vec![0; masks.len() + 1];
        let links = LinkView { links: &[], sides: &[], start: &start, list: &[] };
        let (sources, cycles, _) = topological_order(&mut nodes, by_depth, &links, &mut ready, &mut order);
        (order, sources, cycles)
    }

    /// A synthetic 3-cycle plus a tail: every cell is emitted once and one
    /// cycle is broken.
    #[test]
    fn cycles_are_broken_once_each() {
        // Cells 0 -> 1 -> 2 -> 0 (each "->" = drawn before), 2 -> 3.
        let mut neighbor = vec![NONE; 16];
        let mut masks = vec![0u8; 4];
        let mut link = |a: usize, fa: usize, b: usize, fb: usize| {
            neighbor[4 * a + fa] = b as u32;
            neighbor[4 * b + fb] = a as u32;
            masks[a] |= 0x10 << fa; // b in front of a
            masks[b] |= 1 << fb; // a behind b
        };
        link(0, 1, 1, 0);
        link(1, 1, 2, 0);
        link(2, 1, 0, 0);
        link(2, 2, 3, 0);
        // Farthest first: 1, 2, 0, 3.
        let (order, sources, cycles) = run(&neighbor, &masks, &[1, 2, 0, 3]);
        assert_eq!((sources, cycles), (0, 1));
        // Farthest (1) forced, then its successor 2, then 0 and 3 (0 is farther).
        assert_eq!(order, vec![1, 2, 0, 3]);
        // Two separate 2-cycles: two breaks.
        let mut neighbor = vec![NONE; 16];
        let mut masks = vec![0u8; 4];
        for (a, b) in [(0usize, 1usize), (2, 3)] {
            neighbor[4 * a] = b as u32;
            neighbor[4 * b] = a as u32;
            neighbor[4 * a + 1] = b as u32;
            neighbor[4 * b + 1] = a as u32;
            masks[a] |= 0x10 | 0x2;
            masks[b] |= 0x10 | 0x2;
        }
        let (order, _, cycles) = run(&neighbor, &masks, &[3, 0, 2, 1]);
        assert_eq!(cycles, 2);
        assert_eq!(order, vec![3, 2, 0, 1]);
    }

    #[test]
    fn ready_cells_come_farthest_first() {
        let neighbor = vec![NONE; 12];
        let masks = vec![0u8; 3];
        let (order, sources, cycles) = run(&neighbor, &masks, &[1, 0, 2]);
        assert_eq!((sources, cycles), (3, 0));
        assert_eq!(order, vec![1, 0, 2]);
    }

    #[test]
    fn rank_set_pops_in_order() {
        for n in [1usize, 63, 64, 65, 4096, 4097, 300_000] {
            let mut s = RankSet::new(n);
            let mut state = n as u64 * 7 + 1;
            let mut inserted = std::collections::BTreeSet::new();
            for _ in 0..(n.min(5000)) {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                let x = ((state >> 33) % n as u64) as u32;
                if inserted.insert(x) {
                    s.insert(x);
                }
                if state.is_multiple_of(3) {
                    assert_eq!(s.pop_min(), inserted.pop_first());
                }
                assert_eq!(s.len(), inserted.len());
            }
            while let Some(x) = inserted.pop_first() {
                assert_eq!(s.pop_min(), Some(x));
            }
            assert_eq!(s.pop_min(), None);
        }
    }
}
