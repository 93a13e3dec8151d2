//! Malformed mesh files: every reader answers with an error that names the
//! file and the problem, never a panic (issue 4, item 3). Through the library
//! (byte parsers and path loaders), through the CLI binary (exit code 1, no
//! output file left behind), on the fuzzers' regression inputs
//! (`tests/regressions/`), and on thousands of deterministic mutations of
//! valid files (a bounded, stable-toolchain stand-in for `cargo fuzz`).

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::process::Command;

use volbench::mesh::datasets::{load_path, load_plot3d, Plot3dScalar};
use volbench::mesh::plot3d::{parse_q_bytes, parse_xyz_bytes};
use volbench::mesh::vtk::parse_vtk_bytes;
use volbench::mesh::{check_fits, TetGeometry, TetMesh};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn post_vtk() -> Vec<u8> {
    std::fs::read(repo("data/unstructured/post_tets_vtkdata.vtk")).unwrap()
}

/// `{e:#}` of the error, asserting it starts with `name: ` (the file).
fn err_of<T: std::fmt::Debug>(name: &str, r: anyhow::Result<T>) -> String {
    let e = format!("{:#}", r.expect_err("malformed input must be an error"));
    assert!(e.starts_with(&format!("{name}: ")), "error does not start with the file name: {e}");
    e
}

fn assert_err(name: &str, r: anyhow::Result<TetMesh>, what: &str) {
    let e = err_of(name, r);
    assert!(e.contains(what), "expected '{what}' in: {e}");
}

/// Geometry of a mesh that loaded must be finite.
fn check_finite(m: &TetMesh) {
    for c in &TetGeometry::compute(m).cells {
        let all = c.gradient.iter().chain(c.planes.iter().flatten()).chain([&c.volume]);
        assert!(all.into_iter().all(|v| v.is_finite()), "{c:?}");
    }
}

// ---------------------------------------------------------------- builders

/// ASCII VTK 3.0 with two tets (the second inverted), a vector and a scalar.
const ASCII: &str = "# vtk DataFile Version 3.0
two tets
ASCII
DATASET UNSTRUCTURED_GRID
POINTS 5 float
0 0 0  1 0 0  0 1 0
0 0 1  1 1 1
CELLS 2 10
4 0 1 2 3
4 1 3 2 4
CELL_TYPES 2
10
10
POINT_DATA 5
VECTORS v float
0 0 0 0 0 0 0 0 0 0 0 0 0 0 0
SCALARS temp double
LOOKUP_TABLE default
0.5 1.5 2.5 3.5 4.5
";

const ASCII5: &str = "# vtk DataFile Version 5.1\nv5\nASCII\nDATASET UNSTRUCTURED_GRID\n\
POINTS 4 double\n0 0 0 1 0 0 0 1 0 0 0 1\n\
CELLS 2 4\nOFFSETS vtktypeint64\n0 4\nCONNECTIVITY vtktypeint64\n0 1 2 3\n\
CELL_TYPES 1\n10\nPOINT_DATA 4\nSCALARS s float 1\nLOOKUP_TABLE default\n1 2 3 4\n";

fn be<T: Copy, const N: usize>(vals: &[T], f: impl Fn(T) -> [u8; N]) -> Vec<u8> {
    vals.iter().flat_map(|&v| f(v)).collect()
}

/// A binary VTK with `points` (double), one-tet-per-entry cells and scalars.
fn binary_vtk(points: &[f64], cells: &[[i32; 4]], types: &[i32], scalars: &[f32]) -> Vec<u8> {
    binary_vtk_ordered(points, cells, types, scalars, false, false)
}

/// [`binary_vtk`], with the points and/or the cells written little-endian
/// (wrongly: the format is big-endian).
fn binary_vtk_ordered(
    points: &[f64],
    cells: &[[i32; 4]],
    types: &[i32],
    scalars: &[f32],
    le_points: bool,
    le_cells: bool,
) -> Vec<u8> {
    let mut b = b"# vtk DataFile Version 3.0\nbinary\nBINARY\nDATASET UNSTRUCTURED_GRID\n".to_vec();
    b.extend(format!("POINTS {} double\n", points.len() / 3).bytes());
    b.extend(be(points, if le_points { f64::to_le_bytes } else { f64::to_be_bytes }));
    b.extend(format!("\nCELLS {} {}\n", cells.len(), 5 * cells.len()).bytes());
    let int = if le_cells { i32::to_le_bytes } else { i32::to_be_bytes };
    for c in cells {
        b.extend(be(&[4, c[0], c[1], c[2], c[3]], int));
    }
    b.extend(format!("\nCELL_TYPES {}\n", types.len()).bytes());
    b.extend(be(types, i32::to_be_bytes));
    b.extend(format!("\nPOINT_DATA {}\nSCALARS s float\nLOOKUP_TABLE default\n", scalars.len()).bytes());
    b.extend(be(scalars, f32::to_be_bytes));
    b.push(b'\n');
    b
}

const UNIT_TET: [f64; 12] = [0., 0., 0., 1., 0., 0., 0., 1., 0., 0., 0., 1.];

/// A whole, big-endian PLOT3D grid of `dims` (a slightly sheared lattice),
/// optionally with IBLANK.
fn xyz_bytes(dims: [i32; 3], iblank: bool) -> Vec<u8> {
    let n = dims.iter().map(|&d| d.max(0) as usize).product::<usize>();
    let mut b = be(&dims, i32::to_be_bytes);
    let nx = dims[0].max(1) as usize;
    let ny = dims[1].max(1) as usize;
    for c in 0..3 {
        for p in 0..n {
            let (i, j, k) = (p % nx, (p / nx) % ny, p / (nx * ny));
            let v = [i as f32 + 0.1 * j as f32, j as f32 + 0.05 * k as f32, k as f32 + 0.02 * i as f32][c];
            b.extend(v.to_be_bytes());
        }
    }
    if iblank {
        b.extend(be(&(0..n).map(|p| (p % 3 != 0) as i32).collect::<Vec<_>>(), i32::to_be_bytes));
    }
    b
}

/// A PLOT3D solution of `dims` (no trailing bytes); density varies.
fn q_bytes(dims: [i32; 3]) -> Vec<u8> {
    let n = dims.iter().map(|&d| d.max(0) as usize).product::<usize>();
    let mut b = be(&dims, i32::to_be_bytes);
    b.extend(be(&[0.5f32, 10.0, 1e6, 0.0], f32::to_be_bytes));
    for f in 0..5 {
        b.extend(be(&(0..n).map(|p| 1.0 + 0.1 * (f * p) as f32).collect::<Vec<_>>(), f32::to_be_bytes));
    }
    b
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

// ------------------------------------------------------------ truncation

/// The shipped binary VTK cut at many offsets: every byte of the header
/// and around every section keyword, every byte of the last 64, and a
/// stride through the binary blocks. Only the final newline is optional.
#[test]
fn shipped_vtk_truncated_everywhere_is_an_error() {
    let full = post_vtk();
    let m = parse_vtk_bytes("post.vtk", &full).unwrap();
    assert_eq!(m.tets.len(), 8750);
    let mut cuts: Vec<usize> = (0..400).collect();
    for kw in [&b"\nPOINTS "[..], b"\nCELLS ", b"\nCELL_TYPES ", b"\nPOINT_DATA ", b"\nPressure "] {
        let at = full.windows(kw.len()).position(|w| w == kw).unwrap();
        cuts.extend(at.saturating_sub(48)..at + 48);
    }
    cuts.extend((0..full.len()).step_by(97));
    cuts.extend(full.len() - 64..full.len() - 1);
    cuts.sort_unstable();
    cuts.dedup();
    for &cut in &cuts {
        let r = catch_unwind(|| parse_vtk_bytes("post.vtk", &full[..cut]));
        let r = r.unwrap_or_else(|_| panic!("panic on post.vtk cut at {cut}"));
        err_of("post.vtk", r);
    }
    assert_eq!(parse_vtk_bytes("post.vtk", &full[..full.len() - 1]).unwrap().tets.len(), 8750);
    // The path loader says the same, naming the path.
    let tmp = tempfile::tempdir().unwrap();
    let p = write(tmp.path(), "cut.vtk", &full[..30_000]);
    assert_err(&p.display().to_string(), load_path(&p), "truncated");
}

/// A small PLOT3D pair cut at every byte offset.
#[test]
fn plot3d_truncated_at_every_offset_is_an_error() {
    let dims = [3, 2, 2];
    let xyz = xyz_bytes(dims, true);
    let q = q_bytes(dims);
    let plain_len = 12 + 12 * 12; // the same grid without IBLANK: a valid file
    for cut in 0..xyz.len() {
        let r = parse_xyz_bytes("g.xyz", &xyz[..cut]);
        if cut == plain_len {
            assert!(r.unwrap().iblank.is_none());
        } else {
            err_of("g.xyz", r);
        }
    }
    for cut in 0..q.len() {
        err_of("g.q", parse_q_bytes("g.q", &q[..cut]));
    }
    // Whole files load; cut files through the path loader name the file.
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let (px, pq) = (write(d, "gxyz.bin", &xyz), write(d, "gq.bin", &q));
    let m = load_plot3d("g", &px, &pq, Plot3dScalar::Density).unwrap();
    assert_eq!((m.points.len(), m.tets.len()), (12, 10));
    for cut in [0, 11, 12, 100, xyz.len() - 1] {
        let px = write(d, "cutxyz.bin", &xyz[..cut]);
        let e = format!("{:#}", load_plot3d("g", &px, &pq, Plot3dScalar::Density).unwrap_err());
        assert!(e.contains(&px.display().to_string()), "{e}");
    }
    for cut in [0, 20, 30, q.len() - 1] {
        let pq = write(d, "cutq.bin", &q[..cut]);
        let e = format!("{:#}", load_plot3d("g", &px, &pq, Plot3dScalar::Density).unwrap_err());
        assert!(e.contains(&pq.display().to_string()) && e.contains("truncated"), "{e}");
    }
}

// ------------------------------------------------------- corrupt content

#[test]
fn vtk_corrupt_headers_counts_and_values() {
    let n = "bad.vtk";
    let cases: Vec<(String, &str)> = vec![
        // Headers.
        (String::new(), "truncated"),
        ("# vtk DataFile Version 3.0\n".into(), "title"),
        (ASCII.replace("# vtk DataFile", "# VTK DataFile"), "not a VTK legacy file"),
        (ASCII.replace("ASCII\n", "EBCDIC\n"), "expected ASCII or BINARY"),
        (ASCII.replace("DATASET UNSTRUCTURED_GRID", "DATASET STRUCTURED_POINTS"), "unsupported DATASET"),
        (ASCII.replace("POINTS 5 float", "POINTS 5 quaternion"), "unsupported data type"),
        // Absurd and negative counts.
        (ASCII.replace("POINTS 5 float", "POINTS -5 float"), "bad POINTS count '-5'"),
        (ASCII.replace("POINTS 5 float", "POINTS 99999999999999999999 float"), "bad POINTS count"),
        (ASCII.replace("POINTS 5 float", "POINTS 18446744073709551615 float"), "overflows"),
        (ASCII.replace("POINTS 5 float", "POINTS 1000000000000 float"), "count mismatch: POINTS needs 3000000000000 values, found 15 before 'CELLS'"),
        (ASCII.replace("CELLS 2 10", "CELLS 1000000000000000 10"), "count mismatch"),
        (ASCII.replace("CELLS 2 10", "CELLS 18446744073709551615 10"), "count mismatch"),
        (ASCII.replace("CELLS 2 10", "CELLS 2 1000000000000"), "count mismatch: CELLS needs 1000000000000 values, found 10 before 'CELL_TYPES'"),
        (ASCII.replace("4 0 1 2 3", "9223372036854775807 0 1 2 3"), "value '9223372036854775807' in CELLS (value 0 of 10) does not fit the type int"),
        (ASCII.replace("4 0 1 2 3", "2147483647 0 1 2 3"), "claims 2147483647 vertices"),
        (ASCII.replace("4 0 1 2 3", "-4 0 1 2 3"), "claims -4 vertices"),
        (ASCII.replace("CELL_TYPES 2", "CELL_TYPES 7"), "count mismatch"),
        (ASCII.replace("POINT_DATA 5", "POINT_DATA 4"), "count mismatch"),
        (ASCII.replace("VECTORS v float", "COLOR_SCALARS v 18446744073709551615"), "overflows"),
        (ASCII.replace("VECTORS v float", "TEXTURE_COORDINATES v 18446744073709551615 float"), "overflows"),
        (ASCII.replace("SCALARS temp double", "SCALARS temp double 9"), "bad component count"),
        // A line holding only a vertical tab (ASCII whitespace to some splitters, not to others).
        (ASCII.replace("POINT_DATA 5", "\x0b\nPOINT_DATA 5"), "bad keyword"),
        (ASCII.replace("POINT_DATA 5", "\u{3000}\nPOINT_DATA 5"), "bad keyword"),
        (ASCII.replace("POINT_DATA 5", "\u{ff}\nPOINT_DATA 5"), "bad keyword"),
        // Non-finite or out-of-range values.
        (ASCII.replace("1 1 1", "1 nan 1"), "non-finite coordinate"),
        (ASCII.replace("1 1 1", "1 -inf 1"), "non-finite coordinate"),
        (ASCII.replace("1 1 1", "1 1e39 1"), "beyond the f32 range"),
        (ASCII.replace("0.5 1.5", "0.5 NaN"), "non-finite scalar"),
        (ASCII.replace("0.5 1.5", "0.5 inf"), "non-finite scalar"),
        (ASCII.replace("0.5 1.5", "0.5 1e300"), "beyond the f32 range"),
        // Connectivity.
        (ASCII.replace("4 1 3 2 4", "4 1 3 2 5"), "out of range"),
        (ASCII.replace("4 1 3 2 4", "4 1 3 2 -1"), "out of range"),
        (ASCII.replace("4 1 3 2 4", "4 1 3 3 4"), "repeats a vertex"),
        (ASCII.replace("4 1 3 2 4", "4 1 3 2 x"), "value 'x' in CELLS (value 9 of 10) is not an integer"),
        // Cell types and sizes.
        (ASCII.replace("10\n10\n", "10\n12\n"), "cell 1 is a hexahedron (type 12) but has 4 vertices, not 8"),
        (ASCII.replace("10\n10\n", "10\n-3\n"), "unknown cell type -3 at cell 1"),
        (ASCII.replace("10\n10\n", "10\n24\n"), "cell 1 (quadratic tetra, type 24) has 4 nodes, not 10"),
        (ASCII.replace("10\n10\n", "10\n41\n"), "unsupported cells: 1 cells of type 41 (convex point set)"),
        (ASCII.replace("CELLS 2 10", "CELLS 2 9").replace("4 1 3 2 4", "3 1 3 2"), "has 3 vertices"),
        // Missing or out-of-order sections, empty meshes.
        (ASCII.replace("CELL_TYPES 2\n10\n10\n", ""), "no CELL_TYPES"),
        (ASCII[..ASCII.find("POINT_DATA").unwrap()].to_string(), "no point scalars"),
        (ASCII.replace("POINTS 5 float\n0 0 0  1 0 0  0 1 0\n0 0 1  1 1 1\n", ""), "CELLS before POINTS"),
        (
            "# vtk DataFile Version 3.0\ne\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 0 float\n\
             CELLS 0 0\nCELL_TYPES 0\nPOINT_DATA 0\nSCALARS s float\nLOOKUP_TABLE default\n"
                .into(),
            "empty mesh",
        ),
        // Version 5 offsets.
        (ASCII5.replace("0 4\nCONN", "0 5\nCONN"), "OFFSETS must rise"),
        (ASCII5.replace("0 4\nCONN", "1 4\nCONN"), "OFFSETS must rise"),
        (ASCII5.replace("CELLS 2 4", "CELLS 2 99999999999"), "count mismatch: CONNECTIVITY needs 99999999999 values, found 4 before 'CELL_TYPES'"),
        (ASCII5.replace("0 1 2 3\n", "0 1 2 9\n"), "out of range"),
    ];
    for (i, (text, what)) in cases.iter().enumerate() {
        let r = catch_unwind(|| parse_vtk_bytes(n, text.as_bytes()))
            .unwrap_or_else(|_| panic!("case {i} panicked: {text:?}"));
        let e = err_of(n, r);
        assert!(e.contains(what), "case {i}: expected '{what}' in: {e}");
    }
    // The unmodified inputs are fine.
    assert_eq!(parse_vtk_bytes(n, ASCII.as_bytes()).unwrap().stats.reoriented, 1);
    assert_eq!(parse_vtk_bytes(n, ASCII5.as_bytes()).unwrap().tets.len(), 1);
}

#[test]
fn vtk_binary_bad_values() {
    let n = "bin.vtk";
    let ok = binary_vtk(&UNIT_TET, &[[0, 1, 2, 3]], &[10], &[1., 2., 3., 4.]);
    parse_vtk_bytes(n, &ok).unwrap();
    let mut p = UNIT_TET;
    p[4] = f64::NAN;
    assert_err(n, parse_vtk_bytes(n, &binary_vtk(&p, &[[0, 1, 2, 3]], &[10], &[0.; 4])), "non-finite coordinate");
    p[4] = f64::INFINITY;
    assert_err(n, parse_vtk_bytes(n, &binary_vtk(&p, &[[0, 1, 2, 3]], &[10], &[0.; 4])), "non-finite coordinate");
    p[4] = 1e300;
    assert_err(n, parse_vtk_bytes(n, &binary_vtk(&p, &[[0, 1, 2, 3]], &[10], &[0.; 4])), "supported coordinate range");
    let s = [0., f32::NAN, 0., 0.];
    assert_err(n, parse_vtk_bytes(n, &binary_vtk(&UNIT_TET, &[[0, 1, 2, 3]], &[10], &s)), "non-finite scalar");
    let s = [0., 0., f32::NEG_INFINITY, 0.];
    assert_err(n, parse_vtk_bytes(n, &binary_vtk(&UNIT_TET, &[[0, 1, 2, 3]], &[10], &s)), "non-finite scalar");
    let z = [0.; 4];
    for (cell, what) in [
        ([0, 1, 2, 4], "out of range"),
        ([0, 1, 2, i32::MIN], "out of range"),
        ([0, 1, 1, 3], "repeats a vertex"),
        ([3, 3, 3, 3], "repeats a vertex"),
    ] {
        assert_err(n, parse_vtk_bytes(n, &binary_vtk(&UNIT_TET, &[cell], &[10], &z)), what);
    }
    for (t, what) in [(12, "hexahedron"), (24, "quadratic tetra"), (i32::MAX, "unknown")] {
        assert_err(n, parse_vtk_bytes(n, &binary_vtk(&UNIT_TET, &[[0, 1, 2, 3]], &[t], &z)), what);
    }
    // A header count far beyond the file (checked before allocating).
    let mut big = b"# vtk DataFile Version 3.0\nbinary\nBINARY\nDATASET UNSTRUCTURED_GRID\n".to_vec();
    big.extend(b"POINTS 4000000000000000 double\n");
    big.extend(be(&UNIT_TET, f64::to_be_bytes));
    assert_err(n, parse_vtk_bytes(n, &big), "truncated file: POINTS needs 12000000000000000 values");
}

#[test]
fn plot3d_corrupt_headers_and_values() {
    let x = "g.xyz";
    let dims_case = |d: [i32; 3], len: usize| {
        let mut b = be(&d, i32::to_be_bytes);
        b.resize(len, 0);
        b
    };
    for (bytes, what) in [
        (dims_case([-2, 3, 2], 400), "invalid PLOT3D dimensions [-2, 3, 2]"),
        (dims_case([0, 3, 2], 400), "invalid"),
        (dims_case([65537, 1, 1], 400), "invalid"),
        (dims_case([i32::MIN, i32::MAX, -1], 400), "invalid"),
        // 65536^3 points: overflows the 32-bit point count.
        (dims_case([65536, 65536, 65536], 400), "overflow"),
        // A product far beyond the file size: rejected before allocating.
        (dims_case([1000, 1000, 1000], 400), "truncated PLOT3D grid"),
        (dims_case([2, 2, 2], 12 + 12 * 8 + 5), "unexpected PLOT3D grid size"),
        (dims_case([2, 2, 2], 7), "shorter than the 12-byte"),
        ({
            let mut b = xyz_bytes([3, 2, 2], false);
            for (o, d) in [(0, 3i32), (4, 2), (8, 2)] {
                b[o..o + 4].copy_from_slice(&d.to_le_bytes());
            }
            b
        }, "little-endian"),
    ] {
        let r = catch_unwind(|| parse_xyz_bytes(x, &bytes)).expect("no panic");
        let e = err_of(x, r);
        assert!(e.contains(what), "expected '{what}' in: {e}");
    }
    let mut nan = xyz_bytes([2, 2, 2], false);
    nan[12 + 4 * (8 + 3)..12 + 4 * (8 + 4)].copy_from_slice(&f32::NAN.to_be_bytes());
    let e = err_of(x, parse_xyz_bytes(x, &nan));
    assert!(e.contains("non-finite value NaN in y at point 3"), "{e}");
    let mut inf = xyz_bytes([2, 2, 2], false);
    inf[12..16].copy_from_slice(&f32::INFINITY.to_be_bytes());
    assert!(err_of(x, parse_xyz_bytes(x, &inf)).contains("in x at point 0"));

    let q = "g.q";
    for (bytes, what) in [
        (dims_case([1000, 1000, 1000], 400), "truncated PLOT3D solution"),
        (dims_case([0, 1, 1], 400), "invalid"),
    ] {
        assert!(err_of(q, parse_q_bytes(q, &bytes)).contains(what));
    }
    let mut b = q_bytes([2, 2, 2]);
    b[12 + 8..12 + 12].copy_from_slice(&f32::INFINITY.to_be_bytes());
    assert!(err_of(q, parse_q_bytes(q, &b)).contains("non-finite free-stream value re"));
    let mut b = q_bytes([2, 2, 2]);
    b[28 + 4 * 8 * 4 + 4..28 + 4 * 8 * 4 + 8].copy_from_slice(&f32::NAN.to_be_bytes());
    assert!(err_of(q, parse_q_bytes(q, &b)).contains("non-finite value NaN in stagnation energy at point 1"));
}

#[test]
fn plot3d_pairs_mismatched_empty_and_by_path() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    // A valid pair loads by either file name, as a path.
    let px = write(d, "finxyz.bin", &xyz_bytes([3, 2, 2], true));
    write(d, "finq.bin", &q_bytes([3, 2, 2]));
    for f in ["finxyz.bin", "finq.bin"] {
        let m = load_path(d.join(f)).unwrap();
        assert_eq!((m.name.as_str(), m.tets.len()), ("finxyz", 10));
        check_finite(&m);
    }
    // Solution of other dimensions: names both files.
    write(d, "mixq.bin", &q_bytes([2, 2, 3]));
    std::fs::copy(&px, d.join("mixxyz.bin")).unwrap();
    let e = format!("{:#}", load_path(d.join("mixxyz.bin")).unwrap_err());
    assert!(e.contains("mixq.bin") && e.contains("mixxyz.bin") && e.contains("do not match"), "{e}");
    // One point thick: no cells.
    write(d, "flat.xyz", &xyz_bytes([3, 2, 1], false));
    write(d, "flat.q", &q_bytes([3, 2, 1]));
    let e = format!("{:#}", load_path(d.join("flat.q")).unwrap_err());
    assert!(e.contains("flat.xyz") && e.contains("no hexahedral cells"), "{e}");
    // Missing partner, unknown naming.
    write(d, "lonexyz.bin", &xyz_bytes([2, 2, 2], false));
    let e = format!("{:#}", load_path(d.join("lonexyz.bin")).unwrap_err());
    assert!(e.contains("loneq.bin") && e.contains("not found"), "{e}");
    let e = format!("{:#}", load_path(d.join("grid.bin")).unwrap_err());
    assert!(e.contains("grid.bin") && e.contains("NAMExyz.bin"), "{e}");
    // Collapsed hexes are kept as zero-volume cells beside solid ones...
    let mut some = xyz_bytes([3, 2, 2], false);
    let x = |p: usize| 12 + 4 * p; // x of point p (the first coordinate block)
    for p in [2, 5, 8, 11] {
        // Move the i = 2 face onto the i = 1 face: the second hex is flat.
        let v: [u8; 4] = some[x(p - 1)..x(p - 1) + 4].try_into().unwrap();
        some[x(p)..x(p) + 4].copy_from_slice(&v);
        for c in [1, 2] {
            let (a, b) = (x(p - 1) + 48 * c, x(p) + 48 * c);
            let v: [u8; 4] = some[a..a + 4].try_into().unwrap();
            some[b..b + 4].copy_from_slice(&v);
        }
    }
    write(d, "somexyz.bin", &some);
    write(d, "someq.bin", &q_bytes([3, 2, 2]));
    let m = load_path(d.join("somexyz.bin")).unwrap();
    // Its four corner tets repeat a point; the central one spans the i = 1
    // face, planar but for f32 rounding: a sliver, not zero-volume.
    assert_eq!(m.stats.zero_volume, 4);
    check_finite(&m);
    // ...but a mesh with no volume at all is an error: it would render nothing.
    let mut same = xyz_bytes([2, 2, 2], false);
    for v in same[12..].chunks_exact_mut(4) {
        v.copy_from_slice(&1.0f32.to_be_bytes());
    }
    write(d, "samexyz.bin", &same);
    write(d, "sameq.bin", &q_bytes([2, 2, 2]));
    let e = format!("{:#}", load_path(d.join("samexyz.bin")).unwrap_err());
    assert!(e.contains("samexyz.bin") && e.contains("zero extent: all 8 points are at (1e0, 1e0, 1e0)"), "{e}");
    let mut flat = xyz_bytes([2, 2, 2], false);
    for v in flat[12 + 4 * 16..].chunks_exact_mut(4) {
        v.copy_from_slice(&2.0f32.to_be_bytes()); // every z the same
    }
    write(d, "flatxyz.bin", &flat);
    write(d, "flatq.bin", &q_bytes([2, 2, 2]));
    let e = format!("{:#}", load_path(d.join("flatxyz.bin")).unwrap_err());
    assert!(e.contains("flatxyz.bin") && e.contains("all 5 tets have zero volume"), "{e}");
}

#[test]
fn mesh_size_guard() {
    check_fits(513_375, 528, 1 << 30).unwrap();
    let e = check_fits(513_375, 528, 1 << 20).unwrap_err().to_string();
    assert!(e.contains("513375 cells") && e.contains("too large"), "{e}");
    assert!(check_fits(usize::MAX, usize::MAX, u64::MAX).is_err());
}

// ------------------------------------- messages that say what is wrong (issue 8)

#[test]
fn vtk_messages_say_what_is_wrong() {
    let n = "msg.vtk";
    let cases: Vec<(String, &str)> = vec![
        // Versions: only 1.0 to 5.x, and the cell layout must match the version.
        (ASCII.replace("Version 3.0", "Version 6.0"), "unsupported VTK legacy file version '6.0'"),
        (ASCII.replace("Version 3.0", "Version 0.9"), "unsupported VTK legacy file version '0.9'"),
        (ASCII.replace("Version 3.0", "Version x"), "unsupported VTK legacy file version 'x'"),
        (ASCII.replace("Version 3.0", "Version 5.1"), "expected OFFSETS after CELLS, found '4': a version 5.1 file"),
        (ASCII5.replace("Version 5.1", "Version 4.2"), "OFFSETS after CELLS: that layout needs file version 5.x, but the header says 4.2"),
        // Line endings.
        (ASCII.replace('\n', "\r"), "bare carriage return (CR-only line endings"),
        (ASCII.replacen('\n', "\r", 5), "bare carriage return (CR-only line endings"),
        // Other formats.
        (format!("\u{feff}{ASCII}"), "not a VTK legacy file: it starts with a UTF-8 byte-order mark"),
        ("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\">\n".into(), "this is an XML VTK file"),
        // Values that do not fit the declared (or implied) type.
        (
            ASCII.replace("SCALARS temp double", "SCALARS temp unsigned_char").replace("0.5 1.5", "0 300"),
            "value '300' in SCALARS 'temp' (value 1 of 5) does not fit the type unsigned_char (0 to 255)",
        ),
        (
            ASCII.replace("SCALARS temp double", "SCALARS temp unsigned_int").replace("0.5 1.5 2.5", "0 1 -1"),
            "value '-1' in SCALARS 'temp' (value 2 of 5) does not fit the type unsigned_int (0 to 4294967295)",
        ),
        (
            ASCII.replace("SCALARS temp double", "SCALARS temp int").replace("0.5 1.5", "1 1.5"),
            "value '1.5' in SCALARS 'temp' (value 1 of 5) is not an integer, as the type int requires",
        ),
        (ASCII.replace("POINTS 5 float", "POINTS 5 short").replace("1 1 1", "1 1 1e3"), "value '1e3' in POINTS (value 14 of 15) is not an integer"),
        (ASCII.replace("POINTS 5 float", "POINTS 5 char").replace("1 1 1", "1 1 128"), "does not fit the type char (-128 to 127)"),
        (ASCII.replace("1 1 1", "1 -3.5e38 1"), "value '-3.5e38' in POINTS (value 13 of 15) is beyond the f32 range"),
        (ASCII.replace("4 1 3 2 4", "4 1 3 2 4294967296"), "value '4294967296' in CELLS (value 9 of 10) does not fit the type int"),
        // ...also in arrays that are skipped.
        (ASCII.replace("VECTORS v float", "VECTORS v unsigned_char").replacen(" 0 0 0 0", " 0 0 0 256", 1), "does not fit the type unsigned_char"),
        // An array shorter than its header: the next section is named.
        (ASCII.replace("POINTS 5 float", "POINTS 6 float"), "count mismatch: POINTS needs 18 values, found 15 before 'CELLS'"),
        (ASCII.replace("SCALARS temp double", "SCALARS temp double\nLOOKUP_TABLE default\n1 2\nSCALARS t2 double"), "count mismatch: SCALARS 'temp' needs 5 values, found 2 before 'SCALARS'"),
    ];
    for (i, (text, what)) in cases.iter().enumerate() {
        let r = catch_unwind(|| parse_vtk_bytes(n, text.as_bytes()))
            .unwrap_or_else(|_| panic!("case {i} panicked: {text:?}"));
        let e = err_of(n, r);
        assert!(e.contains(what), "case {i}: expected '{what}' in: {e}");
    }
    // Every supported version and line ending still loads.
    for v in ["1.0", "2.0", "3.0", "4.0", "4.2", "3"] {
        let m = parse_vtk_bytes(n, ASCII.replace("Version 3.0", &format!("Version {v}")).as_bytes());
        assert_eq!(m.unwrap_or_else(|e| panic!("{v}: {e:#}")).tets.len(), 2);
    }
    assert_eq!(parse_vtk_bytes(n, ASCII.replace('\n', "\r\n").as_bytes()).unwrap().tets.len(), 2);
    let typed = ASCII.replace("SCALARS temp double", "SCALARS temp unsigned_char").replace("0.5 1.5 2.5 3.5 4.5", "0 255 7 8 9");
    assert_eq!(parse_vtk_bytes(n, typed.as_bytes()).unwrap().scalars, vec![0.0, 255.0, 7.0, 8.0, 9.0]);
}

#[test]
fn vtk_little_endian_binary_is_recognised() {
    let n = "le.vtk";
    let s = [1.0f32, 2.0, 3.0, 4.0];
    let e = err_of(n, parse_vtk_bytes(n, &binary_vtk_ordered(&UNIT_TET, &[[0, 1, 2, 3]], &[10], &s, true, false)));
    assert!(e.contains("POINTS: the values look little-endian") && e.contains("3 of 12 are implausible"), "{e}");
    assert!(e.contains("write the file big-endian"), "{e}");
    // Realistic coordinates (no zero low bytes) too.
    let pts: Vec<f64> = UNIT_TET.iter().enumerate().map(|(i, v)| v * 1.37 + 0.1 * i as f64).collect();
    let e = err_of(n, parse_vtk_bytes(n, &binary_vtk_ordered(&pts, &[[0, 1, 2, 3]], &[10], &s, true, false)));
    assert!(e.contains("look little-endian"), "{e}");
    // Little-endian cells: the count and the cell type say so.
    let e = err_of(n, parse_vtk_bytes(n, &binary_vtk_ordered(&UNIT_TET, &[[0, 1, 2, 3]], &[10], &s, false, true)));
    assert!(e.contains("claims 67108864 vertices") && e.contains("the file looks little-endian"), "{e}");
    let e = err_of(n, parse_vtk_bytes(n, &binary_vtk(&UNIT_TET, &[[0, 1, 2, 3]], &[10i32.swap_bytes()], &s)));
    assert!(e.contains("unknown cell type 167772160") && e.contains("the file looks little-endian"), "{e}");
    // The same mesh big-endian loads, as does the shipped binary file.
    parse_vtk_bytes(n, &binary_vtk(&pts, &[[0, 1, 2, 3]], &[10], &s)).unwrap();
    parse_vtk_bytes("post.vtk", &post_vtk()).unwrap();
}

#[test]
fn plot3d_messages_say_what_is_wrong() {
    let grid = xyz_bytes([2, 2, 2], false);
    let q = q_bytes([2, 2, 2]);
    let record = |b: &[u8]| [&(b.len() as i32).to_be_bytes()[..], b, &(b.len() as i32).to_be_bytes()[..]].concat();
    let fortran_xyz = [record(&grid[..12]), record(&grid[12..])].concat();
    let fortran_q = [record(&q[..12]), record(&q[12..28]), record(&q[28..])].concat();
    let multi_xyz = [&1i32.to_be_bytes()[..], &grid].concat();
    let multi_q = [&1i32.to_be_bytes()[..], &q].concat();
    let two = [&2i32.to_be_bytes()[..], &grid[..12], &grid[..12], &grid[12..], &grid[12..]].concat();
    let mut le_floats = grid.clone();
    for c in le_floats[12..].chunks_exact_mut(4) {
        c.reverse();
    }
    let mut le_fields = q.clone();
    for c in le_fields[28..].chunks_exact_mut(4) {
        c.reverse();
    }
    for (name, r, what) in [
        ("f.xyz", parse_xyz_bytes("f.xyz", &fortran_xyz).map(drop), "Fortran unformatted PLOT3D file"),
        ("f.q", parse_q_bytes("f.q", &fortran_q).map(drop), "Fortran unformatted PLOT3D file"),
        ("m.xyz", parse_xyz_bytes("m.xyz", &multi_xyz).map(drop), "multi-grid PLOT3D file (1 grid,"),
        ("m.q", parse_q_bytes("m.q", &multi_q).map(drop), "multi-grid PLOT3D file (1 grid,"),
        ("m2.xyz", parse_xyz_bytes("m2.xyz", &two).map(drop), "multi-grid PLOT3D file (2 grids,"),
        ("le.xyz", parse_xyz_bytes("le.xyz", &le_floats).map(drop), "x (byte offset 12): the values look little-endian"),
        ("le.q", parse_q_bytes("le.q", &le_fields).map(drop), "density (byte offset 28): the values look little-endian"),
    ] {
        let e = err_of(name, r);
        assert!(e.contains(what), "{name}: expected '{what}' in: {e}");
    }
}

// ------------------------------- no blank or wrong picture accepted (issue 8)

/// An ASCII VTK of the unit tet and a second tet (the ASCII mesh's points)
/// scaled by `s` and moved by `t`, coordinates written as doubles.
fn scaled_vtk(s: f64, t: f64) -> String {
    let pts = [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.], [1., 1., 1.]];
    let text: Vec<String> = pts.iter().flatten().map(|c| format!("{:e}", c * s + t)).collect();
    ASCII.replace("POINTS 5 float\n0 0 0  1 0 0  0 1 0\n0 0 1  1 1 1", &format!("POINTS 5 double\n{}", text.join(" ")))
}

#[test]
fn meshes_outside_the_supported_ranges_are_rejected() {
    let n = "range.vtk";
    // The stress suite's meshes stay accepted: scaled 1e-12..1e12, moved 1e7.
    for (s, t) in [(1.0, 0.0), (1e-12, 0.0), (1e12, 0.0), (1.0, 1e7), (1e-6, -1e7), (1e14, 0.0)] {
        let m = parse_vtk_bytes(n, scaled_vtk(s, t).as_bytes()).unwrap_or_else(|e| panic!("{s:e} {t:e}: {e:#}"));
        assert_eq!(m.tets.len(), 2);
        check_finite(&m);
    }
    for (s, t, what) in [
        (1e19, 0.0, "point 1 at (1e19, 0e0, 0e0) is outside the supported coordinate range [-1e15, 1e15]"),
        (1e-20, 0.0, "the mesh's extent (bounding-box diagonal) 1.73"),
        (1e-20, 0.0, "e-20 is outside the supported range 1e-15 to 1e15"),
        (1e-16, 0.0, "extent (bounding-box diagonal) 1.7"),
        (1.0, 1e16, "is outside the supported coordinate range"),
        (0.0, 5.0, "the mesh has zero extent: all 5 points are at (5e0, 5e0, 5e0)"),
    ] {
        assert_err(n, parse_vtk_bytes(n, scaled_vtk(s, t).as_bytes()), what);
    }
    // A mesh of flat cells only renders nothing; one flat cell among others is counted.
    let flat = ASCII.replace("0 0 1  1 1 1", "1 1 0  2 0 0").replace("4 1 3 2 4", "4 0 1 3 4");
    assert_err(n, parse_vtk_bytes(n, flat.as_bytes()), "all 2 tets have zero volume");
    let one_flat = ASCII.replace("0 0 1  1 1 1", "0 0 1  1 1 0").replace("CELLS 2 10", "CELLS 3 15").replace(
        "4 1 3 2 4\n",
        "4 1 3 2 4\n4 0 1 2 4\n",
    );
    let m = parse_vtk_bytes(n, one_flat.replace("CELL_TYPES 2\n10\n10", "CELL_TYPES 3\n10 10 10").as_bytes()).unwrap();
    assert_eq!((m.tets.len(), m.stats.zero_volume), (3, 1));
}

#[test]
fn duplicate_tets_are_rejected() {
    let n = "dup.vtk";
    let dup = |cells: &str, k: usize| {
        let types = vec!["10"; k].join(" ");
        ASCII.replace("CELLS 2 10\n4 0 1 2 3\n4 1 3 2 4\n", &format!("CELLS {k} {}\n{cells}", 5 * k))
            .replace("CELL_TYPES 2\n10\n10", &format!("CELL_TYPES {k}\n{types}"))
    };
    // The same four vertices in another order (rotations, reflections).
    let text = dup("4 0 1 2 3\n4 1 3 2 4\n4 3 2 1 0\n4 4 2 3 1\n4 2 0 3 1\n", 5);
    assert_err(n, parse_vtk_bytes(n, text.as_bytes()), "3 duplicate tet(s): tet 2 has the same four vertex positions as tet 0");
    let text = dup("4 1 3 2 4\n4 0 1 2 3\n4 1 2 3 4\n", 3);
    assert_err(n, parse_vtk_bytes(n, text.as_bytes()), "1 duplicate tet(s): tet 2 has the same four vertex positions as tet 0");
    // The same positions through a duplicated point (point 5 repeats point 4).
    let text = ASCII
        .replace("POINTS 5 float\n0 0 0  1 0 0  0 1 0\n0 0 1  1 1 1", "POINTS 6 float\n0 0 0  1 0 0  0 1 0\n0 0 1  1 1 1  1 1 1")
        .replace("CELLS 2 10\n4 0 1 2 3\n4 1 3 2 4\n", "CELLS 3 15\n4 0 1 2 3\n4 1 3 2 4\n4 5 3 2 1\n")
        .replace("CELL_TYPES 2\n10\n10", "CELL_TYPES 3\n10 10 10")
        .replace("POINT_DATA 5", "POINT_DATA 6")
        .replace("0 0 0 0 0 0 0 0 0 0 0 0 0 0 0", &"0 ".repeat(18))
        .replace("0.5 1.5 2.5 3.5 4.5", "0.5 1.5 2.5 3.5 4.5 4.5");
    assert_err(n, parse_vtk_bytes(n, text.as_bytes()), "1 duplicate tet(s): tet 2 has the same four vertex positions as tet 1");
    // A PLOT3D grid folded back onto itself (layer k = 2 on layer k = 0):
    // the second layer of hexes repeats the first one's tets.
    let mut folded = xyz_bytes([2, 2, 3], false);
    let np = 12;
    for c in 0..3 {
        for p in 0..4 {
            let (from, to) = (12 + 4 * (c * np + p), 12 + 4 * (c * np + 8 + p));
            let v: [u8; 4] = folded[from..from + 4].try_into().unwrap();
            folded[to..to + 4].copy_from_slice(&v);
        }
    }
    let tmp = tempfile::tempdir().unwrap();
    let px = write(tmp.path(), "foldxyz.bin", &folded);
    let pq = write(tmp.path(), "foldq.bin", &q_bytes([2, 2, 3]));
    let e = format!("{:#}", load_plot3d("fold", &px, &pq, Plot3dScalar::Density).unwrap_err());
    assert!(e.contains("foldxyz.bin") && e.contains("duplicate tet(s): tet 5 has the same four vertex positions as tet"), "{e}");
}

// -------------------------------------------------- regressions, mutation

/// Every file under `tests/regressions/<parser>/` (inputs found by fuzzing
/// or review that once crashed a reader) is read without a panic; the
/// expected error is checked where known.
#[test]
fn regression_inputs() {
    let known: &[(&str, &str)] = &[
        ("vtk/version-6.vtk", "unsupported VTK legacy file version '6.0'"),
        ("vtk/cr-only-lines.vtk", "bare carriage return (CR-only line endings"),
        ("vtk/unsigned-char-300.vtk", "value '300' in SCALARS 's' (value 1 of 4) does not fit the type unsigned_char"),
        ("vtk/little-endian-floats.vtk", "POINTS: the values look little-endian"),
        ("vtk/duplicate-tets.vtk", "1 duplicate tet(s): tet 2 has the same four vertex positions as tet 0"),
        ("vtk/scaled-1e19.vtk", "outside the supported coordinate range [-1e15, 1e15]"),
        ("vtk/scaled-1e-20.vtk", "is outside the supported range 1e-15 to 1e15"),
        ("vtk/all-cells-flat.vtk", "all 2 tets have zero volume"),
        ("plot3d_xyz/fortran-records.xyz", "Fortran unformatted PLOT3D file"),
        ("plot3d_xyz/multi-grid.xyz", "multi-grid PLOT3D file (1 grid,"),
        ("plot3d_xyz/little-endian.xyz", "read as little-endian they would be [2, 2, 2]"),
        ("plot3d_xyz/little-endian-floats.xyz", "x (byte offset 12): the values look little-endian"),
        ("plot3d_q/fortran-records.q", "Fortran unformatted PLOT3D file"),
        ("plot3d_q/multi-grid.q", "multi-grid PLOT3D file (1 grid,"),
        ("plot3d_q/little-endian-fields.q", "density (byte offset 28): the values look little-endian"),
        ("vtk/huge-coordinates-infinite-volume.vtk", "outside the supported coordinate range"),
        ("vtk/vertical-tab-line.vtk", r"bad keyword '\u{b}'"),
        ("vtk/cells-vertex-count-huge.vtk", "'9223372036854775807' in CELLS (value 0 of 5) does not fit the type int"),
        ("vtk/cells-count-beyond-size.vtk", "count mismatch: CELLS declares"),
        ("vtk/color-scalars-size-overflow.vtk", "overflows"),
    ];
    let root = repo("tests/regressions");
    let mut seen = 0;
    for dir in ["vtk", "plot3d_xyz", "plot3d_q"] {
        // Every reader's folder is committed (a missing one is a failure,
        // not a silently skipped reader).
        let entries = std::fs::read_dir(root.join(dir))
            .unwrap_or_else(|e| panic!("{}: {e}", root.join(dir).display()));
        for entry in entries {
            let path = entry.unwrap().path();
            let bytes = std::fs::read(&path).unwrap();
            let rel = format!("{dir}/{}", path.file_name().unwrap().to_string_lossy());
            let r = catch_unwind(|| match dir {
                "vtk" => parse_vtk_bytes(&rel, &bytes).map(|m| check_finite(&m)),
                "plot3d_xyz" => parse_xyz_bytes(&rel, &bytes).map(drop),
                _ => parse_q_bytes(&rel, &bytes).map(drop),
            })
            .unwrap_or_else(|_| panic!("{rel} panicked"));
            if let Some((_, what)) = known.iter().find(|(k, _)| *k == rel) {
                let e = err_of(&rel, r);
                assert!(e.contains(what), "{rel}: expected '{what}' in: {e}");
            }
            seen += 1;
        }
    }
    assert!(seen >= known.len(), "regression inputs missing under {}", root.display());
    for (k, _) in known {
        assert!(root.join(k).is_file(), "{k} is missing");
    }
}

/// xorshift64*: deterministic, so a failure reproduces.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545F4914F6CDD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

const TOKENS: &[&[u8]] = &[
    b" -1", b" 0", b" 4294967296", b" 18446744073709551615", b" 9223372036854775807", b" nan", b" inf",
    b" 1e308", b" -0", b"\n", b"\x0b", b"\r\n", b" ", b"POINTS 4 float\n", b"CELLS 1 5\n", b"CELL_TYPES 1\n",
    b"POINT_DATA 4\n", b"CELL_DATA 1\n", b"SCALARS s float 1\n", b"LOOKUP_TABLE default\n",
    b"FIELD f 1\n", b"a 1 4 float\n", b"METADATA\n", b"OFFSETS vtktypeint64\n", b"NULL_ARRAY\n", b"\xff\xfe",
];

const WORDS: &[[u8; 4]] = &[
    [0, 0, 0, 0],
    [0xff, 0xff, 0xff, 0xff],
    [0x7f, 0xff, 0xff, 0xff],
    [0x80, 0, 0, 0],
    [0x7f, 0x80, 0, 0],
    [0x7f, 0xc0, 0, 0],
    [0, 1, 0, 0],
    [0, 0, 0, 2],
    [0x7f, 0x7f, 0xff, 0xff],
    [0, 0, 0, 1],
];

fn mutate(rng: &mut Rng, input: &[u8]) -> Vec<u8> {
    let mut b = input.to_vec();
    for _ in 0..1 + rng.below(4) {
        let at = rng.below(b.len() + 1);
        match rng.below(8) {
            0 if !b.is_empty() => {
                let i = rng.below(b.len());
                b[i] ^= 1 << rng.below(8);
            }
            1 if !b.is_empty() => {
                let i = rng.below(b.len());
                b[i] = [0u8, 0xff, b'\n', b' ', b'-', b'9', 0x0b, 0x80][rng.below(8)];
            }
            2 => {
                let end = (at + 1 + rng.below(16)).min(b.len());
                b.drain(at.min(end)..end);
            }
            3 => {
                let t = TOKENS[rng.below(TOKENS.len())];
                b.splice(at..at, t.iter().copied());
            }
            4 if b.len() >= 4 => {
                let i = rng.below(b.len() - 3);
                b[i..i + 4].copy_from_slice(&WORDS[rng.below(WORDS.len())]);
            }
            5 => {
                // Replace an ASCII number with an extreme one.
                let digits: Vec<usize> = (0..b.len()).filter(|&i| b[i].is_ascii_digit()).collect();
                if !digits.is_empty() {
                    let i = digits[rng.below(digits.len())];
                    let t = TOKENS[rng.below(9)];
                    b.splice(i..i + 1, t[1..].iter().copied());
                }
            }
            6 if b.len() > 1 => {
                // Duplicate a chunk.
                let s = rng.below(b.len());
                let e = (s + 1 + rng.below(32)).min(b.len());
                let chunk = b[s..e].to_vec();
                b.splice(at..at, chunk);
            }
            _ => b.truncate(at),
        }
    }
    b
}

/// Thousands of mutations of valid files through every byte parser: no
/// panic, and errors name the file. (The bounded, deterministic counterpart
/// of the cargo-fuzz targets in `fuzz/`; it runs on stable with the tests.)
#[test]
fn mutated_inputs_never_panic() {
    let seeds: Vec<(&str, Vec<u8>)> = vec![
        ("vtk", ASCII.as_bytes().to_vec()),
        ("vtk", ASCII5.as_bytes().to_vec()),
        ("vtk", binary_vtk(&UNIT_TET, &[[0, 1, 2, 3]], &[10], &[1., 2., 3., 4.])),
        ("xyz", xyz_bytes([3, 2, 2], false)),
        ("xyz", xyz_bytes([2, 2, 2], true)),
        ("q", q_bytes([2, 2, 2])),
    ];
    let mut rng = Rng(0x5EED_F022);
    let (mut ok, mut total) = (0, 0);
    for (kind, seed) in &seeds {
        for _ in 0..2500 {
            let input = mutate(&mut rng, seed);
            let r = catch_unwind(AssertUnwindSafe(|| match *kind {
                "vtk" => parse_vtk_bytes("m.in", &input).map(|m| check_finite(&m)),
                "xyz" => parse_xyz_bytes("m.in", &input).map(drop),
                _ => parse_q_bytes("m.in", &input).map(drop),
            }));
            match r {
                Ok(Ok(())) => ok += 1,
                Ok(Err(e)) => {
                    let e = format!("{e:#}");
                    assert!(e.starts_with("m.in: "), "{kind} error without the file name: {e}");
                }
                Err(_) => panic!("{kind} parser panicked on {:?}", String::from_utf8_lossy(&input)),
            }
            total += 1;
        }
    }
    // Some mutations keep the file valid; most must not.
    assert!(ok > 0 && ok < total, "{ok} of {total} mutated inputs loaded");
}

// -------------------------------------------------------------------- CLI

/// `volbench run --mesh PATH` on a bad file: exit code 1 (not a panic's
/// 101), a message naming the file and the problem, and no JSON or PNG left.
/// The mesh loads before any Vulkan work, so these need no device.
fn cli_fails(mesh: &Path, what: &[&str]) {
    let out_dir = tempfile::tempdir().unwrap();
    let json = out_dir.path().join("x.json");
    let png = out_dir.path().join("x.png");
    let out = Command::new(env!("CARGO_BIN_EXE_volbench"))
        .args(["run", "--method", "balanced", "--frames", "1", "--size", "64x64", "--mesh"])
        .arg(mesh)
        .arg("--json")
        .arg(&json)
        .arg("--png")
        .arg(&png)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{}: stderr: {stderr}", mesh.display());
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains("volbench: error:"), "{stderr}");
    assert!(stderr.contains(&mesh.display().to_string()), "file not named: {stderr}");
    for w in what {
        assert!(stderr.contains(w), "expected '{w}' in: {stderr}");
    }
    assert!(!json.exists() && !png.exists(), "output left behind");
}

#[test]
fn cli_rejects_bad_meshes() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    cli_fails(&write(d, "cut.vtk", &post_vtk()[..30_000]), &["truncated"]);
    cli_fails(&write(d, "empty.vtk", b""), &["truncated"]);
    cli_fails(&write(d, "nan.vtk", ASCII.replace("1 1 1", "1 nan 1").as_bytes()), &["non-finite coordinate"]);
    cli_fails(&write(d, "idx.vtk", ASCII.replace("4 1 3 2 4", "4 1 3 2 9").as_bytes()), &["out of range"]);
    cli_fails(&write(d, "rep.vtk", ASCII.replace("4 1 3 2 4", "4 1 3 1 4").as_bytes()), &["repeats a vertex"]);
    cli_fails(&write(d, "hex.vtk", ASCII.replace("10\n10\n", "12\n10\n").as_bytes()), &["hexahedron"]);
    write(d, "mixq.bin", &q_bytes([2, 2, 3]));
    cli_fails(&write(d, "mixxyz.bin", &xyz_bytes([3, 2, 2], false)), &["mixq.bin", "do not match"]);
    cli_fails(&write(d, "grid.bin", &xyz_bytes([3, 2, 2], false)), &["NAMExyz.bin"]);
    cli_fails(&d.join("missing.vtk"), &["no such file"]);
    cli_fails(&write(d, "big.vtk", scaled_vtk(1e19, 0.0).as_bytes()), &["supported coordinate range"]);
    let le = binary_vtk_ordered(&UNIT_TET, &[[0, 1, 2, 3]], &[10], &[1., 2., 3., 4.], true, false);
    cli_fails(&write(d, "le.vtk", &le), &["look little-endian"]);
}
