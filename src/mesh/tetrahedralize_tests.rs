//! Tests of the splitting of every cell kind: higher-order cells,
//! polyhedra, repaired (non-convex, inverted) and collapsed linear cells.

use std::collections::{HashMap, HashSet};

use crate::mesh::adjacency::{FaceAdjacency, FACE_VERTS};
use crate::mesh::cells::RawCells;
use crate::mesh::cells::PolyFaces;
use crate::mesh::{HigherOrder, TetGeometry, TetMesh};

/// A quadratic field: the serendipity formulas are exact for it.
fn field(p: [f64; 3]) -> f64 {
    p[0] * p[0] + 0.5 * p[1] * p[2] - 0.3 * p[2] * p[2] + 2.0 * p[0] + 1.0
}

/// Cells on integer lattice positions, points made once per position (a
/// shuffled numbering, so the diagonal rule varies), straight-sided.
#[derive(Default)]
struct Builder {
    at: HashMap<[i64; 3], u32>,
    points: Vec<[f64; 3]>,
    cells: Vec<(u8, Vec<u32>)>,
    scale: f64,
}

impl Builder {
    fn new(scale: f64) -> Builder {
        Builder { scale, ..Default::default() }
    }
    fn point(&mut self, q: [i64; 3]) -> u32 {
        let n = self.points.len() as u32;
        let s = self.scale;
        *self.at.entry(q).or_insert_with(|| {
            self.points.push(q.map(|x| x as f64 / s));
            n
        })
    }
    fn raw(&self, seed: u64) -> RawCells {
        // Shuffle the numbering.
        let n = self.points.len();
        let mut perm: Vec<u32> = (0..n as u32).collect();
        let mut r = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407) | 1;
        for i in (1..n).rev() {
            r ^= r << 13;
            r ^= r >> 7;
            r ^= r << 17;
            perm.swap(i, (r % (i as u64 + 1)) as usize);
        }
        let mut points = vec![[0.0; 3]; n];
        for (&q, p) in perm.iter().zip(&self.points) {
            points[q as usize] = *p;
        }
        let scalars = points.iter().map(|&p| field(p)).collect();
        let mut raw = RawCells { points, scalars, offsets: vec![0], ..Default::default() };
        for (t, v) in &self.cells {
            raw.types.push(*t);
            raw.conn.extend(v.iter().map(|&i| perm[i as usize]));
            raw.offsets.push(raw.conn.len());
        }
        raw
    }
}

/// The lattice table of a type (node positions at degree `p`).
fn lattice(t: u8, n: usize) -> (usize, &'static [[u8; 3]]) {
    super::higher_order::tests_lattice(t, n).expect("a lattice table")
}

/// An `n`³ block of unit cubes, each filled with cells of type `t`.
fn block(t: u8, nodes: usize, n: i64) -> Builder {
    let (p, lat) = lattice(t, nodes);
    let p = p as i64;
    let mut b = Builder::new(p as f64);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let o = [i * p, j * p, k * p];
                match t {
                    25 | 29 | 33 | 72 => {
                        let v: Vec<u32> = lat.iter().map(|q| b.point([o[0] + q[0] as i64, o[1] + q[1] as i64, o[2] + q[2] as i64])).collect();
                        b.cells.push((t, v));
                    }
                    24 | 71 => {
                        // Six tets of the cube around its main diagonal (Kuhn), each of degree p.
                        let corners = |c: [i64; 3]| [o[0] + c[0] * p, o[1] + c[1] * p, o[2] + c[2] * p];
                        for perm in [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]] {
                            let mut path = vec![[0i64; 3]];
                            let mut c = [0i64; 3];
                            for &a in &perm {
                                c[a] = 1;
                                path.push(c);
                            }
                            let tv: Vec<[i64; 3]> = path.iter().map(|&c| corners(c)).collect();
                            // Positive orientation: swap if needed.
                            let d = det(tv[0], tv[1], tv[2], tv[3]);
                            let tv = if d < 0 { vec![tv[0], tv[1], tv[3], tv[2]] } else { tv };
                            let v: Vec<u32> = lat
                                .iter()
                                .map(|q| {
                                    let (x, y, z) = (q[0] as i64, q[1] as i64, q[2] as i64);
                                    let w0 = p - x - y - z;
                                    let pos: [i64; 3] = std::array::from_fn(|a| (w0 * tv[0][a] + x * tv[1][a] + y * tv[2][a] + z * tv[3][a]) / p);
                                    b.point(pos)
                                })
                                .collect();
                            b.cells.push((t, v));
                        }
                    }
                    26 | 31 | 32 | 73 => {
                        // Two wedges: the cube's bottom square cut along x + y = 1.
                        for (c0, c1, c2) in [([0, 0], [1, 0], [0, 1]), ([1, 1], [0, 1], [1, 0])] {
                            let v: Vec<u32> = lat
                                .iter()
                                .map(|q| {
                                    let (x, y, z) = (q[0] as i64, q[1] as i64, q[2] as i64);
                                    let w0 = p - x - y;
                                    let xy: [i64; 2] = std::array::from_fn(|a| w0 * c0[a] + x * c1[a] + y * c2[a]);
                                    b.point([o[0] + xy[0], o[1] + xy[1], o[2] + z])
                                })
                                .collect();
                            b.cells.push((t, v));
                        }
                    }
                    _ => unreachable!(),
                }
            }
        }
    }
    b
}

fn det(a: [i64; 3], b: [i64; 3], c: [i64; 3], d: [i64; 3]) -> i64 {
    let s = |x: [i64; 3], y: [i64; 3]| [x[0] - y[0], x[1] - y[1], x[2] - y[2]];
    let (u, v, w) = (s(b, a), s(c, a), s(d, a));
    u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) + u[2] * (v[0] * w[1] - v[1] * w[0])
}

/// Closes (no interior boundary face), fills the block's volume, keeps
/// every node as a vertex, and every added point carries the field's value.
fn check_block(m: &TetMesh, raw_conn: &[u32], n: f64, what: &str) {
    assert_eq!(m.stats.reoriented, 0, "{what}");
    assert_eq!(m.stats.repairs, Default::default(), "{what}");
    let vol = TetGeometry::compute(m).total_volume();
    assert!((vol - n * n * n).abs() < 1e-9 * n * n * n, "{what}: volume {vol}");
    let adj = FaceAdjacency::build(&m.tets, None, |_| true);
    assert!(adj.shared.is_empty(), "{what}");
    for &slot in &adj.boundary {
        let (c, f) = (slot as usize / 4, slot as usize % 4);
        let face = FACE_VERTS[f].map(|i| m.points[m.tets[c][i] as usize]);
        let on_surface = (0..3).any(|a| face.iter().all(|p| p[a] == 0.0) || face.iter().all(|p| p[a] == n));
        assert!(on_surface, "{what}: interior boundary face {face:?}: a crack");
    }
    let used: HashSet<u32> = m.tets.iter().flatten().copied().collect();
    for v in raw_conn {
        assert!(used.contains(v), "{what}: node {v} is no tet's vertex");
    }
    for (i, p) in m.points.iter().enumerate() {
        assert!((m.scalars[i] - field(*p)).abs() < 1e-9, "{what}: point {i} at {p:?} has {} not {}", m.scalars[i], field(*p));
    }
}

fn mesh_of(raw: RawCells, mode: HigherOrder) -> anyhow::Result<TetMesh> {
    raw.into_tet_mesh_with("t.vtu", "t".into(), mode)
}

#[test]
fn every_higher_order_type_splits_conformingly() {
    // (type, nodes, tets per cube of the block at degree p)
    let cases: &[(u8, usize, usize)] = &[
        (24, 10, 6 * 8),
        (25, 20, 0),
        (26, 15, 0),
        (29, 27, 0),
        (31, 12, 0),
        (32, 18, 0),
        (33, 24, 0),
        (71, 10, 6 * 8),
        (71, 20, 6 * 27),
        (71, 35, 6 * 64),
        (72, 27, 0),
        (72, 64, 0),
        (73, 18, 0),
        (73, 40, 0),
    ];
    for &(t, nodes, per_cube) in cases {
        for (n, seed) in [(1, 1u64), (2, 7)] {
            let b = block(t, nodes, n);
            let raw = b.raw(seed);
            let conn = raw.conn.clone();
            let what = format!("type {t} with {nodes} nodes, {n}^3 cubes");
            let m = mesh_of(raw, HigherOrder::Subdivide).unwrap_or_else(|e| panic!("{what}: {e:#}"));
            check_block(&m, &conn, n as f64, &what);
            assert_eq!(m.stats.higher_order_cells, b.cells.len(), "{what}");
            assert_eq!(m.stats.higher_order, Some(HigherOrder::Subdivide));
            if per_cube > 0 {
                assert_eq!(m.tets.len(), per_cube * (n * n * n) as usize, "{what}");
            }
        }
    }
}

#[test]
fn added_points_are_shared_and_counted() {
    // A 20-node hexahedron block: face centres shared by the two cells of a
    // face: 2x2x2 cells have 36 faces (+ 8 body centres).
    let b = block(25, 20, 2);
    let m = mesh_of(b.raw(3), HigherOrder::Subdivide).unwrap();
    assert_eq!(m.stats.added_points, 36 + 8);
    // A triquadratic hexahedron has every node: nothing added.
    let m = mesh_of(block(29, 27, 2).raw(3), HigherOrder::Subdivide).unwrap();
    assert_eq!(m.stats.added_points, 0);
    // One quadratic tetra: 8 tets.
    let m = mesh_of(block(24, 10, 1).raw(0), HigherOrder::Subdivide).unwrap();
    assert_eq!(m.tets.len(), 48);
}

#[test]
fn corners_mode_reads_the_corner_nodes() {
    for (t, nodes, tets_per_cube) in [(24u8, 10usize, 6usize), (71, 20, 6)] {
        let m = mesh_of(block(t, nodes, 2).raw(5), HigherOrder::Corners).unwrap();
        assert_eq!(m.tets.len(), tets_per_cube * 8);
        assert_eq!(m.stats.higher_order, Some(HigherOrder::Corners));
        let vol = TetGeometry::compute(&m).total_volume();
        assert!((vol - 8.0).abs() < 1e-9);
    }
    for (t, nodes) in [(25u8, 20usize), (29, 27), (72, 64), (26, 15), (73, 40)] {
        let m = mesh_of(block(t, nodes, 2).raw(5), HigherOrder::Corners).unwrap();
        let vol = TetGeometry::compute(&m).total_volume();
        assert!((vol - 8.0).abs() < 1e-9, "type {t}");
        assert_eq!(m.stats.added_points, 0);
        let adj = FaceAdjacency::build(&m.tets, None, |_| true);
        assert!(adj.shared.is_empty());
    }
}

/// Quadratic hexahedra (20, 24 and 27 nodes, Lagrange of degree 2) and cubes
/// of six quadratic pyramids around a centre node, mixed at random: the
/// faces between them close.
fn mixed_quadratic(n: i64, seed: u64) -> Builder {
    // Lattice step 1/4: a cube's quadratic nodes at even positions, a
    // pyramid's apex-edge nodes at odd ones.
    let mut b = Builder::new(4.0);
    let mut r = seed.wrapping_mul(0x9E3779B97F4A7C15) | 1;
    let mut next = move || {
        r ^= r << 13;
        r ^= r >> 7;
        r ^= r << 17;
        r
    };
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let o = [4 * i, 4 * j, 4 * k];
                let t = [25u8, 29, 33, 72, 27][(next() % 5) as usize];
                if t == 27 {
                    // Six quadratic pyramids on the cube's centre, each base a face
                    // (turned to face the centre).
                    let faces: [[[i64; 3]; 4]; 6] = [
                        [[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 0, 0]],
                        [[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
                        [[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]],
                        [[1, 0, 0], [1, 1, 0], [1, 1, 1], [1, 0, 1]],
                        [[1, 1, 0], [0, 1, 0], [0, 1, 1], [1, 1, 1]],
                        [[0, 1, 0], [0, 0, 0], [0, 0, 1], [0, 1, 1]],
                    ];
                    let apex = [o[0] + 2, o[1] + 2, o[2] + 2];
                    let mid = |a: [i64; 3], c: [i64; 3]| [(a[0] + c[0]) / 2, (a[1] + c[1]) / 2, (a[2] + c[2]) / 2];
                    for f in faces {
                        let mut base: Vec<[i64; 3]> = f.iter().map(|c| [o[0] + 4 * c[0], o[1] + 4 * c[1], o[2] + 4 * c[2]]).collect();
                        if det(base[0], base[1], base[2], apex) < 0 {
                            base.reverse();
                        }
                        let mut v: Vec<[i64; 3]> = base.clone();
                        v.push(apex);
                        for e in 0..4 {
                            v.push(mid(base[e], base[(e + 1) % 4]));
                        }
                        for c in &base {
                            v.push(mid(*c, apex));
                        }
                        let ids: Vec<u32> = v.iter().map(|&p| b.point(p)).collect();
                        b.cells.push((27, ids));
                    }
                    continue;
                }
                let nodes = match t {
                    25 => 20,
                    33 => 24,
                    _ => 27,
                };
                let (_, lat) = lattice(t, nodes);
                let v: Vec<u32> =
                    lat.iter().map(|q| b.point([o[0] + 2 * q[0] as i64, o[1] + 2 * q[1] as i64, o[2] + 2 * q[2] as i64])).collect();
                b.cells.push((t, v));
            }
        }
    }
    b
}

fn check_mixed(n: i64, seed: u64) {
    let b = mixed_quadratic(n, seed);
    let raw = b.raw(seed);
    let conn = raw.conn.clone();
    let m = mesh_of(raw, HigherOrder::Subdivide).unwrap_or_else(|e| panic!("seed {seed}: {e:#}"));
    // Pyramid apex-edge nodes sit at half the lattice: the field is still exact.
    check_block(&m, &conn, n as f64, &format!("mixed quadratic, seed {seed}"));
}

#[test]
fn mixed_quadratic_blocks_close() {
    for seed in 0..12 {
        check_mixed(2, seed);
    }
    check_mixed(3, 99);
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(24))]
    #[test]
    fn random_mixed_higher_order_meshes_are_conforming(seed in 0u64..u64::MAX, n in 1i64..4) {
        check_mixed(n, seed);
    }
}

// ---- polyhedra

/// Two stacked pentagonal prisms and two cubes beside them, all as
/// polyhedra: faces (outward or not: the split orients them).
pub(crate) fn poly_block() -> (Vec<[f64; 3]>, Vec<Vec<Vec<u32>>>) {
    let ring = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.5, 1.5], [0.0, 1.0]];
    let mut points = Vec::new();
    for z in 0..3 {
        for p in ring {
            points.push([p[0], p[1], z as f64]);
        }
        points.push([2.0, 0.0, z as f64]);
        points.push([2.0, 1.0, z as f64]);
    }
    let at = |i: u32, z: u32| i + 7 * z;
    let mut cells = Vec::new();
    for z in 0..2 {
        let mut faces = vec![(0..5).map(|i| at(i, z)).collect::<Vec<u32>>(), (0..5).rev().map(|i| at(i, z + 1)).collect()];
        for i in 0..5 {
            let j = (i + 1) % 5;
            faces.push(vec![at(i, z), at(j, z), at(j, z + 1), at(i, z + 1)]);
        }
        cells.push(faces);
        // The cube on the side x = 1 .. 2, y = 0 .. 1: points 1, 5, 6, 2.
        let q = [at(1, z), at(5, z), at(6, z), at(2, z)];
        let r = [at(1, z + 1), at(5, z + 1), at(6, z + 1), at(2, z + 1)];
        let mut faces = vec![q.to_vec(), r.iter().rev().copied().collect()];
        for i in 0..4 {
            let j = (i + 1) % 4;
            faces.push(vec![q[i], q[j], r[j], r[i]]);
        }
        cells.push(faces);
    }
    (points, cells)
}

fn poly_raw(points: &[[f64; 3]], cells: &[Vec<Vec<u32>>]) -> RawCells {
    let mut raw = RawCells { points: points.to_vec(), scalars: points.iter().map(|&p| field(p)).collect(), offsets: vec![0], ..Default::default() };
    for (c, faces) in cells.iter().enumerate() {
        let mut pts: Vec<u32> = faces.iter().flatten().copied().collect();
        pts.sort_unstable();
        pts.dedup();
        raw.types.push(42);
        raw.conn.extend(pts);
        raw.offsets.push(raw.conn.len());
        raw.faces.push_cell(c, faces);
    }
    raw
}

pub(crate) fn check_poly_block(m: &TetMesh, what: &str) {
    let vol = TetGeometry::compute(m).total_volume();
    // Pentagon area 1 + 0.25, two layers; two unit cubes.
    assert!((vol - (2.0 * 1.25 + 2.0)).abs() < 1e-12, "{what}: volume {vol}");
    assert_eq!(m.stats.polyhedra, 4, "{what}");
    assert_eq!(m.stats.reoriented, 0, "{what}");
    let adj = FaceAdjacency::build(&m.tets, None, |_| true);
    assert!(adj.shared.is_empty(), "{what}");
    // Boundary: pentagons top and bottom (5 triangles each), 2 x 2 cube
    // ends, side quads: prism 4 (not the shared one) x 2 layers, cube 3 x 2.
    assert_eq!(adj.boundary.len(), 2 * 5 + 2 * 2 + 2 * (4 + 3) * 2, "{what}: cracks");
    // 3 cell centroids... 4 cell centroids and 3 pentagon centroids (the middle one shared).
    assert_eq!(m.stats.added_points, 4 + 3, "{what}");
}

#[test]
fn polyhedra_split_conformingly() {
    let (points, cells) = poly_block();
    let m = mesh_of(poly_raw(&points, &cells), HigherOrder::Subdivide).unwrap();
    check_poly_block(&m, "polyhedra");
    // Every added point is the mean of its face's or cell's points.
    for i in points.len()..m.points.len() {
        assert!(m.scalars[i].is_finite());
    }
    // Faces given inward, in any order: the same volume and closure.
    let flipped: Vec<Vec<Vec<u32>>> = cells.iter().map(|fs| fs.iter().rev().map(|f| f.iter().rev().copied().collect()).collect()).collect();
    check_poly_block(&mesh_of(poly_raw(&points, &flipped), HigherOrder::Subdivide).unwrap(), "inward faces");
}

#[test]
fn polyhedra_that_lie_are_refused() {
    let (points, cells) = poly_block();
    let e = |cells: &[Vec<Vec<u32>>]| format!("{:#}", mesh_of(poly_raw(&points, cells), HigherOrder::Subdivide).unwrap_err());
    // A face missing: the faces do not close.
    let mut open = cells.clone();
    open[1].pop();
    let s = e(&open);
    assert!(s.contains("cell 1 (polyhedron, type 42)") && s.contains("do not close"), "{s}");
    // A face with two points.
    let mut thin = cells.clone();
    thin[2][0] = vec![0, 1];
    let s = e(&thin);
    assert!(s.contains("cell 2 (polyhedron, type 42)") && s.contains("three or more distinct points"), "{s}");
    // A face naming a point not among the cell's.
    let mut raw = poly_raw(&points, &cells);
    raw.conn[0] = 20;
    let s = format!("{:#}", mesh_of(raw, HigherOrder::Subdivide).unwrap_err());
    assert!(s.contains("cell 0 (polyhedron, type 42)") && s.contains("not among the cell's"), "{s}");
    // A polyhedron without faces.
    let mut raw = poly_raw(&points, &cells);
    raw.faces = PolyFaces::default();
    let s = format!("{:#}", mesh_of(raw, HigherOrder::Subdivide).unwrap_err());
    assert!(s.contains("cell 0 (polyhedron, type 42) has no faces"), "{s}");
}

#[test]
fn face_streams_are_checked() {
    use crate::mesh::polyhedron::parse_face_stream;
    let ok = [4i64, 3, 0, 1, 2, 3, 0, 1, 3, 3, 1, 2, 3, 3, 2, 0, 3];
    assert_eq!(parse_face_stream(&ok, 4).unwrap().len(), 4);
    for (bad, want) in [
        (&[5i64, 3, 0, 1, 2, 3, 0, 1, 3, 3, 1, 2, 3, 3, 2, 0, 3][..], "ends before face 4"),
        (&[4, 3, 0, 1, 2, 3, 0, 1, 3, 3, 1, 2, 3, 9, 2, 0, 3], "claims 9 points"),
        (&[4, 3, 0, 1, 2, 3, 0, 1, 3, 3, 1, 2, 3, 3, 2, 0, 7], "out of range"),
        (&[4, 3, 0, 1, 2, 3, 0, 1, 3, 3, 1, 2, 3, 3, 2, 0, 3, 5], "its 4 faces use 17"),
        (&[1_000_000_000, 3], "declares 1000000000 faces"),
        (&[], "empty"),
    ] {
        let e = format!("{:#}", parse_face_stream(bad, 4).unwrap_err());
        assert!(e.contains(want), "{bad:?}: {e}");
    }
}

// ---- repairs and collapsed cells

fn hex_raw(points: Vec<[f64; 3]>, cells: &[(u8, Vec<u32>)]) -> RawCells {
    let scalars = points.iter().map(|&p| field(p)).collect();
    let mut raw = RawCells { points, scalars, offsets: vec![0], ..Default::default() };
    for (t, v) in cells {
        raw.types.push(*t);
        raw.conn.extend(v);
        raw.offsets.push(raw.conn.len());
    }
    raw
}

/// A 3x3x1 block of hexahedra whose centre cell's top face is turned by
/// `theta` about its centre (a crash-like twist: the centre cell and its
/// neighbours become non-convex and twisted), numbered by `seed`.
pub(crate) fn twisted_block(theta: f64, seed: u64) -> RawCells {
    let mut b = Builder::new(1.0);
    for j in 0..3 {
        for i in 0..3 {
            let h: Vec<u32> = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]]
                .iter()
                .map(|c| b.point([i + c[0], j + c[1], c[2]]))
                .collect();
            b.cells.push((12u8, h));
        }
    }
    let mut raw = b.raw(seed);
    let (s, c) = theta.sin_cos();
    for (k, p) in raw.points.iter_mut().enumerate() {
        if p[2] == 1.0 && (1.0..=2.0).contains(&p[0]) && (1.0..=2.0).contains(&p[1]) {
            let (x, y) = (p[0] - 1.5, p[1] - 1.5);
            *p = [1.5 + c * x - s * y, 1.5 + s * x + c * y, 1.0];
            raw.scalars[k] = field(*p);
        }
    }
    raw
}

/// One wedge or hexahedron with its top turned by `theta` about the
/// vertical axis, its point ids in the order `perm`.
fn twisted_cell(t: u8, theta: f64, perm: &[u32]) -> RawCells {
    let n = if t == 13 { 3 } else { 4 };
    let mut points = Vec::new();
    for z in 0..2 {
        for k in 0..n {
            let a = std::f64::consts::TAU * k as f64 / n as f64 + if z == 1 { theta } else { 0.0 };
            points.push([a.cos(), a.sin(), z as f64]);
        }
    }
    let mut shuffled = vec![[0.0; 3]; points.len()];
    for (i, p) in points.iter().enumerate() {
        shuffled[perm[i] as usize] = *p;
    }
    let v: Vec<u32> = perm[..points.len()].to_vec();
    hex_raw(shuffled, &[(t, v)])
}

#[test]
fn twisted_cells_are_resplit_or_split_around_their_centroid() {
    for (t, name) in [(13u8, "wedge"), (12, "hexahedron")] {
        let k = if t == 13 { 6 } else { 8 };
        let (mut ok, mut repaired) = (0, 0);
        for (seed, theta) in (0..160u64).zip([0.5, 0.9, 1.3, 1.6, 1.9].iter().cycle()) {
            let theta = if t == 12 { theta * 0.75 } else { *theta };
            let mut perm: Vec<u32> = (0..k as u32).collect();
            let mut r = seed.wrapping_mul(0x9E3779B97F4A7C15) | 1;
            for i in (1..k).rev() {
                r ^= r << 13;
                r ^= r >> 7;
                r ^= r << 17;
                perm.swap(i, (r % (i as u64 + 1)) as usize);
            }
            match mesh_of(twisted_cell(t, theta, &perm), HigherOrder::Subdivide) {
                Ok(m) => {
                    ok += 1;
                    let rp = m.stats.repairs;
                    repaired += rp.resplit_cells + rp.centroid_split_cells;
                    let vol = TetGeometry::compute(&m).total_volume();
                    assert!((vol - enclosed_volume(&m)).abs() < 1e-9, "{name} {perm:?}: {vol}");
                }
                Err(e) => {
                    let e = format!("{e:#}");
                    assert!(e.contains(&format!("cell 0 ({name}, type {t})")) && e.contains("folds over"), "{e}");
                }
            }
        }
        eprintln!("{name}: {ok} of 160 read, {repaired} repaired");
        assert!(ok > 0, "{name}");
        // A wedge has one triangulation per cut, so only the centroid split
        // can repair it, and its twists that fold are not star-shaped either.
        if t == 12 {
            assert!(repaired > 0, "{name}: {ok} read, {repaired} repaired");
        }
    }
}

#[test]
fn a_twisted_block_renders_its_repairs_counted() {
    let mut repaired = 0;
    for seed in 0..30 {
        for theta in [0.6, 0.9] {
            match mesh_of(twisted_block(theta, seed), HigherOrder::Subdivide) {
                Ok(m) => {
                    let r = m.stats.repairs;
                    repaired += r.resplit_cells + r.centroid_split_cells;
                    let adj = FaceAdjacency::build(&m.tets, None, |_| true);
                    assert!(adj.shared.is_empty());
                    let vol = TetGeometry::compute(&m).total_volume();
                    assert!((vol - enclosed_volume(&m)).abs() < 1e-9, "seed {seed}: {vol}");
                }
                Err(e) => {
                    let e = format!("{e:#}");
                    assert!(e.contains("(hexahedron, type 12)"), "seed {seed}: {e}");
                }
            }
        }
    }
    assert!(repaired > 0);
}

/// The volume the triangulated boundary encloses (divergence theorem).
fn enclosed_volume(m: &TetMesh) -> f64 {
    let adj = FaceAdjacency::build(&m.tets, None, |_| true);
    adj.boundary
        .iter()
        .map(|&slot| {
            let (c, f) = (slot as usize / 4, slot as usize % 4);
            let t = m.tets[c];
            // The face opposite vertex f, oriented outward: the tet's other
            // three in an order whose determinant with the opposite vertex is positive.
            let face = FACE_VERTS[f].map(|i| m.points[t[i] as usize]);
            let opp = m.points[t[f] as usize];
            let d = crate::mesh::geometry::tet_det([face[0], face[1], face[2], opp]).0;
            let v = crate::mesh::geometry::tet_det([[0.0; 3], face[0], face[1], face[2]]).0;
            if d > 0.0 { -v / 6.0 } else { v / 6.0 }
        })
        .sum()
}

#[test]
fn inside_out_cells_are_reoriented_and_counted() {
    let mut b = Builder::new(1.0);
    let h: Vec<u32> =
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]].iter().map(|&c| b.point(c)).collect();
    // Top and bottom swapped: inside out.
    let inv = [h[4], h[5], h[6], h[7], h[0], h[1], h[2], h[3]].to_vec();
    let m = mesh_of(hex_raw(b.points.clone(), &[(12, inv)]), HigherOrder::Subdivide).unwrap();
    assert_eq!(m.stats.repairs.reoriented_cells, 1);
    assert!((TetGeometry::compute(&m).total_volume() - 1.0).abs() < 1e-12);
    let tet = vec![h[0], h[2], h[1], h[4]];
    let m = mesh_of(hex_raw(b.points.clone(), &[(10, tet)]), HigherOrder::Subdivide).unwrap();
    assert_eq!(m.stats.repairs.reoriented_cells, 1);
}

#[test]
fn collapsed_cells_read_as_their_degenerate_form() {
    // A hexahedron beside a hexahedron collapsed into a wedge (edge 5-6 onto 1-2... its
    // top face's right edge collapsed onto the bottom's), and one collapsed into a pyramid.
    let mut b = Builder::new(1.0);
    let c = |b: &mut Builder, x: i64, y: i64, z: i64| b.point([x, y, z]);
    let hex: Vec<u32> = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]]
        .iter()
        .map(|q| c(&mut b, q[0], q[1], q[2]))
        .collect();
    // The wedge x = 1..2 under the slope: its top edge at x = 1 (points of the hex), floor to x = 2.
    let (f1, f2) = (c(&mut b, 2, 0, 0), c(&mut b, 2, 1, 0));
    let wedge_as_hex = vec![hex[1], f1, f2, hex[2], hex[5], f1, f2, hex[6]];
    // A pyramid on the top of the hex, as a hexahedron whose top face is one point.
    let apex = c(&mut b, 0, 0, 2);
    let pyr_as_hex = vec![hex[4], hex[5], hex[6], hex[7], apex, apex, apex, apex];
    // A wedge collapsed to a tet, a pyramid collapsed to a tet (beside, apart).
    let cells = vec![(12u8, hex.clone()), (12, wedge_as_hex), (12, pyr_as_hex)];
    let m = mesh_of(hex_raw(b.points.clone(), &cells), HigherOrder::Subdivide).unwrap();
    assert_eq!(m.stats.repairs.degenerate_cells, 2);
    let vol = TetGeometry::compute(&m).total_volume();
    assert!((vol - (1.0 + 0.5 + 1.0 / 3.0)).abs() < 1e-12, "volume {vol}");
    let adj = FaceAdjacency::build(&m.tets, None, |_| true);
    assert!(adj.shared.is_empty());
    assert!((enclosed_volume(&m) - vol).abs() < 1e-12);
    // A wedge with its top triangle collapsed to a point is a tet; a pyramid with a base edge collapsed is a tet.
    let p: Vec<[f64; 3]> = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 0.0]];
    let m = mesh_of(hex_raw(p.clone(), &[(13, vec![0, 1, 2, 3, 3, 3])]), HigherOrder::Subdivide).unwrap();
    assert_eq!(m.tets.len(), 1);
    let m = mesh_of(hex_raw(p.clone(), &[(14, vec![0, 1, 1, 2, 3])]), HigherOrder::Subdivide).unwrap();
    assert_eq!(m.tets.len(), 1);
    assert_eq!(m.stats.repairs.degenerate_cells, 1);
    // Collapsed to nothing at all: the cell adds nothing, but a mesh of only such cells is empty.
    let e = format!("{:#}", mesh_of(hex_raw(p, &[(12, vec![0, 0, 0, 0, 1, 1, 1, 1])]), HigherOrder::Subdivide).unwrap_err());
    assert!(e.contains("empty mesh"), "{e}");
}

#[test]
fn bad_higher_order_cells_are_named() {
    let b = block(24, 10, 1);
    let mut raw = b.raw(0);
    // Cell 2 loses a node.
    raw.conn.remove(raw.offsets[3] - 1);
    for o in raw.offsets.iter_mut().skip(3) {
        *o -= 1;
    }
    let e = format!("{:#}", mesh_of(raw, HigherOrder::Subdivide).unwrap_err());
    assert!(e.contains("cell 2 (quadratic tetra, type 24) has 9 nodes, not 10"), "{e}");
    let mut raw = block(72, 27, 1).raw(0);
    raw.conn.push(0);
    *raw.offsets.last_mut().unwrap() += 1;
    let e = format!("{:#}", mesh_of(raw, HigherOrder::Subdivide).unwrap_err());
    assert!(e.contains("cell 0 (Lagrange hexahedron, type 72) has 28 nodes") && e.contains("8, 27, 64, 125"), "{e}");
    let mut raw = block(25, 20, 1).raw(0);
    raw.conn[3] = 999;
    let e = format!("{:#}", mesh_of(raw, HigherOrder::Subdivide).unwrap_err());
    assert!(e.contains("cell 0 (quadratic hexahedron, type 25) has point index 999 out of range"), "{e}");
    // Bezier cells: corners only.
    let mut raw = block(71, 10, 1).raw(0);
    raw.types.iter_mut().for_each(|t| *t = 78);
    let e = format!("{:#}", mesh_of(raw.clone(), HigherOrder::Subdivide).unwrap_err());
    assert!(e.contains("Bezier") && e.contains("--higher-order corners"), "{e}");
    assert_eq!(mesh_of(raw, HigherOrder::Corners).unwrap().tets.len(), 6);
    // Unsupported types are listed with what is read.
    let mut raw = block(24, 10, 1).raw(0);
    raw.types[0] = 41;
    let e = format!("{:#}", mesh_of(raw, HigherOrder::Subdivide).unwrap_err());
    assert!(e.contains("1 cells of type 41 (convex point set)") && e.contains("polyhedra (42)") && e.contains("Lagrange"), "{e}");
}

/// The polyhedra of [`poly_block`] as a `.vtu` in the layout before VTK
/// 9.4: `faces` (each cell's face stream) and `faceoffsets` (its end).
fn old_layout_vtu(points: &[[f64; 3]], cells: &[Vec<Vec<u32>>], lie: Option<(usize, i64)>) -> String {
    let join = |v: Vec<String>| v.join(" ");
    let mut conn = Vec::new();
    let mut offsets = Vec::new();
    let mut faces: Vec<i64> = Vec::new();
    let mut faceoffsets = Vec::new();
    for fs in cells {
        let mut pts: Vec<u32> = fs.iter().flatten().copied().collect();
        pts.sort_unstable();
        pts.dedup();
        conn.extend(pts);
        offsets.push(conn.len());
        faces.push(fs.len() as i64);
        for f in fs {
            faces.push(f.len() as i64);
            faces.extend(f.iter().map(|&v| v as i64));
        }
        faceoffsets.push(faces.len());
    }
    if let Some((at, value)) = lie {
        faces[at] = value;
    }
    let arr = |name: &str, ty: &str, text: String| format!("<DataArray type=\"{ty}\" Name=\"{name}\" format=\"ascii\">{text}</DataArray>\n");
    let mut x = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt32\">\n<UnstructuredGrid>\n",
    );
    x += &format!("<Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n<PointData>\n", points.len(), cells.len());
    x += &arr("s", "Float64", join(points.iter().map(|p| (p[0] + 2.0 * p[1] + 3.0 * p[2]).to_string()).collect()));
    x += "</PointData>\n<Points>\n";
    x += &format!(
        "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">{}</DataArray>\n",
        join(points.iter().flat_map(|p| p.iter().map(|c| c.to_string())).collect())
    );
    x += "</Points>\n<Cells>\n";
    x += &arr("connectivity", "Int64", join(conn.iter().map(|v| v.to_string()).collect()));
    x += &arr("offsets", "Int64", join(offsets.iter().map(|v| v.to_string()).collect()));
    x += &arr("types", "UInt8", join(cells.iter().map(|_| "42".to_string()).collect()));
    x += &arr("faces", "Int64", join(faces.iter().map(|v| v.to_string()).collect()));
    x += &arr("faceoffsets", "Int64", join(faceoffsets.iter().map(|v| v.to_string()).collect()));
    x += "</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
    x
}

#[test]
fn polyhedra_in_every_layout_read_alike() {
    use crate::mesh::{vtk::parse_vtk_bytes, vtu::parse_vtu_bytes};
    let (points, cells) = poly_block();
    let old = old_layout_vtu(&points, &cells, None);
    let meshes = [
        ("VTK 9.7 .vtu, ascii", parse_vtu_bytes("a.vtu", include_bytes!("../../tests/fixtures/polyhedra_ascii.vtu"), None)),
        ("VTK 9.7 .vtu, appended zlib", parse_vtu_bytes("b.vtu", include_bytes!("../../tests/fixtures/polyhedra_appended.vtu"), None)),
        ("VTK 9.7 legacy 4.2", parse_vtk_bytes("c.vtk", include_bytes!("../../tests/fixtures/polyhedra_42.vtk"))),
        ("VTK 9.7 legacy 5.1", parse_vtk_bytes("d.vtk", include_bytes!("../../tests/fixtures/polyhedra_51.vtk"))),
        ("faces / faceoffsets", parse_vtu_bytes("e.vtu", old.as_bytes(), None)),
    ];
    let mut first: Option<TetMesh> = None;
    for (what, m) in meshes {
        let m = m.unwrap_or_else(|e| panic!("{what}: {e:#}"));
        check_poly_block(&m, what);
        // Added points carry the mean of their face's or cell's values.
        for (i, p) in m.points.iter().enumerate() {
            assert!((m.scalars[i] - (p[0] + 2.0 * p[1] + 3.0 * p[2])).abs() < 1e-6, "{what}: point {i}");
        }
        match &first {
            None => first = Some(m),
            Some(f) => {
                let key = |m: &TetMesh| {
                    let mut k: Vec<[[u64; 3]; 4]> = m
                        .tets
                        .iter()
                        .map(|t| {
                            let mut q = t.map(|v| m.points[v as usize].map(|c| ((c as f32) as f64).to_bits()));
                            q.sort_unstable();
                            q
                        })
                        .collect();
                    k.sort_unstable();
                    k
                };
                assert_eq!(key(&m), key(f), "{what}: the same tets");
            }
        }
    }
    // Lying face streams in the old layout name the cell.
    for (lie, want) in [((0, 9), "cell 0 (polyhedron, type 42)"), ((1, 40), "claims 40 points"), ((2, 99), "out of range")] {
        let bad = old_layout_vtu(&points, &cells, Some(lie));
        let e = format!("{:#}", parse_vtu_bytes("bad.vtu", bad.as_bytes(), None).unwrap_err());
        assert!(e.starts_with("bad.vtu") && e.contains(want), "{lie:?}: {e}");
    }
    // faceoffsets for a cell that is no polyhedron.
    let bad = old.replace("<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">42 42", "<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">12 42");
    let e = format!("{:#}", parse_vtu_bytes("bad.vtu", bad.as_bytes(), None).unwrap_err());
    assert!(e.contains("cell 0 is not a polyhedron"), "{e}");
}

#[test]
fn kinds() {
    use super::{cell_kind, CellKind};
    assert_eq!(cell_kind(12), CellKind::Solid(8));
    assert_eq!(cell_kind(5), CellKind::LowerDim);
    assert_eq!(cell_kind(24), CellKind::HigherOrder);
    assert_eq!(cell_kind(42), CellKind::Polyhedron);
    assert_eq!(cell_kind(41), CellKind::Unsupported);
    assert_eq!(cell_kind(22), CellKind::LowerDim);
}
