//! criterion benches of cell projection on the real meshes (lavapipe by
//! default; VOLBENCH_DEVICE picks another device).
//!
//! - `frame/<mesh>`: one whole frame per iteration (sort, pack, upload, draw,
//!   wait), host wall time, throughput in cells; the camera keeps orbiting.
//! - `gpu/<mesh>`: the same frames, but the time fed to criterion is the GPU
//!   timestamp interval of the draw (`iter_custom`).
//! - `sort/<mesh>`, `pack_balanced/<mesh>`: the CPU hot paths alone, with
//!   throughput in cells and bytes.
//! Frames are 256x256 so that `cargo bench` finishes in a few minutes.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, BenchmarkId, Criterion, Throughput};

use volbench::algo::cell_projection::{balanced, cells_f32, centroids_f32, sort::CentroidSort, FrameSetup, Interpolation, Method};
use volbench::harness::datasets;
use volbench::harness::run::{CellProjectionSession, RunConfig, Scene};
use volbench::mesh::{TetGeometry, TetMesh};
use volbench::scene::{Camera, Projection};
use volbench::vk::{Context, ContextDesc, UploadCounter};

const MESHES: [&str; 2] = ["bluntfin", "oxygenpost"];
const SIZE: u32 = 256;

fn load(name: &str) -> (TetMesh, TetGeometry) {
    let mesh = datasets::load_mesh(name).expect("shipped mesh");
    let geometry = TetGeometry::compute(&mesh);
    (mesh, geometry)
}

fn orbit(mesh: &TetMesh, frame: u64) -> Camera {
    Camera::orbit(&mesh.bounds(), frame as f64 * 5f64.to_radians(), Projection::Perspective { fovy_deg: 30.0 })
}

fn frames(c: &mut Criterion) {
    let ctx = ContextDesc::from_env().and_then(|d| Context::new(&d)).expect("a Vulkan device (run scripts/setup.sh)");
    for name in MESHES {
        let (mesh, geometry) = load(name);
        let tf = datasets::default_transfer_function(&mesh);
        let scene = Scene { mesh: &mesh, geometry: &geometry, tf: &tf };
        for (group_name, use_gpu_time) in [("frame", false), ("gpu", true)] {
            let mut group = c.benchmark_group(format!("{group_name}/{name}"));
            group.sample_size(10).warm_up_time(Duration::from_secs(2)).measurement_time(Duration::from_secs(8));
            group.throughput(Throughput::Elements(mesh.tets.len() as u64));
            for method in [Method::Vicp, Method::Balanced] {
                let mut session = CellProjectionSession::new(&ctx, &scene, &{ let mut c = RunConfig::new(method); c.width = SIZE; c.height = SIZE; c }).expect("session");
                let mut counter = UploadCounter::default();
                let mut frame_no = 0u64;
                group.bench_function(BenchmarkId::from_parameter(method.name()), |b| {
                    b.iter_custom(|iters| {
                        let mut total = Duration::ZERO;
                        for _ in 0..iters {
                            frame_no += 1;
                            let camera = orbit(&mesh, frame_no);
                            let start = Instant::now();
                            let (timing, _) = session.frame(&camera, &mut counter).expect("frame");
                            total += if use_gpu_time { Duration::from_secs_f64(timing.gpu * 1e-3) } else { start.elapsed() };
                        }
                        total
                    })
                });
            }
            group.finish();
        }
    }
}

fn cpu_paths(c: &mut Criterion) {
    for name in MESHES {
        let (mesh, geometry) = load(name);
        let n = mesh.tets.len();
        let camera = orbit(&mesh, 3);

        let mut group = c.benchmark_group(format!("sort/{name}"));
        group.throughput(Throughput::Elements(n as u64));
        let mut sorter = CentroidSort::new(centroids_f32(&geometry));
        group.bench_function("centroid_radix", |b| b.iter(|| black_box(sorter.sort(&camera)[0])));
        group.finish();

        let mut group = c.benchmark_group(format!("pack_balanced/{name}"));
        group.throughput(Throughput::Bytes((n * balanced::FLOATS_PER_CELL * 4) as u64));
        let cells = cells_f32(&mesh, &geometry);
        let order: Vec<u32> = sorter.sort(&camera).to_vec();
        let setup = FrameSetup::for_camera(&camera, mesh.bounds().diagonal(), Interpolation::Paper, &Default::default());
        let mut out = vec![0f32; n * balanced::FLOATS_PER_CELL];
        group.bench_function("intersect_back_face", |b| {
            b.iter(|| {
                balanced::pack_records(&cells, &order, &setup, &mut out);
                black_box(out[0])
            })
        });
        group.finish();
    }
}

criterion_group!(benches, cpu_paths, frames);

// criterion_main!, plus the font criterion's plots need: plotters is built
// with ab_glyph (for volbench's own plots), which finds no system fonts.
fn main() {
    volbench::harness::pareto::register_font().expect("a font for the plots (scripts/setup.sh installs one)");
    benches();
    Criterion::default().configure_from_args().final_summary();
}
