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
    let snapshot: Vec<(f64, f64, bool)> = points.iter().map(|p| (p.frame_ms, p.rmse, p.ok())).collect();
    for (i, p) in points.iter_mut().enumerate() {
        p.on_front = p.ok()
            && !snapshot.iter().enumerate().any(|(j, &(t, e, ok))| {
                ok && j != i && t <= snapshot[i].0 && e <= snapshot[i].1 && (t < snapshot[i].0 || e < snapshot[i].1)
            });
    }
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
        let _ = writeln!(s, "| {status} | {} | | | | | | {} |", p.label, p.error.as_deref().unwrap_or("").replace('|', "/"));
    }
    s
}

const FONT_PATHS: [&str; 2] =
    ["/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf", "/usr/share/fonts/dejavu/DejaVuSans.ttf"];

/// Register a TrueType font for plot labels (plotters is built with
/// `ab_glyph`, which has no system font lookup; criterion's plots need it
/// too). Idempotent.
pub fn register_font() -> Result<()> {
    use std::sync::OnceLock;
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        FONT_PATHS.iter().any(|p| {
            std::fs::read(p)
                .ok()
                .map(|bytes| {
                    let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                    plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, bytes).is_ok()
                })
                .unwrap_or(false)
        })
    });
    anyhow::ensure!(ok, "no font for plot labels: install fonts-dejavu-core (scripts/setup.sh does), looked in {FONT_PATHS:?}");
    Ok(())
}

/// A fixed colour per integrator name (any method family's), grey otherwise.
fn integrator_colour(name: &str) -> plotters::style::RGBColor {
    use plotters::style::RGBColor;
    match name {
        "average" => RGBColor(200, 60, 60),
        "preint" => RGBColor(60, 140, 60),
        "ppi" => RGBColor(40, 90, 200),
        "linear-exact" => RGBColor(150, 60, 180),
        "point" => RGBColor(230, 140, 20),
        _ => RGBColor(110, 110, 110),
    }
}

/// The sweep as JSON: what was swept (dataset, image size, device) and every
/// row, failed ones with their error and no numbers (null).
pub fn write_json(path: &Path, dataset: &str, width: u32, height: u32, device: &str, points: &[ParetoPoint]) -> Result<()> {
    let doc = serde_json::json!({ "dataset": dataset, "width": width, "height": height, "device": device, "points": points });
    let mut bytes = serde_json::to_vec_pretty(&doc)?;
    bytes.push(b'\n');
    crate::fsio::write_output(path, &bytes)
}

/// Frame time (x) against RMSE (y), both logarithmic; the front is joined
/// by a line and its points labelled.
pub fn plot_png(path: &Path, title: &str, points: &[ParetoPoint]) -> Result<()> {
    use plotters::prelude::*;
    register_font()?;
    let points: Vec<&ParetoPoint> = points.iter().filter(|p| p.ok()).collect();
    anyhow::ensure!(!points.is_empty(), "nothing to plot: every run of the sweep failed");
    let mut methods: Vec<&str> = points.iter().map(|p| p.method.as_str()).collect();
    methods.dedup();
    methods.sort();
    methods.dedup();
    let (mut t0, mut t1, mut e0, mut e1) = (f64::MAX, 0f64, f64::MAX, 0f64);
    for p in &points {
        t0 = t0.min(p.frame_ms);
        t1 = t1.max(p.frame_ms);
        e0 = e0.min(p.rmse.max(1e-9));
        e1 = e1.max(p.rmse.max(1e-9));
    }
    // Explicit ticks at 1, 2, 5 x 10^k: a sweep often spans less than a
    // decade, where the log axis would otherwise show no labels at all.
    let ticks = |lo: f64, hi: f64| -> Vec<f64> {
        let mut v = Vec::new();
        let mut decade = 10f64.powf(lo.log10().floor());
        while decade <= hi {
            for m in [1.0, 2.0, 3.0, 5.0, 7.0] {
                let t = m * decade;
                if t >= lo && t <= hi {
                    v.push(t);
                }
            }
            decade *= 10.0;
        }
        v
    };
    let (x_range, y_range) = ((t0 / 1.3, t1 * 1.3), (e0 / 1.5, e1 * 1.5));
    let (w, h) = (1100u32, 750u32);
    let mut rgb = vec![0u8; (w * h * 3) as usize];
    let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
    let draw = || -> Result<(), Box<dyn std::error::Error>> {
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 24))
            .margin(20)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d(
                (x_range.0..x_range.1).log_scale().with_key_points(ticks(x_range.0, x_range.1)),
                (y_range.0..y_range.1).log_scale().with_key_points(ticks(y_range.0, y_range.1)),
            )?;
        chart
            .configure_mesh()
            .x_desc("median frame time (ms)")
            .y_desc("RMSE against the f64 reference")
            .label_style(("sans-serif", 15))
            .axis_desc_style(("sans-serif", 18))
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| format!("{v:.1e}"))
            .draw()?;
        let colour = |p: &ParetoPoint| integrator_colour(&p.integrator);
        for p in &points {
            let c = colour(p);
            // Each method its own marker: filled, ring, then larger ring.
            let m = methods.iter().position(|&n| n == p.method).unwrap_or(0);
            let style = if m % 2 == 0 { c.filled() } else { c.stroke_width(2) };
            chart.draw_series(std::iter::once(Circle::new((p.frame_ms, p.rmse.max(1e-9)), 5, style)))?;
        }
        let mut front: Vec<&ParetoPoint> = points.iter().copied().filter(|p| p.on_front).collect();
        front.sort_by(|a, b| a.frame_ms.total_cmp(&b.frame_ms));
        chart.draw_series(LineSeries::new(front.iter().map(|p| (p.frame_ms, p.rmse.max(1e-9))), BLACK.stroke_width(1)))?;
        // Labels stacked upward from each front point so neighbours don't overlap.
        for (i, p) in front.iter().enumerate() {
            let anchor = chart.backend_coord(&(p.frame_ms, p.rmse.max(1e-9)));
            root.draw(&Text::new(
                p.label.clone(),
                (anchor.0 + 8, anchor.1 - 16 * (i as i32 % 3) - 4),
                ("sans-serif", 13).into_font().color(&BLACK),
            ))?;
        }
        // Legend: colours are integrators (those in the sweep); markers are methods.
        let mut integrators: Vec<&str> = points.iter().map(|p| p.integrator.as_str()).collect();
        integrators.sort();
        integrators.dedup();
        for (i, name) in integrators.iter().enumerate() {
            let y = 560 + 22 * i as i32;
            root.draw(&Circle::new((900, y), 5, integrator_colour(name).filled()))?;
            root.draw(&Text::new(if name.is_empty() { "-" } else { *name }, (912, y - 8), ("sans-serif", 15).into_font()))?;
        }
        let markers: Vec<String> =
            methods.iter().enumerate().map(|(i, m)| format!("{}: {m}", if i % 2 == 0 { "filled" } else { "ring" })).collect();
        root.draw(&Text::new(markers.join(", "), (700, 650), ("sans-serif", 15).into_font()))?;
        root.draw(&Text::new("line: Pareto front", (850, 670), ("sans-serif", 15).into_font()))?;
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| anyhow::anyhow!("drawing {}: {e}", path.display()))?;
    drop(root);
    super::image::write_rgb8_png(path, w, h, &rgb)
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
