//! Hybrid terrain meshes on the shipped Jacksboro DEM, with the validation
//! layer on (any message fails): the coverage test (the union of NC cells,
//! PC tessellations and TINs covers every pixel centre of the domain
//! exactly once, at every level, seen from above into an additive
//! coverage-count target), deterministic counts and bytes along the
//! fly-over, and the elevation readers behind `--data`.

use std::sync::{Arc, Mutex, OnceLock};

use volbench::algo::registry;
use volbench::algo::terrain::top_down;
use volbench::harness::datasets::{self, Dataset, DatasetData};
use volbench::harness::run::{run, RunConfig, RunOutput};
use volbench::terrain::hybrid::HybridModel;
use volbench::vk::{Context, ContextDesc};

fn context() -> std::sync::MutexGuard<'static, Arc<Context>> {
    static CTX: OnceLock<Mutex<Arc<Context>>> = OnceLock::new();
    CTX.get_or_init(|| Mutex::new(Context::new(&ContextDesc { device: None, validation: true }).expect("a Vulkan device")))
        .lock()
        .unwrap_or_else(|p| p.into_inner())
}

fn jacksboro() -> &'static Dataset {
    static D: OnceLock<Dataset> = OnceLock::new();
    D.get_or_init(|| datasets::load("jacksboro").unwrap())
}

fn render(spec: &str, cfg: RunConfig) -> RunOutput {
    let d = jacksboro();
    let spec = registry::builtin().parse_spec(spec, &[]).unwrap();
    let ctx = context();
    let out = run(&ctx, &spec, d, &d.default_transfer_function(), &cfg).unwrap_or_else(|e| panic!("{e:#}"));
    assert!(ctx.validation_messages().is_empty(), "{:?}", ctx.validation_messages());
    out
}

fn one_frame(width: u32, height: u32) -> RunConfig {
    RunConfig { width, height, frames: 1, warmup: 0, overlap: false, ..RunConfig::default() }
}

#[test]
fn every_pixel_centre_of_the_domain_is_covered_exactly_once_at_every_level() {
    let DatasetData::Terrain(map) = &jacksboro().data else { unreachable!() };
    let model = HybridModel::build(map).unwrap();
    let (lo, hi) = map.range();
    let camera = top_down(&model, lo, hi);
    // Not a multiple of the cell counts, so pixel centres also fall on
    // cell edges and TB vertices' lines.
    let (w, h) = (509u32, 431u32);
    let (dw, dh) = (model.domain[0] as f64 * model.spacing[0], model.domain[1] as f64 * model.spacing[1]);
    let half_h = 0.5 * dh;
    let half_w = half_h * w as f64 / h as f64;
    for level in 0..model.levels.len() {
        let out = render(&format!("hm-cpu:level={level},coverage=on"), RunConfig { fixed_camera: Some(camera), ..one_frame(w, h) });
        let (mut inside, mut bad) = (0usize, Vec::new());
        for py in 0..h {
            for px in 0..w {
                let x = 0.5 * dw + ((px as f64 + 0.5) / w as f64 * 2.0 - 1.0) * half_w;
                let y = 0.5 * dh - ((py as f64 + 0.5) / h as f64 * 2.0 - 1.0) * half_h;
                // Pixel centres on the domain's outline belong to no
                // neighbour: leave a hair's width out.
                let eps = 1e-6 * dw;
                if x <= eps || y <= eps || x >= dw - eps || y >= dh - eps {
                    continue;
                }
                inside += 1;
                let count = out.image.pixels[(px + w * py) as usize][0];
                if count != 1.0 {
                    bad.push((px, py, count));
                }
            }
        }
        assert!(inside > 100_000, "{inside}");
        assert!(bad.is_empty(), "level {level}: {} of {inside} pixel centres covered other than once, e.g. {:?}", bad.len(), &bad[..bad.len().min(10)]);
        let work = &out.result.work.counts;
        assert!(work["pc_cells"] > 0 && work["nc_cells"] > 0, "{work:?}");
    }
}

#[test]
fn fly_over_counts_and_bytes_are_deterministic_and_only_pc_triangles_are_uploaded() {
    // A fine threshold for a small image, so that levels mix.
    let a = render("hm-cpu:lod_error=0.1", one_frame(96, 64));
    let b = render("hm-cpu:lod_error=0.1", one_frame(96, 64));
    let (wa, wb) = (&a.result.work.counts, &b.result.work.counts);
    assert_eq!(wa, wb);
    assert!(wa["pc_triangles"] > 0, "{wa:?}");
    // Per frame only the PC triangles' indices cross (3 x u32 each).
    assert_eq!(a.result.upload.cell_bytes_per_frame, 12 * wa["pc_triangles"]);
    assert!(a.result.image.covered_pixels > 96 * 64 / 2, "{}", a.result.image.covered_pixels);
    // The view-dependent choice mixes levels along the fly-over.
    let per_level = a.result.details["blocks_per_level"].as_array().unwrap().clone();
    assert!(per_level.iter().filter(|n| n.as_u64().unwrap() > 0).count() >= 2, "{per_level:?}");
    // A coarser threshold draws fewer triangles and has a larger error.
    let c = render("hm-cpu:lod_error=16", one_frame(96, 64));
    assert!(c.result.work.counts["triangles"] < wa["triangles"]);
    let err = |o: &RunOutput| o.result.details["geometric_error"]["rms"].as_f64().unwrap();
    assert!(err(&c) > err(&a), "{} vs {}", err(&c), err(&a));
}

#[test]
fn elevation_files_load_by_path_and_bad_ones_are_named() {
    let d = jacksboro();
    assert_eq!(d.kind().name(), "terrain");
    assert_eq!(d.summary().counts["samples"], 403 * 344);
    let dir = tempfile::tempdir().unwrap();
    // A small .npy grid by path.
    let mut h = String::from("{'descr': '<f4', 'fortran_order': False, 'shape': (20, 24), }");
    while (h.len() + 11) % 64 != 0 {
        h.push(' ');
    }
    h.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend((h.len() as u16).to_le_bytes());
    bytes.extend(h.as_bytes());
    for j in 0..20 {
        for i in 0..24 {
            bytes.extend(((i * j) as f32 * 0.5).to_le_bytes());
        }
    }
    let p = dir.path().join("small.npy");
    std::fs::write(&p, &bytes).unwrap();
    let s = datasets::load(p.to_str().unwrap()).unwrap();
    let DatasetData::Terrain(m) = &s.data else { panic!("not a terrain") };
    assert_eq!((m.nx, m.ny), (24, 20));
    // The hybrid model builds on an unseen grid too.
    let model = HybridModel::build(m).unwrap();
    assert!(model.levels.len() >= 1 && !model.tin_indices.is_empty());
    // Truncated, and an array name that is not there.
    let t = dir.path().join("cut.npy");
    std::fs::write(&t, &bytes[..200]).unwrap();
    let e = format!("{:#}", datasets::load(t.to_str().unwrap()).err().unwrap());
    assert!(e.contains("cut.npy") && e.contains("data bytes"), "{e}");
    let npz = datasets::data_dir().join("terrain/jacksboro_fault_dem.npz");
    let e = format!("{:#}", datasets::load(&format!("{}#nosuch", npz.display())).err().unwrap());
    assert!(e.contains("no array 'nosuch'"), "{e}");
    let ok = datasets::load(&format!("{}#elevation", npz.display())).unwrap();
    assert_eq!(ok.kind().name(), "terrain");
}
