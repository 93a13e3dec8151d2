//! Result files and the tables printed for people: JSON written atomically,
//! and the comparison table of any set of runs beside the published figures
//! their methods registered.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context as _, Result};
use serde::Serialize;

use super::run::{ErrorKind, RunResult};
use crate::algo::registry::Registry;

/// Write `value` as pretty JSON, all-or-nothing (`fsio::write_output`).
pub fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    crate::fsio::write_output(path, &json_bytes(value)?)
}

/// `value` as the pretty JSON `write_json` writes.
pub fn json_bytes<T: Serialize>(value: &T) -> Result<Vec<u8>> {
    let text = serde_json::to_string_pretty(value).context("serialising results")?;
    Ok((text + "\n").into_bytes())
}

/// `text` as one Markdown table cell: `|` and `\` escaped, `<` as
/// `&lt;` (no HTML), line breaks and every other control character shown
/// as escapes (`\n`, `\u{1b}`; a tab as a space), so a name read from a file can neither end
/// its cell nor start a row of its own.
pub fn md_cell(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '|' => out.push_str("\\|"),
            '\\' => out.push_str("\\\\"),
            '<' => out.push_str("&lt;"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push(' '),
            c if c.is_control() || c == '\u{2028}' || c == '\u{2029}' => {
                let _ = write!(out, "\\u{{{:x}}}", c as u32);
            }
            c => out.push(c),
        }
    }
    out
}

/// A run's rate in its dataset kind's own unit (`DataKind::rate_unit`):
/// `0.961 M cells/s` for a mesh, `25.778 M samples/s` for a volume,
/// `3.459 M triangles/s` for a terrain; "-" when the run counted no such
/// work. The figure is the result's `work.per_second` (the reference
/// view's count over the median frame), unchanged.
pub fn rate(r: &RunResult) -> String {
    rate_of(r.dataset.kind, &r.work.per_second)
}

fn rate_of(kind: crate::algo::method::DataKind, per_second: &std::collections::BTreeMap<&'static str, f64>) -> String {
    let unit = kind.rate_unit();
    per_second.get(unit).map_or("-".into(), |v| format!("{:.3} M {unit}/s", v / 1e6))
}

/// One row of the comparison: a run (or its failure) and its image
/// difference from the first run on the same dataset.
pub struct ComparisonRow<'a> {
    /// How the row is named (`method` or `method variant`).
    pub label: String,
    pub dataset: String,
    pub outcome: Result<&'a RunResult, String>,
    pub rmse_vs_first: Option<f64>,
}

/// A published figure of `result`'s method with its options on its
/// dataset, in cells per second, if the method registered one.
fn published_cells_per_second(result: &RunResult, registry: &Registry) -> Option<f64> {
    registry.published_for(&result.spec, &result.mesh).iter().find_map(|p| p.cells_per_second())
}

pub fn comparison_table(rows: &[ComparisonRow], registry: &Registry) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| dataset | run | cells | floats/cell | MB/frame | static KB | frame ms median [min, max] | CPU prep | upload | GPU | wait | rate | published M cells/s | RMSE vs first | RMSE vs f64 ref | max err |"
    );
    let _ = writeln!(s, "|---|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let mut own_notes = Vec::new();
    for row in rows {
        let r = match &row.outcome {
            Ok(r) => *r,
            Err(e) => {
                let e = md_cell(e);
                let e = if e.starts_with("skipped") { e } else { format!("FAILED: {e}") };
                let _ = writeln!(s, "| {} | {} | {e} |||||||||||||", row.dataset, row.label);
                continue;
            }
        };
        let t = &r.time_ms;
        let published = published_cells_per_second(r, registry).map_or("-".into(), |v| format!("{:.3}", v / 1e6));
        let rmse = row.rmse_vs_first.map_or("-".into(), |v| format!("{v:.2e}"));
        // A method's own measure (not an image error) is marked and explained under the table.
        let (ref_rmse, ref_max) = r.error.as_ref().map_or(("-".into(), "-".into()), |e| {
            let mark = if e.compared == ErrorKind::Own { "†" } else { "" };
            (format!("{:.2e}{mark}", e.rmse), format!("{:.2e}{mark}", e.max_abs))
        });
        if let Some(e) = r.error.as_ref().filter(|e| e.compared == ErrorKind::Own) {
            own_notes.push(format!("† {} / {}: {}", row.dataset, row.label, e.reference));
        }
        // The method's own CPU phases (sort, pack, ...) together; not the
        // device passes it times itself (`*_gpu`, part of `gpu`).
        let cpu = |k: &str| !super::run::RUNNER_PHASES.contains(&k) && !k.ends_with(crate::algo::method::DEVICE_PHASE_SUFFIX);
        // (+ 0.0: an empty float sum is -0.0.)
        let prep: f64 = t.phases.iter().filter(|(k, _)| cpu(k)).map(|(_, v)| v.median).sum::<f64>() + 0.0;
        let frame = t.phase("frame");
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.2} | {:.1} | {:.1} [{:.1}, {:.1}] | {:.1} | {:.1} | {:.1} | {:.1} | {} | {} | {} | {} | {} |",
            row.dataset,
            row.label,
            r.work.counts.get("cells").map_or("-".into(), |c| c.to_string()),
            r.upload.floats_per_cell.map_or("-".into(), |f| format!("{f:.2}")),
            r.upload.bytes_per_frame as f64 / 1e6,
            r.upload.static_bytes as f64 / 1e3,
            frame.median,
            frame.min,
            frame.max,
            prep,
            t.phase("upload").median,
            t.phase("gpu").median,
            t.phase("wait").median,
            rate(r),
            published,
            rmse,
            ref_rmse,
            ref_max,
        );
    }
    if !own_notes.is_empty() {
        s += "\n";
        for n in own_notes {
            let _ = writeln!(s, "{n}");
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algo::method::DataKind;

    #[test]
    fn a_rate_is_given_in_its_kinds_own_unit_or_not_at_all() {
        let per_second = |pairs: &[(&'static str, f64)]| pairs.iter().copied().collect::<std::collections::BTreeMap<_, _>>();
        let mesh = per_second(&[("cells", 961_234.0), ("cells_drawn", 961_234.0)]);
        assert_eq!(rate_of(DataKind::TetMesh, &mesh), "0.961 M cells/s");
        // A volume's rays take samples; it has no cells to give a rate of.
        let volume = per_second(&[("samples", 25_778_121.9), ("rays", 358_087.7), ("pixels", 835_266.1)]);
        assert_eq!(rate_of(DataKind::Volume, &volume), "25.778 M samples/s");
        let terrain = per_second(&[("triangles", 3_459_047.2), ("nc_cells", 72_514.1)]);
        assert_eq!(rate_of(DataKind::Terrain, &terrain), "3.459 M triangles/s");
        // A kind's own count missing (a test method counting nothing): "-", not 0.
        assert_eq!(rate_of(DataKind::Volume, &mesh), "-");
        assert_eq!(rate_of(DataKind::TetMesh, &per_second(&[])), "-");
    }
}
