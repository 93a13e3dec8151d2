//! Rendering the cases with every method and comparing with the reference.

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{Context as _, Result};

use super::{bound, stress_cases, uses_papers_model, CaseData, StressCase, StressRow, PAPERS_DISTANCE_CLAMP_DIAGONALS};
use crate::algo::registry::{MethodSpec, Registry};
use crate::harness::image::RgbaImage;
use crate::harness::reference_cache::reference_image;
use crate::harness::run::{run, RunConfig};
use crate::reference::render_papers_model;
use crate::reference::silhouette::{box_silhouette_pixels, silhouette_pixels, SILHOUETTE_TOLERANCE_PX};
use crate::vk::Context;

/// Which methods and option sets render every case.
#[derive(Debug, Clone)]
pub struct StressConfig {
    pub size: u32,
    pub specs: Vec<MethodSpec>,
    /// Where to write each case's reference and each row's image and
    /// |image - reference| x10 as PNG (none: no images).
    pub images: Option<PathBuf>,
}

impl StressConfig {
    /// Every method of `registry` with each of its stress option sets
    /// (each renders the cases of its kind).
    pub fn full(registry: &Registry, size: u32) -> Result<Self> {
        let mut specs = Vec::new();
        for m in registry.methods() {
            let base = registry.parse_spec(m.name, &[])?;
            for v in m.stress {
                specs.push(registry.variant(&base, v)?);
            }
        }
        Ok(StressConfig { size, specs, images: None })
    }
}

/// Pixels with a NaN component, pixels with an infinite component.
pub fn non_finite_pixels(image: &RgbaImage) -> (usize, usize) {
    let nan = image.pixels.iter().filter(|p| p.iter().any(|c| c.is_nan())).count();
    let inf = image.pixels.iter().filter(|p| p.iter().any(|c| c.is_infinite())).count();
    (nan, inf)
}

/// Render `cases` with every spec of `cfg` and compare each image with the
/// f64 reference (cached on disk, see `reference_cache`).
pub fn run_cases(ctx: &Arc<Context>, cases: &[StressCase], cfg: &StressConfig) -> Result<Vec<StressRow>> {
    run_cases_with_progress(ctx, cases, cfg, |_| Ok(()))
}

/// The pixels on the case's silhouette up to rounding (left out of the
/// max error).
fn ambiguous_pixels(case: &StressCase, size: u32) -> Vec<bool> {
    match &case.data {
        CaseData::TetMesh(m) => silhouette_pixels(m, &case.camera, size, size, SILHOUETTE_TOLERANCE_PX),
        CaseData::Volume(v) => {
            let b = v.bounds();
            box_silhouette_pixels(b.min, b.max, &case.camera, size, size, SILHOUETTE_TOLERANCE_PX)
        }
    }
}

/// The papers' model's image of the case and its own max error against
/// the reference (over the same pixels as the rows), where a row is held
/// against it; else none and 0.
fn papers_model(
    case: &StressCase,
    specs: &[&MethodSpec],
    cfg: &StressConfig,
    reference: &RgbaImage,
    ambiguous: &[bool],
) -> Result<(Option<RgbaImage>, f64)> {
    let CaseData::TetMesh(m) = &case.data else { return Ok((None, 0.0)) };
    if !specs.iter().any(|s| uses_papers_model(case, s)) {
        return Ok((None, 0.0));
    }
    let model = render_papers_model(m, &case.camera, &case.tf, cfg.size, cfg.size, PAPERS_DISTANCE_CLAMP_DIAGONALS)
        .with_context(|| format!("stress case '{}': papers' model", case.name))?;
    let pixels = model.pixels.iter().map(|p| p.map(|c| c as f32)).collect();
    let image = RgbaImage { width: cfg.size, height: cfg.size, pixels };
    if let Some(dir) = &cfg.images {
        image.write_png(&dir.join(format!("{}.papers-model.png", case.name)))?;
    }
    let error = image.compare_excluding(reference, ambiguous)?.max_abs;
    Ok((Some(image), error))
}

/// One frame of the case's fixed camera at `size` x `size`.
fn run_config(case: &StressCase, size: u32) -> RunConfig {
    RunConfig {
        width: size,
        height: size,
        frames: 1,
        warmup: 0,
        overlap: false,
        projection: case.camera.projection,
        fixed_camera: Some(case.camera),
        // Stress checks images; the fixed cost is not measured here.
        fixed_frames: 0,
        ..RunConfig::default()
    }
}

/// [`run_cases`], calling `progress` with each row as soon as it is
/// measured. A render that fails is a `fail` row with its error; the sweep
/// goes on. An error of the reference itself, or one `progress` returns
/// (e.g. the JSON cannot be written), ends the sweep.
pub fn run_cases_with_progress(
    ctx: &Arc<Context>,
    cases: &[StressCase],
    cfg: &StressConfig,
    mut progress: impl FnMut(&StressRow) -> Result<()>,
) -> Result<Vec<StressRow>> {
    let mut rows = Vec::new();
    for case in cases {
        let specs: Vec<&MethodSpec> = cfg.specs.iter().filter(|s| s.info.data == case.data.kind()).collect();
        if specs.is_empty() {
            continue;
        }
        let dataset = case.data.dataset(&case.name);
        let reference = reference_image(&dataset, &case.tf, &case.camera, cfg.size, cfg.size)
            .with_context(|| format!("stress case '{}': reference", case.name))?;
        if let Some(dir) = &cfg.images {
            reference.image.write_png(&dir.join(format!("{}.reference.png", case.name)))?;
        }
        // Pixels on the mesh's silhouette up to rounding: left out of the max error.
        let ambiguous = ambiguous_pixels(case, cfg.size);
        let silhouette_count = ambiguous.iter().filter(|&&a| a).count();
        let not_ambiguous: Vec<bool> = ambiguous.iter().map(|a| !a).collect();
        // The papers' model's own error against the reference, where a row
        // is held against it (over the same pixels as the rows).
        let (papers_model, papers_model_error) = papers_model(case, &specs, cfg, &reference.image, &ambiguous)?;
        for spec in specs {
            let opt = |k: &str| spec.options.text(k).unwrap_or_else(|_| "-".into());
            let Some((b, documented)) = bound(case, spec, papers_model_error) else { continue };
            let rc = run_config(case, cfg.size);
            let mut row = StressRow {
                case: case.name.clone(),
                method: spec.info.name,
                options: spec.options.to_spec_string(),
                integrator: opt("integrator"),
                interpolation: opt("interpolation"),
                sort: opt("sort"),
                adaptive: opt("adaptive"),
                error: None,
                nan_pixels: 0,
                inf_pixels: 0,
                max_abs_error: f64::NAN,
                silhouette_pixels: silhouette_count,
                silhouette_max_error: 0.0,
                papers_model_gap: None,
                rmse: f64::NAN,
                status: "fail",
                bound: b,
            };
            let measured = run(ctx, spec, &dataset, &case.tf, &rc).and_then(|out| {
                if let Some(dir) = &cfg.images {
                    let stem = format!("{}.{}.{}", case.name, spec.info.name, row.options.replace(['=', ','], "-"));
                    out.image.write_png(&dir.join(format!("{stem}.png")))?;
                    out.image.difference(&reference.image).write_png(&dir.join(format!("{stem}.diff.png")))?;
                }
                let e = out.image.compare_excluding(&reference.image, &ambiguous)?;
                let on_silhouette = out.image.compare_excluding(&reference.image, &not_ambiguous)?;
                let gap = match &papers_model {
                    Some(model) if uses_papers_model(case, spec) => {
                        Some(out.image.compare_excluding(model, &ambiguous)?.max_abs)
                    }
                    _ => None,
                };
                Ok((non_finite_pixels(&out.image), e, on_silhouette.max_abs, gap))
            });
            match measured {
                Ok(((nan_pixels, inf_pixels), e, silhouette_max, gap)) => {
                    row.silhouette_max_error = if silhouette_count > 0 { silhouette_max } else { 0.0 };
                    row.papers_model_gap = gap;
                    // NaN compares false: a NaN error is never within the bound.
                    let within = nan_pixels == 0 && inf_pixels == 0 && e.max_abs <= b && e.rmse.is_finite();
                    row.status = match (within, documented) {
                        (false, _) => "fail",
                        (true, true) => "documented",
                        (true, false) => "ok",
                    };
                    (row.nan_pixels, row.inf_pixels, row.max_abs_error, row.rmse) = (nan_pixels, inf_pixels, e.max_abs, e.rmse);
                }
                Err(e) => row.error = Some(format!("{e:#}")),
            }
            progress(&row)?;
            rows.push(row);
        }
    }
    Ok(rows)
}

/// `volbench stress`: every case with every method, integrator,
/// interpolation and sort at `size` x `size` pixels, against the f64
/// reference. About 700 renders; ~2 minutes at 128x128 on 2 cores.
pub fn run_stress(ctx: &Arc<Context>, registry: &Registry, size: u32) -> Result<Vec<StressRow>> {
    run_stress_with_progress(ctx, registry, size, |_| Ok(()))
}

/// [`run_stress`], calling `progress` with each row as soon as it is measured.
pub fn run_stress_with_progress(
    ctx: &Arc<Context>,
    registry: &Registry,
    size: u32,
    progress: impl FnMut(&StressRow) -> Result<()>,
) -> Result<Vec<StressRow>> {
    anyhow::ensure!(
        size >= 16 && size.is_multiple_of(2),
        "--size: the stress image side must be even and at least 16, got {size}"
    );
    run_cases_with_progress(ctx, &stress_cases(size), &StressConfig::full(registry, size)?, progress)
}

/// Rows whose status is "fail" (`volbench stress` exits non-zero if any).
pub fn failures(rows: &[StressRow]) -> usize {
    rows.iter().filter(|r| r.status == "fail").count()
}

/// The Markdown table `volbench stress` prints: one row per render.
pub fn stress_table(rows: &[StressRow]) -> String {
    let mut s = String::from(
        "| case | method | integrator | interpolation | sort | adaptive | NaN px | Inf px | max error | silhouette px (max error) | RMSE | bound | status |\n\
         |---|---|---|---|---|---|---:|---:|---:|---:|---:|---:|---|\n",
    );
    for r in rows {
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {:.2e} | {} ({:.2e}) | {:.2e} | {:.2e} | {} |\n",
            r.case,
            r.method,
            r.integrator,
            r.interpolation,
            r.sort,
            if r.adaptive == "0" { "off" } else { r.adaptive.as_str() },
            r.nan_pixels,
            r.inf_pixels,
            r.max_abs_error,
            r.silhouette_pixels,
            r.silhouette_max_error,
            r.rmse,
            r.bound,
            match &r.error {
                Some(e) => format!("fail: {}", crate::harness::report::md_cell(e)),
                None => r.status.to_string(),
            }
        ));
    }
    s
}
