//! MPVO visibility order: a permutation every time, no face constraint
//! violated on convex meshes, checked independently by casting rays through
//! the cells (cells met farther along a ray must be drawn earlier); the
//! centroid order's violations on stretched cells; non-convex meshes (L, U,
//! separate blocks) without hanging; degenerate cells; welded and
//! non-conforming seams; and (ignored, release) timing and centroid-order
//! violations on the real meshes:
//! `cargo test --release --test mpvo -- --ignored --nocapture`.

use std::time::Instant;

use volbench::algo::cell_projection::centroids_f32;
use volbench::algo::cell_projection::mpvo::MpvoSort;
use volbench::algo::cell_projection::sort::CentroidSort;
use volbench::mesh::split::{hex_grid_tet_indices, hex_grid_to_tets};
use volbench::mesh::{MeshStats, TetGeometry, TetMesh};
use volbench::scene::{Camera, Projection};

const PERSP: Projection = Projection::Perspective { fovy_deg: 30.0 };
const ORTHO: Projection = Projection::Orthographic { height: 1.0 };

/// Structured grid of `dims` points, point (i,j,k) at `f(i,j,k)`.
fn grid(dims: [usize; 3], f: impl Fn(f64, f64, f64) -> [f64; 3]) -> TetMesh {
    let mut points = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                points.push(f(i as f64, j as f64, k as f64));
            }
        }
    }
    let scalars = points.iter().map(|p| p[0]).collect();
    hex_grid_to_tets("grid", dims, points, scalars).unwrap()
}

/// The tets of a `dims` point grid whose hex (i,j,k) satisfies `keep`,
/// points at `f(i,j,k)`.
fn grid_subset(
    dims: [usize; 3],
    f: impl Fn(f64, f64, f64) -> [f64; 3],
    keep: impl Fn(usize, usize, usize) -> bool,
) -> TetMesh {
    let full = grid(dims, f);
    let (hx, hy) = (dims[0] - 1, dims[1] - 1);
    let tets: Vec<[u32; 4]> = hex_grid_tet_indices(dims)
        .unwrap()
        .into_iter()
        .enumerate()
        .filter(|(t, _)| {
            let h = t / 5;
            keep(h % hx, (h / hx) % hy, h / (hx * hy))
        })
        .map(|(_, t)| t)
        .collect();
    let mut m = TetMesh {
        name: "subset".into(),
        points: full.points,
        scalars: full.scalars,
        tets,
        stats: MeshStats::default(),
    };
    m.validate("subset").unwrap();
    m
}

/// Two meshes side by side as one (no shared points).
fn union(a: &TetMesh, b: &TetMesh) -> TetMesh {
    let off = a.points.len() as u32;
    let mut m = TetMesh {
        name: "union".into(),
        points: a.points.iter().chain(&b.points).copied().collect(),
        scalars: a.scalars.iter().chain(&b.scalars).copied().collect(),
        tets: a.tets.iter().copied().chain(b.tets.iter().map(|t| t.map(|v| v + off))).collect(),
        stats: MeshStats::default(),
    };
    m.validate("union").unwrap();
    m
}

fn assert_permutation(order: &[u32], n: usize) {
    assert_eq!(order.len(), n);
    let mut seen = vec![false; n];
    for &c in order {
        assert!(!seen[c as usize], "cell {c} twice");
        seen[c as usize] = true;
    }
}

/// Independent check by ray casting: along each ray (a grid of pixels),
/// every pair of consecutive solid cells it crosses (by clipping the ray
/// against each cell's planes) must appear farther-first in `order`.
/// Returns (pairs checked, pairs in the wrong order).
fn ray_check(mesh: &TetMesh, geometry: &TetGeometry, order: &[u32], camera: &Camera, pixels: u32) -> (usize, usize) {
    let mut pos = vec![0usize; order.len()];
    for (i, &c) in order.iter().enumerate() {
        pos[c as usize] = i;
    }
    let diag = mesh.bounds().diagonal();
    let (mut pairs, mut wrong) = (0, 0);
    for y in 0..pixels {
        for x in 0..pixels {
            let (o, d) = camera.ray(x as f64 + 0.123, y as f64 + 0.377, pixels, pixels);
            let mut hits: Vec<(f64, usize)> = Vec::new();
            for (c, cell) in geometry.cells.iter().enumerate() {
                if cell.degenerate {
                    continue;
                }
                let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
                for pl in &cell.planes {
                    let nd = pl[0] * d.x + pl[1] * d.y + pl[2] * d.z;
                    let no = pl[0] * o.x + pl[1] * o.y + pl[2] * o.z + pl[3];
                    if nd.abs() < 1e-300 {
                        if no > 0.0 {
                            t1 = f64::NEG_INFINITY;
                        }
                    } else if nd > 0.0 {
                        t1 = t1.min(-no / nd);
                    } else {
                        t0 = t0.max(-no / nd);
                    }
                }
                if t0.max(0.0) + 1e-7 * diag < t1 {
                    hits.push((0.5 * (t0.max(0.0) + t1), c));
                }
            }
            hits.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap());
            for w in hits.windows(2) {
                pairs += 1;
                // w[0] is nearer: it must be drawn after w[1].
                if pos[w[0].1] < pos[w[1].1] {
                    wrong += 1;
                }
            }
        }
    }
    (pairs, wrong)
}

fn cameras(mesh: &TetMesh) -> Vec<Camera> {
    let b = mesh.bounds();
    let mut cams = Vec::new();
    for proj in [PERSP, ORTHO] {
        for angle in [0.0, 0.7, 2.0, 3.9, 5.5] {
            cams.push(Camera::orbit(&b, angle, proj));
        }
    }
    // Close to the mesh, looking at a corner; and along a grid axis (faces
    // seen exactly edge-on).
    let mut close = Camera::orbit(&b, 1.0, PERSP);
    close.eye = [b.max[0] + 0.3, b.max[1] + 0.2, b.max[2] + 0.1];
    cams.push(close);
    let mut axis = Camera::orbit(&b, 0.0, ORTHO);
    let c = b.center();
    axis.eye = [c[0], c[1], c[2] + 3.0 * b.diagonal()];
    axis.target = c;
    axis.up = [0.0, 1.0, 0.0];
    cams.push(axis);
    cams
}

#[test]
fn convex_grids_are_ordered_exactly() {
    let meshes = [
        grid([5, 4, 6], |i, j, k| [i, j, k]),
        // Sheared and unevenly spaced: still convex.
        grid([5, 5, 4], |i, j, k| [i + 0.4 * j + 0.1 * k * k, 0.5 * j * j + 0.3 * k, 1.5 * k - 0.2 * i]),
    ];
    for mesh in &meshes {
        let geometry = TetGeometry::compute(mesh);
        let mut mpvo = MpvoSort::new(mesh, &geometry);
        let b = mpvo.build_stats();
        assert_eq!(b.non_manifold_faces, 0);
        assert_eq!(b.welded_faces, 0);
        assert_eq!(b.interior_faces * 2 + b.boundary_faces, 4 * mesh.tets.len());
        for cam in cameras(mesh) {
            let order = mpvo.sort(&cam).to_vec();
            let stats = mpvo.frame_stats();
            assert_permutation(&order, mesh.tets.len());
            assert_eq!(stats.cycles_broken, 0, "{cam:?}");
            let check = mpvo.check_order(&order, &cam);
            assert_eq!(check.violated, 0);
            assert_eq!(check.constraints, stats.constraints);
            assert!(check.constraints + stats.edge_on_faces <= b.interior_faces);
            let (pairs, wrong) = ray_check(mesh, &geometry, &order, &cam, 24);
            assert!(pairs > 100, "{pairs}");
            assert_eq!(wrong, 0, "MPVO order wrong along rays for {cam:?}");
        }
    }
}

#[test]
fn centroid_order_violates_constraints_on_stretched_cells() {
    // Thin, long slabs of cells: centroids far from the faces that decide.
    let mesh = grid([8, 3, 6], |i, j, k| [6.0 * i + 0.5 * k, 0.2 * j, 0.3 * k]);
    let geometry = TetGeometry::compute(&mesh);
    let mut mpvo = MpvoSort::new(&mesh, &geometry);
    let mut centroid = CentroidSort::new(centroids_f32(&geometry));
    let (mut violated, mut ray_wrong) = (0, 0);
    for cam in cameras(&mesh) {
        let order = centroid.sort(&cam).to_vec();
        let check = mpvo.check_order(&order, &cam);
        assert_eq!(check.violated, mpvo.count_out_of_order(&order, &cam));
        assert!(check.cells_out_of_order <= check.violated && check.violated <= check.constraints);
        violated += check.violated;
        ray_wrong += ray_check(&mesh, &geometry, &order, &cam, 16).1;
        let exact = mpvo.sort(&cam).to_vec();
        assert_eq!(mpvo.count_out_of_order(&exact, &cam), 0);
        assert_eq!(ray_check(&mesh, &geometry, &exact, &cam, 16).1, 0);
    }
    println!("centroid order: {violated} face constraints violated, {ray_wrong} ray pairs wrong");
    assert!(violated > 0);
    assert!(ray_wrong > 0);
}

#[test]
fn separate_blocks_are_drawn_far_block_first() {
    // Two blocks along z, a gap between them: no face says which is first.
    let a = grid([4, 4, 3], |i, j, k| [i, j, k]);
    let b = grid([4, 4, 3], |i, j, k| [i + 0.3, j - 0.2, k + 4.0]);
    let mesh = union(&a, &b);
    let na = a.tets.len();
    let geometry = TetGeometry::compute(&mesh);
    let mut mpvo = MpvoSort::new(&mesh, &geometry);
    for (eye_z, far_first_is_a) in [(30.0, true), (-30.0, false)] {
        let mut cam = Camera::orbit(&mesh.bounds(), 0.0, PERSP);
        cam.eye = [1.6, 1.4, eye_z];
        cam.target = [1.5, 1.5, 3.5];
        cam.up = [0.0, 1.0, 0.0];
        let order = mpvo.sort(&cam).to_vec();
        assert_permutation(&order, mesh.tets.len());
        assert_eq!(mpvo.frame_stats().cycles_broken, 0);
        let first_block: Vec<bool> = order.iter().map(|&c| (c as usize) < na).collect();
        let split = if far_first_is_a { na } else { mesh.tets.len() - na };
        assert!(first_block[..split].iter().all(|&x| x == far_first_is_a), "eye z {eye_z}");
        assert_eq!(ray_check(&mesh, &geometry, &order, &cam, 24).1, 0);
    }
}

#[test]
fn non_convex_l_shape_is_a_permutation() {
    // 4×4×2 hexes with the quadrant i, j >= 2 removed, and a U shape.
    let l = grid_subset([5, 5, 3], |i, j, k| [i, j, 0.7 * k], |i, j, _| !(i >= 2 && j >= 2));
    let u = grid_subset([6, 3, 4], |i, j, k| [i, j, k], |i, _, k| !((1..4).contains(&i) && k >= 1));
    for mesh in [&l, &u] {
        let geometry = TetGeometry::compute(mesh);
        let mut mpvo = MpvoSort::new(mesh, &geometry);
        let (mut cycles, mut wrong, mut pairs) = (0, 0, 0);
        for cam in cameras(mesh) {
            let start = Instant::now();
            let order = mpvo.sort(&cam).to_vec();
            assert!(start.elapsed().as_secs_f64() < 1.0);
            assert_permutation(&order, mesh.tets.len());
            let stats = mpvo.frame_stats();
            cycles += stats.cycles_broken;
            if stats.cycles_broken == 0 {
                assert_eq!(mpvo.count_out_of_order(&order, &cam), 0);
            }
            let (p, w) = ray_check(mesh, &geometry, &order, &cam, 20);
            pairs += p;
            wrong += w;
        }
        println!("{} tets: {cycles} cycles broken, {wrong} of {pairs} ray pairs out of order", mesh.tets.len());
    }
}

#[test]
fn degenerate_cells_add_no_bogus_constraints() {
    // The bottom layer collapsed onto z = 0 (as the blunt fin's collapsed
    // grid points do): its cells are flat, the rest is a convex block.
    let mesh = grid([4, 4, 5], |i, j, k| [i, j, (k - 1.0).max(0.0)]);
    assert!(mesh.stats.zero_volume > 0);
    let geometry = TetGeometry::compute(&mesh);
    let mut mpvo = MpvoSort::new(&mesh, &geometry);
    let b = mpvo.build_stats();
    assert_eq!(b.degenerate_cells, mesh.stats.zero_volume);
    println!("{b:?}");
    for cam in cameras(&mesh) {
        let order = mpvo.sort(&cam).to_vec();
        assert_permutation(&order, mesh.tets.len());
        assert_eq!(mpvo.frame_stats().cycles_broken, 0, "{cam:?}");
        assert_eq!(mpvo.count_out_of_order(&order, &cam), 0);
        assert_eq!(ray_check(&mesh, &geometry, &order, &cam, 20).1, 0);
    }
}

#[test]
fn unmerged_seams_are_welded() {
    // One block as two grids with coincident (unmerged) points on the plane
    // x = 2 (like an O-grid's seam). `a` ends with hexes of odd i + j + k
    // parity where `b` starts with even ones, so the two sides cut the seam
    // quads along the same diagonals.
    let a = grid([3, 4, 4], |i, j, k| [i, j, k]);
    let b = grid([4, 4, 4], |i, j, k| [i + 2.0, j, k]);
    let mesh = union(&a, &b);
    let geometry = TetGeometry::compute(&mesh);
    let mut mpvo = MpvoSort::new(&mesh, &geometry);
    let bs = mpvo.build_stats();
    assert_eq!(bs.welded_faces, 3 * 3 * 2, "{bs:?}");
    assert_eq!(bs.non_manifold_faces, 0);
    for cam in cameras(&mesh) {
        let order = mpvo.sort(&cam).to_vec();
        assert_permutation(&order, mesh.tets.len());
        assert_eq!(mpvo.frame_stats().cycles_broken, 0);
        assert_eq!(ray_check(&mesh, &geometry, &order, &cam, 20).1, 0, "{cam:?}");
    }
}

#[test]
fn non_conforming_seams_are_linked() {
    // As above, but both sides start with even parity at the seam, so each
    // seam quad is cut along one diagonal on one side and the other diagonal
    // on the other (the oxygen post's O-grid seam is like this): no face is
    // shared, the overlapping halves are linked instead.
    let a = grid([4, 4, 4], |i, j, k| [i, j, k]);
    let b = grid([4, 4, 4], |i, j, k| [i + 3.0, j, k]);
    let mesh = union(&a, &b);
    let geometry = TetGeometry::compute(&mesh);
    let mut mpvo = MpvoSort::new(&mesh, &geometry);
    let bs = mpvo.build_stats();
    assert_eq!(bs.welded_faces, 0, "{bs:?}");
    // 3×3 quads, each half on one side overlapping both halves on the other.
    assert_eq!(bs.seam_links, 3 * 3 * 4, "{bs:?}");
    for cam in cameras(&mesh) {
        let order = mpvo.sort(&cam).to_vec();
        assert_permutation(&order, mesh.tets.len());
        assert_eq!(mpvo.frame_stats().cycles_broken, 0);
        assert_eq!(mpvo.count_out_of_order(&order, &cam), 0);
        assert_eq!(ray_check(&mesh, &geometry, &order, &cam, 20).1, 0, "{cam:?}");
    }
    // Nothing is linked on the surface of a single block.
    assert_eq!(MpvoSort::from_mesh(&a).build_stats().seam_links, 0);
}

/// Run with `cargo test --release --test mpvo -- --ignored --nocapture`.
#[test]
#[ignore]
fn real_meshes_timing_and_centroid_violations() {
    for name in ["bluntfin", "oxygenpost", "post-small"] {
        let mesh = volbench::harness::datasets::load_mesh(name).unwrap();
        let geometry = TetGeometry::compute(&mesh);
        let t = Instant::now();
        let mut mpvo = MpvoSort::new(&mesh, &geometry);
        let build = t.elapsed();
        let mut centroid = CentroidSort::new(centroids_f32(&geometry));
        println!(
            "{name}: {} tets, build {:.1} ms, {:?}",
            mesh.tets.len(),
            build.as_secs_f64() * 1e3,
            mpvo.build_stats()
        );
        // Along-ray check of both orders at the default camera (a 32×32
        // grid of rays over the image).
        let cam = Camera::orbit(&mesh.bounds(), 0.0, PERSP);
        let exact = mpvo.sort(&cam).to_vec();
        let corder = centroid.sort(&cam).to_vec();
        let (pairs, wrong_m) = ray_check(&mesh, &geometry, &exact, &cam, 32);
        let (_, wrong_c) = ray_check(&mesh, &geometry, &corder, &cam, 32);
        println!("  default camera, along 32x32 rays: {pairs} consecutive cell pairs; wrong: mpvo {wrong_m}, centroid {wrong_c}");
        for proj in [PERSP, ORTHO] {
            for angle in [0.0f64, 0.5, 1.0, 2.0, 3.0, 4.0, 5.0] {
                let cam = Camera::orbit(&mesh.bounds(), angle, proj);
                let order = mpvo.sort(&cam).to_vec();
                assert_permutation(&order, mesh.tets.len());
                let stats = mpvo.frame_stats();
                let mut times = Vec::new();
                for _ in 0..7 {
                    let t = Instant::now();
                    std::hint::black_box(mpvo.sort(&cam)[0]);
                    times.push(t.elapsed().as_secs_f64() * 1e3);
                }
                times.sort_by(|a, b| a.partial_cmp(b).unwrap());
                let mut ctimes = Vec::new();
                for _ in 0..7 {
                    let t = Instant::now();
                    std::hint::black_box(centroid.sort(&cam)[0]);
                    ctimes.push(t.elapsed().as_secs_f64() * 1e3);
                }
                ctimes.sort_by(|a, b| a.partial_cmp(b).unwrap());
                let corder = centroid.sort(&cam).to_vec();
                let cc = mpvo.check_order(&corder, &cam);
                let mc = mpvo.check_order(&order, &cam);
                let kind = if cam.is_perspective() { "persp" } else { "ortho" };
                println!(
                    "  {kind} angle {angle:.1}: mpvo median {:.1} ms (min {:.1}), centroid {:.1} ms; {stats:?}; \
                     centroid violates {} of {} constraints ({} cells); mpvo violates {} ({} cells)",
                    times[3],
                    times[0],
                    ctimes[3],
                    cc.violated,
                    cc.constraints,
                    cc.cells_out_of_order,
                    mc.violated,
                    mc.cells_out_of_order
                );
            }
        }
    }
}
