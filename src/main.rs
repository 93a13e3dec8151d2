//! The volbench command line: `info`, `list`, `run` (one method on one
//! dataset), `compare` (every method side by side), `pareto` (run time
//! against error) and `stress` (adversarial cases). Methods are named by
//! vkmark-style specs (`balanced:integrator=ppi,sort=mpvo`) resolved through
//! the registry; this file never names a method. Every argument and input is
//! checked before Vulkan starts or any output is created.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context as _, Result};
use clap::{Args, Parser, Subcommand, ValueEnum};

use volbench::algo::registry::{self, Registry};
use volbench::fsio::{self, OutputSet};
use volbench::harness::count;
use volbench::harness::datasets::{self, Dataset};
use volbench::harness::reference_cache::reference_image;
use volbench::harness::report::{self, ComparisonRow};
use volbench::harness::run::{run as run_method, RunConfig};
use volbench::harness::sweep;
use volbench::scene::{Projection, TransferFunction};
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
    /// Every method with its options and defaults, and every shipped dataset.
    List,
    /// Render one method on one dataset for N frames and report bytes, times and counts.
    Run(RunArgs),
    /// Run every method (or the given specs) on each dataset: the comparison table.
    Compare(CompareArgs),
    /// Sweep each method's option sets on one dataset: run time against error
    /// (CSV, Markdown, JSON, PNG plot with the Pareto front).
    Pareto(ParetoArgs),
    /// Render adversarial cases (slivers, degenerate cells, grazing rays, far
    /// from the origin, extreme scalars, steps, opaque media, camera inside;
    /// thin, huge, constant and extreme-valued volumes) with every method on
    /// the cases of its kind, each stress option set, against the f64 reference.
    Stress(StressArgs),
    /// Every registered method on every shipped dataset of its kind at
    /// standard settings: results/<run-id>/ with summary.json, summary.csv,
    /// report.md, plots and a montage.
    Suite(SuiteArgs),
}

#[derive(Args)]
struct SuiteArgs {
    /// 256x256 and 3 frames instead of 512x512 and 20 (CI, a first look).
    #[arg(long)]
    quick: bool,
    /// Only runs of these methods or datasets (repeat; names from `volbench list`).
    #[arg(long, value_name = "NAME")]
    filter: Vec<String>,
    /// Output directory (default results/<UTC time>/).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Also run these peers on the same datasets, alternating with volbench's
    /// runs (`vtk`: VTK's Python wheel, installed by scripts/install-vtk.sh).
    #[arg(long, value_name = "PEER", value_delimiter = ',')]
    peers: Vec<String>,
    /// Count instead of timing: run under valgrind (callgrind) and report
    /// each timed frame's instructions per phase (`count` in each result;
    /// docs/tracking.md). No peers, no CPU reference.
    #[arg(long, conflicts_with = "peers")]
    count: bool,
}

/// Options of a method given as flags: shorthands for `method:key=value`.
/// Each applies only where given; a method without that option is an error.
#[derive(Args, Clone, Default)]
struct MethodFlags {
    /// Shorthand for the `integrator` option (average, preint, ppi, linear-exact).
    #[arg(long)]
    integrator: Option<String>,
    /// Shorthand for the `table_size` option.
    #[arg(long)]
    table_size: Option<String>,
    /// Shorthand for the `sort` option (centroid, mpvo).
    #[arg(long)]
    sort: Option<String>,
    /// Shorthand for the `interpolation` option (exact, paper).
    #[arg(long)]
    interpolation: Option<String>,
}

impl MethodFlags {
    fn pairs(&self) -> Vec<(&'static str, String)> {
        [
            ("integrator", &self.integrator),
            ("table_size", &self.table_size),
            ("sort", &self.sort),
            ("interpolation", &self.interpolation),
        ]
        .into_iter()
        .filter_map(|(k, v)| v.clone().map(|v| (k, v)))
        .collect()
    }
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
    /// Zoom the orbit camera in by this factor (its field of view narrowed,
    /// aimed halfway from the centre to the low corner; 4: a quarter of the
    /// dataset across, most cells off-screen).
    #[arg(long, default_value_t = 1.0)]
    zoom: f64,
    /// Run each frame's phases strictly one after another (no CPU/device overlap).
    #[arg(long)]
    no_overlap: bool,
    /// A transfer-function file (JSON, see data/tf/README.md); default: the
    /// dataset's preset.
    #[arg(long)]
    tf: Option<PathBuf>,
    #[command(flatten)]
    method: MethodFlags,
}

#[derive(Args)]
struct RunArgs {
    /// A shipped dataset (`volbench list`) or a file path.
    #[arg(long, alias = "mesh", value_name = "NAME|PATH")]
    data: String,
    /// The method: `name` or `name:key=value,...` (`volbench list`).
    #[arg(long, value_name = "SPEC")]
    method: String,
    #[command(flatten)]
    frame: FrameArgs,
    /// Write the reference-view image (angle 0) as PNG.
    #[arg(long)]
    png: Option<PathBuf>,
    /// Write the full result as JSON (`-`: standard output).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Compare the reference-view image with the f64 CPU reference (adds `error.*`).
    #[arg(long)]
    reference: bool,
    /// Write |image - reference| x10 as PNG (implies --reference).
    #[arg(long)]
    diff_png: Option<PathBuf>,
    /// Count instead of timing: run under valgrind (callgrind) and report
    /// each timed frame's instructions per phase (`count` in the result;
    /// docs/tracking.md). Frames run without overlap.
    #[arg(long)]
    count: bool,
}

#[derive(Args)]
struct CompareArgs {
    /// Comma-separated datasets (names or paths).
    #[arg(long, alias = "meshes", default_value = "bluntfin,oxygenpost", value_delimiter = ',', value_name = "NAMES")]
    data: Vec<String>,
    /// A method spec to run (repeat for several); default: every method for
    /// the dataset's kind with the option sets it registers for comparison.
    #[arg(long = "method", value_name = "SPEC")]
    methods: Vec<String>,
    #[command(flatten)]
    frame: FrameArgs,
    /// Directory for JSON results, PNGs and the Markdown table.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Benchmark tracking instead: `compare BASELINE NEW`, two suite
    /// `summary.json` files. Counts must match exactly, errors must not grow
    /// beyond tolerance, frame-time ratios between methods must stay inside
    /// their noise bands; exits non-zero on a regression.
    #[arg(
        value_name = "SUMMARY",
        num_args = 2,
        conflicts_with_all = ["data", "methods", "out", "size", "frames", "warmup", "projection", "orbit_step", "zoom", "no_overlap", "tf", "integrator", "table_size", "sort", "interpolation"]
    )]
    summaries: Vec<PathBuf>,
    /// Tracking: compare counts and errors only, not times (shared CI runners).
    #[arg(long, requires = "summaries")]
    no_times: bool,
    /// Tracking: also compare absolute frame times (same device, driver and
    /// CPU model only; off by default: the same model is not the same machine).
    #[arg(long, requires = "summaries", conflicts_with = "no_times")]
    absolute_times: bool,
    /// Tracking: write NEW's figures in Bencher Metric Format.
    #[arg(long, requires = "summaries", value_name = "FILE")]
    bmf: Option<PathBuf>,
    /// Tracking: write NEW's figures as github-action-benchmark `customSmallerIsBetter` JSON.
    #[arg(long, requires = "summaries", value_name = "FILE")]
    gha: Option<PathBuf>,
}

#[derive(Args)]
struct ParetoArgs {
    /// A shipped dataset or a file path.
    #[arg(long, alias = "mesh", value_name = "NAME|PATH")]
    data: String,
    /// A method spec to sweep (repeat for several); default: every method for
    /// the dataset's kind. Each is swept over its registered option sets, with
    /// the spec's own options and the shorthand flags held fixed.
    #[arg(long = "method", value_name = "SPEC")]
    methods: Vec<String>,
    #[command(flatten)]
    frame: FrameArgs,
    /// Output directory (default results/runs/pareto-<dataset>).
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(Args)]
struct StressArgs {
    /// Image side in pixels (even, 16..=2048).
    #[arg(long, default_value_t = 128)]
    size: u32,
    /// Only these methods (repeat; default every method).
    #[arg(long = "method", value_name = "NAME")]
    methods: Vec<String>,
    /// Write {"cases": [...]} as JSON (rewritten as each row completes).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Print what each case is and its error allowances, and exit.
    #[arg(long)]
    describe: bool,
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
    /// The transfer function: `--tf FILE`, or the dataset's preset.
    fn transfer_function(&self, dataset: &Dataset) -> Result<TransferFunction> {
        match &self.tf {
            Some(path) => dataset.load_transfer_function(path),
            None => Ok(dataset.default_transfer_function()),
        }
    }

    fn config(&self) -> Result<RunConfig> {
        let cfg = RunConfig {
            width: self.size.0,
            height: self.size.1,
            frames: self.frames,
            warmup: self.warmup,
            orbit_step: self.orbit_step.to_radians(),
            zoom: self.zoom,
            overlap: !self.no_overlap,
            projection: match self.projection {
                ProjectionArg::Perspective => Projection::Perspective { fovy_deg: 30.0 },
                ProjectionArg::Orthographic => Projection::Orthographic { height: 1.0 },
            },
            ..RunConfig::default()
        };
        cfg.validate()?;
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

fn list(registry: &Registry) -> Result<()> {
    println!("Methods (spec: name:key=value,...; [b] = changes shader code, [r] = run-time parameter):");
    for m in registry.methods() {
        println!("\n  {} ({} datasets): {}", m.name, m.data.name(), m.summary);
        if !m.features.is_empty() {
            let f: Vec<&str> = m.features.iter().map(|f| f.name()).collect();
            println!("    needs: {}", f.join(", "));
        }
        for o in m.options {
            let unit = if o.unit.is_empty() { String::new() } else { format!(" ({})", o.unit) };
            println!(
                "    {}={} [{}] {}{unit}: {}",
                o.name,
                o.default,
                if o.build_time { "b" } else { "r" },
                o.allowed(),
                o.help
            );
        }
    }
    println!("\nDatasets (--data NAME, or a file path):");
    for d in datasets::NAMED {
        println!("  {:<12} {:<9} {}", d.name, d.kind.name(), d.description);
    }
    Ok(())
}

/// Before any work: `dir` is a directory or can be made one, and the files
/// a command writes there under fixed names can be written.
fn check_out_dir(dir: &Path, files: &[&str]) -> Result<()> {
    match std::fs::metadata(dir) {
        Ok(m) if !m.is_dir() => bail!("--out {}: exists and is not a directory", dir.display()),
        Ok(_) => {
            let mut set = OutputSet::new();
            for f in files {
                set.add("--out", &dir.join(f))?;
            }
            Ok(())
        }
        Err(_) if std::fs::symlink_metadata(dir).is_ok() => bail!("--out {}: is a dangling symbolic link", dir.display()),
        // Made after the checks; its nearest existing ancestor must be a
        // directory that takes new entries (probed, nothing created).
        Err(_) => {
            let existing = dir
                .ancestors()
                .skip(1)
                .map(|a| if a.as_os_str().is_empty() { Path::new(".") } else { a })
                .find(|a| a.exists())
                .unwrap_or(Path::new("."));
            OutputSet::new()
                .add("--out", &existing.join(".volbench-out-probe"))
                .with_context(|| format!("--out {}: cannot be created", dir.display()))
        }
    }
}

fn run(cli: &Cli, registry: &Registry, args: &RunArgs) -> Result<()> {
    let count_dir = count::child_dir(args.count)?;
    // A counted run's phases must not interleave: no overlap.
    let cfg = RunConfig { overlap: !args.frame.no_overlap && count_dir.is_none(), count_dir, ..args.frame.config()? };
    cfg.validate()?;
    let spec = registry.parse_spec(&args.method, &args.frame.method.pairs()).with_context(|| format!("--method {}", args.method))?;
    let mut outputs = OutputSet::new();
    for (option, path) in [("--png", &args.png), ("--json", &args.json), ("--diff-png", &args.diff_png)] {
        if let Some(p) = path {
            outputs.add(option, p)?;
        }
    }
    let dataset = datasets::load(&args.data)?;
    spec.check_renders(dataset.kind(), &args.data)?;
    let tf = args.frame.transfer_function(&dataset)?;
    let ctx = context(cli)?;
    cfg.check_device(&ctx.info)?;
    let with_reference = args.reference || args.diff_png.is_some();
    let cfg = RunConfig { diagnostics: with_reference, ..cfg };
    let mut out = run_method(&ctx, &spec, &dataset, &tf, &cfg)
        .with_context(|| format!("running {} on {}", spec.canonical(), args.data))?;
    let mut diff = None;
    if with_reference && out.result.error.is_none() {
        let reference = reference_image(&dataset, &tf, &out.result.image.camera, cfg.width, cfg.height)?;
        diff = Some(out.attach_error(&reference)?);
    }
    let row = ComparisonRow { label: spec.label(), dataset: dataset.name.clone(), outcome: Ok(&out.result), rmse_vs_first: None };
    // The table goes to stderr when an output goes to stdout.
    let table = report::comparison_table(&[row], registry);
    let to_stdout = [&args.json, &args.png, &args.diff_png].iter().any(|p| p.as_deref() == Some(Path::new("-")));
    if to_stdout {
        eprint!("{table}");
    } else {
        print!("{table}");
    }
    // All outputs or none.
    let mut files: Vec<(&Path, Vec<u8>)> = Vec::new();
    if let Some(p) = &args.png {
        files.push((p, out.image.png_bytes()?));
    }
    if let (Some(p), Some(d)) = (&args.diff_png, &diff) {
        files.push((p, d.png_bytes()?));
    }
    if let Some(p) = &args.json {
        files.push((p, report::json_bytes(&out.result)?));
    }
    fsio::write_all(&files.iter().map(|(p, b)| (*p, b.as_slice())).collect::<Vec<_>>())
}

fn compare(cli: &Cli, registry: &Registry, args: &CompareArgs) -> Result<()> {
    if let [baseline, new] = args.summaries.as_slice() {
        return track(baseline, new, args);
    }
    let cfg = RunConfig { diagnostics: true, ..args.frame.config()? };
    // Load (and so validate) every dataset, transfer function and spec
    // before any output is written or Vulkan starts.
    let mut jobs = Vec::new();
    for name in &args.data {
        let dataset = datasets::load(name)?;
        let tf = args.frame.transfer_function(&dataset)?;
        let specs = sweep::specs_for(registry, &args.methods, dataset.kind(), &args.frame.method.pairs(), |m| m.compare)?;
        jobs.push(sweep::CompareJob { dataset, tf, specs });
    }
    sweep::check_compare_outputs(&jobs)?;
    if let Some(dir) = &args.out {
        check_out_dir(dir, &["comparison.md"])?;
    }
    let ctx = context(cli)?;
    cfg.check_device(&ctx.info)?;
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let rows = sweep::compare(&ctx, registry, &jobs, &cfg, args.out.as_deref())?;
    println!("device: {} ({}, {})", ctx.info.name, ctx.info.driver_name, ctx.info.driver_info);
    print!("{}", sweep::comparison_markdown(&rows, registry)?);
    let failed = rows.iter().filter(|r| r.outcome.is_err() && !r.skipped).count();
    if failed > 0 {
        bail!("{failed} of {} runs failed (see the table)", rows.len());
    }
    Ok(())
}

/// `compare BASELINE NEW`: benchmark tracking between two suite summaries.
fn track(baseline: &Path, new: &Path, args: &CompareArgs) -> Result<()> {
    use volbench::harness::track;
    let (b, n) = (track::load(baseline)?, track::load(new)?);
    let mut outputs = OutputSet::new();
    for (option, p) in [("--bmf", &args.bmf), ("--gha", &args.gha)] {
        if let Some(p) = p {
            outputs.add(option, p)?;
        }
    }
    let tol = track::Tolerances { times: !args.no_times, absolute_times: args.absolute_times, ..track::Tolerances::default() };
    let c = track::compare(&b, &n, &tol)?;
    println!("baseline {} ({}), new {} ({})", baseline.display(), b.environment.git_sha, new.display(), n.environment.git_sha);
    print!("{}", c.table());
    let mut files: Vec<(&Path, Vec<u8>)> = Vec::new();
    if let Some(p) = &args.bmf {
        files.push((p, report::json_bytes(&track::bmf(&n))?));
    }
    if let Some(p) = &args.gha {
        files.push((p, report::json_bytes(&track::gha(&n))?));
    }
    fsio::write_all(&files.iter().map(|(p, b)| (*p, b.as_slice())).collect::<Vec<_>>())?;
    let r = c.regressions();
    if r > 0 {
        bail!("{r} regression{} against {}", if r == 1 { "" } else { "s" }, baseline.display());
    }
    Ok(())
}

fn pareto(cli: &Cli, registry: &Registry, args: &ParetoArgs) -> Result<()> {
    let cfg = args.frame.config()?;
    let dataset = datasets::load(&args.data)?;
    let tf = args.frame.transfer_function(&dataset)?;
    let specs = sweep::pareto_specs(registry, &args.methods, dataset.kind(), &args.frame.method.pairs())?;
    let out_dir = args.out.clone().unwrap_or_else(|| PathBuf::from(format!("results/runs/pareto-{}", dataset.name)));
    check_out_dir(&out_dir, &["pareto.csv", "pareto.md", "pareto.json", "pareto.png"])?;
    let ctx = context(cli)?;
    cfg.check_device(&ctx.info)?;
    std::fs::create_dir_all(&out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    let points = sweep::pareto(&ctx, &dataset, &tf, &specs, &cfg, &out_dir)?;
    print!("{}", volbench::harness::pareto::markdown(&dataset.name, &points));
    println!("written: {}/pareto.{{csv,md,json,png}}", out_dir.display());
    let failed = points.iter().filter(|p| p.error.is_some() && !p.skipped).count();
    if failed > 0 {
        bail!("{failed} of {} sweep runs failed (see pareto.md)", points.len());
    }
    Ok(())
}

fn stress(cli: &Cli, registry: &Registry, args: &StressArgs) -> Result<()> {
    use volbench::harness::stress::{describe_cases, failures, run_cases_with_progress, stress_cases, stress_table, StressConfig, StressReport};
    if !(16..=2048).contains(&args.size) || args.size % 2 != 0 {
        bail!("--size must be even and within 16..=2048 (the f64 reference renders every pixel on the CPU), got {}", args.size);
    }
    if args.describe {
        print!("{}", describe_cases(args.size));
        return Ok(());
    }
    if let Some(p) = &args.json {
        OutputSet::new().add("--json", p)?;
    }
    let mut cfg = StressConfig::full(registry, args.size)?;
    if !args.methods.is_empty() {
        for m in &args.methods {
            registry.get(m)?;
        }
        cfg.specs.retain(|s| args.methods.iter().any(|m| m == s.info.name));
        anyhow::ensure!(!cfg.specs.is_empty(), "--method: none of {:?} has stress option sets", args.methods);
    }
    let ctx = context(cli)?;
    let mut done = Vec::new();
    // The JSON is rewritten as each row completes; a write that fails ends
    // the run at once (the path was probed up front, so this is rare).
    let rows = run_cases_with_progress(&ctx, &stress_cases(args.size), &cfg, |row| {
        done.push(row.clone());
        if done.len() % 50 == 0 {
            eprintln!("volbench: stress: {} renders ({} ...)", done.len(), row.case);
        }
        match &args.json {
            Some(p) => report::write_json(p, &StressReport { cases: done.clone() }),
            None => Ok(()),
        }
    })?;
    print!("{}", stress_table(&rows));
    let failed = failures(&rows);
    let non_finite: usize = rows.iter().map(|r| r.nan_pixels + r.inf_pixels).sum();
    println!("{} renders, {} NaN/Inf pixels, {} failed", rows.len(), non_finite, failed);
    if failed > 0 {
        bail!("{failed} stress renders failed or exceeded their bounds");
    }
    Ok(())
}

fn suite(cli: &Cli, registry: &Registry, args: &SuiteArgs) -> Result<()> {
    use volbench::harness::suite::{plan, run_suite, utc_now, SuiteSettings};
    let settings = SuiteSettings { peers: args.peers.clone(), ..SuiteSettings::standard(args.quick, args.filter.clone()) }
        .counted(count::child_dir(args.count)?);
    let plan = plan(registry, &settings)?;
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from(format!("results/{}", utc_now())));
    check_out_dir(&out, &["summary.json", "summary.csv", "report.md", "montage.png"])?;
    let ctx = context(cli)?;
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    // A progress bar with ETA on a terminal, plain lines otherwise.
    let bar = indicatif::ProgressBar::new(plan.len() as u64);
    let terminal = std::io::IsTerminal::is_terminal(&std::io::stderr());
    if terminal {
        bar.set_style(
            indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} runs, ETA {eta}: {msg}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
    } else {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    let summary = run_suite(&ctx, registry, &plan, &settings, &out, |i, label| {
        bar.set_position(i as u64);
        bar.set_message(label.to_string());
        if !terminal {
            eprintln!("volbench: suite: [{}/{}] {label}", i + 1, plan.len());
        }
    })?;
    bar.finish_and_clear();
    let failed = summary.runs.iter().filter(|r| r.status == "failed").count();
    let peers_failed = summary.peers.iter().filter(|r| r.status == "failed").count();
    println!("results: {}", out.display());
    if failed > 0 {
        bail!("{failed} of {} suite runs failed (see report.md)", summary.runs.len());
    }
    if peers_failed > 0 {
        bail!("{peers_failed} of {} peer runs failed (see report.md)", summary.peers.len());
    }
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // `--count`: the same command again, under valgrind.
    let count = match &cli.command {
        Command::Run(a) => a.count,
        Command::Suite(a) => a.count,
        _ => false,
    };
    if count && cli.validation {
        eprintln!("volbench: error: --count with --validation: the layer's work would be counted as the method's; validate an uncounted run");
        return ExitCode::FAILURE;
    }
    if count::needs_reexec(count) {
        return count::reexec().unwrap_or_else(|e| {
            eprintln!("volbench: error: {e:#}");
            ExitCode::FAILURE
        });
    }
    let registry = registry::builtin();
    let result = match &cli.command {
        Command::Info => info(&cli),
        Command::List => list(&registry),
        Command::Run(a) => run(&cli, &registry, a),
        Command::Compare(a) => compare(&cli, &registry, a),
        Command::Pareto(a) => pareto(&cli, &registry, a),
        Command::Stress(a) => stress(&cli, &registry, a),
        Command::Suite(a) => suite(&cli, &registry, a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("volbench: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
