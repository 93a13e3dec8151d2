//! One mesh of each kind the cell splitting reads (quadratic tetrahedra,
//! quadratic and triquadratic hexahedra, polyhedra written by VTK, a
//! crash-like twisted block whose cells are repaired, collapsed
//! hexahedra) rendered by `balanced` and `tet-raycast` on lavapipe with the
//! validation layer on, each within 2e-3 RMSE of the f64 reference. Small
//! meshes at 64x64; no timings.

mod common;

use volbench::harness::image::RgbaImage;
use volbench::harness::run::RunConfig;
use volbench::mesh::cells::RawCells;
use volbench::mesh::{HigherOrder, TetMesh};
use volbench::reference::render_reference_with_stats;
use volbench::scene::{Camera, ControlPoint, Projection, TransferFunction};

fn field(p: [f64; 3]) -> f64 {
    p[0] * p[0] + 0.5 * p[1] * p[2] - 0.3 * p[2] * p[2] + 2.0 * p[0]
}

/// Cells on integer lattice points (divided by `scale`), numbered by a
/// shuffle of `seed` so the quad diagonals vary.
struct Builder {
    at: std::collections::HashMap<[i64; 3], u32>,
    points: Vec<[f64; 3]>,
    cells: Vec<(u8, Vec<u32>)>,
    scale: f64,
}

impl Builder {
    fn new(scale: f64) -> Builder {
        Builder { at: Default::default(), points: Vec::new(), cells: Vec::new(), scale }
    }
    fn point(&mut self, q: [i64; 3]) -> u32 {
        let n = self.points.len() as u32;
        let s = self.scale;
        let points = &mut self.points;
        *self.at.entry(q).or_insert_with(|| {
            points.push(q.map(|x| x as f64 / s));
            n
        })
    }
    fn raw(&self, seed: u64) -> RawCells {
        let n = self.points.len();
        let mut perm: Vec<u32> = (0..n as u32).collect();
        let mut r = seed.wrapping_mul(0x9E3779B97F4A7C15) | 1;
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

const HEX: [[i64; 3]; 8] = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]];

/// VTK's node order of the 20- and 27-node hexahedra on a lattice of step 1/2.
fn quadratic_hex_nodes(nodes: usize) -> Vec<[i64; 3]> {
    let mut v: Vec<[i64; 3]> = HEX.iter().map(|c| c.map(|x| 2 * x)).collect();
    let mid = |a: usize, b: usize| -> [i64; 3] { std::array::from_fn(|k| HEX[a][k] + HEX[b][k]) };
    for (a, b) in [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7)] {
        v.push(mid(a, b));
    }
    if nodes == 27 {
        // Face centres x-, x+, y-, y+, z-, z+ and the body centre.
        v.extend([[0, 1, 1], [2, 1, 1], [1, 0, 1], [1, 2, 1], [1, 1, 0], [1, 1, 2], [1, 1, 1]]);
    }
    v
}

fn quadratic_hexes(n: i64) -> TetMesh {
    let mut b = Builder::new(2.0);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let nodes = if (i + j + k) % 2 == 0 { 20 } else { 27 };
                let v: Vec<u32> = quadratic_hex_nodes(nodes).iter().map(|q| b.point([2 * i + q[0], 2 * j + q[1], 2 * k + q[2]])).collect();
                b.cells.push((if nodes == 20 { 25 } else { 29 }, v));
            }
        }
    }
    b.raw(3).into_tet_mesh_with("hex.vtu", "hex".into(), HigherOrder::Subdivide).unwrap()
}

fn quadratic_tets(n: i64) -> TetMesh {
    let mut b = Builder::new(2.0);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                for perm in [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]] {
                    let mut c = [0i64; 3];
                    let mut path = vec![c];
                    for &a in &perm {
                        c[a] = 1;
                        path.push(c);
                    }
                    let mut t: Vec<[i64; 3]> = path.iter().map(|c| [2 * (i + c[0]), 2 * (j + c[1]), 2 * (k + c[2])]).collect();
                    let s = |x: [i64; 3], y: [i64; 3]| [x[0] - y[0], x[1] - y[1], x[2] - y[2]];
                    let (u, v, w) = (s(t[1], t[0]), s(t[2], t[0]), s(t[3], t[0]));
                    let det = u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) + u[2] * (v[0] * w[1] - v[1] * w[0]);
                    if det < 0 {
                        t.swap(2, 3);
                    }
                    let mid = |a: usize, b: usize| -> [i64; 3] { std::array::from_fn(|x| (t[a][x] + t[b][x]) / 2) };
                    let mut nodes = t.clone();
                    for (a, b2) in [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)] {
                        nodes.push(mid(a, b2));
                    }
                    let ids: Vec<u32> = nodes.iter().map(|&q| b.point(q)).collect();
                    b.cells.push((24, ids));
                }
            }
        }
    }
    b.raw(5).into_tet_mesh_with("tet.vtu", "tet".into(), HigherOrder::Subdivide).unwrap()
}

/// A 3x3x1 block of hexahedra whose centre cell's top face is turned by
/// 0.9 rad: the first numbering whose split needs repairs.
fn twisted_block() -> TetMesh {
    for seed in 0..64 {
        let mut b = Builder::new(1.0);
        for j in 0..3 {
            for i in 0..3 {
                let v: Vec<u32> = HEX.iter().map(|c| b.point([i + c[0], j + c[1], c[2]])).collect();
                b.cells.push((12, v));
            }
        }
        let mut raw = b.raw(seed);
        let (s, c) = 0.9f64.sin_cos();
        for (k, p) in raw.points.iter_mut().enumerate() {
            if p[2] == 1.0 && (1.0..=2.0).contains(&p[0]) && (1.0..=2.0).contains(&p[1]) {
                let (x, y) = (p[0] - 1.5, p[1] - 1.5);
                *p = [1.5 + c * x - s * y, 1.5 + s * x + c * y, 1.0];
                raw.scalars[k] = field(*p);
            }
        }
        if let Ok(m) = raw.into_tet_mesh_with("twist.vtu", "twist".into(), HigherOrder::Subdivide) {
            let r = m.stats.repairs;
            if r.resplit_cells + r.centroid_split_cells > 0 {
                return m;
            }
        }
    }
    panic!("no numbering of the twisted block needed a repair");
}

/// A hexahedron, a hexahedron collapsed into a wedge beside it and one
/// collapsed into a pyramid on top.
fn collapsed() -> TetMesh {
    let mut b = Builder::new(1.0);
    let hex: Vec<u32> = HEX.iter().map(|&c| b.point(c)).collect();
    let (f1, f2) = (b.point([2, 0, 0]), b.point([2, 1, 0]));
    let apex = b.point([0, 0, 2]);
    b.cells.push((12, hex.clone()));
    b.cells.push((12, vec![hex[1], f1, f2, hex[2], hex[5], f1, f2, hex[6]]));
    b.cells.push((12, vec![hex[4], hex[5], hex[6], hex[7], apex, apex, apex, apex]));
    let m = b.raw(1).into_tet_mesh_with("collapsed.vtu", "collapsed".into(), HigherOrder::Subdivide).unwrap();
    assert_eq!(m.stats.repairs.degenerate_cells, 2);
    m
}

fn check(name: &str, mesh: &TetMesh) {
    let (lo, hi) = mesh.scalar_range();
    let d = mesh.bounds().diagonal();
    let tf = TransferFunction {
        name: "linear".into(),
        points: vec![
            ControlPoint { scalar: lo, color: [0.1, 0.2, 0.9], attenuation: 2.0 / d },
            ControlPoint { scalar: hi, color: [1.0, 0.5, 0.1], attenuation: 8.0 / d },
        ],
    };
    let size = 64;
    let camera = Camera::orbit(&mesh.bounds(), 0.6, Projection::Perspective { fovy_deg: 30.0 });
    let (r, _) = render_reference_with_stats(mesh, &camera, &tf, size, size).unwrap();
    let want = RgbaImage { width: size, height: size, pixels: r.pixels.iter().map(|p| p.map(|c| c as f32)).collect() };
    assert!(want.covered_pixels() > (size * size / 20) as usize, "{name}: the view must see the mesh");
    let cfg = RunConfig { width: size, height: size, frames: 1, warmup: 1, fixed_camera: Some(camera), ..RunConfig::default() };
    for spec in ["balanced", "tet-raycast"] {
        let out = common::run_mesh(mesh, &tf, spec, &cfg);
        let e = out.image.compare(&want).unwrap();
        eprintln!("{name} {spec}: RMSE {:.3e} (max {:.3e})", e.rmse, e.max_abs);
        assert!(e.rmse <= 2e-3, "{name} {spec}: RMSE {}", e.rmse);
    }
}

#[test]
fn every_kind_of_split_cell_renders_like_the_reference() {
    check("quadratic tetra", &quadratic_tets(2));
    check("quadratic and triquadratic hexahedra", &quadratic_hexes(2));
    let poly = volbench::mesh::vtu::parse_vtu_bytes("polyhedra.vtu", include_bytes!("fixtures/polyhedra_appended.vtu"), None).unwrap();
    assert_eq!(poly.stats.polyhedra, 4);
    check("polyhedra (VTK 9.7)", &poly);
    let twisted = twisted_block();
    eprintln!("twisted block repairs: {:?}", twisted.stats.repairs);
    check("twisted block", &twisted);
    check("collapsed hexahedra", &collapsed());
}

/// `--higher-order` is a global option, checked by clap; the result
/// records the mode (`dataset.stats.higher_order`).
#[test]
fn the_higher_order_option_is_checked() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_volbench")).args(["--higher-order", "cubic", "list"]).output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--higher-order") && err.contains("subdivide") && err.contains("corners"), "{err}");
}
