//! The CPU reference renderer against closed forms: homogeneous slabs seen
//! along the grid (rays along edges, in faces, through vertices), oblique and
//! perspective views (chord lengths by box clipping), linear ramps through a
//! tet, non-convex meshes, touching parts, a flat (zero-volume) cell.
//! Tolerance 1e-9 everywhere (the renderer is exact up to f64 rounding).

use std::time::Instant;

use volbench::mesh::TetMesh;
use volbench::reference::{
    integrate_segment, render_reference, render_reference_with_stats, ReferenceStats,
};
use volbench::scene::{Camera, ControlPoint, Projection, TransferFunction};

const TOL: f64 = 1e-9;

// ---------------------------------------------------------------- meshes

fn det(p: &[[f64; 3]], t: [u32; 4]) -> f64 {
    let p0 = p[t[0] as usize];
    let e = |k: usize| {
        let q = p[t[k] as usize];
        [q[0] - p0[0], q[1] - p0[1], q[2] - p0[2]]
    };
    let (a, b, c) = (e(1), e(2), e(3));
    a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
        + a[2] * (b[0] * c[1] - b[1] * c[0])
}

fn oriented(p: &[[f64; 3]], mut t: [u32; 4]) -> [u32; 4] {
    if det(p, t) < 0.0 {
        t.swap(2, 3);
    }
    t
}

#[derive(Clone, Copy, Debug)]
enum Split {
    /// 6 tets around the main diagonal of every cube (Kuhn/Freudenthal).
    Six,
    /// 5 tets, mirrored pattern on alternate cubes (as the PLOT3D loader does).
    Five,
}

/// A box of n[0]×n[1]×n[2] cubes of edge `h` from `origin`, split into tets;
/// vertex scalars from `scalar(position)`.
fn grid_mesh(
    n: [usize; 3],
    h: f64,
    origin: [f64; 3],
    split: Split,
    scalar: impl Fn([f64; 3]) -> f64,
) -> TetMesh {
    let idx = |i: usize, j: usize, k: usize| (i + (n[0] + 1) * (j + (n[1] + 1) * k)) as u32;
    let mut points = Vec::new();
    for k in 0..=n[2] {
        for j in 0..=n[1] {
            for i in 0..=n[0] {
                points.push([
                    origin[0] + h * i as f64,
                    origin[1] + h * j as f64,
                    origin[2] + h * k as f64,
                ]);
            }
        }
    }
    let mut tets = Vec::new();
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                // Corner c = x + 2y + 4z.
                let c = |b: usize| idx(i + (b & 1), j + ((b >> 1) & 1), k + ((b >> 2) & 1));
                match split {
                    Split::Six => {
                        for perm in [
                            [1, 2, 4],
                            [1, 4, 2],
                            [2, 1, 4],
                            [2, 4, 1],
                            [4, 1, 2],
                            [4, 2, 1],
                        ] {
                            let (a, b) = (perm[0], perm[0] + perm[1]);
                            tets.push(oriented(&points, [c(0), c(a), c(b), c(7)]));
                        }
                    }
                    Split::Five => {
                        let list: [[usize; 4]; 5] = if (i + j + k) % 2 == 0 {
                            [
                                [0, 3, 5, 6],
                                [1, 0, 3, 5],
                                [2, 0, 3, 6],
                                [4, 0, 5, 6],
                                [7, 3, 5, 6],
                            ]
                        } else {
                            [
                                [1, 2, 4, 7],
                                [0, 1, 2, 4],
                                [3, 1, 2, 7],
                                [5, 1, 4, 7],
                                [6, 2, 4, 7],
                            ]
                        };
                        for t in list {
                            tets.push(oriented(&points, [c(t[0]), c(t[1]), c(t[2]), c(t[3])]));
                        }
                    }
                }
            }
        }
    }
    let scalars = points.iter().map(|&p| scalar(p)).collect();
    TetMesh {
        name: format!("grid{n:?}{split:?}"),
        points,
        scalars,
        tets,
        stats: Default::default(),
    }
}

/// Several meshes in one (vertex indices shifted, nothing merged).
fn union(parts: &[TetMesh]) -> TetMesh {
    let mut m = TetMesh {
        name: "union".into(),
        points: vec![],
        scalars: vec![],
        tets: vec![],
        stats: Default::default(),
    };
    for p in parts {
        let off = m.points.len() as u32;
        m.points.extend_from_slice(&p.points);
        m.scalars.extend_from_slice(&p.scalars);
        m.tets.extend(p.tets.iter().map(|t| t.map(|v| v + off)));
    }
    m
}

// ---------------------------------------------------------------- helpers

fn ortho(eye: [f64; 3], target: [f64; 3], up: [f64; 3], height: f64) -> Camera {
    Camera {
        eye,
        target,
        up,
        projection: Projection::Orthographic { height },
        near: 0.01,
        far: 100.0,
    }
}

fn tf_points(points: &[(f64, [f64; 3], f64)]) -> TransferFunction {
    TransferFunction {
        name: "test".into(),
        points: points
            .iter()
            .map(|&(scalar, color, attenuation)| ControlPoint {
                scalar,
                color,
                attenuation,
            })
            .collect(),
    }
}

/// Length of the line o + t·d (t ≥ 0) inside the box [lo, hi].
fn chord(o: [f64; 3], d: [f64; 3], lo: [f64; 3], hi: [f64; 3]) -> f64 {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for k in 0..3 {
        if d[k] == 0.0 {
            if o[k] < lo[k] || o[k] > hi[k] {
                return 0.0;
            }
        } else {
            let (a, b) = ((lo[k] - o[k]) / d[k], (hi[k] - o[k]) / d[k]);
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
    }
    (t1 - t0).max(0.0)
}

/// The chords of the ray and of four copies moved by ±1e-10 across it: a ray
/// that grazes a box face or lies in it may legitimately take any of them.
fn chord_candidates(o: [f64; 3], d: [f64; 3], boxes: &[([f64; 3], [f64; 3])]) -> Vec<f64> {
    let a = if d[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let n1 = normalize(cross(d, a));
    let n2 = cross(d, n1);
    let mut out = Vec::new();
    for (s1, s2) in [
        (0.0, 0.0),
        (1.0, 0.3),
        (-1.0, 0.3),
        (0.3, 1.0),
        (0.3, -1.0),
        (1.0, 1.0),
        (-1.0, -1.0),
        (1.0, -1.0),
        (-1.0, 1.0),
    ] {
        let e = 1e-10;
        let oo = [0, 1, 2].map(|k| o[k] + e * (s1 * n1[k] + s2 * n2[k]));
        out.push(boxes.iter().map(|&(lo, hi)| chord(oo, d, lo, hi)).sum());
    }
    out
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

/// No sign pattern needed the fallback rule, no walk was cut short.
fn assert_no_anomalies(stats: &ReferenceStats) {
    assert_eq!(stats.fallback_exits, 0, "{stats:?}");
    assert_eq!(stats.aborted_walks, 0, "{stats:?}");
    assert_eq!(stats.skipped_entries, 0, "{stats:?}");
}

/// Renders a constant medium (colour `l`, attenuation `tau`) and checks every
/// pixel against the total chord through `boxes`: α = 1 − e^{−τ·chord},
/// colour = l·α. A ray that grazes or lies in a box face may take the chord
/// of any nearby ray. Returns the traversal stats.
fn check_homogeneous(
    mesh: &TetMesh,
    boxes: &[([f64; 3], [f64; 3])],
    cam: &Camera,
    w: u32,
    h: u32,
) -> ReferenceStats {
    let (l, tau) = ([0.2, 0.5, 0.8], 1.7);
    let tf = TransferFunction::constant(l, tau);
    let (img, stats) = render_reference_with_stats(mesh, cam, &tf, w, h).unwrap();
    let mut hits = 0;
    for y in 0..h {
        for x in 0..w {
            let (o, d) = cam.ray(x as f64, y as f64, w, h);
            let cands = chord_candidates(o.into(), d.into(), boxes);
            let px = img.get(x, y);
            let alphas: Vec<f64> = cands.iter().map(|c| 1.0 - (-tau * c).exp()).collect();
            if alphas[0] > 0.0 {
                hits += 1;
            }
            assert!(
                alphas.iter().any(|a| (px[3] - a).abs() <= TOL),
                "{}: pixel ({x},{y}) alpha {} not in {alphas:?} (o={o}, d={d})",
                mesh.name,
                px[3]
            );
            for i in 0..3 {
                assert!(
                    (px[i] - l[i] * px[3]).abs() <= TOL,
                    "{}: pixel ({x},{y}) colour {px:?}",
                    mesh.name
                );
            }
        }
    }
    assert!(hits > 0, "{}: the view misses the mesh", mesh.name);
    assert_eq!(
        (stats.aborted_walks, stats.skipped_entries),
        (0, 0),
        "{stats:?}"
    );
    stats
}

// ---------------------------------------------------------------- tests

/// Views along the grid axes with pixel centres exactly on grid lines and on
/// cube mid-lines: rays run along mesh edges (4–8 cells around them), lie in
/// cube faces and in the diagonal faces of the splits, and pass through
/// vertices. Every ray strictly inside the slab's silhouette must see the
/// full thickness exactly once: α = 1 − e^{−τ·thickness}.
#[test]
fn homogeneous_slab_axis_views_rays_along_edges_and_faces() {
    for split in [Split::Six, Split::Five] {
        let mesh = grid_mesh([4, 3, 2], 0.25, [0.0; 3], split, |_| 0.0);
        let bx = [([0.0, 0.0, 0.0], [1.0, 0.75, 0.5])];
        // 16×16 pixels, height 2: centres at eye ± (2k+1)/16, all exact in
        // binary; eye offsets of 1/16 put them on multiples of 1/8.
        let c = [0.5 + 1.0 / 16.0, 0.375 + 1.0 / 16.0, 0.25 + 1.0 / 16.0];
        let views = [
            ([c[0], c[1], 5.0], [c[0], c[1], 0.0], [0.0, 1.0, 0.0]), // looking down −z
            ([c[0], c[1], -5.0], [c[0], c[1], 0.0], [0.0, 1.0, 0.0]), // +z
            ([5.0, c[1], c[2]], [0.0, c[1], c[2]], [0.0, 0.0, 1.0]), // −x
            ([c[0], -5.0, c[2]], [c[0], 0.0, c[2]], [1.0, 0.0, 0.0]), // +y
        ];
        for (eye, target, up) in views {
            let cam = ortho(eye, target, up, 2.0);
            // Sanity: the pixel centres really are exact grid coordinates.
            let (o, _) = cam.ray(7.0, 7.0, 16, 16);
            let o: [f64; 3] = o.into();
            assert!(o.iter().all(|v| (v * 8.0).fract() == 0.0), "{o:?}");
            // Exact zeros are resolved by the symbolic perturbation alone.
            assert_no_anomalies(&check_homogeneous(&mesh, &bx, &cam, 16, 16));
        }
    }
}

/// Oblique orthographic and perspective views in general position (and the
/// main diagonal direction of the Kuhn cubes): α against the box chord.
/// Rays that pass within rounding of a vertex, or along an edge that is
/// parallel to them only up to rounding (the diagonal view), may need the
/// fallback exit rule; the pixels must be right all the same.
#[test]
fn homogeneous_slab_oblique_and_perspective_views() {
    for split in [Split::Six, Split::Five] {
        let mesh = grid_mesh([5, 4, 3], 0.2, [-0.5, -0.4, -0.3], split, |_| 0.0);
        let bx = [([-0.5, -0.4, -0.3], [0.5, 0.4, 0.3])];
        let cams = [
            ortho([2.3, 1.7, 3.1], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 1.6),
            ortho([3.0, 3.0, 3.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 1.6), // along the cube diagonals
            ortho([0.0, 0.0, 4.0], [0.0, 0.0, 0.0], [0.3, 1.0, 0.0], 1.3), // rolled
            Camera {
                eye: [1.9, -1.3, 2.2],
                target: [0.05, 0.0, -0.02],
                up: [0.0, 0.0, 1.0],
                projection: Projection::Perspective { fovy_deg: 40.0 },
                near: 0.1,
                far: 20.0,
            },
            Camera {
                eye: [0.0, 0.0, 2.0],
                target: [0.0, 0.0, 0.0],
                up: [0.0, 1.0, 0.0],
                projection: Projection::Perspective { fovy_deg: 45.0 },
                near: 0.1,
                far: 20.0,
            },
        ];
        for cam in &cams {
            check_homogeneous(&mesh, &bx, cam, 41, 37);
        }
    }
}

/// One tet, scalar = z, seen along +z from below: the ray through (x, y)
/// enters at z = 0 and leaves at z = D = 1 − x − y, with s going 0 → D.
/// Transfer functions linear in s; closed forms (ι = ∫τ, T = e^{−ι}):
///   α = 1 − e^{−ι(D)},  C = ∫ L τ T dz = L(0) − L(D)·T(D) + L'·∫₀ᴰ T dz.
#[test]
fn linear_ramp_through_one_tet() {
    let mesh = TetMesh {
        name: "one tet".into(),
        points: vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ],
        scalars: vec![0.0, 0.0, 0.0, 1.0],
        tets: vec![[0, 1, 2, 3]],
        stats: Default::default(),
    };
    let cam = ortho([0.3, 0.3, -3.0], [0.3, 0.3, 0.0], [0.0, 1.0, 0.0], 1.4);
    let (l0, l1) = ([1.0, 0.0, 0.5], [0.0, 1.0, 0.25]);
    // (τ at s = 0, τ at s = 1)
    for (tau0, tau1) in [(2.0, 2.0), (0.5, 3.5), (4.0, 0.0), (0.0, 9.0), (30.0, 35.0)] {
        let tf = tf_points(&[(0.0, l0, tau0), (1.0, l1, tau1)]);
        let (img, stats) = render_reference_with_stats(&mesh, &cam, &tf, 24, 24).unwrap();
        assert_no_anomalies(&stats);
        let k = tau1 - tau0; // dτ/dz
        let mut inside = 0;
        for y in 0..24 {
            for x in 0..24 {
                let (o, _) = cam.ray(x as f64, y as f64, 24, 24);
                let dd = 1.0 - o.x - o.y;
                let px = img.get(x, y);
                if o.x <= 1e-9 || o.y <= 1e-9 || dd <= 1e-9 {
                    if o.x < -1e-9 || o.y < -1e-9 || dd < -1e-9 {
                        assert_eq!(px, [0.0; 4], "outside pixel ({x},{y})");
                    }
                    continue;
                }
                inside += 1;
                let iota = |z: f64| tau0 * z + 0.5 * k * z * z;
                let t_d = (-iota(dd)).exp();
                // ∫₀ᴰ T: closed form for constant τ, else composite Simpson
                // (independent of the renderer's quadrature).
                let int_t = if k == 0.0 {
                    if tau0 == 0.0 {
                        dd
                    } else {
                        -(-tau0 * dd).exp_m1() / tau0
                    }
                } else {
                    let n = 20000;
                    let hh = dd / n as f64;
                    let f = |z: f64| (-iota(z)).exp();
                    (0..n)
                        .map(|i| {
                            let a = i as f64 * hh;
                            hh / 6.0 * (f(a) + 4.0 * f(a + 0.5 * hh) + f(a + hh))
                        })
                        .sum()
                };
                let alpha = -(-iota(dd)).exp_m1();
                assert!(
                    (px[3] - alpha).abs() <= TOL,
                    "τ {tau0}->{tau1} ({x},{y}): α {} vs {alpha}",
                    px[3]
                );
                for i in 0..3 {
                    let ld = l0[i] + (l1[i] - l0[i]) * dd;
                    let c = l0[i] - ld * t_d + (l1[i] - l0[i]) * int_t;
                    assert!(
                        (px[i] - c).abs() <= TOL,
                        "τ {tau0}->{tau1} ({x},{y}) ch{i}: {} vs {c}",
                        px[i]
                    );
                }
            }
        }
        assert!(inside > 100);
    }
}

/// Brute-force emission–absorption along a ray whose scalar is linear in
/// depth, s(z) = s0 + (s1 − s0)·z/len: composite Simpson split at the control
/// points (samples nudged inside each stretch so steps take the right side).
fn brute_ray(tf: &TransferFunction, s0: f64, s1: f64, len: f64) -> [f64; 4] {
    let mut cuts = vec![0.0, 1.0];
    for p in &tf.points {
        let u = (p.scalar - s0) / (s1 - s0);
        if u > 0.0 && u < 1.0 {
            cuts.push(u);
        }
    }
    cuts.sort_by(f64::total_cmp);
    let (mut depth, mut col) = (0.0f64, [0.0f64; 3]);
    for w in cuts.windows(2) {
        let (ua, ub) = (w[0], w[1]);
        let at = |u: f64| {
            tf.eval(s0 + (s1 - s0) * u.clamp(ua + 1e-12 * (ub - ua), ub - 1e-12 * (ub - ua)))
        };
        let n = 4000;
        let h = (ub - ua) / n as f64;
        for k in 0..n {
            let u0 = ua + k as f64 * h;
            let ((c0, t0), (cm, tm), (c1, t1)) = (at(u0), at(u0 + 0.5 * h), at(u0 + h));
            let dm = depth + 0.25 * h * len * (t0 + tm);
            let d1 = depth + h * len / 6.0 * (t0 + 4.0 * tm + t1);
            let (w0, wm, w1) = (t0 * (-depth).exp(), tm * (-dm).exp(), t1 * (-d1).exp());
            for i in 0..3 {
                col[i] += h * len / 6.0 * (c0[i] * w0 + 4.0 * cm[i] * wm + c1[i] * w1);
            }
            depth = d1;
        }
    }
    [col[0], col[1], col[2], -(-depth).exp_m1()]
}

/// A slab of cubes with scalar linear in z and a transfer function with
/// several control points and a step: along every ray the scalar is linear,
/// so the composite over all cells must equal one segment's integral
/// (brute force), with pixel centres on grid lines and diagonal faces.
#[test]
fn ramp_through_slab_matches_single_segment() {
    let tf = tf_points(&[
        (0.1, [0.0, 0.0, 1.0], 0.0),
        (0.3, [0.0, 1.0, 0.0], 2.0),
        (0.5, [1.0, 0.0, 0.0], 6.0),
        (0.5, [0.2, 0.2, 0.2], 0.5),
        (0.9, [1.0, 1.0, 0.0], 3.0),
    ]);
    let scalar = |p: [f64; 3]| 0.05 + 0.4 * p[2];
    for split in [Split::Six, Split::Five] {
        let mesh = grid_mesh([4, 3, 8], 0.25, [0.0; 3], split, scalar);
        let (zmax, xmax, ymax) = (2.0, 1.0, 0.75);
        let c = [0.5 + 1.0 / 16.0, 0.375 + 1.0 / 16.0];
        for (eye_z, tgt_z) in [(5.0, 0.0), (-5.0, 0.0)] {
            let cam = ortho(
                [c[0], c[1], eye_z],
                [c[0], c[1], tgt_z],
                [0.0, 1.0, 0.0],
                2.0,
            );
            let (img, stats) = render_reference_with_stats(&mesh, &cam, &tf, 16, 16).unwrap();
            assert_no_anomalies(&stats);
            let (s_front, s_back) = if eye_z > 0.0 {
                (scalar([0.0, 0.0, zmax]), scalar([0.0; 3]))
            } else {
                (scalar([0.0; 3]), scalar([0.0, 0.0, zmax]))
            };
            let expect = brute_ray(&tf, s_front, s_back, zmax);
            let seg = integrate_segment(&tf, s_front, s_back, zmax).rgba();
            for i in 0..4 {
                assert!(
                    (seg[i] - expect[i]).abs() <= TOL,
                    "segment vs brute ch{i}: {} {}",
                    seg[i],
                    expect[i]
                );
            }
            for y in 0..16 {
                for x in 0..16 {
                    let (o, _) = cam.ray(x as f64, y as f64, 16, 16);
                    let on_edge = o.x == 0.0 || o.x == xmax || o.y == 0.0 || o.y == ymax;
                    let inside = o.x > 0.0 && o.x < xmax && o.y > 0.0 && o.y < ymax;
                    let px = img.get(x, y);
                    if inside {
                        for i in 0..4 {
                            assert!(
                                (px[i] - expect[i]).abs() <= TOL,
                                "{split:?} ({x},{y}) ch{i}: {} vs {}",
                                px[i],
                                expect[i]
                            );
                        }
                    } else if on_edge {
                        // On the silhouette: the perturbed ray is either in or out.
                        assert!(
                            px == [0.0; 4] || (0..4).all(|i| (px[i] - expect[i]).abs() <= TOL),
                            "{px:?}"
                        );
                    } else {
                        assert_eq!(px, [0.0; 4]);
                    }
                }
            }
        }
    }
}

/// Two separate cubes one behind the other (a gap between them), a box with
/// a hole (the middle cube of a 3×1×3 block removed), and two blocks whose
/// faces touch without sharing vertices (each face is a boundary face, exit
/// and re-entry at the same depth): α = 1 − e^{−τ·(total chord)}.
#[test]
fn non_convex_meshes() {
    for split in [Split::Six, Split::Five] {
        // Separated along z: [0,1]³ and [0,1]²×[2,3].
        let a = grid_mesh([2, 2, 2], 0.5, [0.0, 0.0, 0.0], split, |_| 0.0);
        let b = grid_mesh([2, 2, 2], 0.5, [0.0, 0.0, 2.0], split, |_| 0.0);
        let two = union(&[a.clone(), b]);
        let boxes = [
            ([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]),
            ([0.0, 0.0, 2.0], [1.0, 1.0, 3.0]),
        ];
        let c = 0.5 + 1.0 / 16.0;
        assert_no_anomalies(&check_homogeneous(
            &two,
            &boxes,
            &ortho([c, c, 9.0], [c, c, 0.0], [0.0, 1.0, 0.0], 2.0),
            16,
            16,
        ));
        assert_no_anomalies(&check_homogeneous(
            &two,
            &boxes,
            &ortho([c, c, -9.0], [c, c, 0.0], [0.0, 1.0, 0.0], 2.0),
            16,
            16,
        ));
        check_homogeneous(
            &two,
            &boxes,
            &ortho([2.0, 1.5, 6.0], [0.5, 0.5, 1.5], [0.0, 1.0, 0.0], 3.0),
            33,
            31,
        );
        // A single ray through both cubes, by hand.
        let tf = TransferFunction::constant([1.0, 0.5, 0.25], 0.9);
        let img = render_reference(
            &two,
            &ortho([0.3, 0.6, 9.0], [0.3, 0.6, 0.0], [0.0, 1.0, 0.0], 1.0),
            &tf,
            1,
            1,
        )
        .unwrap();
        let alpha = 1.0 - (-0.9f64 * (1.0 + 1.0)).exp();
        assert!(
            (img.pixels[0][3] - alpha).abs() <= TOL && (img.pixels[0][0] - alpha).abs() <= TOL,
            "{:?}",
            img.pixels[0]
        );

        // A 3×1×3 block of unit cubes with the middle one missing.
        let mut holed = grid_mesh([3, 1, 3], 1.0, [0.0; 3], split, |_| 0.0);
        let per_cube = match split {
            Split::Six => 6,
            Split::Five => 5,
        };
        let middle = 4; // cube (i, j, k) = (1, 0, 1): i + 3·(j + k)
        holed.tets.drain(middle * per_cube..(middle + 1) * per_cube);
        let boxes: Vec<_> = (0..3)
            .flat_map(|k| (0..3).map(move |i| (i, k)))
            .filter(|&(i, k)| !(i == 1 && k == 1))
            .map(|(i, k)| {
                (
                    [i as f64, 0.0, k as f64],
                    [i as f64 + 1.0, 1.0, k as f64 + 1.0],
                )
            })
            .collect();
        assert_no_anomalies(&check_homogeneous(
            &holed,
            &boxes,
            &ortho(
                [1.5 + 1.0 / 8.0, 0.5 + 1.0 / 8.0, 9.0],
                [1.5 + 1.0 / 8.0, 0.5 + 1.0 / 8.0, 0.0],
                [0.0, 1.0, 0.0],
                4.0,
            ),
            16,
            16,
        ));
        check_homogeneous(
            &holed,
            &boxes,
            &ortho([4.0, 2.5, 6.0], [1.5, 0.5, 1.5], [0.0, 1.0, 0.0], 5.0),
            40,
            40,
        );

        // Touching along z = 1 with duplicated vertices.
        let top = grid_mesh([2, 2, 2], 0.5, [0.0, 0.0, 1.0], split, |_| 0.0);
        let touching = union(&[a, top]);
        let boxes = [
            ([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]),
            ([0.0, 0.0, 1.0], [1.0, 1.0, 2.0]),
        ];
        assert_no_anomalies(&check_homogeneous(
            &touching,
            &boxes,
            &ortho([c, c, 9.0], [c, c, 0.0], [0.0, 1.0, 0.0], 2.0),
            16,
            16,
        ));
        check_homogeneous(
            &touching,
            &boxes,
            &ortho([2.0, 1.5, 6.0], [0.5, 0.5, 1.0], [0.0, 1.0, 0.0], 3.0),
            33,
            31,
        );
    }
}

/// A square bipyramid whose upper half is split along one diagonal of the
/// square and lower half along the other, glued by a *flat* tet (the four
/// square corners, zero volume), in either vertex order, also touching the
/// boundary (a version without the lower half): the walk must pass the flat
/// cell (contributing nothing) in both directions. Chord at (x, y):
/// (height above + below)·(1 − 2·max(|x − ½|, |y − ½|)).
#[test]
fn flat_cell_is_crossed_in_both_directions() {
    let points = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.5, 0.5, 0.8],  // p: apex above
        [0.5, 0.5, -0.6], // q: apex below
    ];
    let up_tets = [
        oriented(&points, [0, 1, 2, 4]),
        oriented(&points, [0, 2, 3, 4]),
    ];
    let down_tets = [
        oriented(&points, [0, 1, 3, 5]),
        oriented(&points, [1, 2, 3, 5]),
    ];
    let (l, tau) = ([0.3, 0.6, 0.9], 2.3);
    let tf = TransferFunction::constant(l, tau);
    for flat in [[0u32, 1, 2, 3], [0, 1, 3, 2], [3, 2, 1, 0], [2, 0, 1, 3]] {
        for with_lower in [true, false] {
            let mut tets = vec![up_tets[0], up_tets[1], flat];
            if with_lower {
                tets.extend_from_slice(&down_tets);
            }
            let mesh = TetMesh {
                name: "bipyramid".into(),
                points: points.clone(),
                scalars: vec![0.0; 6],
                tets,
                stats: Default::default(),
            };
            let height = if with_lower { 1.4 } else { 0.8 };
            for eye_z in [5.0, -5.0] {
                // Pixel centres on multiples of 1/8 (including both diagonals).
                let cam = ortho(
                    [0.5 + 1.0 / 16.0, 0.5 + 1.0 / 16.0, eye_z],
                    [0.5 + 1.0 / 16.0, 0.5 + 1.0 / 16.0, 0.0],
                    [0.0, 1.0, 0.0],
                    2.0,
                );
                let (img, stats) = render_reference_with_stats(&mesh, &cam, &tf, 16, 16).unwrap();
                assert_eq!(stats.aborted_walks, 0);
                for y in 0..16 {
                    for x in 0..16 {
                        let (o, _) = cam.ray(x as f64, y as f64, 16, 16);
                        let m = (o.x - 0.5).abs().max((o.y - 0.5).abs());
                        let px = img.get(x, y);
                        if m >= 0.5 {
                            if m > 0.5 {
                                assert_eq!(px, [0.0; 4]);
                            }
                            continue;
                        }
                        let alpha = 1.0 - (-tau * height * (1.0 - 2.0 * m)).exp();
                        assert!((px[3] - alpha).abs() <= TOL, "flat {flat:?} lower {with_lower} eye {eye_z} ({x},{y}) m={m}: {} vs {alpha}", px[3]);
                        for i in 0..3 {
                            assert!((px[i] - l[i] * alpha).abs() <= TOL);
                        }
                    }
                }
            }
        }
    }
}

/// Depth clipping: a camera whose near plane cuts the slab sees only the part
/// beyond it.
#[test]
fn near_plane_clips_the_segment() {
    let mesh = grid_mesh([2, 2, 2], 0.5, [0.0; 3], Split::Six, |_| 0.0);
    let tf = TransferFunction::constant([1.0, 1.0, 1.0], 1.3);
    let mut cam = ortho([0.3, 0.4, 3.0], [0.3, 0.4, 0.0], [0.0, 1.0, 0.0], 0.5);
    cam.near = 2.4; // the slab spans depth 2..3: 0.6 remains
    let img = render_reference(&mesh, &cam, &tf, 1, 1).unwrap();
    let alpha = 1.0 - (-1.3f64 * 0.6).exp();
    assert!(
        (img.pixels[0][3] - alpha).abs() <= TOL,
        "{:?}",
        img.pixels[0]
    );
}

/// Large-mesh timing (run with `cargo test --release --test reference_analytic
/// -- --ignored --nocapture`): the oxygen post (513,375 tets) if its data is
/// present, and a synthetic 44³-cube Kuhn grid (511,104 tets), 512×512.
#[test]
#[ignore]
fn large_mesh_timing() {
    let tf = tf_points(&[
        (0.0, [0.0, 0.0, 0.5], 0.0),
        (0.3, [0.0, 0.6, 1.0], 1.0),
        (0.7, [1.0, 0.8, 0.0], 4.0),
        (1.4, [1.0, 0.0, 0.0], 10.0),
    ]);
    let mut meshes = Vec::new();
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data");
    match volbench::mesh::datasets::load_oxygenpost(&data) {
        Ok(m) => meshes.push(m),
        Err(e) => println!("oxygen post not loaded: {e:#}"),
    }
    meshes.push(grid_mesh(
        [44, 44, 44],
        1.0 / 44.0,
        [0.0; 3],
        Split::Six,
        |p| 0.7 + 0.5 * ((6.0 * p[0]).sin() * (5.0 * p[1]).cos() + (4.0 * p[2]).sin() * 0.5),
    ));
    for mesh in &meshes {
        let b = mesh.bounds();
        // Rescale the transfer function to the mesh's scalar range.
        let (smin, smax) = mesh.scalar_range();
        let mut tf = tf.clone();
        for p in &mut tf.points {
            p.scalar = smin + (smax - smin) * p.scalar / 1.4;
            p.attenuation *= 2.0 / b.diagonal();
        }
        for projection in [
            Projection::Perspective { fovy_deg: 30.0 },
            Projection::Orthographic { height: 1.0 },
        ] {
            let cam = Camera::orbit(&b, 0.6, projection);
            let t = Instant::now();
            let (img, stats) = render_reference_with_stats(mesh, &cam, &tf, 512, 512).unwrap();
            let el = t.elapsed();
            let mean_a: f64 =
                img.pixels.iter().map(|p| p[3]).sum::<f64>() / img.pixels.len() as f64;
            println!(
                "{} ({} tets, {} threads) {:?} 512x512: {:.2} s, mean alpha {:.4}, {:?}",
                mesh.name,
                mesh.tets.len(),
                rayon::current_num_threads(),
                projection,
                el.as_secs_f64(),
                mean_a,
                stats
            );
        }
    }
}

/// Independent check on the real meshes (run with `--ignored`, needs
/// `data/`): for a sample of pixels, clip the ray against *every* tet
/// (Cyrus–Beck on the four face planes, scalar from the tet's gradient), sort
/// the intervals, composite them with `integrate_segment`, and compare with
/// the walking renderer.
#[test]
#[ignore]
fn real_meshes_match_per_ray_brute_force() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data");
    type Loader = fn(&std::path::Path) -> anyhow::Result<TetMesh>;
    let loaders: [(&str, Loader); 2] = [
        ("bluntfin", volbench::mesh::datasets::load_bluntfin),
        ("oxygenpost", volbench::mesh::datasets::load_oxygenpost),
    ];
    for (name, load) in loaders {
        let mesh = match load(&data) {
            Ok(m) => m,
            Err(e) => {
                println!("{name} not loaded: {e:#}");
                continue;
            }
        };
        let (smin, smax) = mesh
            .scalars
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &s| {
                (a.min(s), b.max(s))
            });
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in &mesh.points {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let b = volbench::mesh::Bounds { min: lo, max: hi };
        let r = |u: f64| smin + (smax - smin) * u;
        let k = 3.0 / b.diagonal();
        let tf = tf_points(&[
            (r(0.0), [0.0, 0.0, 0.5], 0.2 * k),
            (r(0.3), [0.0, 0.6, 1.0], 1.0 * k),
            (r(0.5), [1.0, 0.8, 0.0], 4.0 * k),
            (r(0.5), [0.3, 0.8, 0.0], 0.5 * k),
            (r(1.0), [1.0, 0.0, 0.0], 8.0 * k),
        ]);
        let (w, h) = (96u32, 96u32);
        for projection in [
            Projection::Perspective { fovy_deg: 30.0 },
            Projection::Orthographic { height: 1.0 },
        ] {
            let cam = Camera::orbit(&b, 1.1, projection);
            let (img, stats) = render_reference_with_stats(&mesh, &cam, &tf, w, h).unwrap();
            println!("{name} {projection:?}: {stats:?}");
            let mut worst = 0.0f64;
            let (mut checked, mut hit) = (0, 0);
            for py in (1..h).step_by(4) {
                for px in (2..w).step_by(4) {
                    let (o, d) = cam.ray(px as f64, py as f64, w, h);
                    let (o, d): ([f64; 3], [f64; 3]) = (o.into(), d.into());
                    let mut iv: Vec<(f64, f64, f64, f64)> = Vec::new();
                    for t in &mesh.tets {
                        if let Some(x) = clip_tet(&mesh, t, o, d) {
                            iv.push(x);
                        }
                    }
                    iv.sort_by(|a, b| a.0.total_cmp(&b.0));
                    let mut acc = volbench::reference::Segment::default();
                    for &(t0, t1, s0, s1) in &iv {
                        acc = acc.over(&integrate_segment(&tf, s0, s1, t1 - t0));
                    }
                    let want = acc.rgba();
                    let got = img.get(px, py);
                    for i in 0..4 {
                        worst = worst.max((want[i] - got[i]).abs());
                    }
                    checked += 1;
                    hit += (!iv.is_empty()) as usize;
                }
            }
            println!("{name} {projection:?}: {checked} pixels ({hit} on the mesh), max |walk − brute force| = {worst:e}");
            assert!(hit > 50);
            assert!(worst <= 1e-9);
        }
    }
}

/// The interval of the line o + t·d inside tet `t` and the scalars at its
/// ends: (t0, t1, s0, s1), if non-empty.
fn clip_tet(
    mesh: &TetMesh,
    t: &[u32; 4],
    o: [f64; 3],
    d: [f64; 3],
) -> Option<(f64, f64, f64, f64)> {
    let p = t.map(|v| mesh.points[v as usize]);
    let s = t.map(|v| mesh.scalars[v as usize]);
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let vol = det(&mesh.points, *t);
    if vol.is_nan() || vol <= 0.0 {
        return None;
    }
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for i in 0..4 {
        let [a, b, c] = [(i + 1) % 4, (i + 2) % 4, (i + 3) % 4].map(|k| p[k]);
        let mut n = cross(sub(b, a), sub(c, a));
        if dot(n, sub(p[i], a)) > 0.0 {
            n = n.map(|v| -v);
        }
        // Inside: n·(x − a) ≤ 0.
        let num = -dot(n, sub(o, a));
        let den = dot(n, d);
        if den == 0.0 {
            if num < 0.0 {
                return None;
            }
        } else if den > 0.0 {
            t1 = t1.min(num / den);
        } else {
            t0 = t0.max(num / den);
        }
    }
    if t1.is_nan() || t0.is_nan() || t1 <= t0 {
        return None;
    }
    // Linear scalar: s(x) = s0 + g·(x − p0), g = M⁻¹ Δs (Cramer).
    let (e1, e2, e3) = (sub(p[1], p[0]), sub(p[2], p[0]), sub(p[3], p[0]));
    let ds = [s[1] - s[0], s[2] - s[0], s[3] - s[0]];
    // Rows of M are e1, e2, e3; g = (ds1 (e2×e3) + ds2 (e3×e1) + ds3 (e1×e2)) / det.
    let (c23, c31, c12) = (cross(e2, e3), cross(e3, e1), cross(e1, e2));
    let g = [0, 1, 2].map(|k| (ds[0] * c23[k] + ds[1] * c31[k] + ds[2] * c12[k]) / vol);
    let at = |tt: f64| {
        s[0] + dot(
            g,
            sub([o[0] + tt * d[0], o[1] + tt * d[1], o[2] + tt * d[2]], p[0]),
        )
    };
    Some((t0, t1, at(t0), at(t1)))
}
