//! The three real meshes load with the published counts, and malformed files
//! give errors that name the file.

use std::path::{Path, PathBuf};
use volbench::mesh::datasets::{load_bluntfin, load_oxygenpost, load_path, load_post_small};
use volbench::mesh::plot3d::{read_q, read_xyz};
use volbench::mesh::vtk::read_vtk_legacy;
use volbench::mesh::{TetGeometry, TetMesh};

fn data_dir() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/data"))
}

fn summary(m: &TetMesh) {
    let (lo, hi) = m.scalar_range();
    let b = m.bounds();
    println!(
        "{}: {} points, {} tets, stats {:?}, scalar [{lo}, {hi}], bounds {:?} .. {:?}",
        m.name,
        m.points.len(),
        m.tets.len(),
        m.stats,
        b.min,
        b.max
    );
}

/// Geometry is finite everywhere; degenerate cells agree with the zero-volume
/// count; every non-degenerate cell is positively oriented.
fn check_geometry(m: &TetMesh) -> TetGeometry {
    let g = TetGeometry::compute(m);
    assert_eq!(g.cells.len(), m.tets.len());
    assert_eq!(g.centroids.len(), m.tets.len());
    for (c, cell) in g.cells.iter().enumerate() {
        let finite = cell
            .gradient
            .iter()
            .chain(cell.planes.iter().flatten())
            .chain(std::iter::once(&cell.volume))
            .chain(g.centroids[c].iter())
            .all(|v| v.is_finite());
        assert!(finite, "{}: cell {c} has non-finite geometry {cell:?}", m.name);
        let p = m.tet_points(c);
        for (i, &pi) in p.iter().enumerate() {
            let n3 = cell.opposite_plane_3(pi, i);
            assert!(n3.iter().all(|v| v.is_finite()));
        }
        assert!(cell.degenerate || cell.volume > 0.0);
    }
    assert_eq!(g.degenerate_count(), m.stats.zero_volume, "{}", m.name);
    g
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

#[test]
fn blunt_fin() {
    let m = load_bluntfin(&data_dir()).unwrap();
    summary(&m);
    assert_eq!(m.name, "bluntfin");
    assert_eq!(m.points.len(), 40_960);
    assert_eq!(m.tets.len(), 187_395);
    let (lo, hi) = m.scalar_range();
    assert!(close(lo, 0.193, 1e-3) && close(hi, 4.978, 1e-3), "density [{lo}, {hi}]");
    // Zero-volume cells: 77, all with det exactly 0. The grid collapses the
    // edge between points (i,0,0) and (i,1,0) for i = 1..39 (39 coincident
    // point pairs along the k = 0 grid line). In the 5-tet split each hex of
    // the row j = 0, k = 0 has exactly one tet on each of its two y-edges at
    // k = 0, whatever the parity pattern, so hexes i = 1..38 give 2 flat tets
    // each and hex i = 0 (whose edge at i = 0 is not collapsed) gives 1:
    // 38 * 2 + 1 = 77 (the datasets README's "about 77").
    assert_eq!(m.stats.zero_volume, 77);
    assert_eq!(m.stats.reoriented, 0); // the grid is right-handed
    assert_eq!(m.stats.blanked_cells, 0);
    let g = check_geometry(&m);
    assert!(g.total_volume() > 0.0);
    // Conforming: no triangle (by vertex indices) is shared by more than two tets.
    let mut faces = std::collections::HashMap::<[u32; 3], u8>::new();
    for t in &m.tets {
        for i in 0..4 {
            let mut f = [t[(i + 1) % 4], t[(i + 2) % 4], t[(i + 3) % 4]];
            f.sort();
            *faces.entry(f).or_default() += 1;
        }
    }
    assert!(faces.values().all(|&c| c <= 2));
    // 2 triangles per boundary quad of the 39x31x31-cell block.
    let boundary = faces.values().filter(|&&c| c == 1).count();
    assert_eq!(boundary, 4 * (39 * 31 + 31 * 31 + 39 * 31));
}

#[test]
fn oxygen_post() {
    let m = load_oxygenpost(&data_dir()).unwrap();
    summary(&m);
    assert_eq!(m.name, "oxygenpost");
    assert_eq!(m.points.len(), 109_744);
    assert_eq!(m.tets.len(), 513_375);
    let (lo, hi) = m.scalar_range();
    assert!(close(lo, 0.0, 5e-4) && close(hi, 1.391, 5e-4), "velocity magnitude [{lo}, {hi}]");
    // No collapsed points (the unmerged O-grid seam duplicates points, but
    // never within one hex) and a right-handed grid.
    assert_eq!(m.stats.zero_volume, 0);
    assert_eq!(m.stats.reoriented, 0);
    // IBLANK blanks nothing (it is -1 only on the seam rows, a fringe marker).
    assert_eq!(m.stats.blanked_cells, 0);
    check_geometry(&m);
    // The density of the post solution is constant 1.
    let q = read_q(data_dir().join("plot3d/postq.bin")).unwrap();
    assert!(q.density().iter().all(|&d| d == 1.0));
    let grid = read_xyz(data_dir().join("plot3d/postxyz.bin")).unwrap();
    assert!(grid.iblank.is_some());
    assert_eq!(grid.blanked_points(), 0);
    assert_eq!(grid.fringe_points(), 3 * 38 * 38);
}

#[test]
fn post_small_vtk() {
    let m = load_post_small(&data_dir()).unwrap();
    summary(&m);
    assert_eq!(m.points.len(), 2_288);
    assert_eq!(m.tets.len(), 8_750);
    assert_eq!(m.stats.zero_volume, 0);
    assert_eq!(m.stats.reoriented, 0);
    let (lo, hi) = m.scalar_range();
    assert!(close(lo, 0.3554, 1e-3) && close(hi, 1.6412, 1e-3), "pressure [{lo}, {hi}]");
    check_geometry(&m);
    // Same file through the extension dispatcher.
    let m2 = load_path(data_dir().join("unstructured/post_tets_vtkdata.vtk")).unwrap();
    assert_eq!(m2.tets, m.tets);
    assert_eq!(m2.scalars, m.scalars);
}

#[test]
fn oxygen_post_loads_fast() {
    // Debug-profile builds of this crate are optimised (opt-level 1/2), so a
    // generous bound still catches accidental quadratic work.
    let t = std::time::Instant::now();
    let m = load_oxygenpost(&data_dir()).unwrap();
    let g = TetGeometry::compute(&m);
    let dt = t.elapsed();
    println!("oxygen post load + precompute: {dt:?}");
    assert_eq!(g.cells.len(), 513_375);
    assert!(dt.as_secs_f64() < 5.0, "{dt:?}");
}

// ---- malformed input ---------------------------------------------------------

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn err_text<T: std::fmt::Debug>(r: anyhow::Result<T>) -> String {
    format!("{:#}", r.unwrap_err())
}

#[test]
fn truncated_plot3d() {
    let tmp = tempfile::tempdir().unwrap();
    let xyz = std::fs::read(data_dir().join("plot3d/bluntfinxyz.bin")).unwrap();
    let q = std::fs::read(data_dir().join("plot3d/bluntfinq.bin")).unwrap();
    for cut in [0, 5, 12, 100, xyz.len() / 2, xyz.len() - 1] {
        let p = write(tmp.path(), "bluntfinxyz.bin", &xyz[..cut]);
        let e = err_text(read_xyz(&p));
        assert!(e.contains(&p.display().to_string()) && e.contains("truncated"), "{e}");
    }
    // q: truncating only the 484 trailing bytes is fine, more is not.
    let p = write(tmp.path(), "q.bin", &q[..q.len() - 484]);
    read_q(&p).unwrap();
    let p = write(tmp.path(), "q.bin", &q[..q.len() - 485]);
    let e = err_text(read_q(&p));
    assert!(e.contains(&p.display().to_string()) && e.contains("truncated"), "{e}");
    // A q file from the other dataset does not match the grid.
    let dir = tmp.path().join("d");
    std::fs::create_dir_all(dir.join("plot3d")).unwrap();
    std::fs::write(dir.join("plot3d/bluntfinxyz.bin"), &xyz).unwrap();
    std::fs::copy(data_dir().join("plot3d/postq.bin"), dir.join("plot3d/bluntfinq.bin")).unwrap();
    let e = err_text(load_bluntfin(&dir));
    assert!(e.contains("bluntfinq.bin") && e.contains("do not match"), "{e}");
}

#[test]
fn nan_coordinate_plot3d() {
    let tmp = tempfile::tempdir().unwrap();
    let mut xyz = std::fs::read(data_dir().join("plot3d/bluntfinxyz.bin")).unwrap();
    let off = 12 + 4 * (40_960 + 1234); // y of point 1234
    xyz[off..off + 4].copy_from_slice(&f32::NAN.to_be_bytes());
    let p = write(tmp.path(), "nan.xyz", &xyz);
    let e = err_text(read_xyz(&p));
    assert!(e.contains(&p.display().to_string()) && e.contains("non-finite") && e.contains("1234"), "{e}");
}

fn small_vtk() -> Vec<u8> {
    std::fs::read(data_dir().join("unstructured/post_tets_vtkdata.vtk")).unwrap()
}

fn find(hay: &[u8], needle: &[u8]) -> usize {
    hay.windows(needle.len()).position(|w| w == needle).unwrap()
}

#[test]
fn truncated_vtk() {
    let tmp = tempfile::tempdir().unwrap();
    let b = small_vtk();
    let cells = find(&b, b"CELLS");
    let types = find(&b, b"CELL_TYPES");
    for cut in [0, 30, 80, 200, cells + 3, cells + 100, types - 1, types + 30, b.len() - 10] {
        let p = write(tmp.path(), "post.vtk", &b[..cut]);
        let e = err_text(read_vtk_legacy(&p));
        assert!(e.contains(&p.display().to_string()), "cut {cut}: {e}");
    }
    let p = write(tmp.path(), "post.vtk", &b[..types + 30]);
    let e = err_text(read_vtk_legacy(&p));
    assert!(e.contains("truncated"), "{e}");
}

#[test]
fn out_of_range_index_vtk() {
    let tmp = tempfile::tempdir().unwrap();
    let mut b = small_vtk();
    // First cell record: "CELLS 8750 43750\n" then int32 4, i0, i1, i2, i3.
    let data = find(&b, b"CELLS 8750 43750\n") + "CELLS 8750 43750\n".len();
    b[data + 8..data + 12].copy_from_slice(&5000i32.to_be_bytes());
    let p = write(tmp.path(), "post.vtk", &b);
    let e = err_text(read_vtk_legacy(&p));
    assert!(e.contains(&p.display().to_string()) && e.contains("out of range") && e.contains("5000"), "{e}");
}

#[test]
fn nan_coordinate_vtk() {
    let tmp = tempfile::tempdir().unwrap();
    let mut b = small_vtk();
    let data = find(&b, b"POINTS 2288 float\n") + "POINTS 2288 float\n".len();
    let off = data + 4 * (3 * 17 + 2); // z of point 17
    b[off..off + 4].copy_from_slice(&f32::NAN.to_be_bytes());
    let p = write(tmp.path(), "post.vtk", &b);
    let e = err_text(read_vtk_legacy(&p));
    assert!(e.contains(&p.display().to_string()) && e.contains("non-finite") && e.contains("point 17"), "{e}");
}

#[test]
fn non_tet_cell_type_vtk() {
    let tmp = tempfile::tempdir().unwrap();
    let mut b = small_vtk();
    let data = find(&b, b"CELL_TYPES 8750\n") + "CELL_TYPES 8750\n".len();
    b[data + 4 * 7..data + 4 * 8].copy_from_slice(&12i32.to_be_bytes());
    let p = write(tmp.path(), "post.vtk", &b);
    let e = err_text(read_vtk_legacy(&p));
    // A tetra's 4 vertices cannot make a hexahedron.
    assert!(e.contains(&p.display().to_string()) && e.contains("cell 7 is a hexahedron (type 12) but has 4 vertices"), "{e}");
    // A quadratic tetra needs 10 nodes; a convex point set is refused with its count.
    b[data + 4 * 7..data + 4 * 8].copy_from_slice(&24i32.to_be_bytes());
    let p = write(tmp.path(), "post.vtk", &b);
    let e = err_text(read_vtk_legacy(&p));
    assert!(e.contains("cell 7 (quadratic tetra, type 24) has 4 nodes, not 10"), "{e}");
    b[data + 4 * 7..data + 4 * 8].copy_from_slice(&41i32.to_be_bytes());
    let p = write(tmp.path(), "post.vtk", &b);
    let e = err_text(read_vtk_legacy(&p));
    assert!(e.contains("unsupported cells: 1 cells of type 41 (convex point set)"), "{e}");
}
