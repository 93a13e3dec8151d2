//! The volbench command line: `info`, `run` (one method on one mesh) and
//! `compare` (VICP against balanced cell projection on several meshes).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context as _, Result};
use clap::{Args, Parser, Subcommand, ValueEnum};

use volbench::algo::cell_projection::sort::SortKind;
use volbench::algo::cell_projection::{Interpolation, Method};
use volbench::algo::integrate::Integrator;
use volbench::harness::report::{self, ComparisonRow};
use volbench::harness::reference_cache::reference_image;
use volbench::harness::run::{run_cell_projection, RunConfig, Scene};
use volbench::harness::datasets;
use volbench::mesh::TetGeometry;
use volbench::scene::Projection;
use volbench::vk::{Context, ContextDesc};

#[derive(Parser)]
#[command(name = "volbench", version, about = "Measure GPU volume-rendering algorithms: bytes moved, frame time, image error")]
struct Cli {
    /// Vulkan device: index or name substring (default: lavapipe). Also VOLBENCH_DEVICE.
    #[arg(long, global = true)]
    device: Option<String>,
    /// Enable the Khronos validation layer; any message fails the run. Also VOLBENCH_VALIDATION=1.
    #[arg(long, global = true)]
    validation: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The device, driver, API version and the limits that matter here.
    Info,
    /// Render one method on one mesh for N frames and report bytes, times and counts.
    Run(RunArgs),
    /// Run VICP and balanced cell projection on each mesh and print the comparison table.
    Compare(CompareArgs),
    /// Sweep methods x integrators x table sizes x interpolations on one mesh: run
    /// time against error (CSV, Markdown, PNG plot with the Pareto front).
    Pareto(ParetoArgs),
    /// Render adversarial cases (slivers, degenerate cells, grazing rays, far
    /// from the origin, extreme scalars, steps, opaque media, camera inside)
    /// with every method and integrator against the f64 reference.
    Stress(StressArgs),
}

#[derive(Args)]
struct StressArgs {
    /// Image side in pixels (even, >= 16).
    #[arg(long, default_value_t = 128)]
    size: u32,
    /// Write {"cases": [...]} as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Print what each case is and its error allowances, and exit.
    #[arg(long)]
    describe: bool,
}

#[derive(Args)]
struct ParetoArgs {
    /// bluntfin, oxygenpost, post-small, or a mesh file.
    #[arg(long)]
    mesh: String,
    #[command(flatten)]
    frame: FrameArgs,
    /// Output directory (default results/runs/pareto-<mesh>).
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(Clone, Copy, ValueEnum)]
enum ProjectionArg {
    Perspective,
    Orthographic,
}

#[derive(Args, Clone)]
struct FrameArgs {
    /// Image size, WxH.
    #[arg(long, default_value = "512x512", value_parser = parse_size)]
    size: (u32, u32),
    /// Timed frames.
    #[arg(long, default_value_t = 10)]
    frames: usize,
    /// Untimed warm-up frames (shader compilation happens on the first draw).
    #[arg(long, default_value_t = 2)]
    warmup: usize,
    #[arg(long, value_enum, default_value = "perspective")]
    projection: ProjectionArg,
    /// Camera rotation per frame, degrees.
    #[arg(long, default_value_t = 5.0)]
    orbit_step: f64,
    /// How exit data crosses a face under perspective: as the papers do, or exactly.
    #[arg(long, value_enum, default_value = "paper")]
    interpolation: Interpolation,
    /// Run each frame's phases strictly one after another (no CPU/device overlap).
    #[arg(long)]
    no_overlap: bool,
    /// How the fragment stage integrates each cell's segment.
    #[arg(long, value_enum, default_value = "ppi")]
    integrator: Integrator,
    /// Side of the integrator's table (ppi: Psi table, default 512; preint:
    /// scalar samples per axis, default 128, with a quarter as many lengths).
    #[arg(long, value_parser = clap::value_parser!(u32).range(2..=4096))]
    table_size: Option<u32>,
    /// Visibility order: centroid distance, or MPVO from face adjacency.
    #[arg(long, value_enum, default_value = "centroid")]
    sort: SortKind,
    /// A transfer-function file (JSON, see data/tf/README.md); default: the
    /// mesh's preset.
    #[arg(long)]
    tf: Option<PathBuf>,
}

#[derive(Args)]
struct RunArgs {
    /// bluntfin, oxygenpost, post-small, or a path to a mesh file (.vtk).
    #[arg(long)]
    mesh: String,
    #[arg(long, value_enum)]
    method: Method,
    #[command(flatten)]
    frame: FrameArgs,
    /// Write the reference-view image (angle 0) as PNG.
    #[arg(long)]
    png: Option<PathBuf>,
    /// Write the full result as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Compare the reference-view image with the f64 CPU reference (adds `error.*`).
    #[arg(long)]
    reference: bool,
    /// Write |image - reference| x10 as PNG (implies --reference).
    #[arg(long)]
    diff_png: Option<PathBuf>,
}

#[derive(Args)]
struct CompareArgs {
    /// Comma-separated meshes.
    #[arg(long, default_value = "bluntfin,oxygenpost", value_delimiter = ',')]
    meshes: Vec<String>,
    #[command(flatten)]
    frame: FrameArgs,
    /// Directory for JSON results, PNGs and the Markdown table.
    #[arg(long)]
    out: Option<PathBuf>,
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("'{s}' is not WxH (e.g. 512x512)"))?;
    let parse = |v: &str| v.trim().parse::<u32>().map_err(|_| format!("'{s}' is not WxH (e.g. 512x512)"));
    let (w, h) = (parse(w)?, parse(h)?);
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        return Err(format!("size {w}x{h} out of range (1..=16384 per side)"));
    }
    Ok((w, h))
}

impl FrameArgs {
    /// The transfer function: `--tf FILE`, or the mesh's built-in preset.
    fn transfer_function(&self, mesh: &volbench::mesh::TetMesh) -> Result<volbench::scene::TransferFunction> {
        match &self.tf {
            Some(path) => volbench::scene::tf_file::load_tf(path, mesh.scalar_range(), mesh.bounds().diagonal()),
            None => Ok(datasets::default_transfer_function(mesh)),
        }
    }

    fn config(&self, method: Method) -> Result<RunConfig> {
        if self.frames == 0 {
            bail!("--frames must be at least 1");
        }
        if !self.orbit_step.is_finite() {
            bail!("--orbit-step must be a finite number of degrees");
        }
        let mut cfg = RunConfig::new(method);
        (cfg.width, cfg.height) = self.size;
        cfg.frames = self.frames;
        cfg.warmup = self.warmup;
        cfg.orbit_step = self.orbit_step.to_radians();
        cfg.interpolation = self.interpolation;
        cfg.overlap = !self.no_overlap;
        cfg.integrator = self.integrator;
        cfg.table_size = self.table_size.unwrap_or(0) as usize;
        cfg.sort = self.sort;
        cfg.projection = match self.projection {
            ProjectionArg::Perspective => Projection::Perspective { fovy_deg: 30.0 },
            ProjectionArg::Orthographic => Projection::Orthographic { height: 1.0 },
        };
        Ok(cfg)
    }
}

fn context(cli: &Cli) -> Result<std::sync::Arc<Context>> {
    let mut desc = ContextDesc::from_env()?;
    if cli.device.is_some() {
        desc.device = cli.device.clone();
    }
    desc.validation |= cli.validation;
    Context::new(&desc).context("creating the Vulkan context")
}

fn info(cli: &Cli) -> Result<()> {
    for (i, (name, kind)) in volbench::vk::list_devices().context("listing Vulkan devices")?.iter().enumerate() {
        println!("device [{i}] {name} ({kind})");
    }
    let ctx = context(cli)?;
    println!("selected: {}", serde_json::to_string_pretty(&ctx.info)?);
    Ok(())
}

fn run(cli: &Cli, args: &RunArgs) -> Result<()> {
    let cfg = args.frame.config(args.method)?;
    let mesh = datasets::load_mesh(&args.mesh)?;
    let geometry = TetGeometry::compute(&mesh);
    let tf = args.frame.transfer_function(&mesh)?;
    let ctx = context(cli)?;
    let scene = Scene { mesh: &mesh, geometry: &geometry, tf: &tf };
    let mut cfg = cfg;
    cfg.check_visibility = args.reference || args.diff_png.is_some();
    let mut out = run_cell_projection(&ctx, &scene, &cfg)
        .with_context(|| format!("running {} on {}", args.method.name(), args.mesh))?;
    if args.reference || args.diff_png.is_some() {
        let reference = reference_image(&scene, &out.result.image.camera, cfg.width, cfg.height)?;
        let diff = out.attach_error(&reference)?;
        if let Some(p) = &args.diff_png {
            diff.write_png(p)?;
        }
    }
    print!("{}", report::comparison_table(&[ComparisonRow { result: &out.result, rmse_vs_other: None }]));
    if let Some(p) = &args.png {
        out.image.write_png(p)?;
    }
    if let Some(p) = &args.json {
        report::write_json(p, &out.result)?;
    }
    Ok(())
}

fn compare(cli: &Cli, args: &CompareArgs) -> Result<()> {
    // Load (and so validate) every mesh before any output is written.
    let meshes = args.meshes.iter().map(|name| datasets::load_mesh(name)).collect::<Result<Vec<_>>>()?;
    let ctx = context(cli)?;
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let mut results = Vec::new();
    let mut rmses = Vec::new();
    for (name, mesh) in args.meshes.iter().zip(meshes) {
        let geometry = TetGeometry::compute(&mesh);
        let tf = args.frame.transfer_function(&mesh)?;
        let scene = Scene { mesh: &mesh, geometry: &geometry, tf: &tf };
        let mut images = Vec::new();
        let mut reference = None;
        for method in [Method::Vicp, Method::Balanced] {
            eprintln!("volbench: {} on {} ({} cells)...", method.name(), mesh.name, mesh.tets.len());
            let mut cfg = args.frame.config(method)?;
            cfg.check_visibility = true;
            let mut out = run_cell_projection(&ctx, &scene, &cfg)
                .with_context(|| format!("running {} on {}", method.name(), name))?;
            if reference.is_none() {
                eprintln!("volbench: f64 reference of {}...", mesh.name);
                reference = Some(reference_image(&scene, &out.result.image.camera, cfg.width, cfg.height)?);
            }
            let diff = match &reference {
                Some(r) => Some(out.attach_error(r)?),
                None => None,
            };
            if let Some(dir) = &args.out {
                let stem = format!("{}-{}", mesh.name, method.name());
                out.image.write_png(&dir.join(format!("{stem}.png")))?;
                if let Some(d) = diff {
                    d.write_png(&dir.join(format!("{stem}-diff.png")))?;
                }
                report::write_json(&dir.join(format!("{stem}.json")), &out.result)?;
            }
            images.push(out.image);
            results.push(out.result);
        }
        let rmse = images[0].compare(&images[1])?.rmse;
        rmses.push(Some(rmse));
        rmses.push(Some(rmse));
    }
    let rows: Vec<ComparisonRow> =
        results.iter().zip(&rmses).map(|(r, &rmse_vs_other)| ComparisonRow { result: r, rmse_vs_other }).collect();
    let table = report::comparison_table(&rows);
    println!("device: {} ({}, {})", ctx.info.name, ctx.info.driver_name, ctx.info.driver_info);
    print!("{table}");
    if let Some(dir) = &args.out {
        volbench::fsio::write_output(&dir.join("comparison.md"), table.as_bytes())?;
    }
    Ok(())
}

fn pareto(cli: &Cli, args: &ParetoArgs) -> Result<()> {
    use volbench::harness::pareto::{mark_front, markdown, plot_png, write_csv, ParetoPoint};
    let mesh = datasets::load_mesh(&args.mesh)?;
    let out_dir = args.out.clone().unwrap_or_else(|| PathBuf::from(format!("results/runs/pareto-{}", mesh.name)));
    std::fs::create_dir_all(&out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    let geometry = TetGeometry::compute(&mesh);
    let tf = args.frame.transfer_function(&mesh)?;
    let scene = Scene { mesh: &mesh, geometry: &geometry, tf: &tf };
    let ctx = context(cli)?;
    let variants: Vec<(Integrator, usize)> = vec![
        (Integrator::Average, 0),
        (Integrator::Preint, 128),
        (Integrator::Ppi, 128),
        (Integrator::Ppi, 512),
        (Integrator::Ppi, 1024),
        (Integrator::LinearExact, 0),
    ];
    let mut points = Vec::new();
    let mut reference = None;
    for method in [Method::Vicp, Method::Balanced] {
        for (interpolation, sort) in [Interpolation::Paper, Interpolation::Exact]
            .into_iter()
            .flat_map(|i| [SortKind::Centroid, SortKind::Mpvo].map(|s| (i, s)))
        {
            for &(integrator, table_size) in &variants {
                let mut cfg = args.frame.config(method)?;
                cfg.interpolation = interpolation;
                cfg.integrator = integrator;
                cfg.table_size = table_size;
                cfg.sort = sort;
                eprintln!(
                    "volbench: {} {} {} {} {}...",
                    method.name(),
                    integrator.name(),
                    if table_size > 0 { table_size.to_string() } else { "-".into() },
                    interpolation.name(),
                    sort.name()
                );
                let mut out = run_cell_projection(&ctx, &scene, &cfg)?;
                if reference.is_none() {
                    reference = Some(reference_image(&scene, &out.result.image.camera, cfg.width, cfg.height)?);
                }
                if let Some(r) = &reference {
                    out.attach_error(r)?;
                }
                points.extend(ParetoPoint::from_result(&out.result));
            }
        }
    }
    mark_front(&mut points);
    let table = markdown(&mesh.name, &points);
    write_csv(&out_dir.join("pareto.csv"), &points)?;
    volbench::fsio::write_output(&out_dir.join("pareto.md"), table.as_bytes())?;
    let title = format!("{}: frame time against error ({}x{}, {})", mesh.name, args.frame.size.0, args.frame.size.1, ctx.info.name);
    plot_png(&out_dir.join("pareto.png"), &title, &points)?;
    print!("{table}");
    println!("written: {}/pareto.{{csv,md,png}}", out_dir.display());
    Ok(())
}

fn stress(cli: &Cli, args: &StressArgs) -> Result<()> {
    use volbench::harness::stress::{describe_cases, failures, run_stress_with_progress, stress_table, StressReport};
    if args.size < 16 || args.size % 2 != 0 {
        bail!("--size must be even and at least 16, got {}", args.size);
    }
    if args.describe {
        print!("{}", describe_cases(args.size));
        return Ok(());
    }
    let ctx = context(cli)?;
    let mut done = 0usize;
    let rows = run_stress_with_progress(&ctx, args.size, |row| {
        done += 1;
        if done % 50 == 0 {
            eprintln!("volbench: stress: {done} renders ({} ...)", row.case);
        }
    })?;
    print!("{}", stress_table(&rows));
    let failed = failures(&rows);
    let non_finite: usize = rows.iter().map(|r| r.nan_pixels + r.inf_pixels).sum();
    println!("{} renders, {} NaN/Inf pixels, {} failed", rows.len(), non_finite, failed);
    if let Some(p) = &args.json {
        report::write_json(p, &StressReport { cases: rows })?;
    }
    if failed > 0 {
        bail!("{failed} stress renders exceeded their bounds");
    }
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Info => info(&cli),
        Command::Run(a) => run(&cli, a),
        Command::Compare(a) => compare(&cli, a),
        Command::Pareto(a) => pareto(&cli, a),
        Command::Stress(a) => stress(&cli, a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("volbench: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
