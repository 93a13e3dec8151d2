//! The suite's report: `report.md` (the runs table, published figures as
//! ratios, the placement, culling and peer sections) and its pictures
//! (montages, frame-time and bytes plots, time against error).

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;

use super::plan::Scene;
use super::summary::{CullCheck, Summary};
use crate::algo::registry::Registry;
use crate::harness::image::RgbaImage;
use crate::harness::plots::{Bar, Marker, ScatterPoint, Tile};
use crate::harness::run::RunResult;

/// The report: environment, the runs table, and measured figures set
/// beside the published ones as ratios between methods on the same dataset
/// (absolute times from other hardware are not comparable; ratios are).
pub fn report(s: &Summary, registry: &Registry) -> String {
    let e = &s.environment;
    let mut t = format!(
        "# volbench suite {}\n\nDevice {} ({}, {}), CPU {} ({} cores, LP_NUM_THREADS {}), volbench {} at {}. \
         Settings: {}x{}, {} timed frames after {} warm-up, camera orbiting {}° per frame{}.\n\n",
        e.started_utc,
        e.device.name,
        e.device.driver_name,
        e.device.driver_info,
        e.cpu_model,
        e.cores,
        e.lp_num_threads.as_deref().unwrap_or("unset"),
        e.volbench_version,
        e.git_sha,
        s.settings.width,
        s.settings.height,
        s.settings.frames,
        s.settings.warmup,
        s.settings.orbit_step_deg,
        if s.settings.quick { " (--quick)" } else { "" },
    );
    if !e.env_switches.is_empty() {
        t += &format!(
            "**Environment switches set** (they change what is measured): {}.\n\n",
            e.env_switches.iter().map(|(k, v)| format!("`{k}={}`", v.escape_debug())).collect::<Vec<_>>().join(", ")
        );
    }
    t += "| dataset | method | status | frame ms median [min, max] | GPU ms | MB/frame | bytes/cell | static KB | rate | error RMSE | max err |\n";
    t += "|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|\n";
    for r in &s.runs {
        match &r.result {
            Some(x) => {
                let f = x.time_ms.phase("frame");
                let _ = writeln!(
                    t,
                    "| {} | {} | ok | {:.1} [{:.1}, {:.1}] | {:.1} | {:.2} | {} | {:.1} | {} | {} | {} |",
                    r.dataset,
                    r.label,
                    f.median,
                    f.min,
                    f.max,
                    x.time_ms.phase("gpu").median,
                    x.upload.bytes_per_frame as f64 / 1e6,
                    x.upload.bytes_per_cell.map_or("-".into(), |v| format!("{v:.0}")),
                    x.upload.static_bytes as f64 / 1e3,
                    crate::harness::report::rate(x),
                    x.error.as_ref().map_or("-".into(), |e| format!("{:.2e}", e.rmse)),
                    x.error.as_ref().map_or("-".into(), |e| format!("{:.2e}", e.max_abs)),
                );
            }
            None => {
                let _ = writeln!(t, "| {} | {} | {}: {} |||||||||", r.dataset, r.label, r.status, r.message.as_deref().unwrap_or("").replace('|', "/"));
            }
        }
    }
    t += &datasets_report(s);
    t += &error_legend(s);
    t += &published_ratios(s, registry);
    t += &placement_report(s);
    t += &cull_report(s);
    t += &peer_report(s);
    t += "\nPictures, per dataset: `plots/time_error-<dataset>.png` (frame time against error, the Pareto front joined, peers included), \
          `plots/frame_time-<dataset>.{png,svg}` (median with the min–max spread), `plots/bytes_per_frame-<dataset>.{png,svg}`; \
          `montage-<dataset>.png`: the f64 reference, then each run beside its ×10 difference from it; every image in `runs/`.\n";
    t
}

/// Where each dataset came from and the transfer function it was shown
/// with, when that is not the shipped datasets' presets: users' files
/// (`--data FILE`) or a `--tf` file.
fn datasets_report(s: &Summary) -> String {
    if !s.datasets.iter().any(|d| d.user) && s.settings.tf.is_none() {
        return String::new();
    }
    let mut t = String::from(
        "\n## Datasets\n\nA user's file is read by volbench's reader; its peers read the original file with their own readers. \
         Transfer function: the standard scene's (`--tf FILE`, the shipped preset, or for a file without `--tf` \
         volbench's generic ramp over the scalar range).\n\n\
         | dataset | source | kind | scalar | transfer function | from |\n|---|---|---|---|---|---|\n",
    );
    for d in &s.datasets {
        let _ = writeln!(
            t,
            "| {} | {}{} | {} | {} | {} | {} |",
            d.name,
            d.source.replace('|', "/"),
            if d.user { " (your file)" } else { "" },
            d.kind.name(),
            d.scalar_array.as_deref().unwrap_or("the reader's default").replace('|', "/"),
            d.transfer_function.as_deref().unwrap_or("-").replace('|', "/"),
            d.transfer_function_from.replace('|', "/"),
        );
    }
    t
}

/// What the runs table's error columns compare: the f64 reference image,
/// or (rows listed by name) a method's own measure in its own unit.
fn error_legend(s: &Summary) -> String {
    use crate::harness::run::ErrorKind;
    let mut t = String::from("\nError columns: the reference-view image against the f64 CPU reference image (RGBA in [0, 1])");
    let own: Vec<String> = s
        .runs
        .iter()
        .filter_map(|r| {
            let e = r.result.as_ref()?.error.as_ref()?;
            (e.compared == ErrorKind::Own).then(|| format!("{} / {}: {}", r.dataset, r.label, e.reference))
        })
        .collect();
    if own.is_empty() {
        t += ".\n";
    } else {
        t += ", except these rows, which report the method's own measure:\n\n";
        for line in own {
            let _ = writeln!(t, "- {line}");
        }
    }
    t
}

/// Runs that do the same work in different places (a method's family
/// names the work, `Family::placement`; e.g. the terrain methods' PC-cell
/// tessellation on the CPU, in a geometry shader, in a compute pass), per
/// dataset, set side by side with the first such run as the base: frame
/// time, device time and per-frame bytes as ratios inside this run, with
/// the work counts that must agree between them.
fn placement_report(s: &Summary) -> String {
    type Group<'a> = (String, String, Vec<(&'a str, &'a RunResult)>);
    let mut groups: Vec<Group> = Vec::new();
    for r in &s.runs {
        let Some(x) = &r.result else { continue };
        let Some(work) = r.placement else { continue };
        match groups.iter_mut().find(|g| g.0 == r.dataset && g.1 == work) {
            Some(g) => g.2.push((&r.label, x)),
            None => groups.push((r.dataset.clone(), work.to_string(), vec![(&r.label, x)])),
        }
    }
    let mut t = String::new();
    for (dataset, work, runs) in groups.iter().filter(|g| g.2.len() >= 2) {
        let (_, base) = runs[0];
        let (bf, bg, bb) = (base.time_ms.phase("frame").median, base.time_ms.phase("gpu").median, base.upload.bytes_per_frame);
        let _ = write!(
            t,
            "\n## {dataset}: {work}, placed differently\n\nRatios against `{}` inside this run (speed: its frame time ÷ the run's; bytes: the run's ÷ its). \
             Counts are the reference view's.\n\n| run | frame ms | speed × | GPU ms | GPU speed × | bytes/frame | bytes × | static KB | CPU phases ms | work |\n|---|---:|---:|---:|---:|---:|---:|---:|---|---|\n",
            runs[0].0
        );
        for (label, x) in runs {
            let (f, g) = (x.time_ms.phase("frame").median, x.time_ms.phase("gpu").median);
            let phases: Vec<String> =
                x.time_ms.phases.iter().filter(|(k, _)| !crate::harness::run::RUNNER_PHASES.contains(&k.as_str())).map(|(k, v)| format!("{k} {:.2}", v.median)).collect();
            let work: Vec<String> = x.work.counts.iter().map(|(k, v)| format!("{k} {v}")).collect();
            let ratio = |a: f64, b: f64| if b > 0.0 { format!("{:.2}", a / b) } else { "-".into() };
            let _ = writeln!(
                t,
                "| {label} | {f:.2} | {} | {g:.2} | {} | {} | {} | {:.1} | {} | {} |",
                ratio(bf, f),
                ratio(bg, g),
                x.upload.bytes_per_frame,
                ratio(x.upload.bytes_per_frame as f64, bb as f64),
                x.upload.static_bytes as f64 / 1e3,
                phases.join(", "),
                work.join(", "),
            );
        }
    }
    t
}

/// The culling scenes: per method, what each rule skipped, the frame time
/// with culling on and off and the speed-up, the rasterizer's work both
/// ways, and the unchanged-image check (culled against unculled image).
pub fn cull_report(s: &Summary) -> String {
    if s.cull_checks.is_empty() {
        return String::new();
    }
    let find = |c: &CullCheck, on: bool| {
        s.runs.iter().find(|r| r.dataset == c.dataset && r.scene == c.scene && r.method == c.method && r.result.as_ref().is_some_and(|x| x.options.flag(c.option).ok() == Some(on)))
    };
    let per_frame = |x: &RunResult, k: &str| x.frame_counts.get(k).filter(|c| c.frames > 0).map_or(0.0, |c| c.total as f64 / c.frames as f64);
    let mut t = String::from(
        "\n## Culling: skipping what a scene does not need\n\n\
         Each scene runs the first tetrahedral methods with culling on (`cull=on`, the default) and off (the zoomed scene \
         times a third of the suite's frames: its frames cost several standard ones). Skipped per timed frame \
         (mean): cells whose table lookups read zero attenuation (transparent), other cells outside the view volume \
         (off-screen); frames re-used: frames with the same view and transfer function as the one before (no cull, sort, \
         pack or upload; the draw is repeated). Primitives in / fragments: pipeline statistics of the reference-view frame, \
         culled / unculled. The image check compares the culled and the unculled reference-view image (culling is exact: \
         RMSE 0 expected, ≤ 1e-6 required).\n\n\
         | dataset | scene | method | cells | transparent | off-screen | frames re-used | drawn | frame ms culled | unculled | speed-up | MB/frame culled / unculled | primitives in | fragments | RMSE culled vs unculled | image |\n\
         |---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---|---|---:|---|\n",
    );
    for c in &s.cull_checks {
        let (Some(on), Some(off)) = (find(c, true).and_then(|r| r.result.as_ref()), find(c, false).and_then(|r| r.result.as_ref())) else { continue };
        let (f_on, f_off) = (on.time_ms.phase("frame").median, off.time_ms.phase("frame").median);
        let reused = on.frame_counts.get("cull.reused").map_or(0, |x| x.total);
        let stats = |x: &RunResult| x.stats.map_or(("-".to_string(), "-".to_string()), |st| (st.input_primitives.to_string(), st.fragment_invocations.to_string()));
        let ((p_on, fr_on), (p_off, fr_off)) = (stats(on), stats(off));
        let _ = writeln!(
            t,
            "| {} | {} | {} | {} | {:.0} | {:.0} | {}/{} | {:.0} | {:.1} | {:.1} | **{:.2}** | {:.2} / {:.2} | {p_on} / {p_off} | {fr_on} / {fr_off} | {:.2e} | {} |",
            c.dataset,
            c.scene.name(),
            c.method,
            on.work.counts.get("cells").copied().unwrap_or(0),
            per_frame(on, "cull.transparent"),
            per_frame(on, "cull.frustum"),
            reused,
            on.frames,
            per_frame(on, "cells_drawn"),
            f_on,
            f_off,
            if f_on > 0.0 { f_off / f_on } else { 0.0 },
            on.upload.bytes_per_frame as f64 / 1e6,
            off.upload.bytes_per_frame as f64 / 1e6,
            c.rmse,
            if c.rmse <= 1e-6 { "unchanged" } else { "**CHANGED**" },
        );
    }
    t
}

/// Every published figure set beside its measured counterpart, as ratios
/// inside this run: two frame rates from one source on one dataset (methods
/// or option sets) against the same two measured; a "defaults up to N×
/// faster" claim against the measured speed-up on each dataset.
fn published_ratios(s: &Summary, registry: &Registry) -> String {
    use crate::algo::method::PublishedFigure;
    // The measured median frame time of a published figure's run.
    let measured = |p: &crate::algo::method::Published, dataset: &str| -> Option<(f64, String)> {
        let spec = registry.published_spec(p).ok()?;
        let canonical = spec.canonical();
        let r = s.runs.iter().filter_map(|r| r.result.as_ref()).find(|r| r.mesh == dataset && r.spec == canonical)?;
        Some((r.time_ms.phase("frame").median, spec.label()))
    };
    let default_time = |method: &str, dataset: &str| -> Option<f64> {
        let spec = registry.parse_spec(method, &[]).ok()?.canonical();
        s.runs.iter().filter_map(|r| r.result.as_ref()).find(|r| r.mesh == dataset && r.spec == spec).map(|r| r.time_ms.phase("frame").median)
    };
    let published = registry.published();
    let mut rows = String::new();
    for (i, p) in published.iter().enumerate() {
        for q in &published[i + 1..] {
            let (Some(d), Some(fp), Some(fq)) = (p.dataset, p.fps(), q.fps()) else { continue };
            if q.source != p.source || q.dataset != p.dataset {
                continue;
            }
            let (Some((tp, lp)), Some((tq, lq))) = (measured(p, d), measured(q, d)) else { continue };
            if tp <= 0.0 || tq <= 0.0 {
                continue;
            }
            let (m, pubr) = (tp / tq, fq / fp);
            let verdict = if (m / pubr - 1.0).abs() <= 0.25 { "agrees (within 25 %)" } else if m > pubr { "larger here" } else { "smaller here" };
            let _ = writeln!(rows, "| {d} | {lq} ÷ {lp} | {m:.2} | {pubr:.2} | {verdict} | {} |", p.source);
        }
    }
    for p in &published {
        let PublishedFigure::DefaultsFasterUpTo(bound) = p.figure else { continue };
        let Ok(off) = registry.published_spec(p) else { continue };
        let (off_spec, l_off) = (off.canonical(), off.label());
        // Every run of the figure's option set, on each dataset it speaks about.
        for r in s.runs.iter().filter_map(|r| r.result.as_ref()).filter(|r| r.spec == off_spec && p.applies_to(&r.mesh)) {
            let t_off = r.time_ms.phase("frame").median;
            let Some(t_def) = default_time(p.method, &r.mesh).filter(|&t| t > 0.0) else { continue };
            let m = t_off / t_def;
            let verdict = if m <= bound * 1.1 { "within the claim" } else { "beyond the claim" };
            let _ = writeln!(rows, "| {} | {} ÷ {l_off} | {m:.2} | up to {bound:.1} | {verdict} | {} |", r.mesh, p.method, p.source);
        }
    }
    // Cells drawn per frame (a method drawing cells more than once): the
    // growth over the mesh's cell count, measured from the run's work counts.
    for p in &published {
        let PublishedFigure::CellsRendered { rendered, cells } = p.figure else { continue };
        let Ok(spec) = registry.published_spec(p) else { continue };
        let canonical = spec.canonical();
        for r in s.runs.iter().filter_map(|r| r.result.as_ref()).filter(|r| r.spec == canonical && p.applies_to(&r.mesh)) {
            let (Some(&drawn), Some(&n)) = (r.work.counts.get("pieces"), r.work.counts.get("cells")) else { continue };
            if n == 0 || cells == 0 {
                continue;
            }
            let (m, pubr) = (drawn as f64 / n as f64, rendered as f64 / cells as f64);
            let verdict = if (m / pubr - 1.0).abs() <= 0.25 { "agrees (within 25 %)" } else if m > pubr { "larger here" } else { "smaller here" };
            let _ = writeln!(
                rows,
                "| {} | {} cells drawn ÷ cells ({drawn} for {n}; published {rendered} for {cells}) | {m:.2} | {pubr:.2} | {verdict} | {} |",
                r.mesh,
                spec.label(),
                p.source
            );
        }
    }
    if rows.is_empty() {
        return String::new();
    }
    let mut notes = String::new();
    let mut seen = Vec::new();
    for p in &published {
        if rows.contains(p.source) && !seen.contains(&p.source) {
            seen.push(p.source);
            let _ = writeln!(notes, "- {}: {}", p.source, p.note);
        }
    }
    rows += "\nWhy a ratio here differs from the paper's:\n\n";
    rows += &notes;
    format!(
        "\n## Measured against published, as speed ratios inside this run\n\n\
         Absolute times from the papers' hardware are not comparable with this machine; ratios between \
         runs on one dataset are. A ratio a ÷ b is how many times faster a ran than b (frame rate of a over \
         frame rate of b; published: the paper's two frame rates); \"cells drawn ÷ cells\" is how many times a \
         method draws the mesh's cell count per frame (counts, not speeds).\n\n\
         | dataset | ratio | measured | published | | source |\n|---|---|---:|---:|---|---|\n{rows}"
    )
}

/// The peers' section of the report: each peer renderer's frame time and
/// error against the same f64 reference, and each volbench run's speed
/// ratio to it (measured in this run, alternating, so the ratio is
/// comparable where absolute times across machines are not).
pub fn peer_report(s: &Summary) -> String {
    if s.peers.is_empty() {
        return String::new();
    }
    let mut t = String::from(
        "\n## Peers measured in the same run\n\nOther programs' renderers given the same data, camera path, transfer function and image size, \
         run alternating with volbench's runs. A peer frame is its Render() plus glFinish (VTK: WaitForCompletion); \
         its image is compared with the same f64 reference (RGBA, 8-bit framebuffer). \
         The transfer function is encoded for each renderer's opacity model (`attenuation`: exact; `correction`: resampled, see `harness::peers`).\n\n\
         | dataset | peer | renderer (class) | status | frame ms median [min, max] | RMSE vs f64 | max err | opacity model |\n|---|---|---|---|---|---:|---:|---|\n",
    );
    for p in &s.peers {
        match (&p.frame_ms, &p.error) {
            (Some(f), Some(e)) => {
                let _ = writeln!(
                    t,
                    "| {} | {} {} | {} (`{}`) | ok | {:.1} [{:.1}, {:.1}] | {:.2e} | {:.2e} | {} |",
                    p.dataset,
                    p.peer,
                    p.library_version.as_deref().unwrap_or(""),
                    p.renderer,
                    p.class,
                    f.median,
                    f.min,
                    f.max,
                    e.rmse,
                    e.max_abs,
                    p.opacity_model.as_deref().unwrap_or("")
                );
            }
            _ => {
                let _ = writeln!(
                    t,
                    "| {} | {} | {} (`{}`) | {}: {} |||||",
                    p.dataset,
                    p.peer,
                    p.renderer,
                    p.class,
                    p.status,
                    p.message.as_deref().unwrap_or("").replace('|', "/")
                );
            }
        }
    }
    let mut ratios = String::new();
    // Peers render the standard scene only: a culling scene (another
    // transfer function or camera) is no like-for-like comparison.
    for r in s.runs.iter().filter(|r| r.scene == Scene::Standard) {
        let Some(x) = &r.result else { continue };
        let ours = x.time_ms.phase("frame").median;
        for p in s.peers.iter().filter(|p| p.dataset == r.dataset) {
            let (Some(f), Some(e)) = (&p.frame_ms, &p.error) else { continue };
            if ours > 0.0 {
                let _ = writeln!(
                    ratios,
                    "| {} | {} | {}/{} | {:.1} | {:.1} | **{:.2}** | {} | {:.2e} |",
                    r.dataset,
                    r.label,
                    p.peer,
                    p.renderer,
                    ours,
                    f.median,
                    f.median / ours,
                    x.error.as_ref().map_or("-".into(), |e| format!("{:.2e}", e.rmse)),
                    e.rmse
                );
            }
        }
    }
    if !ratios.is_empty() {
        t += "\nSpeed ratio = peer's median frame time / volbench's (above 1: volbench is faster), same run, same machine.\n\n\
              | dataset | volbench method | peer | volbench ms | peer ms | speed ratio | volbench RMSE | peer RMSE |\n|---|---|---|---:|---:|---:|---:|---:|\n";
        t += &ratios;
    }
    t += &matched_error(s);
    t += &agreement_report(s);
    t
}

/// Each peer's image against volbench's of the same view: the RMSE to each
/// volbench run's reference-view image (all of them in `summary.json`
/// `peers[].vs_volbench`; here the closest and the farthest), beside the
/// peer's and that run's own RMSE against the f64 reference. On a user's
/// file the peer read the original with its own reader, so a reading
/// mistake on either side shows here as images far apart (and a peer
/// error far above its level on data it reads from volbench's export).
fn agreement_report(s: &Summary) -> String {
    let mut rows = String::new();
    for p in &s.peers {
        let Some(pe) = &p.error else { continue };
        let own = |label: &str| {
            s.runs
                .iter()
                .find(|r| r.dataset == p.dataset && r.scene == Scene::Standard && r.label == label)
                .and_then(|r| r.result.as_ref()?.error.as_ref().map(|e| format!("{:.2e}", e.rmse)))
                .unwrap_or_else(|| "-".into())
        };
        let closest = p.vs_volbench.iter().min_by(|a, b| a.rmse.total_cmp(&b.rmse));
        let farthest = p.vs_volbench.iter().max_by(|a, b| a.rmse.total_cmp(&b.rmse));
        let (Some(c), Some(f)) = (closest, farthest) else { continue };
        let input = match p.input.as_deref() {
            Some("export") | None => "volbench's export".to_string(),
            Some(format) => format!("original file ({format})"),
        };
        let _ = writeln!(
            rows,
            "| {} | {}/{} | {input} | {:.2e} | {} | {:.2e} | {} | {} | {:.2e} | {} |",
            p.dataset,
            p.peer,
            p.renderer,
            pe.rmse,
            c.label,
            c.rmse,
            own(&c.label),
            f.label,
            f.rmse,
            own(&f.label),
        );
    }
    if rows.is_empty() {
        return rows;
    }
    format!(
        "\nThe peer's image against volbench's of the same view (the reference view): RMSE between the two images, for the \
         volbench run closest to the peer's image and the farthest (every run in `summary.json`, `peers[].vs_volbench`), \
         beside each one's RMSE against the f64 reference (of volbench's reading). On a user's file the peer read the \
         original file with its own reader, so a reading mistake on either side shows here as images far apart and a \
         peer error far above its level on the shipped datasets (which it reads from volbench's export).\n\n\
         | dataset | peer | peer read | peer RMSE vs f64 | closest volbench run | RMSE peer vs it | its RMSE vs f64 | farthest volbench run | RMSE peer vs it | its RMSE vs f64 |\n\
         |---|---|---|---:|---|---:|---:|---|---:|---:|\n{rows}"
    )
}

/// Speed at matched error: per peer renderer, the fastest volbench run on
/// the same dataset whose image error is no larger than the peer's
/// (`Summary::matched_run`) and its ratio in the first pass; then, the
/// headline, the alternating rounds (`suite::rounds`): the better of the
/// two fastest runs, its rounds' median ratio and spread.
fn matched_error(s: &Summary) -> String {
    let mut rows = String::new();
    for p in &s.peers {
        let (Some(f), Some(pe)) = (&p.frame_ms, &p.error) else { continue };
        let fastest = s.matched_run(p);
        let (label, ms, rmse) = match fastest {
            Some((r, ms, rmse)) => (r.label.as_str(), format!("{ms:.1}"), format!("{rmse:.2e}")),
            None => ("none as accurate", "-".into(), "-".into()),
        };
        let first = fastest.map_or("-".into(), |(_, ms, _)| format!("{:.2}", f.median / ms));
        let rounds = s.matched.iter().find(|m| m.dataset == p.dataset && m.peer == p.peer && m.renderer == p.renderer);
        let spread = |r: &crate::harness::stats::Summary| format!("{:.2} [{:.2}, {:.2}]", r.median, r.min, r.max);
        let (mut quoted, mut alternating, mut other) = ("-".to_string(), "-".to_string(), "-".to_string());
        if let Some(m) = rounds {
            if let Some((l, r)) = m.quoted() {
                (quoted, alternating) = (l.to_string(), format!("**{:.2}** [{:.2}, {:.2}] ({})", r.median, r.min, r.max, m.rounds.len()));
            }
            if let Some((l, r)) = m.other() {
                other = format!("{l}: {}", spread(r));
            }
            if let Some(why) = &m.message {
                let failed = format!("failed: {}", why.replace('|', "/"));
                alternating = if m.rounds.is_empty() { failed } else { format!("{alternating}; {failed}") };
            }
        }
        let _ = writeln!(
            rows,
            "| {} | {}/{} | {:.1} | {:.2e} | {label} | {ms} | {rmse} | {first} | {quoted} | {alternating} | {other} |",
            p.dataset, p.peer, p.renderer, f.median, pe.rmse
        );
    }
    if rows.is_empty() {
        return rows;
    }
    let n = s.settings.rounds;
    let rounds = if n == 0 {
        "No rounds were run (`--rounds 0`).".to_string()
    } else {
        format!(
            "Then the ratio to quote: after the dataset's runs, the peer ran again with the two fastest such runs (or the one) \
             in {n} rounds, the peer between the two and the order reversed every other round, so that a slow phase of the \
             machine meets every side; each run's rounds' median [min, max] (rounds completed), the higher median quoted and \
             the other run's beside it (the higher of two medians leans high when the two are close). All rounds' times: \
             `summary.json`, `matched`."
        )
    };
    format!(
        "\nAt matched error: the fastest volbench run of this suite on the dataset whose RMSE against the f64 reference is \
         no larger than the peer's, and the speed ratio (peer ms / volbench ms) in the first pass (the times before it). \
         {rounds}\n\n\
         | dataset | peer | peer ms | peer RMSE | fastest volbench run at most as far from the reference | volbench ms | volbench RMSE | first pass | run quoted from the rounds | alternating rounds | the other run |\n\
         |---|---|---:|---:|---|---:|---:|---:|---|---:|---|\n{rows}"
    )
}

/// The suite's pictures, per dataset: `montage-<group>.png` (the reference,
/// then each run beside its ×10 difference), and in `plots/` the frame time
/// with its min–max spread (`frame_time-<dataset>`, peers in their own
/// colour), the bytes per frame (`bytes_per_frame-<dataset>`) and the frame
/// time against the error with the Pareto front (`time_error-<dataset>.png`,
/// standard scene, peers included).
pub(super) fn figures(out: &Path, s: &Summary, images: &[(String, String, Tile)], references: &[(String, RgbaImage)]) -> Result<()> {
    use crate::harness::run::ErrorKind;
    let mut groups: Vec<&str> = Vec::new();
    for (g, _, _) in images {
        if !groups.contains(&g.as_str()) {
            groups.push(g);
        }
    }
    for g in groups {
        let tiles: Vec<Tile> = images.iter().filter(|(x, _, _)| x == g).map(|(_, _, t)| t.clone()).collect();
        let reference = references.iter().find(|(x, _)| x == g).map(|(_, r)| r);
        crate::harness::plots::montage(&out.join(format!("montage-{g}.png")), g, reference, &tiles)?;
    }
    let plots = out.join("plots");
    let device = &s.environment.device.name;
    let mut datasets: Vec<&str> = Vec::new();
    for d in s.runs.iter().map(|r| r.dataset.as_str()).chain(s.peers.iter().map(|p| p.dataset.as_str())) {
        if !datasets.contains(&d) {
            datasets.push(d);
        }
    }
    for d in datasets {
        let ok = || s.runs.iter().filter(move |r| r.dataset == d).filter_map(|r| Some((r, r.result.as_ref()?)));
        let peers = || s.peers.iter().filter(move |p| p.dataset == d).filter_map(|p| Some((p, p.frame_ms.as_ref()?)));
        let times: Vec<Bar> = ok()
            .map(|(r, x)| {
                let f = x.time_ms.phase("frame");
                Bar { label: r.label.clone(), median: f.median, spread: Some((f.min, f.max)), peer: false }
            })
            .chain(peers().map(|(p, f)| Bar { label: format!("peer {}/{}", p.peer, p.renderer), median: f.median, spread: Some((f.min, f.max)), peer: true }))
            .collect();
        let size = format!("{}x{}", s.settings.width, s.settings.height);
        let title = format!("{d}: frame time (ms), median and min–max of {} frames, {size}, {device}", s.settings.frames);
        crate::harness::plots::bar_chart(&plots, &format!("frame_time-{d}"), &title, &times)?;
        let bytes: Vec<Bar> =
            ok().map(|(r, x)| Bar { label: r.label.clone(), median: x.upload.bytes_per_frame as f64 / 1e6, spread: None, peer: false }).collect();
        crate::harness::plots::bar_chart(&plots, &format!("bytes_per_frame-{d}"), &format!("{d}: bytes crossing to the device per frame (MB)"), &bytes)?;
        // Standard scene only: the culling scenes have other views and references.
        let mut points: Vec<ScatterPoint> = ok()
            .filter(|(r, _)| r.scene == Scene::Standard)
            .filter_map(|(r, x)| {
                let e = x.error.as_ref()?;
                Some(ScatterPoint {
                    label: r.label.clone(),
                    series: r.method.clone(),
                    marker: if e.compared == ErrorKind::Image { Marker::Filled } else { Marker::Ring },
                    time_ms: x.time_ms.phase("frame").median,
                    error: e.rmse,
                    on_front: false,
                })
            })
            .chain(peers().filter_map(|(p, f)| {
                Some(ScatterPoint {
                    label: format!("peer {}/{}", p.peer, p.renderer),
                    series: format!("peer {}/{}", p.peer, p.renderer),
                    marker: Marker::Triangle,
                    time_ms: f.median,
                    error: p.error.as_ref()?.rmse,
                    on_front: false,
                })
            }))
            .collect();
        if points.is_empty() {
            continue;
        }
        crate::harness::plots::mark_front(&mut points, |p| Some((p.time_ms, p.error)), |p, on| p.on_front = on);
        // A method with its own error (terrain) says what it measures.
        let own = ok().find_map(|(_, x)| x.error.as_ref().filter(|e| e.compared == ErrorKind::Own));
        let y_desc = if own.is_some() { "RMSE (the method's own measure, see report)" } else { "RMSE against the f64 reference image" };
        let note = "filled: volbench run\nring: own error measure\ntriangle: peer (same run)";
        crate::harness::plots::time_error_scatter(&plots.join(format!("time_error-{d}.png")), &format!("{d}: frame time against error, {size}"), y_desc, note, &points)?;
    }
    Ok(())
}
