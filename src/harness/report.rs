//! Result files and the tables printed for people: JSON written atomically,
//! and the VICP-vs-balanced comparison set beside the published figures.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context as _, Result};
use serde::Serialize;

use super::run::RunResult;

/// Write `value` as pretty JSON via a temporary file (no partial output).
pub fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let text = serde_json::to_string_pretty(value).context("serialising results")?;
    crate::fsio::write_output(path, (text + "\n").as_bytes())
}

/// Moreland's thesis Table 6.3 (Quadro FX 3000, 800x800), tets per second.
pub fn published_tets_per_second(mesh: &str, method: &str) -> Option<f64> {
    match (mesh, method) {
        ("bluntfin", "vicp") => Some(618e3),
        ("bluntfin", "balanced") => Some(843e3),
        ("oxygenpost", "vicp") => Some(690e3),
        ("oxygenpost", "balanced") => Some(1168e3),
        _ => None,
    }
}

/// One row of the comparison: a run and its image difference from the other
/// method's image of the same frame.
pub struct ComparisonRow<'a> {
    pub result: &'a RunResult,
    pub rmse_vs_other: Option<f64>,
}

pub fn comparison_table(rows: &[ComparisonRow]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| mesh | method | cells | floats/cell | MB/frame | static KB | frame ms median [min, max] | sort | pack | upload | GPU | wait | M cells/s | thesis M tets/s | RMSE vs other | RMSE vs f64 ref | max err |"
    );
    let _ = writeln!(s, "|---|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for row in rows {
        let r = row.result;
        let t = &r.time_ms;
        let published = published_tets_per_second(&r.mesh, r.method).map_or("-".into(), |v| format!("{:.3}", v / 1e6));
        let rmse = row.rmse_vs_other.map_or("-".into(), |v| format!("{v:.2e}"));
        let (ref_rmse, ref_max) = r
            .error
            .as_ref()
            .map_or(("-".into(), "-".into()), |e| (format!("{:.2e}", e.rmse), format!("{:.2e}", e.max_abs)));
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.2} | {:.2} | {:.1} | {:.1} [{:.1}, {:.1}] | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.3} | {} | {} | {} | {} |",
            r.mesh,
            r.method,
            r.cells,
            r.upload.floats_per_cell,
            r.upload.bytes_per_frame as f64 / 1e6,
            r.upload.static_bytes as f64 / 1e3,
            t.frame.median,
            t.frame.min,
            t.frame.max,
            t.sort.median,
            t.pack.median,
            t.upload.median,
            t.gpu.median,
            t.wait.median,
            r.cells_per_second / 1e6,
            published,
            rmse,
            ref_rmse,
            ref_max,
        );
    }
    s
}
