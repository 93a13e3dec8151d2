//! criterion benches of every registered method on the shipped datasets of
//! its kind (lavapipe by default; VOLBENCH_DEVICE picks another device). The
//! methods come from the registry: a method added there is benched here
//! without a change.
//!
//! - `frame/<dataset>/<method>`: one whole frame per iteration (prepare,
//!   upload, draw, wait), host wall time, throughput in the method's work
//!   units; the camera keeps orbiting.
//! - `gpu/<dataset>/<method>`: the same frames, but the time fed to criterion
//!   is the GPU timestamp interval (`iter_custom`).
//! - `prepare/<dataset>/<method>`: the method's per-frame CPU work alone
//!   (sort and pack for cell projection).
//! - `setup/<dataset>/<method>`: creating the method's session: static
//!   uploads, the tables it builds from the transfer function (integration
//!   tables, brick flags, ...), pipelines (from the process-wide cache).
//! - `sort/<dataset>`: the centroid radix sort shared by the tetrahedral
//!   methods.
//! - `tables/<integrator>/<size>`: the cell-projection integration tables
//!   (pre-integration, partial pre-integration's Psi) at their default sizes.
//!
//! Every shipped dataset (`datasets::NAMED`) is benched with every method of
//! its kind, and the ray casters also with their suite's adaptive-refinement
//! tolerances (`tet-raycast:adaptive=0.008`, ...). Frames are 256x256 so that `cargo bench` finishes in minutes.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, BenchmarkId, Criterion, Throughput};

use volbench::algo::cell_projection::{centroids_f32, sort::CentroidSort};
use volbench::algo::integrate::{preint_table, psi_table, Integrator};
use volbench::algo::registry;
use volbench::harness::datasets::{self, Dataset, DatasetData};
use volbench::harness::run::{MethodSession, RunConfig};
use volbench::mesh::TetGeometry;
use volbench::scene::Projection;
use volbench::vk::{Context, ContextDesc, UploadCounter};

const SIZE: u32 = 256;

fn orbit(dataset: &Dataset, frame: u64) -> volbench::scene::Camera {
    dataset.orbit_camera(frame as f64 * 5f64.to_radians(), Projection::Perspective { fovy_deg: 30.0 })
}

fn throughput(dataset: &Dataset) -> Throughput {
    Throughput::Elements(dataset.summary().counts.get("cells").copied().unwrap_or((SIZE * SIZE) as u64))
}

/// Every method of `kind` with its defaults, and with each suite option set
/// of adaptive refinement (`adaptive=TOL`, issue 37: the same method casting
/// fewer rays), benched beside it as `<group>/<dataset>/<method>:adaptive=TOL`.
fn specs(registry: &registry::Registry, kind: volbench::algo::method::DataKind) -> Vec<(&volbench::algo::method::MethodInfo, registry::MethodSpec)> {
    let mut out = Vec::new();
    for method in registry.for_kind(kind) {
        let base = registry.parse_spec(method.name, &[]).expect("default spec");
        let adaptive: Vec<registry::MethodSpec> =
            method.suite.iter().filter(|v| v.contains("adaptive=")).map(|v| registry.variant(&base, v).expect("suite option set")).collect();
        out.push((method, base));
        out.extend(adaptive.into_iter().map(|s| (method, s)));
    }
    out
}

fn frames(c: &mut Criterion) {
    let ctx = Context::new(&ContextDesc::from_env().expect("VOLBENCH_* variables")).expect("a Vulkan device (run scripts/setup.sh)");
    let registry = registry::builtin();
    let cfg = RunConfig { width: SIZE, height: SIZE, ..RunConfig::default() };
    for name in datasets::NAMED.iter().map(|d| d.name) {
        let dataset = datasets::load(name).expect("shipped dataset");
        let tf = dataset.default_transfer_function().expect("preset transfer function");
        for (method, spec) in specs(&registry, dataset.kind()) {
            if let Some(why) = method.unsupported_reason(&ctx.info) {
                eprintln!("skipping {}: {why}", spec.label());
                continue;
            }
            let id = spec.label();
            let mut group = c.benchmark_group(format!("setup/{name}"));
            group.sample_size(10).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(5));
            group.bench_function(BenchmarkId::from_parameter(&id), |b| {
                b.iter(|| black_box(MethodSession::new(&ctx, &spec, &dataset, &tf, &cfg).expect("session")))
            });
            group.finish();
            let mut session = MethodSession::new(&ctx, &spec, &dataset, &tf, &cfg).expect("session");
            let mut counter = UploadCounter::default();
            let mut frame_no = 0u64;
            for (group_name, use_gpu_time) in [("frame", false), ("gpu", true)] {
                let mut group = c.benchmark_group(format!("{group_name}/{name}"));
                group.sample_size(10).warm_up_time(Duration::from_secs(2)).measurement_time(Duration::from_secs(8));
                group.throughput(throughput(&dataset));
                group.bench_function(BenchmarkId::from_parameter(&id), |b| {
                    b.iter_custom(|iters| {
                        let mut total = Duration::ZERO;
                        for _ in 0..iters {
                            frame_no += 1;
                            let camera = orbit(&dataset, frame_no);
                            let start = Instant::now();
                            let (timing, _) = session.frame(&camera, &mut counter).expect("frame");
                            total += if use_gpu_time { Duration::from_secs_f64(timing.gpu * 1e-3) } else { start.elapsed() };
                        }
                        total
                    })
                });
                group.finish();
            }
            let mut group = c.benchmark_group(format!("prepare/{name}"));
            group.sample_size(20);
            group.throughput(throughput(&dataset));
            let camera = orbit(&dataset, 3);
            group.bench_function(BenchmarkId::from_parameter(&id), |b| {
                b.iter(|| black_box(session.prepare(&camera).expect("prepare").method.0.len()))
            });
            group.finish();
        }
    }
}

fn sort(c: &mut Criterion) {
    for name in datasets::NAMED.iter().map(|d| d.name) {
        let dataset = datasets::load(name).expect("shipped dataset");
        let DatasetData::TetMesh { mesh } = &dataset.data else { continue };
        let geometry = &TetGeometry::compute(mesh);
        let camera = orbit(&dataset, 3);
        let mut group = c.benchmark_group(format!("sort/{name}"));
        group.throughput(Throughput::Elements(mesh.tets.len() as u64));
        let mut sorter = CentroidSort::new(centroids_f32(geometry));
        group.bench_function("centroid_radix", |b| b.iter(|| black_box(sorter.sort(&camera)[0])));
        group.finish();
    }
}

fn tables(c: &mut Criterion) {
    let dataset = datasets::load("oxygenpost").expect("shipped dataset");
    let tf = dataset.default_transfer_function().expect("preset transfer function");
    let range = dataset.scalar_range();
    for integrator in [Integrator::Preint, Integrator::Ppi] {
        let n = integrator.default_table_size();
        let mut group = c.benchmark_group(format!("tables/{}", integrator.name()));
        group.sample_size(10);
        group.bench_function(BenchmarkId::from_parameter(n), |b| {
            b.iter(|| match integrator {
                Integrator::Preint => black_box(preint_table(&tf, range, n, 1.0).expect("table").len()),
                _ => black_box(psi_table(n).expect("table").len()),
            })
        });
        group.finish();
    }
}

criterion_group!(benches, sort, tables, frames);

// criterion_main!, plus the font criterion's plots need: plotters is built
// with ab_glyph (for volbench's own plots), which finds no system fonts.
fn main() {
    volbench::harness::plots::register_font().expect("a font for the plots (scripts/setup.sh installs one)");
    benches();
    Criterion::default().configure_from_args().final_summary();
}
