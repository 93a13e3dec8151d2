//! Running the plan: each row's run (or why it failed or was skipped), its
//! image and difference written as it completes, the peers alternating with
//! volbench's runs, the culling scenes' unchanged-image checks, and at the
//! end the summary, the report and the pictures.

use std::path::Path;
use std::sync::Arc;

use anyhow::{Context as _, Result};

use super::plan::{PlannedRun, Scene, SuiteDataset, SuiteSettings};
use super::report::{figures, report};
use super::rounds::{run_rounds, RoundsJob};
use super::summary::{csv, CullCheck, Environment, SuiteDatasetRow, SuiteRow, Summary};
use crate::algo::registry::{MethodSpec, Registry};
use crate::fsio;
use crate::harness::datasets::Dataset;
use crate::harness::image::RgbaImage;
use crate::harness::peers::{ImageAgreement, LocatedPeer, PeerRenderer, PeerRow};
use crate::harness::plots::Tile;
use crate::harness::reference_cache::reference_image;
use crate::harness::run::{run, RunConfig, RunOutput};
use crate::harness::sweep::skip_reason;
use crate::vk::Context;

/// `spec` with its culling option on.
fn cull_on(registry: &Registry, spec: &MethodSpec) -> Result<MethodSpec> {
    let option = spec.info.culling_option().unwrap_or_default();
    registry.parse_spec(&format!("{}:{option}=on", spec.info.name), &[])
}

/// Whether a run of `info` with `options` culls (`None`: the method has no
/// culling option).
fn culling(info: &crate::algo::method::MethodInfo, options: &crate::algo::method::Options) -> Option<bool> {
    info.culling_option().and_then(|o| options.flag(o).ok())
}

/// Run the plan; each row's JSON, PNG and difference PNG go to
/// `out/runs/` as it completes, and `summary.json` is rewritten after each.
pub fn run_suite(
    ctx: &Arc<Context>,
    registry: &Registry,
    plan: &[PlannedRun],
    settings: &SuiteSettings,
    out: &Path,
    mut progress: impl FnMut(usize, &str),
) -> Result<Summary> {
    let cfg = settings.run_config();
    cfg.check_device(&ctx.info)?;
    let runs_dir = out.join("runs");
    create_dir(&runs_dir)?;
    let summary =
        Summary { environment: Environment::of(ctx), settings: settings.clone(), datasets: Vec::new(), runs: Vec::new(), peers: Vec::new(), cull_checks: Vec::new(), matched: Vec::new() };
    let mut g = Gathered { summary, images: Vec::new(), references: Vec::new(), sequence: 0 };
    let located: Vec<LocatedPeer> = settings.peers.iter().map(|p| crate::harness::peers::locate(p)).collect::<Result<_>>()?;
    let peers_dir = out.join("peers");
    if !located.is_empty() {
        create_dir(&peers_dir)?;
    }
    let mut loaded: Option<(&str, std::result::Result<Dataset, String>)> = None;
    // The current dataset's standard transfer function (`--tf`, or its own).
    let mut standard_tf: Option<crate::scene::TransferFunction> = None;
    // Peer renderers still to run on the current dataset, and its exported copy.
    let mut pending: Vec<(&LocatedPeer, &'static PeerRenderer)> = Vec::new();
    let mut export: Option<(std::path::PathBuf, crate::harness::peers::PeerDataset)> = None;
    for (i, p) in plan.iter().enumerate() {
        let label = format!("{} on {}", p.label(), p.dataset.name);
        progress(i, &label);
        let first_of_dataset = i == 0 || plan[i - 1].dataset != p.dataset;
        let last_of_dataset = plan.get(i + 1).is_none_or(|n| n.dataset != p.dataset);
        if loaded.as_ref().is_none_or(|(n, _)| *n != p.dataset.name) {
            // Rows, results and files name it as the suite does.
            loaded = Some((&p.dataset.name, p.dataset.load(settings.cell_data).map_err(|e| format!("{e:#}"))));
            standard_tf = None;
        }
        let Some((_, loaded_dataset)) = &mut loaded else { continue };
        // A dataset that cannot be loaded fails its rows; the suite goes on.
        let dataset = match loaded_dataset {
            Ok(d) => d,
            Err(why) => {
                pending.clear();
                let row = g.row(p, "failed", Some(format!("loading {}: {why}", p.dataset.source)));
                g.summary.runs.push(row);
                g.write_summary(out)?;
                continue;
            }
        };
        if first_of_dataset {
            // Popped from the end: reversed so they run in their listed order.
            pending = located.iter().flat_map(|l| l.renderers_for(dataset.kind()).map(move |r| (l, r))).collect();
            pending.reverse();
            standard_tf = dataset_row(&mut g.summary, p, dataset, settings);
        }
        let row = run_row(&RowJob { ctx, registry, p, settings, cfg: &cfg, runs_dir: &runs_dir }, dataset, label, &mut g)?;
        g.summary.runs.push(row);
        // Peers alternate with volbench's runs on the same dataset (one after
        // each run; the rest after the dataset's last run), so that machine
        // noise hits both.
        let take = if last_of_dataset { pending.len() } else { pending.len().min(1) };
        for _ in 0..take {
            let Some((peer, renderer)) = pending.pop() else { break };
            let label = format!("peer {}/{} on {}", peer.peer.name, renderer.name, p.dataset.name);
            progress(i, &label);
            let job = PeerJob { peer, renderer, dataset, suite_dataset: &p.dataset, tf: standard_tf.as_ref(), cfg: &cfg, peers_dir: &peers_dir, runs_dir: &runs_dir };
            g.peer(&job, &mut export, label);
        }
        if last_of_dataset {
            let job = RoundsJob {
                ctx,
                plan,
                cfg: &cfg,
                rounds: settings.rounds,
                peers_dir: &peers_dir,
                located: &located,
                tf: standard_tf.as_ref(),
                exported: export.as_ref().map(|(_, d)| d),
            };
            run_rounds(&job, dataset, &p.dataset.name, &mut g.summary, &mut |label| progress(i, label));
            remove_export(&mut export);
        }
        g.write_summary(out)?;
    }
    finish(out, registry, g)
}

/// What the suite has gathered so far: the summary, every image shown (by
/// montage group, with the run's label), the reference image of each
/// group, and the next row's sequence number.
struct Gathered {
    summary: Summary,
    images: Vec<(String, String, Tile)>,
    references: Vec<(String, RgbaImage)>,
    sequence: usize,
}

impl Gathered {
    /// A new row of volbench's for the run `p`, numbered next.
    fn row(&mut self, p: &PlannedRun, status: &'static str, message: Option<String>) -> SuiteRow {
        let row = SuiteRow {
            dataset: p.dataset.name.clone(),
            method: p.spec.info.name.into(),
            label: p.label(),
            scene: p.scene,
            status,
            message,
            sequence: self.sequence,
            result: None,
            placement: p.spec.info.family.placement,
        };
        self.sequence += 1;
        row
    }

    /// Runs a peer's job, numbered next: its row, and its image shown.
    fn peer(&mut self, job: &PeerJob, export: &mut Option<(std::path::PathBuf, crate::harness::peers::PeerDataset)>, label: String) {
        let (row, shown) = run_peer_row(job, export, self.sequence);
        self.sequence += 1;
        if let Some((image, diff)) = shown {
            let tile = Tile { label: format!("peer {}/{}", job.peer.peer.name, job.renderer.name), image, diff: Some(diff) };
            self.images.push((job.suite_dataset.name.clone(), label, tile));
        }
        self.summary.peers.push(row);
    }

    /// Rewrites `out/summary.json`.
    fn write_summary(&self, out: &Path) -> Result<()> {
        fsio::write_output(&out.join("summary.json"), &crate::harness::report::json_bytes(&self.summary)?)
    }
}

fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))
}

/// The dataset's row of the summary; its standard transfer function.
fn dataset_row(summary: &mut Summary, p: &PlannedRun, dataset: &Dataset, settings: &SuiteSettings) -> Option<crate::scene::TransferFunction> {
    let tf = Scene::Standard.transfer_function(dataset, settings.tf.as_deref());
    summary.datasets.push(SuiteDatasetRow::of(&p.dataset, dataset, tf.as_ref().ok(), settings.tf.as_deref()));
    tf.ok()
}

/// What a row of volbench's runs with: the run `p` and where it writes.
struct RowJob<'a> {
    ctx: &'a Arc<Context>,
    registry: &'a Registry,
    p: &'a PlannedRun,
    settings: &'a SuiteSettings,
    cfg: &'a RunConfig,
    runs_dir: &'a Path,
}

/// The row of the run `job.p` (labelled `label`) on `dataset`: skipped on
/// this device, failed, or run (its image shown, a culling scene's pair
/// checked).
fn run_row(job: &RowJob, dataset: &mut Dataset, label: String, g: &mut Gathered) -> Result<SuiteRow> {
    let p = job.p;
    let mut row = g.row(p, "ok", None);
    if let Some(why) = skip_reason(&p.spec, &job.ctx.info) {
        (row.status, row.message) = ("skipped", Some(why));
        return Ok(row);
    }
    let group = p.montage_group();
    match run_and_write(job, dataset, &group, &mut g.references) {
        Ok((r, diff)) => {
            check_culling(job.registry, p, &r.image, &g.images, &mut g.summary)?;
            g.images.push((group, label, Tile { label: p.label(), image: r.image, diff }));
            row.result = Some(r.result);
        }
        Err(e) => (row.status, row.message) = ("failed", Some(format!("{e:#}"))),
    }
    Ok(row)
}

/// Runs `job.p` on `dataset`, compares it with the reference image (kept
/// as `group`'s if it is the first) and writes its JSON, PNG and
/// difference PNG; the run and its difference image.
fn run_and_write(job: &RowJob, dataset: &mut Dataset, group: &str, references: &mut Vec<(String, RgbaImage)>) -> Result<(RunOutput, Option<RgbaImage>)> {
    let (p, settings, runs_dir) = (job.p, job.settings, job.runs_dir);
    let tf = p.scene.transfer_function(dataset, settings.tf.as_deref())?;
    let cfg = p.scene.config(job.cfg);
    let mut r = dataset.run_handing_over(|d| run(job.ctx, &p.spec, d, &tf, &cfg))??;
    let stem = format!("{}-{}", p.dataset.name, p.file_stem());
    let (json, png, dpng) = (runs_dir.join(format!("{stem}.json")), runs_dir.join(format!("{stem}.png")), runs_dir.join(format!("{stem}-diff.png")));
    // A method with its own error (terrain) has no image reference.
    let diff = if r.result.error.is_none() && settings.count_dir.is_none() {
        let reference = reference_image(dataset, &tf, &r.result.image.camera, cfg.width, cfg.height)?;
        if !references.iter().any(|(g, _)| *g == group) {
            references.push((group.to_string(), reference.image.clone()));
        }
        Some(r.attach_error(&reference)?)
    } else {
        None
    };
    let bytes = [crate::harness::report::json_bytes(&r.result)?, r.image.png_bytes()?];
    match &diff {
        Some(d) => fsio::write_all(&[(&json, &bytes[0]), (&png, &bytes[1]), (&dpng, &d.png_bytes()?)])?,
        None => fsio::write_all(&[(&json, &bytes[0]), (&png, &bytes[1])])?,
    }
    Ok((r, diff))
}

/// A culling scene's pair: the culled image against the unculled one
/// `image` (the unchanged-image check), once both have run.
fn check_culling(registry: &Registry, p: &PlannedRun, image: &RgbaImage, images: &[(String, String, Tile)], summary: &mut Summary) -> Result<()> {
    if p.scene == Scene::Standard || culling(&p.spec.info, &p.spec.options) != Some(false) {
        return Ok(());
    }
    let on = PlannedRun { dataset: p.dataset.clone(), spec: cull_on(registry, &p.spec)?, scene: p.scene };
    let on_label = format!("{} on {}", on.label(), p.dataset.name);
    if let Some((_, _, on)) = images.iter().find(|(_, l, _)| *l == on_label) {
        let e = on.image.compare(image)?;
        summary.cull_checks.push(CullCheck {
            dataset: p.dataset.name.clone(),
            scene: p.scene,
            method: p.spec.info.name.into(),
            option: p.spec.info.culling_option().unwrap_or_default(),
            rmse: e.rmse,
            max_abs: e.max_abs,
        });
    }
    Ok(())
}

/// The exported copy is only the peers' input: not a result (a user's
/// original file is never removed).
fn remove_export(export: &mut Option<(std::path::PathBuf, crate::harness::peers::PeerDataset)>) {
    if let Some((path, d)) = export.take() {
        if !d.original {
            let _ = std::fs::remove_file(path);
        }
    }
}

/// The end of the suite: the peers' agreement, and the summary, the CSV,
/// the report and the pictures written.
fn finish(out: &Path, registry: &Registry, g: Gathered) -> Result<Summary> {
    let Gathered { mut summary, images, references, .. } = g;
    agreement(&mut summary, &images);
    fsio::write_output(&out.join("summary.json"), &crate::harness::report::json_bytes(&summary)?)?;
    fsio::write_output(&out.join("summary.csv"), csv(&summary).as_bytes())?;
    fsio::write_output(&out.join("report.md"), report(&summary, registry).as_bytes())?;
    figures(out, &summary, &images, &references)?;
    Ok(summary)
}

/// Each peer image against every volbench image of the same view on the
/// same dataset (the standard scene's montage group; peers render only
/// that scene): `PeerRow::vs_volbench`.
fn agreement(summary: &mut Summary, images: &[(String, String, Tile)]) {
    for row in summary.peers.iter_mut().filter(|r| r.status == "ok") {
        let peer_label = format!("peer {}/{} on {}", row.peer, row.renderer, row.dataset);
        let Some((_, _, peer)) = images.iter().find(|(g, l, _)| *g == row.dataset && *l == peer_label) else { continue };
        row.vs_volbench = images
            .iter()
            .filter(|(g, l, _)| *g == row.dataset && !l.starts_with("peer "))
            .filter_map(|(_, _, t)| {
                let e = peer.image.compare(&t.image).ok()?;
                Some(ImageAgreement { label: t.label.clone(), rmse: e.rmse, max_abs: e.max_abs })
            })
            .collect();
    }
}

/// What one peer row needs: the renderer, the loaded dataset and how the
/// suite knows it, the standard scene's transfer function, where files go.
struct PeerJob<'a> {
    peer: &'a LocatedPeer,
    renderer: &'static PeerRenderer,
    dataset: &'a Dataset,
    suite_dataset: &'a SuiteDataset,
    /// `None`: it could not be made (the volbench rows say why).
    tf: Option<&'a crate::scene::TransferFunction>,
    cfg: &'a RunConfig,
    peers_dir: &'a Path,
    runs_dir: &'a Path,
}

/// One peer renderer on one dataset: a shipped dataset exported once per
/// dataset (`export`), a user's file named as it is (the peer reads the
/// original with its own reader); the scene written, the peer run, its
/// image compared with the same f64 reference as volbench's runs. A failure
/// is the row's status.
fn run_peer_row(job: &PeerJob, export: &mut Option<(std::path::PathBuf, crate::harness::peers::PeerDataset)>, sequence: usize) -> (PeerRow, Option<(RgbaImage, RgbaImage)>) {
    use crate::harness::peers as pe;
    let PeerJob { peer, renderer, dataset, suite_dataset, tf, cfg, peers_dir, runs_dir } = *job;
    let mut row = PeerRow {
        peer: peer.peer.name.into(),
        renderer: renderer.name.into(),
        class: renderer.class.into(),
        dataset: suite_dataset.name.clone(),
        status: "ok",
        message: None,
        sequence,
        library_version: None,
        gl_renderer: None,
        opacity_model: None,
        frame_ms: None,
        frame_samples_ms: Vec::new(),
        setup_ms: None,
        error: None,
        covered_pixels: None,
        input: None,
        vs_volbench: Vec::new(),
    };
    let outcome = (|| -> Result<(pe::PeerResult, RgbaImage, RgbaImage, crate::harness::image::ImageError, String)> {
        if export.is_none() {
            *export = Some(if suite_dataset.user {
                let d = pe::original_dataset(dataset, &suite_dataset.name, &suite_dataset.source)?;
                (std::path::PathBuf::from(&d.file), d)
            } else {
                let path = peers_dir.join(format!("{}.vtk", dataset.name));
                let d = pe::write_dataset(dataset, &path).with_context(|| format!("exporting '{}' for the peers", dataset.name))?;
                (path, d)
            });
        }
        let Some((_, exported)) = export.as_ref() else { anyhow::bail!("internal: dataset not exported") };
        row.input = Some(if exported.original { exported.format.clone() } else { "export".into() });
        let tf = tf.context("the dataset's transfer function could not be made (see its runs)")?;
        let scene = pe::scene(peer.peer, renderer, dataset, tf, cfg, exported, peers_dir)?;
        let stem = scene.stem();
        let reference_camera = scene.reference_camera;
        let (result, image) = pe::run_peer(peer, &scene, &peers_dir.join(format!("{stem}.scene.json")))?;
        let reference = reference_image(dataset, tf, &reference_camera, cfg.width, cfg.height)?;
        // A blank picture is a failure, not a result (docs/bad-input.md).
        let expected = reference.image.covered_pixels();
        anyhow::ensure!(
            image.covered_pixels() > 0 || expected == 0,
            "peer {}/{} returned an empty image although the f64 reference covers {expected} pixels",
            peer.peer.name,
            renderer.name
        );
        let error = image.compare(&reference.image)?;
        let diff = image.difference(&reference.image);
        let (png, dpng) = (runs_dir.join(format!("{stem}.png")), runs_dir.join(format!("{stem}-diff.png")));
        let bytes = [image.png_bytes()?, diff.png_bytes()?];
        fsio::write_all(&[(&png, &bytes[0]), (&dpng, &bytes[1])])?;
        // The raw image was only the transport; the PNG is the record.
        let _ = std::fs::remove_file(&scene.output.image);
        Ok((result, image, diff, error, scene.transfer_function.opacity_model))
    })();
    match outcome {
        Ok((result, image, diff, error, model)) => {
            row.library_version = Some(result.library_version);
            row.gl_renderer = Some(result.gl_renderer);
            row.opacity_model = Some(model);
            row.frame_ms = Some(crate::harness::stats::Summary::of(&result.frame_ms));
            row.frame_samples_ms = result.frame_ms;
            row.setup_ms = Some(result.load_ms + result.setup_ms);
            row.error = Some(error);
            row.covered_pixels = Some(image.covered_pixels());
            (row, Some((image, diff)))
        }
        Err(e) => {
            (row.status, row.message) = ("failed", Some(format!("{e:#}")));
            (row, None)
        }
    }
}
