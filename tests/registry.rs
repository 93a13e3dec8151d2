//! The method contract from the outside: a test-only method (a solid-colour
//! bounding box) registered here, and nowhere in the harness, runs through
//! the runner, `compare` and a `pareto` sweep; every JSON they write
//! validates against the committed schema; a failing row does not stop a
//! sweep; unknown and inapplicable options are errors.

mod common;

use std::sync::{Arc, Mutex, OnceLock};

use anyhow::Result;

use volbench::algo::method::{
    DataKind, Family, Feature, MethodInfo, MethodInputs, OptionSpec, OptionValues, Phases, RenderMethod, SceneData, View, Work,
};
use volbench::algo::registry::{self, Registry};
use volbench::harness::datasets;
use volbench::harness::run::{run, RunConfig};
use volbench::harness::sweep;
use volbench::vk::{
    compile_glsl, Blend, ColorTarget, CommandRecorder, Context, ContextDesc, GraphicsPipelineDesc, Image, Pipeline, ShaderModule,
    ShaderStage, UploadCounter,
};
use volbench::vk::{Cull, Topology, Winding};

fn context() -> std::sync::MutexGuard<'static, Arc<Context>> {
    static CTX: OnceLock<Mutex<Arc<Context>>> = OnceLock::new();
    CTX.get_or_init(|| Mutex::new(Context::new(&ContextDesc { device: None, validation: true }).expect("a Vulkan device")))
        .lock()
        .unwrap_or_else(|p| p.into_inner())
}

const BOX_VERT: &str = "#version 450
layout(push_constant) uniform P { mat4 view_proj; vec4 lo; vec4 hi; vec4 color; } pc;
// 36 vertices: the 12 triangles of the unit cube.
const int IDX[36] = int[36](0,1,3, 0,3,2, 4,6,7, 4,7,5, 0,4,5, 0,5,1, 2,3,7, 2,7,6, 0,2,6, 0,6,4, 1,5,7, 1,7,3);
void main() {
    int c = IDX[gl_VertexIndex];
    vec3 t = vec3(c & 1, (c >> 1) & 1, (c >> 2) & 1);
    gl_Position = pc.view_proj * vec4(mix(pc.lo.xyz, pc.hi.xyz, t), 1.0);
}";
const BOX_FRAG: &str = "#version 450
layout(push_constant) uniform P { mat4 view_proj; vec4 lo; vec4 hi; vec4 color; } pc;
layout(location = 0) out vec4 out_color;
void main() { out_color = pc.color; }";

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct BoxConstants {
    view_proj: [[f32; 4]; 4],
    lo: [f32; 4],
    hi: [f32; 4],
    color: [f32; 4],
}

/// Draws the dataset's bounding box in one colour (the `shade` option).
struct SolidBox {
    pipeline: Pipeline,
    lo: [f64; 3],
    hi: [f64; 3],
    shade: f32,
    prepared: Option<BoxConstants>,
}

fn create_box(inputs: MethodInputs) -> Result<Box<dyn RenderMethod>> {
    let SceneData::TetMesh { mesh, .. } = inputs.data else { anyhow::bail!("meshes only") };
    let source = |p: &str| match p {
        "box.vert" => Some(BOX_VERT),
        "box.frag" => Some(BOX_FRAG),
        _ => None,
    };
    let vs = compile_glsl("box.vert", ShaderStage::Vertex, &[], &source)?;
    let fs = compile_glsl("box.frag", ShaderStage::Fragment, &[], &source)?;
    let vs = ShaderModule::new(inputs.ctx, "box.vert", ShaderStage::Vertex, &vs)?;
    let fs = ShaderModule::new(inputs.ctx, "box.frag", ShaderStage::Fragment, &fs)?;
    let pipeline = Pipeline::graphics(
        inputs.ctx,
        &GraphicsPipelineDesc {
            name: "solid box",
            vertex: &vs,
            fragment: &fs,
            vertex_stride: 0,
            attributes: &[],
            topology: Topology::TriangleList,
            primitive_restart: false,
            cull: Cull::None,
            front_face: Winding::CounterClockwise,
            targets: &[ColorTarget::rgba32f(Blend::PremultipliedOver)],
            depth_test: false,
            depth_clamp: false,
            geometry: None,
            push_constant_bytes: std::mem::size_of::<BoxConstants>() as u32,
            descriptor_layouts: &[],
        },
    )?;
    let b = mesh.bounds();
    Ok(Box::new(SolidBox { pipeline, lo: b.min, hi: b.max, shade: inputs.options.float("shade")? as f32, prepared: None }))
}

impl RenderMethod for SolidBox {
    fn prepare(&mut self, view: &View, phases: &mut Phases) -> Result<()> {
        let vp = view.camera.view_proj(view.width, view.height).to_cols_array_2d();
        let f = |v: [f64; 3]| [v[0] as f32, v[1] as f32, v[2] as f32, 1.0];
        // Drawn once per pixel where front and back faces overlap: alpha
        // 0.5 twice composites to 0.75.
        let s = self.shade;
        self.prepared =
            Some(BoxConstants { view_proj: vp.map(|c| c.map(|x| x as f32)), lo: f(self.lo), hi: f(self.hi), color: [s * 0.5, 0.0, 0.0, 0.5] });
        phases.add("box_setup", 0.0);
        Ok(())
    }
    fn upload(&mut self, _counter: &mut UploadCounter) -> Result<()> {
        Ok(())
    }
    fn record(&mut self, rec: &CommandRecorder, target: &Image, _view: &View, counter: &mut UploadCounter) -> Result<()> {
        let c = self.prepared.take().ok_or_else(|| anyhow::anyhow!("not prepared"))?;
        rec.begin_rendering(target, [0.0; 4]);
        rec.bind_pipeline(&self.pipeline, None);
        rec.push_constants(&self.pipeline, bytemuck::bytes_of(&c), counter);
        rec.draw(36);
        rec.end_rendering();
        Ok(())
    }
    fn work(&self) -> Work {
        Work::default().with("triangles", 12)
    }
    fn details(&self) -> serde_json::Value {
        serde_json::json!({ "family": "test-box" })
    }
}

const BOX_OPTIONS: &[OptionSpec] = &[OptionSpec {
    name: "shade",
    default: "1",
    unit: "",
    values: OptionValues::Float { min: 0.0, max: 1.0 },
    build_time: false,
    help: "red intensity",
}];

const SOLID_BOX: MethodInfo = MethodInfo {
    name: "test-solid-box",
    data: DataKind::TetMesh,
    summary: "test only: the bounding box in one colour",
    options: BOX_OPTIONS,
    features: &[],
    sweep: &["shade=0.25", "shade=1"],
    compare: &[""],
    stress: &[],
    suite: &[],
    published: &[],
    family: Family { accuracy_bound: |_, _| Some(1e-3), ..Family::plain("test") },
    create: create_box,
};

/// A method whose every run fails after the sweep has started (a table
/// too large is now refused when its spec is parsed, so it cannot be used).
const FAILS: MethodInfo = MethodInfo {
    name: "test-fails",
    summary: "test only: fails when created",
    create: |_| anyhow::bail!("test-fails: this method always fails"),
    ..SOLID_BOX
};

fn registry_with_box() -> Registry {
    registry::builtin().with(SOLID_BOX)
}

fn small() -> RunConfig {
    RunConfig { width: 64, height: 64, frames: 2, warmup: 1, ..RunConfig::default() }
}

#[test]
fn a_test_only_method_runs_through_the_runner_with_the_common_schema() {
    let registry = registry_with_box();
    let dataset = datasets::load("post-small").unwrap();
    let tf = dataset.default_transfer_function().unwrap();
    let spec = registry.parse_spec("test-solid-box:shade=0.5", &[]).unwrap();
    let ctx = context();
    let out = run(&ctx, &spec, &dataset, &tf, &small()).unwrap();
    assert!(ctx.validation_messages().is_empty(), "{:?}", ctx.validation_messages());
    let r = &out.result;
    assert_eq!(r.method, "test-solid-box");
    assert_eq!(r.work.counts["triangles"], 12);
    assert!(r.upload.bytes_per_cell.is_none(), "no cells, no bytes per cell");
    assert_eq!(r.upload.constant_bytes_per_frame, std::mem::size_of::<BoxConstants>() as u64);
    assert!(r.time_ms.phases.contains_key("box_setup"), "the method's own phases are reported");
    let covered = out.image.covered_pixels();
    assert!(covered > 200 && covered < 64 * 64, "{covered}");
    // Over itself: front and back faces, 0.5 + 0.5 * 0.5.
    let p = out.image.pixels.iter().find(|p| p[3] > 0.0).unwrap();
    assert!((p[3] - 0.75).abs() < 1e-6 && (p[0] - 0.375).abs() < 1e-6, "{p:?}");
    common::assert_matches_schema("run.schema.json", &serde_json::to_value(r).unwrap(), "the box's result");
}

#[test]
fn sweeps_iterate_over_the_registry_and_survive_a_failing_row() {
    let registry = registry_with_box().with(FAILS);
    let mut dataset = datasets::load("post-small").unwrap();
    let tf = dataset.default_transfer_function().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let ctx = context();
    // pareto over the box's own sweep, with no harness code naming it.
    let specs = sweep::pareto_specs(&registry, &["test-solid-box".into()], DataKind::TetMesh, &[]).unwrap();
    assert_eq!(specs.len(), 2);
    let points = sweep::pareto(&ctx, &mut dataset, &tf, &specs, &small(), dir.path()).unwrap();
    assert_eq!(points.len(), 2);
    assert!(points.iter().all(|p| p.error.is_none() && p.rmse > 0.0));
    for f in ["pareto.csv", "pareto.md", "pareto.json", "pareto.png"] {
        assert!(dir.path().join(f).is_file(), "{f}");
    }
    let sweep_json: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.path().join("pareto.json")).unwrap()).unwrap();
    assert_eq!(sweep_json["points"].as_array().map(Vec::len), Some(2));
    assert_eq!(sweep_json["dataset"], "post-small");
    std::fs::remove_file(dir.path().join("pareto.json")).unwrap();
    // compare: the box and balanced side by side, plus a row that fails in
    // the middle. (A table too large is refused before any work.)
    let e = registry.parse_spec("balanced:integrator=preint,table_size=4096", &[]).unwrap_err().to_string();
    assert!(e.contains("--table-size 4096 for preint"), "{e}");
    let specs = vec![
        registry.parse_spec("test-solid-box", &[]).unwrap(),
        registry.parse_spec("test-fails", &[]).unwrap(),
        registry.parse_spec("balanced", &[]).unwrap(),
    ];
    let mut jobs = vec![sweep::CompareJob { dataset, tf, specs }];
    sweep::check_compare_outputs(&jobs).unwrap();
    let rows = sweep::compare(&ctx, &registry, &mut jobs, &small(), Some(dir.path())).unwrap();
    assert_eq!(rows.len(), 3, "the failing row does not end the sweep");
    assert!(rows[0].outcome.is_ok() && rows[2].outcome.is_ok());
    let err = rows[1].outcome.as_ref().err().expect("the failing method fails");
    assert!(err.contains("always fails"), "{err}");
    let table = sweep::comparison_markdown(&rows, &registry).unwrap();
    assert!(table.contains("FAILED"), "{table}");
    // Every run JSON written validates against the schema.
    let mut n = 0;
    for e in std::fs::read_dir(dir.path()).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "json") {
            let value: serde_json::Value = serde_json::from_slice(&std::fs::read(&p).unwrap()).unwrap();
            common::assert_matches_schema("run.schema.json", &value, &p.display().to_string());
            n += 1;
        }
    }
    assert_eq!(n, 2, "one JSON per successful row");
    assert!(!dir.path().join("post-small-test-fails.json").exists());
}

#[test]
fn a_method_whose_features_are_missing_is_skipped_with_the_reason() {
    const NEEDS_GS: MethodInfo = MethodInfo { name: "test-needs-gs", features: &[Feature::GeometryShader], ..SOLID_BOX };
    let registry = registry::builtin().with(NEEDS_GS);
    let spec = registry.parse_spec("test-needs-gs", &[]).unwrap();
    let mut info = context().info.clone();
    assert!(sweep::skip_reason(&spec, &info).is_none(), "lavapipe has geometry shaders");
    info.features.geometry_shader = false;
    let why = sweep::skip_reason(&spec, &info).expect("skipped");
    assert!(why.starts_with("skipped") && why.contains("geometryShader"), "{why}");
}

#[test]
fn options_are_checked_against_the_method() {
    let registry = registry_with_box();
    let e = registry.parse_spec("test-solid-box:integrator=ppi", &[]).unwrap_err().to_string();
    assert!(e.contains("'test-solid-box'") && e.contains("'integrator'"), "{e}");
    let e = registry.parse_spec("test-solid-box:shade=2", &[]).unwrap_err().to_string();
    assert!(e.contains("shade") && e.contains("out of range"), "{e}");
    // A flag shorthand the method lacks is an error naming both.
    let e = sweep::specs_for(&registry, &["test-solid-box".into()], DataKind::TetMesh, &[("sort", "mpvo".into())], |m| m.compare)
        .unwrap_err()
        .to_string();
    assert!(e.contains("test-solid-box") && e.contains("sort"), "{e}");
}

#[test]
fn the_suite_runs_every_registered_method_on_the_shipped_datasets_of_its_kind() {
    use volbench::harness::suite::{plan, run_suite, SuiteSettings};
    let registry = registry_with_box();
    let settings = SuiteSettings { width: 48, height: 48, frames: 1, warmup: 0, ..SuiteSettings::standard(true, vec!["post-small".into()]) };
    let planned = plan(&registry, &settings).unwrap();
    let names: Vec<&str> = planned.iter().map(|p| p.spec.info.name).collect();
    // Every registered method of the kind, in registry order, the new one
    // last (no change in the suite for it); a method runs its defaults and
    // at most its own suite sets and published figures' sets besides.
    let mut methods = names.clone();
    methods.dedup();
    assert_eq!(methods, registry.for_kind(DataKind::TetMesh).map(|m| m.name).collect::<Vec<_>>());
    assert_eq!(methods.last(), Some(&"test-solid-box"), "the new method is in the suite with no change there");
    for m in registry.for_kind(DataKind::TetMesh) {
        let n = names.iter().filter(|x| **x == m.name).count();
        assert!((1..=1 + m.suite.len() + m.published.len()).contains(&n), "{}: {n} runs", m.name);
    }
    assert!(plan(&registry, &SuiteSettings::standard(true, vec!["nosuch".into()])).unwrap_err().to_string().contains("nosuch"));
    let dir = tempfile::tempdir().unwrap();
    let ctx = context();
    let summary = run_suite(&ctx, &registry, &planned, &settings, dir.path(), |_, _| {}).unwrap();
    assert!(summary.runs.iter().all(|r| r.status == "ok"), "{:?}", summary.runs.iter().map(|r| &r.message).collect::<Vec<_>>());
    for f in ["summary.json", "summary.csv", "report.md", "montage-post-small.png", "plots/frame_time-post-small.png", "plots/frame_time-post-small.svg", "plots/bytes_per_frame-post-small.svg", "plots/time_error-post-small.png"] {
        assert!(dir.path().join(f).is_file(), "{f}");
    }
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.path().join("summary.json")).unwrap()).unwrap();
    for run in v["runs"].as_array().unwrap() {
        common::assert_matches_schema("run.schema.json", &run["result"], "a suite row");
    }
    let report = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    assert!(report.contains("test-solid-box") && report.contains("| post-small | balanced | ok"), "{report}");
}

#[test]
fn the_suite_runs_the_option_sets_published_figures_name_and_reports_the_ratios() {
    use volbench::harness::suite::{plan, run_suite, SuiteSettings};
    let registry = registry::builtin();
    let labels = |filter: &str| -> Vec<String> {
        plan(&registry, &SuiteSettings::standard(true, vec![filter.into()])).unwrap().iter().map(|p| p.label()).collect()
    };
    // Every tetrahedral method at its defaults, in registry order, and the
    // option sets published figures name: thesis Table 6.4 names the
    // integrators on the blunt fin only.
    let tet: Vec<String> = registry.for_kind(DataKind::TetMesh).map(|m| m.name.to_string()).collect();
    let defaults = |labels: &[String]| -> Vec<String> { labels.iter().filter(|l| !l.contains([':', '@'])).cloned().collect() };
    let bluntfin = labels("bluntfin");
    assert_eq!(defaults(&bluntfin), tet);
    for l in ["balanced:integrator=average", "balanced:integrator=linear-exact", "balanced:primitives=strip", "balanced:sort=mpvo"] {
        assert!(bluntfin.contains(&l.to_string()), "{l} missing from {bluntfin:?}");
    }
    // The oxygen post also has the culling scenes, culling on and off
    // (--quick: the first method with a culling option, no zoomed scene).
    let oxygen = labels("oxygenpost");
    assert_eq!(defaults(&oxygen), tet);
    let first = registry.for_kind(DataKind::TetMesh).find_map(|m| m.culling_option().map(|o| (m.name, o))).unwrap();
    let (m, o) = first;
    assert_eq!(
        oxygen[oxygen.len() - 4..],
        [format!("{m} @transparent"), format!("{m}:{o}=off @transparent"), format!("{m} @still"), format!("{m}:{o}=off @still")]
    );
    // Krüger & Westermann's claim is about any volume.
    let ct = labels("chest-ct");
    for m in ["raycast-fragment", "raycast-compute"] {
        assert!(ct.contains(&m.to_string()) && ct.contains(&format!("{m}:ert=1,skip=off")), "{ct:?}");
        // The method's own suite set (the cheap end of its trade-off), for comparisons at matched error.
        assert!(ct.contains(&format!("{m}:step=1,reads=quads")), "{ct:?}");
    }
    let settings = SuiteSettings { width: 32, height: 32, frames: 1, warmup: 0, ..SuiteSettings::standard(true, vec!["bluntfin".into()]) };
    let planned = plan(&registry, &settings).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let ctx = context();
    let summary = run_suite(&ctx, &registry, &planned, &settings, dir.path(), |_, _| {}).unwrap();
    assert!(summary.runs.iter().all(|r| r.status == "ok"), "{:?}", summary.runs.iter().map(|r| &r.message).collect::<Vec<_>>());
    let report = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    for line in [
        "| bluntfin | balanced ÷ vicp |",
        "| bluntfin | balanced:integrator=average ÷ balanced |",
        "| bluntfin | balanced:integrator=linear-exact ÷ balanced |",
        "| bluntfin | balanced:integrator=average | ok |",
        // Thesis Table 6.3 (atfs against balanced) and Table 6.2 (cells drawn).
        "| bluntfin | atfs ÷ balanced |",
        "| bluntfin | atfs cells drawn ÷ cells (",
    ] {
        assert!(report.contains(line), "{line} missing from\n{report}");
    }
    // Published 4.50 / 3.30 fps (Table 6.3) and 1.31 / 0.94 (Table 6.4).
    assert!(report.contains("| 1.36 |") && report.contains("| 1.39 |"), "{report}");
}
