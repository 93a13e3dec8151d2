//! Property tests (proptest) of the view-independent tet geometry in
//! `mesh::geometry` (issue 4, item 4): gradients, face planes, the 3-float
//! plane identity, orientation by `validate`, and finiteness for nearly
//! degenerate and far-translated cells. Case counts are kept small so the
//! file runs in about a second in the dev profile; raise them with
//! `PROPTEST_CASES=10000 cargo test --test geometry_props`.

use proptest::prelude::*;
use volbench::mesh::geometry::{tet_det, MAX_ABS_VALUE};
use volbench::mesh::{MeshStats, TetMesh, TetPrecomputed};

type V3 = [f64; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V3, b: V3) -> V3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}
fn longest_edge(p: &[V3; 4]) -> f64 {
    let mut l: f64 = 0.0;
    for i in 0..4 {
        for j in i + 1..4 {
            l = l.max(norm(sub(p[i], p[j])));
        }
    }
    l
}

fn v3(r: f64) -> impl Strategy<Value = V3> {
    [-r..r, -r..r, -r..r]
}

fn unit() -> impl Strategy<Value = V3> {
    v3(1.0).prop_filter("non-zero direction", |d| norm(*d) > 0.1).prop_map(|d| d.map(|c| c / norm(d)))
}

/// A tet whose volume is not small against its longest edge
/// (`|det| >= 0.01 L^3`: aspect ratios of a few tens at worst), at any scale
/// from 1e-3 to 1e3 and any orientation.
fn shaped_tet() -> impl Strategy<Value = [V3; 4]> {
    shaped_tet_scaled(-3, 3)
}

/// [`shaped_tet`] at scales `10^lo..=10^hi`.
fn shaped_tet_scaled(lo: i32, hi: i32) -> impl Strategy<Value = [V3; 4]> {
    ([v3(1.0), v3(1.0), v3(1.0), v3(1.0)], lo..=hi, v3(10.0))
        .prop_map(|(p, e, off)| {
            let s = 10f64.powi(e);
            p.map(|q| [q[0] * s + off[0] * s, q[1] * s + off[1] * s, q[2] * s + off[2] * s])
        })
        .prop_filter("well-shaped tet", |p| tet_det(*p).0.abs() >= 0.01 * longest_edge(p).powi(3))
}

fn config(cases: u32) -> ProptestConfig {
    ProptestConfig { cases, failure_persistence: None, ..ProptestConfig::default() }
}

fn all_finite(t: &TetPrecomputed) -> bool {
    t.gradient.iter().chain(t.planes.iter().flatten()).chain([&t.volume]).all(|v| v.is_finite())
}

proptest! {
    #![proptest_config(config(256))]

    /// A linear field `s = g·x + c` sampled at the vertices gives back `g`.
    #[test]
    fn gradient_is_exact_for_linear_fields(p in shaped_tet(), g in v3(100.0), c in -1e3..1e3f64) {
        let s = p.map(|q| dot(g, q) + c);
        let t = TetPrecomputed::from_vertices(p, s);
        prop_assert!(!t.degenerate);
        // Rounding of the scalars (|s| up to |g| |x| + |c|) over an edge L,
        // amplified by the shape's conditioning (|det| >= 0.01 L^3).
        let x_max = p.iter().map(|q| norm(*q)).fold(0.0, f64::max);
        let tol = 1e-11 * (norm(g) * (1.0 + x_max / longest_edge(&p)) + c.abs() / longest_edge(&p));
        for k in 0..3 {
            prop_assert!((t.gradient[k] - g[k]).abs() <= tol, "gradient {:?} vs {g:?} (tol {tol:e})", t.gradient);
        }
        prop_assert!((t.volume - tet_det(p).0.abs() / 6.0).abs() <= 1e-15 * t.volume);
    }

    /// Each plane has a unit normal, passes through its three face vertices,
    /// has the opposite vertex strictly inside and points out of the tet.
    #[test]
    fn planes_are_outward_and_through_their_faces(p in shaped_tet()) {
        let t = TetPrecomputed::from_vertices(p, [0.0; 4]);
        let l = longest_edge(&p);
        let x_max = p.iter().map(|q| norm(*q)).fold(0.0, f64::max);
        let centroid: V3 = std::array::from_fn(|k| p.iter().map(|q| q[k]).sum::<f64>() / 4.0);
        for i in 0..4 {
            let [nx, ny, nz, a] = t.planes[i];
            let n = [nx, ny, nz];
            prop_assert!((norm(n) - 1.0).abs() < 1e-14);
            let eval = |q: V3| dot(n, q) + a;
            for (j, &q) in p.iter().enumerate() {
                if j != i {
                    prop_assert!(eval(q).abs() <= 1e-13 * (l + x_max), "vertex {j} off plane {i}: {}", eval(q));
                }
            }
            // Inside: the opposite vertex and the centroid (by a margin: the
            // tet is well shaped, so heights are >= ~0.01 L / 2).
            prop_assert!(eval(p[i]) < -1e-3 * l);
            prop_assert!(eval(centroid) < 0.0);
            // Outward: the normal points from the centroid towards the face.
            let fc: V3 = std::array::from_fn(|k| (0..4).filter(|&j| j != i).map(|j| p[j][k]).sum::<f64>() / 3.0);
            prop_assert!(dot(n, sub(fc, centroid)) > 0.0);
        }
    }

    /// The 3-float plane `n' = n / (n·v + a)` at vertex `v` gives the exit
    /// distance along a unit ray as `t = -1 / (n'·d)`, equal to the f64
    /// ray-plane distance `-(n·v + a) / (n·d)`.
    #[test]
    fn three_float_plane_gives_the_ray_plane_distance(p in shaped_tet(), d in unit(), i in 0usize..4) {
        let t = TetPrecomputed::from_vertices(p, [0.0; 4]);
        let [nx, ny, nz, a] = t.planes[i];
        let n = [nx, ny, nz];
        let nd = dot(n, d);
        prop_assume!(nd.abs() > 1e-3);
        let t_ref = -(dot(n, p[i]) + a) / nd;
        let n3 = t.opposite_plane_3(p[i], i);
        let t3 = -1.0 / dot(n3, d);
        prop_assert!((t3 - t_ref).abs() <= 1e-9 * t_ref.abs(), "{t3} vs {t_ref}");
        // The point reached lies on the face's plane.
        let q: V3 = std::array::from_fn(|k| p[i][k] + t3 * d[k]);
        let x_max = p.iter().chain([&q]).map(|v| norm(*v)).fold(0.0, f64::max);
        prop_assert!((dot(n, q) + a).abs() <= 1e-9 * (longest_edge(&p) + x_max));
    }

    /// `validate` reorients exactly the negatively oriented cells (keeping
    /// each cell's vertex set) and leaves every non-degenerate cell with
    /// positive volume.
    #[test]
    fn validate_reorients_negative_tets(
        tets in prop::collection::vec((shaped_tet(), any::<bool>()), 1..20),
    ) {
        let mut points = Vec::new();
        let mut cells = Vec::new();
        let mut negative = 0;
        for (c, (p, flip)) in tets.iter().enumerate() {
            let mut p = *p;
            if *flip {
                p.swap(0, 1);
            }
            negative += (tet_det(p).0 < 0.0) as usize;
            points.extend_from_slice(&p);
            let b = 4 * c as u32;
            cells.push([b, b + 1, b + 2, b + 3]);
        }
        let scalars = points.iter().map(|q| q[0] - q[2]).collect();
        let before = cells.clone();
        let mut m = TetMesh { name: "p".into(), points, scalars, tets: cells, stats: MeshStats::default() };
        m.validate("prop").unwrap();
        prop_assert_eq!(m.stats.reoriented, negative);
        for (c, t) in m.tets.iter().enumerate() {
            prop_assert!(tet_det(m.tet_points(c)).0 > 0.0);
            let (mut x, mut y) = (*t, before[c]);
            x.sort();
            y.sort();
            prop_assert_eq!(x, y);
            let g = TetPrecomputed::from_vertices(m.tet_points(c), m.tet_scalars(c));
            prop_assert!(!g.degenerate && g.volume > 0.0);
        }
        // Idempotent.
        m.validate("prop").unwrap();
        prop_assert_eq!(m.stats.reoriented, negative);
    }
}

/// Slivers, needles and caps: a base triangle of size up to `size`, the
/// fourth vertex at a height giving a volume down to 1e-12 of the bounding
/// box, or on a base edge / at a base vertex; everything translated 1e3..1e7
/// away from the origin; scalars from 1e-6 to 1e6.
fn hard_tet() -> impl Strategy<Value = ([V3; 4], [f64; 4])> {
    (
        [v3(1.0), v3(1.0), v3(1.0)],
        (0.0..1.0f64, 0.0..1.0f64),
        -12i32..=0,
        prop_oneof![Just(0u8), Just(1), Just(2)],
        -2i32..=3,
        unit(),
        3i32..=7,
        [-1.0..1.0f64, -1.0..1.0, -1.0..1.0, -1.0..1.0],
        -6i32..=6,
    )
        .prop_map(|(base, (u, v), vol_exp, kind, size_exp, dir, far_exp, s, s_exp)| {
            let size = 10f64.powi(size_exp);
            let [a, b, c] = base.map(|q| q.map(|x| x * size));
            let normal = cross(sub(b, a), sub(c, a));
            let nn = norm(normal).max(f64::MIN_POSITIVE);
            let top: V3 = match kind {
                // Sliver / cap: over a point of the base at a tiny height.
                0 => {
                    let h = 10f64.powi(vol_exp) * size;
                    std::array::from_fn(|k| a[k] + u * (b[k] - a[k]) + v * (c[k] - a[k]) + h * normal[k] / nn)
                }
                // Needle-ish: near a base vertex.
                1 => std::array::from_fn(|k| a[k] + 10f64.powi(vol_exp) * size * (normal[k] / nn + u)),
                // On a base edge (zero volume up to rounding).
                _ => std::array::from_fn(|k| a[k] + u * (b[k] - a[k])),
            };
            let far = 10f64.powi(far_exp);
            let shift = dir.map(|x| x * far);
            let p = [a, b, c, top].map(|q| [q[0] + shift[0], q[1] + shift[1], q[2] + shift[2]]);
            (p, s.map(|x| x * 10f64.powi(s_exp)))
        })
}

proptest! {
    #![proptest_config(config(512))]

    /// Never NaN/Inf for finite input, however thin the cell or far from the
    /// origin; degenerate cells are all zeros.
    #[test]
    fn precompute_is_finite_for_hard_tets((p, s) in hard_tet()) {
        let t = TetPrecomputed::from_vertices(p, s);
        prop_assert!(all_finite(&t), "{t:?}");
        prop_assert!(t.volume >= 0.0);
        if t.degenerate {
            prop_assert_eq!(t.gradient, [0.0; 3]);
            prop_assert_eq!(t.planes, [[0.0; 4]; 4]);
        }
        for (i, &q) in p.iter().enumerate() {
            prop_assert!(t.opposite_plane_3(q, i).iter().all(|v| v.is_finite()));
        }
        // Swapping two vertices changes nothing but the order of the planes.
        let mut r = p;
        r.swap(0, 1);
        let u = TetPrecomputed::from_vertices(r, [s[1], s[0], s[2], s[3]]);
        prop_assert!(all_finite(&u));
        prop_assert_eq!(u.degenerate, t.degenerate);
    }

    /// The same for arbitrary finite input, up to the largest values a
    /// validated mesh may hold (and beyond, up to f64::MAX).
    #[test]
    fn precompute_is_finite_for_any_finite_input(
        p in [[any::<f64>(); 3]; 4],
        s in [any::<f64>(); 4],
        clamp in any::<bool>(),
    ) {
        let fix = |x: f64| {
            let x = if x.is_finite() { x } else { 1.0 };
            if clamp { x.clamp(-MAX_ABS_VALUE, MAX_ABS_VALUE) } else { x }
        };
        let p = p.map(|q| q.map(fix));
        let t = TetPrecomputed::from_vertices(p, s.map(fix));
        prop_assert!(all_finite(&t), "{p:?} -> {t:?}");
        for (i, &q) in p.iter().enumerate() {
            prop_assert!(t.opposite_plane_3(q, i).iter().all(|v| v.is_finite()));
        }
    }

    /// Well-shaped cells far from the origin (1e3..1e7 mesh units away, as in
    /// georeferenced data) keep an accurate gradient: the loss is only the
    /// rounding of the translated coordinates.
    #[test]
    fn gradient_survives_translation(p in shaped_tet_scaled(-1, 3), g in v3(10.0), dir in unit(), far_exp in 3i32..=7) {
        let l = longest_edge(&p);
        let shift = dir.map(|x| x * 10f64.powi(far_exp));
        let q = p.map(|v| [v[0] + shift[0], v[1] + shift[1], v[2] + shift[2]]);
        // The field is linear in the local coordinates (as it would be in the file).
        let s = p.map(|v| dot(g, v));
        let t = TetPrecomputed::from_vertices(q, s);
        prop_assert!(!t.degenerate);
        // Coordinates carry absolute error ~ eps * |shift|; relative to the
        // edge and amplified by the conditioning (<= ~100 for these shapes).
        let tol = norm(g) * (1e-13 + 1e-13 * 10f64.powi(far_exp) / l);
        for k in 0..3 {
            prop_assert!((t.gradient[k] - g[k]).abs() <= tol, "{:?} vs {g:?} (tol {tol:e})", t.gradient);
        }
    }
}
