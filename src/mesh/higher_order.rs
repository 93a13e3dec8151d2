//! Higher-order VTK cells split into linear tetrahedra.
//!
//! `--higher-order subdivide` (the default) keeps every nodal value: a cell
//! is cut into the linear sub-cells of its node lattice and those go through
//! the conforming split of linear cells (`cells`, `repair`), so the image is
//! of the *linearised* field (piecewise linear between the nodes), as
//! VTK's `vtkDataSetTriangleFilter` renders it:
//!
//! - tetra of degree p (quadratic tetra 24, Lagrange tetra 71): p³ tets,
//!   the lattice's corner tets, each octahedron cut into 4 tets around its
//!   diagonal from the node over a lattice point's `e3` to the one over its
//!   `e1 + e2` (for a quadratic tetra the diagonal mid(0,3)–mid(1,2) that
//!   VTK's filter uses: 8 tets) and the inverted tets;
//! - hexahedron of degree p (quadratic hexahedron 25, triquadratic 29,
//!   biquadratic-quadratic 33, Lagrange 72): p³ sub-hexahedra;
//! - wedge of degree p (quadratic wedge 26, quadratic-linear wedge 31,
//!   biquadratic-quadratic wedge 32, Lagrange 73): p³ sub-wedges (p² for
//!   the quadratic-linear wedge);
//! - quadratic pyramid (27): 6 pyramids and 4 tets (VTK's subdivision).
//!
//! Node positions on the lattice are VTK's own (`higher_order_tables.rs`,
//! generated from VTK's parametric coordinates), Lagrange cells of degree 1
//! to 4. Sub-cells share their faces with the neighbours' sub-cells, so the
//! quad-diagonal rule keeps the mesh conforming.
//!
//! Serendipity cells lack some lattice nodes (the 20-node hexahedron its
//! six face centres and its body centre, the 15-node wedge the centres of
//! its quad faces, the 13-node pyramid its base centre, the 24-node hex its
//! top and bottom centres and body centre). Those are added as points with
//! the value the cell's own interpolation gives there (a face centre:
//! -1/4 of the face's corners plus 1/2 of its mid-edge nodes; the body
//! centre of a hexahedron: -1/4 of the corners plus 1/4 of the mid-edge
//! nodes), at the position the same weights give. A face centre is shared
//! by the two cells of the face (keyed by its corner ids; a neighbour that
//! has the node, a triquadratic hexahedron, lends its own), so the split
//! stays conforming.
//!
//! `--higher-order corners` reads only the corner nodes, as the linear cell
//! of the same shape (also for Bezier cells, whose corner control points
//! are on the field, and the Lagrange and triquadratic pyramids).
//!
//! The mode is process-wide ([`set_mode`], from the command line's
//! `--higher-order`); `RawCells::into_tet_mesh_with` takes it explicitly.

use std::sync::atomic::{AtomicU8, Ordering};

use anyhow::{bail, Result};

use super::cells::{VTK_HEXAHEDRON, VTK_PYRAMID, VTK_TETRA, VTK_WEDGE};
use super::repair::split_linear;
use super::tet_builder::Tetrahedralizer;
use super::HigherOrder;

#[path = "higher_order_tables.rs"]
mod tables;

static MODE: AtomicU8 = AtomicU8::new(0);

/// Sets how higher-order cells are read from now on (the command line's
/// `--higher-order`).
pub fn set_mode(m: HigherOrder) {
    MODE.store(if m == HigherOrder::Corners { 1 } else { 0 }, Ordering::Relaxed);
}

/// How higher-order cells are read ([`set_mode`]; default subdivide).
pub fn mode() -> HigherOrder {
    if MODE.load(Ordering::Relaxed) == 1 {
        HigherOrder::Corners
    } else {
        HigherOrder::Subdivide
    }
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Shape {
    Tet,
    Hex,
    Wedge,
    Pyramid,
}

/// The shape of a higher-order 3-D cell type, `None` for any other type.
fn shape(t: u8) -> Option<Shape> {
    Some(match t {
        24 | 71 | 78 => Shape::Tet,
        25 | 29 | 33 | 72 | 79 => Shape::Hex,
        26 | 31 | 32 | 73 | 80 => Shape::Wedge,
        27 | 37 | 74 | 81 => Shape::Pyramid,
        _ => return None,
    })
}

/// Whether `t` is a higher-order 3-D cell type read here.
pub fn is_higher_order(t: u8) -> bool {
    shape(t).is_some()
}

/// Whether `--higher-order subdivide` subdivides type `t` (the others are
/// read by their corners only, or refused in subdivide mode).
pub fn subdivides(t: u8) -> bool {
    matches!(t, 24..=27 | 29 | 31..=33 | 71..=73)
}

/// The linear cell of the same shape and its corner count.
fn linear_of(s: Shape) -> (u8, usize) {
    match s {
        Shape::Tet => (VTK_TETRA, 4),
        Shape::Hex => (VTK_HEXAHEDRON, 8),
        Shape::Wedge => (VTK_WEDGE, 6),
        Shape::Pyramid => (VTK_PYRAMID, 5),
    }
}

/// Checks a higher-order cell's node count; the error says what it should be.
pub fn check_node_count(t: u8, n: usize) -> Result<()> {
    let Some(s) = shape(t) else { bail!("not a higher-order cell type") };
    let fixed = match t {
        24 => Some(10),
        25 => Some(20),
        26 => Some(15),
        27 => Some(13),
        29 => Some(27),
        31 => Some(12),
        32 => Some(18),
        33 => Some(24),
        37 => Some(19),
        _ => None,
    };
    if let Some(k) = fixed {
        if n != k {
            bail!("has {n} nodes, not {k}");
        }
        return Ok(());
    }
    // Lagrange / Bezier: the node count of some uniform degree p >= 1.
    let count = |p: usize| match s {
        Shape::Tet => (p + 1) * (p + 2) * (p + 3) / 6,
        Shape::Hex => (p + 1).pow(3),
        Shape::Wedge => (p + 1) * (p + 1) * (p + 2) / 2,
        Shape::Pyramid => (p + 1) * (p + 2) * (2 * p + 3) / 6,
    };
    let examples: Vec<String> = (1..=4).map(|p| count(p).to_string()).collect();
    if (1..=64).any(|p| count(p) == n) {
        Ok(())
    } else {
        bail!(
            "has {n} nodes, which is no uniform degree's node count ({}, ... for degrees 1, 2, 3, 4, ...; \
             cells of direction-dependent degree, VTK's HigherOrderDegrees, are not read)",
            examples.join(", ")
        )
    }
}

/// The node lattice of a type with `n` nodes: the degree and each node's
/// lattice position.
fn lattice_of(t: u8, n: usize) -> Option<(usize, &'static [[u8; 3]])> {
    tables::NODE_LATTICES.iter().find(|e| e.0 == t && e.1 == n).map(|e| (e.2 as usize, e.3))
}

#[cfg(test)]
pub(crate) fn tests_lattice(t: u8, n: usize) -> Option<(usize, &'static [[u8; 3]])> {
    lattice_of(t, n)
}

/// Before the cells are split: registers the face-centre nodes of the
/// quadratic cells that have them, so that a serendipity neighbour uses the
/// same node for the shared face instead of adding its own point.
pub(crate) fn register_face_nodes(tz: &mut Tetrahedralizer, t: u8, v: &[u32]) {
    if tz.mode != HigherOrder::Subdivide || !matches!(t, 29 | 32 | 33 | 72 | 73) {
        return;
    }
    let Some((2, lat)) = lattice_of(t, v.len()) else { return };
    let mut l = Lattice::new(2);
    for (i, p) in lat.iter().enumerate() {
        l.set(*p, v[i]);
    }
    let faces = match shape(t) {
        Some(Shape::Hex) => hex_faces(),
        Some(Shape::Wedge) => wedge_quad_faces(),
        _ => return,
    };
    for f in faces {
        if let (Some(c), Some(key)) = (l.get(f.centre), l.key(&f.corners)) {
            tz.register_face_point(key, c);
        }
    }
}

/// Splits one higher-order cell (node count already checked by
/// [`check_node_count`], indices in range) into `tz`.
pub(crate) fn split(tz: &mut Tetrahedralizer, t: u8, v: &[u32]) -> Result<()> {
    let Some(s) = shape(t) else { bail!("not a higher-order cell type") };
    let (lin, k) = linear_of(s);
    if tz.mode == HigherOrder::Corners {
        return split_linear(tz, lin, &v[..k]);
    }
    if !subdivides(t) {
        bail!(
            "is not subdivided ({}); read it by its corner nodes with --higher-order corners",
            if (78..=81).contains(&t) {
                "a Bezier cell's inner control points are not values of the field"
            } else {
                "no subdivision of this pyramid is built"
            }
        );
    }
    if t == 27 {
        return quadratic_pyramid(tz, v);
    }
    let Some((p, lat)) = lattice_of(t, v.len()) else {
        bail!("a {}-node cell of this type is beyond the degrees read (Lagrange cells of degree 1 to 4)", v.len());
    };
    let mut l = Lattice::new(p);
    for (i, q) in lat.iter().enumerate() {
        l.set(*q, v[i]);
    }
    match s {
        Shape::Hex => subdivide_hex(tz, &mut l, p),
        Shape::Wedge => subdivide_wedge(tz, &mut l, p, t),
        Shape::Tet => subdivide_tet(tz, &l, p),
        Shape::Pyramid => bail!("no subdivision of this pyramid is built"),
    }
}

/// A hexahedron of degree `p` as its p³ sub-hexahedra (a serendipity
/// cell's missing face and body centres added first).
fn subdivide_hex(tz: &mut Tetrahedralizer, l: &mut Lattice, p: usize) -> Result<()> {
    if p == 2 {
        for f in hex_faces() {
            l.fill_face(tz, &f)?;
        }
        if l.get([1, 1, 1]).is_none() {
            add_body_centre(tz, l)?;
        }
    }
    for i in 0..p {
        for j in 0..p {
            for k in 0..p {
                let c = |di: usize, dj: usize, dk: usize| l.need(lp(i + di, j + dj, k + dk));
                let h = [c(0, 0, 0)?, c(1, 0, 0)?, c(1, 1, 0)?, c(0, 1, 0)?, c(0, 0, 1)?, c(1, 0, 1)?, c(1, 1, 1)?, c(0, 1, 1)?];
                split_linear(tz, VTK_HEXAHEDRON, &h)?;
            }
        }
    }
    Ok(())
}

/// The serendipity body centre of a quadratic hexahedron, added as a
/// point: -1/4 corners + 1/4 mid-edge nodes.
fn add_body_centre(tz: &mut Tetrahedralizer, l: &mut Lattice) -> Result<()> {
    let mut terms = Vec::new();
    for x in 0..3u8 {
        for y in 0..3u8 {
            for z in 0..3u8 {
                let ones = [x, y, z].iter().filter(|&&c| c == 1).count();
                let w = match ones {
                    0 => -0.25,
                    1 => 0.25,
                    _ => continue,
                };
                terms.push((l.need([x, y, z])?, w));
            }
        }
    }
    let (pos, val) = tz.combine(&terms);
    let c = tz.add_point(pos, val)?;
    l.set([1, 1, 1], c);
    Ok(())
}

/// A wedge of degree `p` (type `t`) as its sub-wedges (a serendipity
/// cell's missing quad-face centres added first).
fn subdivide_wedge(tz: &mut Tetrahedralizer, l: &mut Lattice, p: usize, t: u8) -> Result<()> {
    // The quadratic-linear wedge has only the bottom and top layers.
    let step = if t == 31 { 2 } else { 1 };
    if p == 2 && t != 31 {
        for f in wedge_quad_faces() {
            l.fill_face(tz, &f)?;
        }
    }
    for k in (0..p).step_by(step) {
        for i in 0..p {
            for j in 0..p - i {
                let mut tris = vec![[(i, j), (i + 1, j), (i, j + 1)]];
                if i + j + 2 <= p {
                    tris.push([(i + 1, j), (i + 1, j + 1), (i, j + 1)]);
                }
                for tri in tris {
                    let at = |n: usize, kk: usize| l.need(lp(tri[n].0, tri[n].1, kk));
                    let w = [at(0, k)?, at(1, k)?, at(2, k)?, at(0, k + step)?, at(1, k + step)?, at(2, k + step)?];
                    split_linear(tz, VTK_WEDGE, &w)?;
                }
            }
        }
    }
    Ok(())
}

/// A tetra of degree `p` as the p³ tets of [`tet_lattice_tets`], each
/// positively oriented on the lattice.
fn subdivide_tet(tz: &mut Tetrahedralizer, l: &Lattice, p: usize) -> Result<()> {
    for mut q in tet_lattice_tets(p) {
        let di = |a: [usize; 3]| a.map(|x| x as i64);
        if det3(q.map(di)) < 0 {
            q.swap(2, 3);
        }
        let g = [l.need(lpa(q[0]))?, l.need(lpa(q[1]))?, l.need(lpa(q[2]))?, l.need(lpa(q[3]))?];
        split_linear(tz, VTK_TETRA, &g)?;
    }
    Ok(())
}

/// The tets of a degree-`p` tetra's lattice, as lattice points: each
/// point's corner tet, the octahedron above it cut into 4 tets around its
/// diagonal e3 .. e1+e2, and the inverted tet.
fn tet_lattice_tets(p: usize) -> Vec<[[usize; 3]; 4]> {
    let mut local: Vec<[[usize; 3]; 4]> = Vec::new();
    for i in 0..p {
        for j in 0..p - i {
            for k in 0..p - i - j {
                let o = [i, j, k];
                let add = |d: [usize; 3]| [o[0] + d[0], o[1] + d[1], o[2] + d[2]];
                local.push([o, add([1, 0, 0]), add([0, 1, 0]), add([0, 0, 1])]);
                if i + j + k + 2 <= p {
                    // The octahedron, cut around the diagonal e3 .. e1+e2.
                    let (a, b, c, d, e, f) =
                        (add([1, 0, 0]), add([0, 1, 0]), add([0, 0, 1]), add([1, 1, 0]), add([1, 0, 1]), add([0, 1, 1]));
                    for (x, y) in [(a, b), (b, f), (f, e), (e, a)] {
                        local.push([c, d, x, y]);
                    }
                }
                if i + j + k + 3 <= p {
                    local.push([add([1, 1, 0]), add([1, 0, 1]), add([0, 1, 1]), add([1, 1, 1])]);
                }
            }
        }
    }
    local
}

fn lp(i: usize, j: usize, k: usize) -> [u8; 3] {
    [i as u8, j as u8, k as u8]
}
fn lpa(a: [usize; 3]) -> [u8; 3] {
    a.map(|x| x as u8)
}

fn det3(p: [[i64; 3]; 4]) -> i64 {
    let s = |a: [i64; 3], b: [i64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let (a, b, c) = (s(p[1], p[0]), s(p[2], p[0]), s(p[3], p[0]));
    a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])
}

/// A cell's nodes by lattice position.
struct Lattice {
    p: usize,
    at: Vec<Option<u32>>,
}

/// A quad face of a degree-2 lattice: its centre, corners and mid-edge nodes.
struct QuadFace {
    centre: [u8; 3],
    corners: [[u8; 3]; 4],
    edges: [[u8; 3]; 4],
}

fn hex_faces() -> Vec<QuadFace> {
    let mut out = Vec::new();
    for axis in 0..3 {
        for w in [0u8, 2] {
            let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
            let put = |x: u8, y: u8| {
                let mut q = [0u8; 3];
                q[axis] = w;
                q[a] = x;
                q[b] = y;
                q
            };
            out.push(QuadFace {
                centre: put(1, 1),
                corners: [put(0, 0), put(2, 0), put(2, 2), put(0, 2)],
                edges: [put(1, 0), put(2, 1), put(1, 2), put(0, 1)],
            });
        }
    }
    out
}

fn wedge_quad_faces() -> Vec<QuadFace> {
    [((0u8, 0u8), (2u8, 0u8)), ((2, 0), (0, 2)), ((0, 2), (0, 0))]
        .iter()
        .map(|&(pp, qq)| {
            let m = ((pp.0 + qq.0) / 2, (pp.1 + qq.1) / 2);
            let at = |t: (u8, u8), k: u8| [t.0, t.1, k];
            QuadFace {
                centre: at(m, 1),
                corners: [at(pp, 0), at(qq, 0), at(qq, 2), at(pp, 2)],
                edges: [at(m, 0), at(qq, 1), at(m, 2), at(pp, 1)],
            }
        })
        .collect()
}

impl Lattice {
    fn new(p: usize) -> Lattice {
        Lattice { p, at: vec![None; (p + 1).pow(3)] }
    }
    fn index(&self, q: [u8; 3]) -> usize {
        let n = self.p + 1;
        q[0] as usize + n * (q[1] as usize + n * q[2] as usize)
    }
    fn set(&mut self, q: [u8; 3], v: u32) {
        let i = self.index(q);
        self.at[i] = Some(v);
    }
    fn get(&self, q: [u8; 3]) -> Option<u32> {
        self.at.get(self.index(q)).copied().flatten()
    }
    fn need(&self, q: [u8; 3]) -> Result<u32> {
        self.get(q).ok_or_else(|| anyhow::anyhow!("internal: no node at lattice position {q:?}"))
    }
    /// The sorted corner ids of a face: the key of its centre point.
    fn key(&self, corners: &[[u8; 3]; 4]) -> Option<Vec<u32>> {
        let mut k: Vec<u32> = corners.iter().map(|&c| self.get(c)).collect::<Option<_>>()?;
        k.sort_unstable();
        Some(k)
    }
    /// Adds (or finds, shared with the neighbour) a missing face centre.
    fn fill_face(&mut self, tz: &mut Tetrahedralizer, f: &QuadFace) -> Result<()> {
        if self.get(f.centre).is_some() {
            return Ok(());
        }
        let mut terms = Vec::new();
        for c in f.corners {
            terms.push((self.need(c)?, -0.25));
        }
        for e in f.edges {
            terms.push((self.need(e)?, 0.5));
        }
        let key = self.key(&f.corners).ok_or_else(|| anyhow::anyhow!("internal: face corners missing"))?;
        let c = tz.face_point(key, &terms)?;
        self.set(f.centre, c);
        Ok(())
    }
}

/// The 13-node pyramid: base centre added (shared with the neighbour), then
/// 4 base pyramids, the top pyramid, the inverted middle pyramid and 4 tets.
fn quadratic_pyramid(tz: &mut Tetrahedralizer, v: &[u32]) -> Result<()> {
    let mut key = vec![v[0], v[1], v[2], v[3]];
    key.sort_unstable();
    let terms = [(v[0], -0.25), (v[1], -0.25), (v[2], -0.25), (v[3], -0.25), (v[5], 0.5), (v[6], 0.5), (v[7], 0.5), (v[8], 0.5)];
    let b = tz.face_point(key, &terms)?;
    let n = |i: usize| v[i];
    let pyramids = [
        [n(0), n(5), b, n(8), n(9)],
        [n(5), n(1), n(6), b, n(10)],
        [b, n(6), n(2), n(7), n(11)],
        [n(8), b, n(7), n(3), n(12)],
        [n(9), n(10), n(11), n(12), n(4)],
        [n(9), n(12), n(11), n(10), b],
    ];
    for q in pyramids {
        split_linear(tz, VTK_PYRAMID, &q)?;
    }
    for q in [[n(5), b, n(9), n(10)], [n(6), b, n(10), n(11)], [n(7), b, n(11), n(12)], [n(8), b, n(12), n(9)]] {
        split_linear(tz, VTK_TETRA, &q)?;
    }
    Ok(())
}
