//! Sweeps over the registry: `compare` (every method, or the given specs,
//! side by side on several datasets) and `pareto` (each method's option
//! sets on one dataset, run time against error). Both write each row as it
//! completes, record a failed row with its error and go on; the caller
//! exits non-zero when any row failed. Nothing here names a method.

use std::path::Path;
use std::sync::Arc;

use anyhow::{Context as _, Result};

use super::datasets::Dataset;
use super::pareto::{mark_front, markdown, plot_png, write_csv, write_json, ParetoPoint};
use super::reference_cache::reference_image;
use super::report::{self, ComparisonRow};
use super::run::{run, RunConfig, RunOutput};
use crate::algo::method::{DataKind, MethodInfo};
use crate::algo::registry::{MethodSpec, Registry};
use crate::fsio;
use crate::scene::TransferFunction;
use crate::vk::Context;

fn pairs_text(pairs: &[(&str, String)]) -> String {
    pairs.iter().map(|(k, v)| format!("{k}={v}")).collect::<Vec<_>>().join(",")
}

fn push_unique(specs: &mut Vec<MethodSpec>, spec: MethodSpec) {
    if !specs.iter().any(|s| s.canonical() == spec.canonical()) {
        specs.push(spec);
    }
}

/// The specs `names` with the option flags `flags` applied (a method
/// without one of those options is an error naming both), or, when `names`
/// is empty, every registered method for `kind` with each of its option
/// sets `variants(method)`, the flags holding their options fixed.
pub fn specs_for(
    registry: &Registry,
    names: &[String],
    kind: DataKind,
    flags: &[(&str, String)],
    variants: impl Fn(&MethodInfo) -> &'static [&'static str],
) -> Result<Vec<MethodSpec>> {
    let mut specs = Vec::new();
    if names.is_empty() {
        for m in registry.for_kind(kind) {
            let base = registry.parse_spec(m.name, &[])?;
            for v in variants(m) {
                let spec = registry.variant(&registry.variant(&base, v)?, &pairs_text(flags))?;
                push_unique(&mut specs, spec);
            }
        }
        anyhow::ensure!(!specs.is_empty(), "no registered method renders {} datasets", kind.name());
    } else {
        for n in names {
            let spec = registry.parse_spec(n, flags)?;
            spec.check_renders(kind, "the dataset")?;
            push_unique(&mut specs, spec);
        }
    }
    Ok(specs)
}

/// The runs of a run-time-against-error sweep: each method (the given
/// specs, or every method for `kind`) over its registered sweep option
/// sets, with the spec's own options and the flags held fixed.
pub fn pareto_specs(registry: &Registry, names: &[String], kind: DataKind, flags: &[(&str, String)]) -> Result<Vec<MethodSpec>> {
    if names.is_empty() {
        return specs_for(registry, names, kind, flags, |m| m.sweep);
    }
    let mut specs = Vec::new();
    for n in names {
        let given = registry.parse_spec(n, flags)?;
        given.check_renders(kind, "the dataset")?;
        let own = n.split_once(':').map_or("", |(_, o)| o);
        let fixed = [own.to_string(), pairs_text(flags)].join(",");
        let variants: &[&str] = if given.info.sweep.is_empty() { &[""] } else { given.info.sweep };
        for v in variants {
            push_unique(&mut specs, registry.variant(&registry.variant(&given, v)?, &fixed)?);
        }
    }
    Ok(specs)
}

/// One dataset of a comparison with its transfer function and runs.
pub struct CompareJob {
    pub dataset: Dataset,
    pub tf: TransferFunction,
    pub specs: Vec<MethodSpec>,
}

/// One finished row of a comparison.
pub struct CompareRow {
    pub dataset: String,
    pub label: String,
    /// The run, or why it failed or was skipped.
    pub outcome: Result<RunOutput, String>,
    /// The device lacks a feature the method needs (not a failure).
    pub skipped: bool,
}

/// Why `spec` cannot run on this device (a skipped row, not a failure).
pub fn skip_reason(spec: &MethodSpec, info: &crate::vk::DeviceInfo) -> Option<String> {
    spec.info.unsupported_reason(info).map(|why| format!("skipped: {why}"))
}

/// Refuse comparisons whose output files would overwrite each other.
pub fn check_compare_outputs(jobs: &[CompareJob]) -> Result<()> {
    let mut datasets = std::collections::HashSet::new();
    let mut stems = std::collections::HashSet::new();
    for j in jobs {
        anyhow::ensure!(
            datasets.insert(j.dataset.name.clone()),
            "--data: two datasets are named '{}'; their output files would overwrite each other",
            j.dataset.name
        );
        for s in &j.specs {
            anyhow::ensure!(
                stems.insert(format!("{}-{}", j.dataset.name, s.file_stem())),
                "two runs of '{}' on '{}' would write the same files",
                s.label(),
                j.dataset.name
            );
        }
    }
    Ok(())
}

/// Run every job's specs; with `out`, each row's JSON, PNG and difference
/// PNG (all or none) and the table so far are written as the row completes.
pub fn compare(ctx: &Arc<Context>, registry: &Registry, jobs: &mut [CompareJob], cfg: &RunConfig, out: Option<&Path>) -> Result<Vec<CompareRow>> {
    let mut rows = Vec::new();
    for job in jobs.iter_mut() {
        let dataset = &mut job.dataset;
        let mut reference = None;
        for spec in &job.specs {
            if let Some(why) = skip_reason(spec, &ctx.info) {
                crate::progress!("volbench: {} on {}: {why}", spec.label(), dataset.name);
                rows.push(CompareRow { dataset: dataset.name.clone(), label: spec.label(), outcome: Err(why), skipped: true });
                continue;
            }
            crate::progress!("volbench: {} on {}...", spec.label(), dataset.name);
            let outcome = (|| -> Result<RunOutput> {
                let mut result = dataset.run_handing_over(|d| run(ctx, spec, d, &job.tf, cfg))??;
                if reference.is_none() && result.result.error.is_none() {
                    crate::progress!("volbench: f64 reference of {}...", dataset.name);
                    reference = Some(reference_image(dataset, &job.tf, &result.result.image.camera, cfg.width, cfg.height)?);
                }
                let diff = match &reference {
                    Some(r) if result.result.error.is_none() => Some(result.attach_error(r)?),
                    _ => None,
                };
                if let Some(dir) = out {
                    let stem = format!("{}-{}", dataset.name, spec.file_stem());
                    let json = report::json_bytes(&result.result)?;
                    let png = result.image.png_bytes()?;
                    let diff_png = diff.map(|d| d.png_bytes()).transpose()?;
                    let (j, p, dp) = (dir.join(format!("{stem}.json")), dir.join(format!("{stem}.png")), dir.join(format!("{stem}-diff.png")));
                    let mut files: Vec<(&Path, &[u8])> = vec![(&j, &json), (&p, &png)];
                    if let Some(d) = &diff_png {
                        files.push((&dp, d));
                    }
                    fsio::write_all(&files)?;
                }
                Ok(result)
            })();
            if let Err(e) = &outcome {
                crate::progress!("volbench: {} on {} failed: {e:#}", spec.label(), dataset.name);
            }
            let outcome = outcome.map_err(|e| format!("{e:#}"));
            rows.push(CompareRow { dataset: dataset.name.clone(), label: spec.label(), outcome, skipped: false });
            if let Some(dir) = out {
                fsio::write_output(&dir.join("comparison.md"), comparison_markdown(&rows, registry)?.as_bytes())?;
            }
        }
    }
    Ok(rows)
}

/// The comparison table of `rows`, each with its RMSE against the first
/// successful row of the same dataset.
pub fn comparison_markdown(rows: &[CompareRow], registry: &Registry) -> Result<String> {
    let mut table_rows = Vec::new();
    for (i, row) in rows.iter().enumerate() {
        let first = rows[..i].iter().find_map(|r| if r.dataset == row.dataset { r.outcome.as_ref().ok() } else { None });
        let rmse_vs_first = match (first, &row.outcome) {
            (Some(f), Ok(o)) => Some(f.image.compare(&o.image)?.rmse),
            _ => None,
        };
        table_rows.push(ComparisonRow {
            label: row.label.clone(),
            dataset: row.dataset.clone(),
            outcome: row.outcome.as_ref().map(|o| &o.result).map_err(Clone::clone),
            rmse_vs_first,
        });
    }
    Ok(report::comparison_table(&table_rows, registry))
}

/// Run every spec on `dataset`, compare each image with the (cached) f64
/// reference, and keep `pareto.csv` (rewritten as each row completes),
/// `pareto.md`, `pareto.json` and `pareto.png` in `out_dir`. Failed rows are recorded.
pub fn pareto(
    ctx: &Arc<Context>,
    dataset: &mut Dataset,
    tf: &TransferFunction,
    specs: &[MethodSpec],
    cfg: &RunConfig,
    out_dir: &Path,
) -> Result<Vec<ParetoPoint>> {
    let mut points = Vec::new();
    let mut reference = None;
    for spec in specs {
        let label = spec.label();
        if let Some(why) = skip_reason(spec, &ctx.info) {
            crate::progress!("volbench: {label}: {why}");
            let mut p = ParetoPoint::failed(&label, spec.info.name, &spec.options.to_spec_string(), why);
            p.skipped = true;
            points.push(p);
            continue;
        }
        crate::progress!("volbench: {label}...");
        let point = (|| -> Result<ParetoPoint> {
            let mut out = dataset.run_handing_over(|d| run(ctx, spec, d, tf, cfg))??;
            // A method's own error (terrain height error) needs no image.
            if out.result.error.is_none() {
                if reference.is_none() {
                    reference = Some(reference_image(dataset, tf, &out.result.image.camera, cfg.width, cfg.height)?);
                }
                if let Some(r) = &reference {
                    out.attach_error(r)?;
                }
            }
            ParetoPoint::from_result(&label, &out.result).context("no error against the reference")
        })()
        .unwrap_or_else(|e| {
            crate::progress!("volbench: {label} failed: {e:#}");
            ParetoPoint::failed(&label, spec.info.name, &spec.options.to_spec_string(), format!("{e:#}"))
        });
        points.push(point);
        mark_front(&mut points);
        write_csv(&out_dir.join("pareto.csv"), &points)?;
    }
    fsio::write_output(&out_dir.join("pareto.md"), markdown(&dataset.name, &points).as_bytes())?;
    write_json(&out_dir.join("pareto.json"), &dataset.name, cfg.width, cfg.height, &ctx.info.name, &points)?;
    if points.iter().any(|p| p.error.is_none()) {
        let title = format!("{}: frame time against error ({}x{}, {})", dataset.name, cfg.width, cfg.height, ctx.info.name);
        plot_png(&out_dir.join("pareto.png"), &title, &points)?;
    }
    Ok(points)
}
