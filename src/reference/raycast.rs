//! Per-ray cell traversal: boundary-entry search (screen-space bins of the
//! boundary faces) and the tet-to-tet walk, both decided by Plücker-style
//! edge signs with a symbolic perturbation (see the parent module docs for why
//! this cannot lose or double-count cells).

use crate::mesh::TetMesh;
use crate::scene::{Camera, TransferFunction};

use super::integrate::{integrate_segment, Segment};
use crate::mesh::topology::Topology;
use crate::mesh::adjacency::{FACE_VERTS, NONE};
use super::papers::PapersModel;
use super::ReferenceStats;

/// Stop compositing once the optical depth exceeds this: what lies behind is
/// attenuated by e⁻⁶⁰ ≈ 1e-26.
pub(crate) const DEPTH_STOP: f64 = 60.0;
/// A walk that makes no progress along the ray (only zero-length segments)
/// for this many consecutive cells is abandoned (counted in the stats).
const STALL_LIMIT: u32 = 1024;
/// Screen tile edge, in pixels, of the boundary-face bins.
const TILE: u32 = 8;
/// Slack, in pixels, added around each projected boundary face when binning
/// (projection and `Camera::ray` agree to ~1e-9 px).
const BIN_MARGIN: f64 = 0.01;

use crate::mesh::geometry::{cross, dot, sub};

#[inline]
fn sign(x: f64) -> i8 {
    if x > 0.0 {
        1
    } else if x < 0.0 {
        -1
    } else {
        0
    }
}

/// Local edge index of the pair (i, j), i ≠ j.
const EDGE: [[usize; 4]; 4] = [[9, 0, 1, 2], [0, 9, 3, 4], [1, 3, 9, 5], [2, 4, 5, 9]];
const EDGE_ENDS: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];

/// One ray: origin (relative to `eye`), unit direction and the two
/// perturbation directions.
pub(crate) struct Ray<'a> {
    eye: [f64; 3],
    o: [f64; 3],
    d: [f64; 3],
    n1: [f64; 3],
    n2: [f64; 3],
    pts: &'a [[f64; 3]],
    /// The ids edges are oriented by: the point a vertex copies
    /// (`MeshStats::vertex_origin`, constant cells), so that two cells
    /// sharing a face through copies see the same numbers; empty: the
    /// indices themselves.
    ids: &'a [u32],
}

impl<'a> Ray<'a> {
    /// `o` is relative to `eye` (0 for perspective rays): points are taken
    /// relative to the eye first, exact for points near it, so nothing is
    /// lost to the magnitude of world coordinates far from the origin.
    pub fn new(eye: [f64; 3], o: [f64; 3], d: [f64; 3], pts: &'a [[f64; 3]]) -> Self {
        // n1, n2: an orthonormal pair perpendicular to d (any fixed choice).
        let ax = if d[0].abs() <= d[1].abs() && d[0].abs() <= d[2].abs() {
            [1.0, 0.0, 0.0]
        } else if d[1].abs() <= d[2].abs() {
            [0.0, 1.0, 0.0]
        } else {
            [0.0, 0.0, 1.0]
        };
        let n1 = cross(d, ax);
        let l = dot(n1, n1).sqrt();
        let n1 = [n1[0] / l, n1[1] / l, n1[2] / l];
        let n2 = cross(d, n1);
        Ray { eye, o, d, n1, n2, pts, ids: &[] }
    }

    /// Orients edges by `ids` (a vertex map covering every index) instead
    /// of the vertex indices.
    pub fn with_ids(self, ids: &'a [u32]) -> Self {
        Ray { ids, ..self }
    }

    #[inline]
    fn id(&self, v: u32) -> u32 {
        self.ids.get(v as usize).copied().unwrap_or(v)
    }

    #[inline]
    fn q(&self, v: u32) -> [f64; 3] {
        sub(sub(self.pts[v as usize], self.eye), self.o)
    }

    /// The edge value of the *canonically oriented* edge lo → hi (global
    /// indices, lo < hi): `w = d · ((p_lo − o) × (p_hi − o))`, and its sign
    /// under the symbolic perturbation o → o + ε·n1' + ε²·n2' (n1', n2' ⊥ d):
    /// exactly zero values take the sign of the ε, then ε², coefficient. The
    /// value depends only on (lo, hi) and the ray, bit for bit, whichever cell
    /// asks.
    #[inline]
    fn edge(&self, lo: u32, hi: u32, q_lo: [f64; 3], q_hi: [f64; 3]) -> (f64, i8) {
        let w = dot(self.d, cross(q_lo, q_hi));
        let s = sign(w);
        if s != 0 || w.is_nan() {
            return (w, s);
        }
        // w(o + δ) = w − (p_hi − p_lo)·(d × δ); d × δ spans n1, n2.
        let e = sub(self.pts[hi as usize], self.pts[lo as usize]);
        let s1 = sign(-dot(e, self.n1));
        if s1 != 0 {
            return (w, s1);
        }
        (w, sign(-dot(e, self.n2)))
    }

    /// Oriented edge a → b (any order of global indices).
    #[inline]
    fn oriented(&self, a: u32, b: u32, qa: [f64; 3], qb: [f64; 3]) -> (f64, i8) {
        if self.id(a) < self.id(b) {
            self.edge(a, b, qa, qb)
        } else {
            let (w, s) = self.edge(b, a, qb, qa);
            (-w, -s)
        }
    }

    /// If the ray line crosses the outward-oriented face (v0, v1, v2), in the
    /// entering direction (all three perturbed edge signs negative) or, when
    /// `either_way`, in any direction (all three signs equal): the crossing
    /// (t, scalar).
    #[inline]
    pub fn crosses(&self, v: [u32; 3], either_way: bool, scalars: &[f64]) -> Option<(f64, f64)> {
        let q = [self.q(v[0]), self.q(v[1]), self.q(v[2])];
        let (w01, s01) = self.oriented(v[0], v[1], q[0], q[1]);
        if s01 == 0 || (s01 > 0 && !either_way) {
            return None;
        }
        let (w12, s12) = self.oriented(v[1], v[2], q[1], q[2]);
        if s12 != s01 {
            return None;
        }
        let (w20, s20) = self.oriented(v[2], v[0], q[2], q[0]);
        if s20 != s01 {
            return None;
        }
        Some(self.crossing(q, [w12, w20, w01], v, scalars))
    }

    /// Point where the line crosses the face with vertex offsets `q` and
    /// barycentric weights `bw` (bw[i] = edge value opposite vertex i).
    /// Returns (t, scalar); NaN when the weights sum to 0.
    #[inline]
    fn crossing(&self, q: [[f64; 3]; 3], bw: [f64; 3], v: [u32; 3], scalars: &[f64]) -> (f64, f64) {
        let sum = bw[0] + bw[1] + bw[2];
        let inv = 1.0 / sum;
        let x = [
            bw[0] * q[0][0] + bw[1] * q[1][0] + bw[2] * q[2][0],
            bw[0] * q[0][1] + bw[1] * q[1][1] + bw[2] * q[2][1],
            bw[0] * q[0][2] + bw[1] * q[1][2] + bw[2] * q[2][2],
        ];
        let t = dot(x, self.d) * inv;
        // Interpolated as the lowest scalar plus weighted differences and
        // kept within the three values, so a face whose vertices share a
        // scalar gives exactly it: the weighted mean itself may round to a
        // neighbouring value, which would put a constant field on the wrong
        // side of a transfer-function step at its value (the GPU gets the
        // value exactly).
        let sv = v.map(|i| scalars[i as usize]);
        let (lo, hi) = (sv[0].min(sv[1]).min(sv[2]), sv[0].max(sv[1]).max(sv[2]));
        let s = (lo + (bw[0] * (sv[0] - lo) + bw[1] * (sv[1] - lo) + bw[2] * (sv[2] - lo)) * inv).clamp(lo, hi);
        if sum != 0.0 && t.is_finite() && s.is_finite() {
            (t, s)
        } else {
            (f64::NAN, f64::NAN)
        }
    }
}

/// The edge values of one tet for one ray (local edge i<j oriented i → j).
struct TetEdges {
    q: [[f64; 3]; 4],
    w: [f64; 6],
    s: [i8; 6],
}

impl TetEdges {
    #[inline]
    fn new(ray: &Ray, v: &[u32; 4]) -> Self {
        let q = [ray.q(v[0]), ray.q(v[1]), ray.q(v[2]), ray.q(v[3])];
        let mut w = [0.0; 6];
        let mut s = [0i8; 6];
        for (e, &(i, j)) in EDGE_ENDS.iter().enumerate() {
            (w[e], s[e]) = ray.oriented(v[i], v[j], q[i], q[j]);
        }
        TetEdges { q, w, s }
    }

    #[inline]
    fn get(&self, i: usize, j: usize) -> (f64, i8) {
        let e = EDGE[i][j];
        if i < j {
            (self.w[e], self.s[e])
        } else {
            (-self.w[e], -self.s[e])
        }
    }

    /// Face `f` (outward order): +1 if its three perturbed edge signs are all
    /// positive (the line crosses it leaving a positively oriented cell), −1
    /// if all negative (entering), 0 if mixed (not crossed); and the
    /// barycentric weights of the crossing.
    #[inline]
    fn face(&self, f: usize) -> (i8, [f64; 3]) {
        let [x, y, z] = FACE_VERTS[f];
        let (wxy, sxy) = self.get(x, y);
        let (wyz, syz) = self.get(y, z);
        let (wzx, szx) = self.get(z, x);
        let u = if sxy == syz && syz == szx { sxy } else { 0 };
        (u, [wyz, wzx, wxy])
    }
}

/// A boundary face the ray enters through.
#[derive(Clone, Copy)]
pub(crate) struct Entry {
    t: f64,
    s: f64,
    face: u32,
}

/// Boundary faces binned by the screen tiles their projection overlaps.
pub(crate) struct Bins {
    tiles_x: u32,
    /// Per binned face: `4·tet + face` and its pixel bounding box.
    faces: Vec<(u32, [f64; 4])>,
    /// CSR: items of tile k are `items[start[k]..start[k+1]]` (indices into `faces`).
    start: Vec<u32>,
    items: Vec<u32>,
    /// Faces that straddle the eye plane (perspective): tested by every ray.
    global: Vec<u32>,
}

impl Bins {
    pub fn build(
        mesh: &TetMesh,
        topo: &Topology,
        camera: &Camera,
        width: u32,
        height: u32,
    ) -> Bins {
        // Relative to the eye (see `Camera::view_proj_relative`): exact for
        // the points near it, so binning stays right far from the origin.
        let eye = camera.eye;
        let vp = camera.view_proj_relative(eye, width, height);
        let tiles_x = width.div_ceil(TILE);
        let tiles_y = height.div_ceil(TILE);
        let (wf, hf) = (width as f64, height as f64);
        let mut faces = Vec::new();
        let mut global = Vec::new();
        let mut ranges = Vec::new();
        for &id in &topo.boundary {
            let tet = &mesh.tets[(id >> 2) as usize];
            let fv = FACE_VERTS[(id & 3) as usize];
            let mut bb = [
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ];
            let (mut wmin, mut wmax) = (f64::INFINITY, f64::NEG_INFINITY);
            for &k in &fv {
                let p = sub(mesh.points[tet[k] as usize], eye);
                let c = vp * glam::DVec4::new(p[0], p[1], p[2], 1.0);
                wmin = wmin.min(c.w);
                wmax = wmax.max(c.w);
                let px = (c.x / c.w + 1.0) * 0.5 * wf - 0.5;
                let py = (c.y / c.w + 1.0) * 0.5 * hf - 0.5;
                bb = [bb[0].min(px), bb[1].max(px), bb[2].min(py), bb[3].max(py)];
            }
            // w has one sign on the whole face (orthographic: w = 1): its
            // projection is a triangle, also behind the eye, since the test is
            // on the whole line. Otherwise, or if anything is not finite: global.
            let wscale = wmax.abs().max(wmin.abs());
            let one_sided = wmin > 1e-9 * wscale || wmax < -1e-9 * wscale;
            if !one_sided || !bb.iter().all(|v| v.is_finite()) {
                global.push(id);
                continue;
            }
            let bb = [
                bb[0] - BIN_MARGIN,
                bb[1] + BIN_MARGIN,
                bb[2] - BIN_MARGIN,
                bb[3] + BIN_MARGIN,
            ];
            if bb[1] < 0.0 || bb[0] > wf - 1.0 || bb[3] < 0.0 || bb[2] > hf - 1.0 {
                continue;
            }
            let tx0 = (bb[0].max(0.0) as u32 / TILE).min(tiles_x - 1);
            let tx1 = (bb[1].min(wf - 1.0) as u32 / TILE).min(tiles_x - 1);
            let ty0 = (bb[2].max(0.0) as u32 / TILE).min(tiles_y - 1);
            let ty1 = (bb[3].min(hf - 1.0) as u32 / TILE).min(tiles_y - 1);
            ranges.push((tx0, tx1, ty0, ty1));
            faces.push((id, bb));
        }
        let ntiles = (tiles_x * tiles_y) as usize;
        let mut start = vec![0u32; ntiles + 1];
        for &(tx0, tx1, ty0, ty1) in &ranges {
            for ty in ty0..=ty1 {
                for tx in tx0..=tx1 {
                    start[(ty * tiles_x + tx) as usize + 1] += 1;
                }
            }
        }
        for k in 0..ntiles {
            start[k + 1] += start[k];
        }
        let mut fill = start.clone();
        let mut items = vec![0u32; start[ntiles] as usize];
        for (fi, &(tx0, tx1, ty0, ty1)) in ranges.iter().enumerate() {
            for ty in ty0..=ty1 {
                for tx in tx0..=tx1 {
                    let k = (ty * tiles_x + tx) as usize;
                    items[fill[k] as usize] = fi as u32;
                    fill[k] += 1;
                }
            }
        }
        Bins {
            tiles_x,
            faces,
            start,
            items,
            global,
        }
    }
}

/// Everything a ray needs, shared by all rays of a frame.
pub(crate) struct Tracer<'a> {
    pub mesh: &'a TetMesh,
    pub topo: &'a Topology,
    pub bins: &'a Bins,
    pub tf: &'a TransferFunction,
    /// A boundary entry more than this before the previous walk's exit is
    /// taken as already covered (only happens for overlapping meshes).
    pub entry_tolerance: f64,
    pub max_steps_per_ray: u64,
    /// The camera's eye: ray origins are relative to it (`Ray::new`).
    pub eye: [f64; 3],
    /// Segments as the papers' interpolation gives them (`papers.rs`)
    /// instead of exact; the walk itself is the same.
    pub papers: Option<PapersModel>,
}

impl Tracer<'_> {
    /// The ids edges are oriented by (`Ray::with_ids`): the copied points of
    /// a mesh of constant cells, else none (the indices).
    fn vertex_ids(&self) -> &[u32] {
        let origin = &self.mesh.stats.vertex_origin;
        if origin.len() == self.mesh.points.len() { origin } else { &[] }
    }
}

/// Front-to-back accumulation along one ray.
struct Acc {
    color: [f64; 3],
    depth: f64,
}

impl Acc {
    #[inline]
    fn add(&mut self, seg: &Segment) {
        let t = (-self.depth).exp();
        for i in 0..3 {
            self.color[i] += t * seg.color[i];
        }
        self.depth += seg.optical_depth;
    }
}

enum WalkEnd {
    /// Left the mesh through a boundary face at this t.
    Exit(f64),
    /// Ray finished (opaque, past the far clip, or step budget exhausted).
    Done,
}

impl Tracer<'_> {
    /// Premultiplied RGBA for the ray through pixel (px, py), origin `o`
    /// (relative to `self.eye`), unit
    /// direction `d`, clipped to t ∈ [t_min, t_max].
    #[allow(clippy::too_many_arguments)]
    pub fn trace(
        &self,
        px: u32,
        py: u32,
        o: [f64; 3],
        d: [f64; 3],
        t_min: f64,
        t_max: f64,
        entries: &mut Vec<Entry>,
        stats: &mut ReferenceStats,
    ) -> [f64; 4] {
        let ray = Ray::new(self.eye, o, d, &self.mesh.points).with_ids(self.vertex_ids());
        let scalars = &self.mesh.scalars;
        entries.clear();
        let tile = ((py / TILE) * self.bins.tiles_x + px / TILE) as usize;
        let (x, y) = (px as f64, py as f64);
        let tiled = self.bins.items
            [self.bins.start[tile] as usize..self.bins.start[tile + 1] as usize]
            .iter()
            .map(|&fi| {
                let (id, bb) = self.bins.faces[fi as usize];
                (id, x >= bb[0] && x <= bb[1] && y >= bb[2] && y <= bb[3])
            });
        for (id, inside) in tiled.chain(self.bins.global.iter().map(|&id| (id, true))) {
            if !inside {
                continue;
            }
            let ti = (id >> 2) as usize;
            let tet = &self.mesh.tets[ti];
            let fv = FACE_VERTS[(id & 3) as usize];
            // A boundary face of a flat cell counts whichever way it is
            // crossed (its orientation says nothing); see `walk`.
            let either_way = !self.topo.solid[ti];
            if let Some((t, s)) =
                ray.crosses([tet[fv[0]], tet[fv[1]], tet[fv[2]]], either_way, scalars)
            {
                entries.push(Entry { t, s, face: id });
            }
        }
        // Ties in t broken by face id, so the result is deterministic.
        entries.sort_unstable_by(|a, b| a.t.total_cmp(&b.t).then(a.face.cmp(&b.face)));
        stats.rays += 1;
        let mut acc = Acc {
            color: [0.0; 3],
            depth: 0.0,
        };
        let mut t_done = f64::NEG_INFINITY;
        let mut steps = 0u64;
        for e in entries.iter() {
            if !e.t.is_finite() {
                // Crossing of an edge-on face (only possible through rounding).
                continue;
            }
            if e.t >= t_max {
                break;
            }
            if e.t < t_done - self.entry_tolerance {
                stats.skipped_entries += 1;
                continue;
            }
            stats.walks += 1;
            match self.walk(&ray, e, t_min, t_max, &mut acc, &mut steps, stats) {
                WalkEnd::Exit(t) => t_done = t,
                WalkEnd::Done => break,
            }
        }
        if !entries.is_empty() {
            stats.rays_hit += 1;
        }
        stats.steps += steps;
        [
            acc.color[0],
            acc.color[1],
            acc.color[2],
            -(-acc.depth).exp_m1(),
        ]
    }

    #[allow(clippy::too_many_arguments)]
    fn walk(
        &self,
        ray: &Ray,
        entry: &Entry,
        t_min: f64,
        t_max: f64,
        acc: &mut Acc,
        steps: &mut u64,
        stats: &mut ReferenceStats,
    ) -> WalkEnd {
        let (mesh, scalars) = (self.mesh, &self.mesh.scalars);
        let mut tet = entry.face >> 2;
        let mut f_in = (entry.face & 3) as usize;
        let (mut t_in, mut s_in) = (entry.t, entry.s);
        let mut stall = 0u32;
        // Constant cells (`cell_data`): the field jumps across faces, so a
        // cell's entry value is its own, not the last cell's exit value.
        let own_entry = !self.vertex_ids().is_empty();
        let mut first = true;
        loop {
            *steps += 1;
            if *steps > self.max_steps_per_ray {
                stats.aborted_walks += 1;
                return WalkEnd::Done;
            }
            let v = &mesh.tets[tet as usize];
            let te = TetEdges::new(ray, v);
            let faces = [te.face(0), te.face(1), te.face(2), te.face(3)];
            if own_entry && !first {
                s_in = own_entry_value(ray, &te, v, faces[f_in].1, f_in, scalars).unwrap_or(s_in);
            }
            first = false;
            // The line crosses exactly two faces of a cell (exact arithmetic,
            // perturbed ray): we came in through one, we leave through the
            // other. In a positively oriented cell the entry face reads −1 and
            // the exit +1. A flat (zero-volume) cell has no meaningful
            // orientation: whichever sign its entry face shows, the exit is the
            // face with the opposite one. A solid cell entered through a face
            // it reads as +1 is being walked backwards (possible only after a
            // flat cell on the boundary): stop there.
            let target: i8 = match faces[f_in].0 {
                1 if self.topo.solid[tet as usize] => {
                    stats.reversed_walks += 1;
                    return WalkEnd::Exit(t_in);
                }
                1 => -1,
                _ => 1,
            };
            let (f_out, fallback) = exit_face(&faces, f_in, target);
            let mut bw = faces[f_out].1;
            if fallback {
                stats.fallback_exits += 1;
                bw = bw.map(|w| if w * target as f64 > 0.0 { w } else { 0.0 });
            }
            let (t_out, s_out) = exit_point(ray, &te, v, f_out, bw, (t_in, s_in), scalars);
            let (start, end) = self.cell_segment(ray, v, f_in, (t_in, s_in), (t_out, s_out));
            self.add_clipped(acc, start, end, t_min, t_max);
            if t_out > t_in {
                stall = 0;
                if acc.depth > DEPTH_STOP || t_out >= t_max {
                    return WalkEnd::Done;
                }
            } else {
                stall += 1;
                if stall > STALL_LIMIT {
                    stats.aborted_walks += 1;
                    return WalkEnd::Exit(t_out);
                }
            }
            let nb = self.topo.neighbor[4 * tet as usize + f_out];
            if nb == NONE {
                return WalkEnd::Exit(t_out);
            }
            tet = nb >> 2;
            f_in = (nb & 3) as usize;
            t_in = t_out;
            s_in = s_out;
        }
    }

    /// The segment (start, end as (t, scalar)) cell `v`, entered through
    /// face `f_in` at `entry` and left at `exit`, contributes: exact, or the
    /// papers' from its entry point, or in the cell holding the eye
    /// (perspective: entered at or behind the eye) from its near cap.
    #[inline(always)]
    fn cell_segment(&self, ray: &Ray, v: &[u32; 4], f_in: usize, entry: (f64, f64), exit: (f64, f64)) -> ((f64, f64), (f64, f64)) {
        let (t_in, s_in) = entry;
        let Some(m) = &self.papers else {
            return (entry, exit);
        };
        let scalars = &self.mesh.scalars;
        let q = [0, 1, 2, 3].map(|i| sub(self.mesh.points[v[i] as usize], self.eye));
        let s = [0, 1, 2, 3].map(|i| scalars[v[i] as usize]);
        let nothing = (entry, entry);
        if t_in > 0.0 {
            let p = std::array::from_fn(|c| ray.o[c] + t_in * ray.d[c]);
            m.segment(&q, &s, f_in, p, s_in).map_or(nothing, |(len, sb)| ((t_in, s_in), (t_in + len, sb)))
        } else if m.perspective && exit.0 > 0.0 {
            m.cap_segment(&q, &s, ray.d).unwrap_or(nothing)
        } else {
            // Behind the eye, or (orthographic) a cell the view plane cuts:
            // not modelled, exact.
            (entry, exit)
        }
    }

    /// Adds to `acc` the part of the segment `start`..`end` (t, scalar)
    /// within [`t_min`, `t_max`], its end values interpolated.
    #[inline(always)]
    fn add_clipped(&self, acc: &mut Acc, (t_start, s_start): (f64, f64), (t_end, s_end): (f64, f64), t_min: f64, t_max: f64) {
        if t_end > t_start && t_end > t_min && t_start < t_max {
            let (ta, tb) = (t_start.max(t_min), t_end.min(t_max));
            let lerp = |t: f64| s_start + (s_end - s_start) * ((t - t_start) / (t_end - t_start));
            let sa = if ta > t_start { lerp(ta) } else { s_start };
            let sb = if tb < t_end { lerp(tb) } else { s_end };
            acc.add(&integrate_segment(self.tf, sa, sb, tb - ta));
        }
    }
}

/// A constant cell's own value where the ray enters it through face
/// `f_in` (barycentric weights `bw`), if the crossing is usable.
#[inline(always)]
fn own_entry_value(ray: &Ray, te: &TetEdges, v: &[u32; 4], bw: [f64; 3], f_in: usize, scalars: &[f64]) -> Option<f64> {
    let fv = FACE_VERTS[f_in];
    let (_, s) = ray.crossing([te.q[fv[0]], te.q[fv[1]], te.q[fv[2]]], bw, [v[fv[0]], v[fv[1]], v[fv[2]]], scalars);
    s.is_finite().then_some(s)
}

/// The face a cell is left through: the one other than `f_in` whose sign
/// is `target`, and whether that was not unique (rounding made the sign
/// pattern inconsistent: a ray within ~1 ulp of a vertex or edge), in
/// which case it is the face whose worst edge is least wrong.
#[inline(always)]
fn exit_face(faces: &[(i8, [f64; 3]); 4], f_in: usize, target: i8) -> (usize, bool) {
    let mut found = (usize::MAX, 0usize);
    let mut best = (usize::MAX, f64::NEG_INFINITY);
    for (f, &(u, bw)) in faces.iter().enumerate() {
        if f == f_in {
            continue;
        }
        if u == target {
            found = (f, found.1 + 1);
        }
        // Fallback score: the face whose worst edge is least wrong.
        let score = bw.iter().fold(f64::INFINITY, |m, &w| m.min(w * target as f64));
        if score > best.1 || best.0 == usize::MAX {
            best = (f, score);
        }
    }
    if found.1 == 1 {
        (found.0, false)
    } else {
        (best.0, true)
    }
}

/// Where (t, scalar) the ray leaves cell `v` through face `f_out`
/// (barycentric weights `bw`); an unusable crossing (edge-on face, NaN)
/// gives a zero-length segment, at `entry`.
#[inline(always)]
fn exit_point(ray: &Ray, te: &TetEdges, v: &[u32; 4], f_out: usize, bw: [f64; 3], entry: (f64, f64), scalars: &[f64]) -> (f64, f64) {
    let fv = FACE_VERTS[f_out];
    let (t_c, s_c) = ray.crossing([te.q[fv[0]], te.q[fv[1]], te.q[fv[2]]], bw, [v[fv[0]], v[fv[1]], v[fv[2]]], scalars);
    if t_c.is_finite() {
        (t_c.max(entry.0), s_c)
    } else {
        entry
    }
}
