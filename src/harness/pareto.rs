//! Run time against error: a sweep over methods, integrators, table sizes,
//! sorts and interpolations on one mesh, each run compared with the (cached)
//! f64 reference, written as CSV, a Markdown table and a log-log plot with
//! the Pareto front (no other run is both faster and more accurate) marked.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use serde::Serialize;

use super::run::RunResult;

/// One row of the sweep: a view of the run's result record (or of its
/// failure: `error` set, no numbers).
#[derive(Debug, Clone, Serialize)]
pub struct ParetoPoint {
    /// `method variant` as the sweep names it.
    pub label: String,
    pub method: String,
    /// The full option set (`key=value,...`).
    pub options: String,
    /// The `integrator` option where the method has one (colours the plot).
    pub integrator: String,
    /// Median frame time (ms).
    pub frame_ms: f64,
    pub gpu_ms: f64,
    pub table_build_ms: f64,
    pub rmse: f64,
    pub max_abs: f64,
    pub psnr_db: f64,
    pub on_front: bool,
    /// Why the run failed or was skipped (the row has no numbers then).
    pub error: Option<String>,
    /// Skipped (the device lacks a feature), not failed.
    pub skipped: bool,
}

impl ParetoPoint {
    pub fn from_result(label: &str, r: &RunResult) -> Option<Self> {
        let e = r.error.as_ref()?;
        Some(ParetoPoint {
            label: label.to_string(),
            method: r.method.to_string(),
            options: r.options.to_spec_string(),
            integrator: r.options.0.get("integrator").map(|v| v.to_string()).unwrap_or_default(),
            frame_ms: r.time_ms.phase("frame").median,
            gpu_ms: r.time_ms.phase("gpu").median,
            table_build_ms: r.time_ms.table_build_ms,
            rmse: e.rmse,
            max_abs: e.max_abs,
            psnr_db: e.psnr_db,
            on_front: false,
            error: None,
            skipped: false,
        })
    }

    /// A row whose run failed with `error`.
    pub fn failed(label: &str, method: &str, options: &str, error: String) -> Self {
        ParetoPoint {
            label: label.to_string(),
            method: method.to_string(),
            options: options.to_string(),
            integrator: String::new(),
            frame_ms: f64::NAN,
            gpu_ms: f64::NAN,
            table_build_ms: f64::NAN,
            rmse: f64::NAN,
            max_abs: f64::NAN,
            psnr_db: f64::NAN,
            on_front: false,
            error: Some(error),
            skipped: false,
        }
    }

    fn ok(&self) -> bool {
        self.error.is_none()
    }
}

/// Mark the points no other point dominates (faster or equal and more
/// accurate or equal, strictly better in one).
pub fn mark_front(points: &mut [ParetoPoint]) {
    super::plots::mark_front(points, |p| p.ok().then_some((p.frame_ms, p.rmse)), |p, on| p.on_front = on);
}

pub fn write_csv(path: &Path, points: &[ParetoPoint]) -> Result<()> {
    let mut s = String::from("method,options,frame_ms,gpu_ms,table_build_ms,rmse,max_abs,psnr_db,on_front,error\n");
    for p in points {
        // Options hold commas: quoted; errors likewise, quotes doubled.
        let quote = |t: &str| format!("\"{}\"", t.replace('"', "\"\""));
        let _ = writeln!(
            s,
            "{},{},{:.3},{:.3},{:.3},{:.6e},{:.6e},{:.3},{},{}",
            p.method,
            quote(&p.options),
            p.frame_ms,
            p.gpu_ms,
            p.table_build_ms,
            p.rmse,
            p.max_abs,
            p.psnr_db,
            p.on_front,
            quote(p.error.as_deref().unwrap_or(""))
        );
    }
    crate::fsio::write_output(path, s.as_bytes())
}

pub fn markdown(mesh: &str, points: &[ParetoPoint]) -> String {
    let mut sorted: Vec<&ParetoPoint> = points.iter().collect();
    sorted.sort_by(|a, b| a.rmse.total_cmp(&b.rmse));
    let mut s = format!("### {mesh}: run time against error (sorted by RMSE; * = Pareto front)\n\n");
    s += "| | run | frame ms | GPU ms | table build ms | RMSE | max abs | PSNR dB |\n";
    s += "|---|---|---:|---:|---:|---:|---:|---:|\n";
    for p in sorted.iter().filter(|p| p.ok()) {
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} | {:.1} | {:.1} | {:.2e} | {:.2e} | {:.1} |",
            if p.on_front { "*" } else { "" },
            p.label,
            p.frame_ms,
            p.gpu_ms,
            p.table_build_ms,
            p.rmse,
            p.max_abs,
            p.psnr_db
        );
    }
    for p in sorted.iter().filter(|p| !p.ok()) {
        let status = if p.skipped { "SKIPPED" } else { "FAILED" };
        let _ = writeln!(s, "| {status} | {} | | | | | | {} |", p.label, super::report::md_cell(p.error.as_deref().unwrap_or("")));
    }
    s
}

/// The sweep as JSON: what was swept (dataset, image size, device) and every
/// row, failed ones with their error and no numbers (null).
pub fn write_json(path: &Path, dataset: &str, width: u32, height: u32, device: &str, points: &[ParetoPoint]) -> Result<()> {
    let doc = serde_json::json!({ "dataset": dataset, "width": width, "height": height, "device": device, "points": points });
    let mut bytes = serde_json::to_vec_pretty(&doc)?;
    bytes.push(b'\n');
    crate::fsio::write_output(path, &bytes)
}

/// Frame time (x) against RMSE (y), both logarithmic, coloured by
/// integrator, one marker per method; the front joined and labelled.
pub fn plot_png(path: &Path, title: &str, points: &[ParetoPoint]) -> Result<()> {
    use super::plots::{Marker, ScatterPoint};
    let ok: Vec<&ParetoPoint> = points.iter().filter(|p| p.ok()).collect();
    anyhow::ensure!(!ok.is_empty(), "nothing to plot: every run of the sweep failed");
    let mut methods: Vec<&str> = ok.iter().map(|p| p.method.as_str()).collect();
    methods.sort();
    methods.dedup();
    let marker = |m: &str| if methods.iter().position(|&n| n == m).unwrap_or(0) % 2 == 0 { Marker::Filled } else { Marker::Ring };
    let scatter: Vec<ScatterPoint> = ok
        .iter()
        .map(|p| ScatterPoint {
            label: p.label.clone(),
            series: if p.integrator.is_empty() { "-".into() } else { p.integrator.clone() },
            marker: marker(&p.method),
            time_ms: p.frame_ms,
            error: p.rmse,
            on_front: p.on_front,
        })
        .collect();
    let note: Vec<String> = methods.iter().map(|m| format!("{}: {m}", if marker(m) == Marker::Filled { "filled" } else { "ring" })).collect();
    super::plots::time_error_scatter(path, title, "RMSE against the f64 reference", &format!("colours: integrators\n{}", note.join("\n")), &scatter)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pt(t: f64, e: f64) -> ParetoPoint {
        ParetoPoint {
            label: String::new(),
            method: "balanced".into(),
            options: "integrator=ppi".into(),
            integrator: "ppi".into(),
            error: None,
            skipped: false,
            frame_ms: t,
            gpu_ms: t,
            table_build_ms: 0.0,
            rmse: e,
            max_abs: e,
            psnr_db: 0.0,
            on_front: false,
        }
    }

    #[test]
    fn plot_is_written() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.png");
        let mut p = vec![pt(100.0, 1e-3), pt(300.0, 5e-4), pt(200.0, 2e-3)];
        mark_front(&mut p);
        plot_png(&path, "test", &p).unwrap();
        assert!(std::fs::metadata(&path).unwrap().len() > 1000);
    }

    #[test]
    fn front_keeps_only_undominated_points() {
        let mut p = vec![pt(1.0, 5.0), pt(2.0, 2.0), pt(3.0, 3.0), pt(4.0, 1.0), pt(2.0, 2.0)];
        p.push(ParetoPoint::failed("x", "balanced", "", "boom".into()));
        mark_front(&mut p);
        let on: Vec<bool> = p.iter().map(|p| p.on_front).collect();
        assert_eq!(on, vec![true, true, false, true, true, false]);
    }
}
