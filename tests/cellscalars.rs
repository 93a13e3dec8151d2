//! Cell-centred scalars (issue 34 item 1, issue 35 item 20): both readers
//! (legacy `.vtk` and XML `.vtu`) read a cell array, chosen by name or as
//! the fallback when a file has no point scalar; the two treatments
//! (`constant` per cell, `average` to the points as VTK's
//! vtkCellDataToPointData); vectors by magnitude, without overflow; the
//! choice recorded in the dataset summary. On lavapipe with validation:
//! tet-raycast, balanced, pt-compute and the f64 reference agree on a constant-per-cell
//! mesh at two image sizes, tet-raycast with every integrator;
//! one value in every cell gives exactly the homogeneous block's image. No
//! timings.

mod common;
use common::context;

use volbench::algo::registry;
use volbench::harness::datasets::{self, Dataset};
use volbench::harness::image::RgbaImage;
use volbench::harness::run::{run as run_method, RunConfig, RunOutput};
use volbench::mesh::cell_data::{Association, CellData, ScalarChoice};
use volbench::mesh::topology::Topology;
use volbench::mesh::vtk::parse_vtk_bytes_with;
use volbench::mesh::vtu::parse_vtu_bytes_with;
use volbench::mesh::TetMesh;
use volbench::reference::render_reference_with_stats;
use volbench::scene::{Camera, Projection, TransferFunction};

/// A block of `n³` hexahedra on a mildly warped grid, with a cell value per
/// hexahedron and a cell vector; `point_data` adds a point scalar. Point
/// ids are scattered (`perm`) so the quad cuts vary.
struct Block {
    n: usize,
    points: Vec<[f64; 3]>,
    hexes: Vec<[u32; 8]>,
    value: Vec<f64>,
    vector: Vec<[f64; 3]>,
}

fn block(n: usize) -> Block {
    let np = (n + 1).pow(3);
    let perm: Vec<u32> = (0..np as u32).map(|i| (i * 7919) % np as u32).collect();
    let mut seen = perm.clone();
    seen.sort_unstable();
    seen.dedup();
    assert_eq!(seen.len(), np, "7919 is coprime with the point count");
    let at = |i: usize, j: usize, k: usize| perm[i + (n + 1) * (j + (n + 1) * k)];
    let mut points = vec![[0.0; 3]; np];
    for k in 0..=n {
        for j in 0..=n {
            for i in 0..=n {
                let (x, y, z) = (i as f64, j as f64, k as f64);
                points[at(i, j, k) as usize] = [x + 0.08 * (y * 1.3).sin(), y + 0.06 * (z + x).cos(), z + 0.03 * x * y / n as f64];
            }
        }
    }
    let mut hexes = Vec::new();
    let mut value = Vec::new();
    let mut vector = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let c = |di, dj, dk| at(i + di, j + dj, k + dk);
                hexes.push([c(0, 0, 0), c(1, 0, 0), c(1, 1, 0), c(0, 1, 0), c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1)]);
                let h = hexes.len() as f64;
                value.push(((h * 0.37).sin() + 1.0) * 2.0 + 0.1 * i as f64);
                vector.push([3.0 * (h * 0.2).cos(), 4.0, h * 0.1]);
            }
        }
    }
    Block { n, points, hexes, value, vector }
}

impl Block {
    fn legacy(&self, point_data: bool) -> String {
        let mut s = format!("# vtk DataFile Version 3.0\ncells\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS {} double\n", self.points.len());
        for p in &self.points {
            s += &format!("{:?} {:?} {:?}\n", p[0], p[1], p[2]);
        }
        s += &format!("CELLS {} {}\n", self.hexes.len(), 9 * self.hexes.len());
        for h in &self.hexes {
            s += &format!("8 {}\n", h.map(|v| v.to_string()).join(" "));
        }
        s += &format!("CELL_TYPES {}\n{}\n", self.hexes.len(), vec!["12"; self.hexes.len()].join("\n"));
        s += &format!("CELL_DATA {}\nVECTORS vel double\n", self.hexes.len());
        for v in &self.vector {
            s += &format!("{:?} {:?} {:?}\n", v[0], v[1], v[2]);
        }
        s += "SCALARS density double 1\nLOOKUP_TABLE default\n";
        for v in &self.value {
            s += &format!("{v:?}\n");
        }
        if point_data {
            s += &format!("POINT_DATA {}\nSCALARS height double 1\nLOOKUP_TABLE default\n", self.points.len());
            for p in &self.points {
                s += &format!("{:?}\n", p[2]);
            }
        }
        s
    }

    fn vtu(&self, point_data: bool) -> String {
        let join = |v: Vec<String>| v.join(" ");
        let mut s = format!(
            "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\">\n<UnstructuredGrid>\n\
             <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n",
            self.points.len(),
            self.hexes.len()
        );
        if point_data {
            s += &format!(
                "<PointData><DataArray type=\"Float64\" Name=\"height\" format=\"ascii\">{}</DataArray></PointData>\n",
                join(self.points.iter().map(|p| format!("{:?}", p[2])).collect())
            );
        }
        s += &format!(
            "<CellData><DataArray type=\"UInt8\" Name=\"vtkGhostType\" format=\"ascii\">{}</DataArray>\n\
             <DataArray type=\"Float64\" Name=\"vel\" NumberOfComponents=\"3\" format=\"ascii\">{}</DataArray>\n\
             <DataArray type=\"Float64\" Name=\"density\" format=\"ascii\">{}</DataArray></CellData>\n",
            join(vec!["0".to_string(); self.hexes.len()]),
            join(self.vector.iter().flat_map(|v| v.map(|x| format!("{x:?}"))).collect()),
            join(self.value.iter().map(|v| format!("{v:?}")).collect())
        );
        s += &format!(
            "<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">{}</DataArray></Points>\n",
            join(self.points.iter().flat_map(|p| p.map(|x| format!("{x:?}"))).collect())
        );
        s += &format!(
            "<Cells><DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">{}</DataArray>\n\
             <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">{}</DataArray>\n\
             <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">{}</DataArray></Cells>\n",
            join(self.hexes.iter().flat_map(|h| h.map(|v| v.to_string())).collect()),
            join((1..=self.hexes.len()).map(|c| (8 * c).to_string()).collect()),
            join(vec!["12".to_string(); self.hexes.len()])
        );
        s + "</Piece>\n</UnstructuredGrid>\n</VTKFile>\n"
    }

    /// vtkCellDataToPointData's default, from its definition: per point, the
    /// plain mean over the cells using it.
    fn averaged(&self, values: &[f64]) -> Vec<f64> {
        let mut sum = vec![0.0; self.points.len()];
        let mut n = vec![0.0; self.points.len()];
        for (h, cell) in self.hexes.iter().enumerate() {
            for &v in cell {
                sum[v as usize] += values[h];
                n[v as usize] += 1.0;
            }
        }
        sum.iter().zip(&n).map(|(s, n)| s / n).collect()
    }
}

fn legacy(text: &str, array: Option<&str>, cell_data: CellData) -> anyhow::Result<TetMesh> {
    parse_vtk_bytes_with("b.vtk", text.as_bytes(), ScalarChoice { array, cell_data })
}

fn xml(text: &str, array: Option<&str>, cell_data: CellData) -> anyhow::Result<TetMesh> {
    parse_vtu_bytes_with("b.vtu", text.as_bytes(), ScalarChoice { array, cell_data })
}

/// Every tet's four vertices carry one value, its hexahedron's; the copies
/// point back at the file's points, and the walks' adjacency closes as on
/// the mesh with shared points.
fn check_constant(m: &TetMesh, b: &Block, values: &[f64], what: &str) {
    assert_eq!(m.points.len(), 4 * m.tets.len(), "{what}");
    assert_eq!(m.stats.vertex_origin.len(), m.points.len(), "{what}");
    for (t, tet) in m.tets.iter().enumerate() {
        let s = m.scalars[tet[0] as usize];
        assert!(tet.iter().all(|&v| m.scalars[v as usize] == s), "{what}: tet {t}");
        assert!(values.contains(&s), "{what}: tet {t} has {s}, no cell's value");
        for &v in tet {
            assert_eq!(m.points[v as usize], b.points[m.stats.vertex_origin[v as usize] as usize], "{what}");
        }
    }
    let topo = Topology::build(m);
    // Two triangles per boundary quad of the block: nothing else is boundary.
    assert_eq!(topo.boundary.len(), 2 * 6 * b.n * b.n, "{what}: the walks' adjacency must cross between cells");
}

#[test]
fn both_readers_read_cell_data_alike() {
    for n in [2, 3] {
        let b = block(n);
        let (lt, xt) = (b.legacy(false), b.vtu(false));
        for cell_data in [CellData::Constant, CellData::Average] {
            // No point scalar: the first numeric cell scalar (not the ghost
            // marker, not the 3-component vector), noted by the loader.
            let l = legacy(&lt, None, cell_data).unwrap();
            let x = xml(&xt, None, cell_data).unwrap();
            for (m, what) in [(&l, "legacy"), (&x, "xml")] {
                let s = m.stats.scalar.as_ref().unwrap();
                assert_eq!((s.array.as_str(), s.association, s.components, s.cell_data), ("density", Association::Cell, 1, Some(cell_data)), "{what}");
                assert!(s.fallback && s.fallback_note("b").unwrap().contains("'density'"), "{what}");
                match cell_data {
                    CellData::Constant => check_constant(m, &b, &b.value, what),
                    CellData::Average => {
                        assert_eq!(m.scalars, b.averaged(&b.value), "{what}");
                        assert!(m.stats.vertex_origin.is_empty());
                    }
                }
            }
            assert_eq!((l.tets.clone(), l.scalars.clone()), (x.tets.clone(), x.scalars.clone()), "n {n} {cell_data:?}");
            // By name: the vector by magnitude (averaged by component first).
            let mags: Vec<f64> = b.vector.iter().map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()).collect();
            for m in [legacy(&lt, Some("vel"), cell_data).unwrap(), xml(&xt, Some("vel"), cell_data).unwrap()] {
                let s = m.stats.scalar.as_ref().unwrap();
                assert_eq!((s.components, s.fallback), (3, false));
                match cell_data {
                    CellData::Constant => check_constant(&m, &b, &mags, "vel"),
                    CellData::Average => {
                        let c: Vec<Vec<f64>> = (0..3).map(|k| b.averaged(&b.vector.iter().map(|v| v[k]).collect::<Vec<_>>())).collect();
                        for (i, s) in m.scalars.iter().enumerate() {
                            let want = (c[0][i] * c[0][i] + c[1][i] * c[1][i] + c[2][i] * c[2][i]).sqrt();
                            assert!((s - want).abs() <= 1e-14 * want, "point {i}: {s} vs |mean| {want}");
                        }
                    }
                }
            }
        }
        // A point scalar wins when there is one; a cell array by name is taken.
        let (lp, xp) = (b.legacy(true), b.vtu(true));
        for m in [legacy(&lp, None, CellData::Constant).unwrap(), xml(&xp, None, CellData::Constant).unwrap()] {
            let s = m.stats.scalar.as_ref().unwrap();
            assert_eq!((s.array.as_str(), s.association, s.cell_data), ("height", Association::Point, None));
            assert_eq!(m.points.len(), b.points.len());
        }
        for m in [legacy(&lp, Some("density"), CellData::Constant).unwrap(), xml(&xp, Some("density"), CellData::Constant).unwrap()] {
            assert!(!m.stats.scalar.as_ref().unwrap().fallback);
            check_constant(&m, &b, &b.value, "named");
        }
    }
}

#[test]
fn missing_arrays_and_overflowing_magnitudes_are_named() {
    let b = block(2);
    let e = format!("{:#}", legacy(&b.legacy(true), Some("nope"), CellData::Constant).unwrap_err());
    assert!(e.contains("no point or cell array named 'nope'") && e.contains("SCALARS height") && e.contains("VECTORS vel") && e.contains("SCALARS density"), "{e}");
    let e = format!("{:#}", xml(&b.vtu(true), Some("nope"), CellData::Constant).unwrap_err());
    assert!(e.contains("no point or cell array named 'nope'") && e.contains("'height'") && e.contains("'vel' (3 components)"), "{e}");
    // Issue 35 item 20: finite components whose magnitude leaves f32's range.
    let first_vector = |x: &str| {
        let t = b.legacy(false);
        let at = t.find("VECTORS vel double\n").unwrap() + "VECTORS vel double\n".len();
        let end = at + t[at..].find('\n').unwrap();
        format!("{}{x} {x} 0{}", &t[..at], &t[end..])
    };
    for (i, big) in [(1usize, "1e300"), (3, "3e38")] {
        let text = first_vector(big);
        for cell_data in [CellData::Constant, CellData::Average] {
            let e = format!("{:#}", legacy(&text, Some("vel"), cell_data).unwrap_err());
            assert!(e.contains("b.vtk") && e.contains("vel") && e.contains("overflowed"), "case {i} {cell_data:?}: {e}");
            assert!(!e.contains("non-finite"), "{e}");
        }
    }
    // Just inside the range: read.
    legacy(&first_vector("1e37"), Some("vel"), CellData::Constant).unwrap();
    // A point vector, likewise.
    let mut text = b.legacy(false) + &format!("POINT_DATA {}\nVECTORS pv double\n1e300 1e300 0\n", b.points.len());
    text += &"0 0 0\n".repeat(b.points.len() - 1);
    let e = format!("{:#}", legacy(&text, Some("pv"), CellData::Constant).unwrap_err());
    assert!(e.contains("VECTORS 'pv'") && e.contains("point 0") && e.contains("overflowed"), "{e}");
}

#[test]
fn the_summary_records_array_association_and_treatment() {
    let b = block(2);
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("cells.vtk");
    std::fs::write(&p, b.legacy(false)).unwrap();
    for (cell_data, name) in [(CellData::Constant, "constant"), (CellData::Average, "average")] {
        let d = datasets::load_with(p.to_str().unwrap(), cell_data).unwrap();
        let s = d.summary().stats;
        assert_eq!((s["scalar_array"].as_str(), s["scalar_association"].as_str(), s["cell_data"].as_str()), (Some("density"), Some("cell"), Some(name)));
        assert_eq!(s["scalar_components"], 1);
    }
    // Constant and average are different images: different digests.
    let digests: Vec<String> = [CellData::Constant, CellData::Average].iter().map(|&c| datasets::load_with(p.to_str().unwrap(), c).unwrap().digest).collect();
    assert_ne!(digests[0], digests[1]);
    let q = tmp.path().join("points.vtk");
    std::fs::write(&q, b.legacy(true)).unwrap();
    let s = datasets::load(&format!("{}#vel", q.display())).unwrap().summary().stats;
    assert_eq!((s["scalar_array"].as_str(), s["scalar_association"].as_str(), s["scalar_components"].as_u64()), (Some("vel"), Some("cell"), Some(3)));
    let s = datasets::load(q.to_str().unwrap()).unwrap().summary().stats;
    assert_eq!((s["scalar_association"].as_str(), s.get("cell_data")), (Some("point"), None));
}

fn run(mesh: &TetMesh, tf: &TransferFunction, spec: &str, camera: Camera, size: u32) -> RunOutput {
    let dataset = Dataset::from_mesh(mesh.clone(), false, "test".into());
    let spec = registry::builtin().parse_spec(spec, &[]).expect("spec");
    let cfg = RunConfig { width: size, height: size, frames: 1, warmup: 0, fixed_frames: 0, fixed_camera: Some(camera), ..RunConfig::default() };
    let ctx = context();
    let out = run_method(&ctx, &spec, &dataset, tf, &cfg).unwrap_or_else(|e| panic!("{e:#}"));
    assert!(ctx.validation_messages().is_empty(), "{:?}", ctx.validation_messages());
    out
}

/// The reference image of a block of `n³` hexahedra.
fn reference(mesh: &TetMesh, n: u64, tf: &TransferFunction, camera: &Camera, size: u32) -> RgbaImage {
    let (r, stats) = render_reference_with_stats(mesh, camera, tf, size, size).unwrap();
    assert_eq!((stats.aborted_walks, stats.fallback_exits), (0, 0));
    // The walk crosses between cells whose vertices are copies: only the
    // block's surface (2 triangles per quad) is boundary.
    assert_eq!(stats.boundary_faces, 2 * 6 * n * n);
    RgbaImage { width: size, height: size, pixels: r.pixels.iter().map(|p| p.map(|c| c as f32)).collect() }
}

/// Constant cells: the f64 reference walks across faces whose vertices
/// are copies (its boundary is the block's surface) and takes each cell's
/// own value on entry, so it agrees with the cell-projection methods, which
/// project each tet on its own, at two sizes; balanced with the exact
/// integrator is exact on each constant segment, so its remaining error is
/// its visibility order's; pt-compute sorts exactly per pixel; tet-raycast
/// walks like the reference (renaming the entry face to the next cell's
/// copies, walk.comp's CELL_CONSTANT) and is exact with every integrator.
#[test]
fn constant_cells_render_alike() {
    let b = block(3);
    let mesh = legacy(&b.legacy(false), None, CellData::Constant).unwrap();
    let tf = datasets::mesh_transfer_function(&mesh, None);
    let camera = Camera::orbit(&mesh.bounds(), 0.6, Projection::Perspective { fovy_deg: 30.0 });
    for size in [24, 40] {
        let want = reference(&mesh, 3, &tf, &camera, size);
        assert!(want.covered_pixels() > (size * size / 4) as usize);
        // tet-raycast is exact on each constant segment with every integrator
        // (up to f32, and the pre-integration table's resolution).
        for integrator in ["average", "preint", "ppi", "linear-exact"] {
            let out = run(&mesh, &tf, &format!("tet-raycast:integrator={integrator}"), camera, size);
            let e = out.image.compare(&want).unwrap();
            eprintln!("{size} tet-raycast {integrator}: RMSE {:.3e} max {:.3e} {:?}", e.rmse, e.max_abs, out.result.work.counts);
            // Measured 3.1e-7 to 3.4e-7 (f32), pre-integration 8.0e-5 (its table's resolution).
            let bound = if integrator == "preint" { 3e-4 } else { 1e-5 };
            assert!(e.rmse < bound, "{size} tet-raycast {integrator}: RMSE {:e}, max {:e}", e.rmse, e.max_abs);
            assert_eq!(out.result.work.counts.get("stalled_walks"), Some(&0));
        }
        for (spec, bound) in [("balanced:integrator=linear-exact", 2e-3), ("balanced:integrator=ppi", 2e-3), ("pt-compute", 1e-4)] {
            let out = run(&mesh, &tf, spec, camera, size);
            let e = out.image.compare(&want).unwrap();
            eprintln!("{size} {spec}: RMSE {:.3e} max {:.3e}", e.rmse, e.max_abs);
            assert!(e.rmse < bound, "{size} {spec}: RMSE {:e}, max {:e}", e.rmse, e.max_abs);
        }
    }
}

/// Exactness of the constant treatment: one value in every cell makes a
/// homogeneous block, whose colour along a ray is the closed form
/// `C·(1 − e^(−τL))` of the length `L` inside it; the reference (walking
/// through the copies, every cell's own value on entry) gives it, and so
/// does the same block with shared points (the point field, which is the
/// same constant).
#[test]
fn constant_cells_of_one_value_are_exact() {
    let mut b = block(2);
    b.value.iter_mut().for_each(|v| *v = 2.5);
    let cells = legacy(&b.legacy(false), Some("density"), CellData::Constant).unwrap();
    let points = {
        let mut m = legacy(&b.legacy(true), Some("height"), CellData::Constant).unwrap();
        m.scalars.iter_mut().for_each(|s| *s = 2.5);
        m
    };
    let tf = datasets::mesh_transfer_function(&cells, None);
    for size in [16, 28] {
        let camera = Camera::orbit(&cells.bounds(), 0.3, Projection::Perspective { fovy_deg: 30.0 });
        let (a, b2) = (reference(&cells, 2, &tf, &camera, size), reference(&points, 2, &tf, &camera, size));
        let e = a.compare(&b2).unwrap();
        assert!(e.max_abs < 1e-12, "{size}: constant cells against the shared-point block: max {:e}", e.max_abs);
    }
}

/// Average: the point field VTK's filter gives, rendered as any point field
/// (tet-raycast and balanced against the reference within the usual bound).
#[test]
fn averaged_cells_render_as_a_point_field() {
    let b = block(3);
    let mesh = xml(&b.vtu(false), None, CellData::Average).unwrap();
    let tf = datasets::mesh_transfer_function(&mesh, None);
    let camera = Camera::orbit(&mesh.bounds(), 1.1, Projection::Perspective { fovy_deg: 30.0 });
    let want = reference(&mesh, 3, &tf, &camera, 32);
    for spec in ["tet-raycast:integrator=linear-exact", "balanced"] {
        let out = run(&mesh, &tf, spec, camera, 32);
        let e = out.image.compare(&want).unwrap();
        eprintln!("average {spec}: RMSE {:.3e}", e.rmse);
        assert!(e.rmse < 4e-3, "{spec}: RMSE {:e}", e.rmse);
    }
}

/// The command line: `--cell-data` is refused beyond its two values, in
/// every command that has it; a run on a file with only cell data notes the
/// choice on stderr and records it in the result.
#[test]
fn the_command_line_takes_and_records_the_choice() {
    let volbench = || std::process::Command::new(env!("CARGO_BIN_EXE_volbench"));
    for args in [
        &["run", "--data", "post-small", "--method", "balanced", "--cell-data", "mean"][..],
        &["suite", "--quick", "--cell-data", "mean"],
        &["scale", "--data", "post-small", "--cell-data", "mean"],
        &["compare", "--data", "post-small", "--cell-data", "mean"],
    ] {
        let out = volbench().args(args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?}");
        assert!(err.contains("--cell-data") && err.contains("'constant'") && err.contains("'average'"), "{args:?}: {err}");
    }
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("cells.vtk");
    std::fs::write(&p, block(2).legacy(false)).unwrap();
    for (treatment, points) in [("constant", None), ("average", Some(27))] {
        let out = volbench()
            .args(["run", "--data", p.to_str().unwrap(), "--method", "balanced", "--size", "16x16", "--frames", "1", "--warmup", "0"])
            .args(["--fixed-frames", "0", "--cell-data", treatment, "--json", "-"])
            .env("VOLBENCH_VALIDATION", "1")
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        assert!(err.contains("note:") && err.contains("cell array 'density'"), "{err}");
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let d = &json["dataset"];
        assert_eq!(d["stats"]["scalar_association"], "cell");
        assert_eq!(d["stats"]["cell_data"], treatment);
        if let Some(n) = points {
            assert_eq!(d["counts"]["points"], n);
        } else {
            assert_eq!(d["counts"]["points"], 4 * d["counts"]["cells"].as_u64().unwrap());
        }
    }
}

