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
use volbench::harness::datasets::{self, Dataset, DatasetData};
use volbench::harness::reference_cache::reference_image;
use volbench::harness::report::{self, ComparisonRow};
use volbench::harness::run::{run as run_method, RunConfig};
use volbench::harness::sweep;
use volbench::mesh::cell_data::CellData;
use volbench::scene::{Projection, TransferFunction};
use volbench::vk::{Context, ContextDesc};

/// `print!` that returns the write error instead of panicking (a closed
/// pipe or a full device; see `exit_code`).
macro_rules! out {
    ($($t:tt)*) => { write_stdout(&format!($($t)*))? };
}

macro_rules! outln {
    () => { write_stdout("\n")? };
    ($($t:tt)*) => { write_stdout(&format!("{}\n", format_args!($($t)*)))? };
}

fn write_stdout(text: &str) -> Result<()> {
    use std::io::Write as _;
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes()).and_then(|()| out.flush()).context("writing to standard output")
}

#[derive(Parser)]
#[command(name = "volbench", version, about = "Measure GPU volume-rendering algorithms: bytes moved, frame time, image error")]
struct Cli {
    /// Vulkan device: index or name substring (default: lavapipe). Also VOLBENCH_DEVICE.
    #[arg(long, global = true)]
    device: Option<String>,
    /// Enable the Khronos validation layer; any message fails the run. Also VOLBENCH_VALIDATION=1.
    #[arg(long, global = true)]
    validation: bool,
    /// How quadratic and Lagrange cells of an unstructured mesh are read: `subdivide` (into linear
    /// tets through every node, the default) or `corners` (corner nodes only). See docs/formats.md.
    #[arg(long, global = true, value_name = "MODE", default_value = "subdivide", value_parser = ["subdivide", "corners"])]
    higher_order: String,
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
    /// Every registered method on every shipped dataset of its kind (or on
    /// the datasets and files `--data` names) at standard settings:
    /// results/<run-id>/ with summary.json, summary.csv, report.md, plots
    /// and a montage.
    Suite(SuiteArgs),
    /// Paired A/B timing of two volbench binaries (or git revisions, built
    /// here): the same benchmarks alternately in one sitting, each one's
    /// speed ratio NEW/BASE with a 95 % interval; fails on a slowdown.
    Ab(AbArgs),
    /// Scaling study: red-refine a tet mesh level by level (x8 tets each)
    /// and run each method on every level in a fresh process: time, phases,
    /// tets/s, bytes, peak RSS; JSON, CSV, Markdown and log-log plots.
    Scale(ScaleArgs),
}

#[derive(Args)]
struct ScaleArgs {
    /// A shipped tet mesh (`volbench list`) or a mesh file.
    #[arg(long, value_name = "NAME|PATH")]
    data: String,
    /// Refinements after the input (level 0); each multiplies the tets by 8.
    #[arg(long, default_value_t = 1)]
    levels: usize,
    /// A method spec to run (repeat); default: every tet-mesh method at its defaults.
    #[arg(long = "method", value_name = "SPEC")]
    methods: Vec<String>,
    /// Image size, WxH.
    #[arg(long, default_value = "512x512", value_parser = parse_size)]
    size: (u32, u32),
    /// Timed frames per run.
    #[arg(long, default_value_t = 3)]
    frames: usize,
    /// Untimed warm-up frames per run.
    #[arg(long, default_value_t = 1)]
    warmup: usize,
    /// Time the f64 reference on levels with at most this many tets (0: never).
    #[arg(long, default_value_t = 1_000_000)]
    reference_max_cells: u64,
    /// Also run these peers on every level (`vtk`: its projected tetrahedra).
    #[arg(long, value_name = "PEER", value_delimiter = ',')]
    peers: Vec<String>,
    /// Output directory (default results/scale-<dataset>).
    #[arg(long)]
    out: Option<PathBuf>,
    /// How a mesh file's cell array is shown (as for `run`); scale refines
    /// and writes point fields, so only `average` applies to cell data.
    #[arg(long, default_value = "constant", value_name = "constant|average", value_parser = parse_cell_data)]
    cell_data: CellData,
}

#[derive(Args)]
struct AbArgs {
    /// The baseline: a volbench binary, or a git revision to build.
    #[arg(value_name = "BASE")]
    base: String,
    /// The candidate: a volbench binary, or a git revision to build.
    #[arg(value_name = "NEW")]
    new: String,
    /// Only benchmarks of these methods or datasets (repeat; as the suite's).
    #[arg(long, value_name = "NAME")]
    filter: Vec<String>,
    /// Run these specs instead of every method at its defaults (repeat).
    #[arg(long, value_name = "SPEC")]
    spec: Vec<String>,
    /// An environment variable set for BASE's processes only (repeat), e.g.
    /// a driver setting measured with the same binary on both sides.
    #[arg(long, value_name = "VAR=VALUE")]
    base_env: Vec<String>,
    /// An environment variable set for NEW's processes only (repeat).
    #[arg(long, value_name = "VAR=VALUE")]
    new_env: Vec<String>,
    /// Samples per binary and benchmark (default: 300 per frame, 10 per run).
    #[arg(long)]
    pairs: Option<usize>,
    /// Alternate whole runs (one fresh process per sample) instead of frames
    /// between two resident serve processes.
    #[arg(long)]
    per_run: bool,
    /// Per frame: frames per alternation step (the sample is their median).
    #[arg(long, default_value_t = 1)]
    batch: usize,
    /// Per frame: rounds of fresh serve processes the pairs are shared out
    /// over; the interval is over the rounds (a process's own bias counts).
    #[arg(long, default_value_t = 10)]
    processes: usize,
    /// Seconds any child may take before its process group is killed: a
    /// serve process's answer (its start, loading and warm-up included), a
    /// per-run run, a binary's `--version`.
    #[arg(long, default_value_t = 600.0)]
    timeout: f64,
    /// Seconds building a revision (`cargo build --release`, from scratch
    /// about 10 minutes on 2 cores) may take before cargo and its jobs are killed.
    #[arg(long, default_value_t = 3600.0)]
    build_timeout: f64,
    /// Slowdown threshold in percent: fail where the interval lies wholly above 1 + this.
    #[arg(long, default_value_t = 3.0)]
    threshold: f64,
    /// Image size of each run, WxH.
    #[arg(long, default_value = "128x128", value_parser = parse_size)]
    size: (u32, u32),
    /// Per run: timed frames per run (the run's sample is their median).
    #[arg(long, default_value_t = 5)]
    frames: usize,
    /// Untimed warm-up frames per run (per frame: once per serve process).
    #[arg(long, default_value_t = 1)]
    warmup: usize,
    /// Seed of the per-pair order (default: from the clock; recorded).
    #[arg(long)]
    seed: Option<u64>,
    /// Target directory for building revisions (default: CARGO_TARGET_DIR or ./target).
    #[arg(long)]
    target_dir: Option<PathBuf>,
    /// Write ab.json and ab.md here.
    #[arg(long)]
    out: Option<PathBuf>,
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
    /// With --peers: after each dataset, run each peer renderer again with
    /// the two fastest volbench runs at no more error, in this many rounds
    /// (one run, the peer, the other; reversed every other round); the
    /// report quotes the better run's median ratio (default 3, --quick 1;
    /// 0: none).
    #[arg(long, value_name = "N", requires = "peers", value_parser = clap::value_parser!(u16).range(0..=20))]
    rounds: Option<u16>,
    /// Count instead of timing: run under valgrind (callgrind) and report
    /// each timed frame's instructions per phase (`count` in each result;
    /// docs/tracking.md). No peers, no CPU reference.
    #[arg(long, conflicts_with = "peers")]
    count: bool,
    /// How a mesh file's cell array is shown (as for `run`; the shipped
    /// meshes have point data).
    #[arg(long, default_value = "constant", value_name = "constant|average", value_parser = parse_cell_data)]
    cell_data: CellData,
    /// Run these datasets instead of every shipped one (repeat): shipped
    /// names (`volbench list`) or your own files, `FILE#SCALAR` as for
    /// `run`; every method of the file's kind runs, and with `--peers` the
    /// peers read the original file with their own readers.
    #[arg(long, value_name = "NAME|FILE")]
    data: Vec<String>,
    /// A transfer-function file (JSON, see data/tf/README.md) for every
    /// dataset's standard scene; default: a shipped dataset's preset, a
    /// file's generic ramp over its scalar range.
    #[arg(long, value_name = "FILE")]
    tf: Option<PathBuf>,
}

/// Options of a method given as flags: shorthands for `method:key=value`.
/// Each applies only where given; a method without that option is an error.
#[derive(Args, Clone, Default)]
struct MethodFlags {
    /// Shorthand for the `integrator` option (its values per method: `volbench list`).
    #[arg(long)]
    integrator: Option<String>,
    /// Shorthand for the `table_size` option.
    #[arg(long)]
    table_size: Option<String>,
    /// Shorthand for the `sort` option (its values per method: `volbench list`).
    #[arg(long)]
    sort: Option<String>,
    /// Shorthand for the `interpolation` option (its values per method: `volbench list`).
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
    /// Frames with nothing in view (the camera turned away) after the timed
    /// ones: the frame's fixed cost, reported as `fixed` and `fixed_gpu` (0: none).
    #[arg(long, default_value_t = 5)]
    fixed_frames: usize,
    /// A transfer-function file (JSON, see data/tf/README.md); default: the
    /// dataset's preset.
    #[arg(long)]
    tf: Option<PathBuf>,
    /// How a mesh file's cell array (one value per cell) is shown: `constant`
    /// (each cell its own value) or `average` (averaged to the points as
    /// VTK's vtkCellDataToPointData does). Point arrays are not affected.
    #[arg(long, default_value = "constant", value_name = "constant|average", value_parser = parse_cell_data)]
    cell_data: CellData,
    #[command(flatten)]
    method: MethodFlags,
}

#[derive(Args)]
struct RunArgs {
    /// A shipped dataset (`volbench list`) or a file path.
    #[arg(long, alias = "mesh", value_name = "NAME|PATH")]
    data: String,
    /// The point or cell array of a VTK unstructured grid (.vtk, .vtu, .pvtu)
    /// to render (vector arrays by magnitude; a point array of that name
    /// first; cell data as --cell-data says); the same as `--data FILE#NAME`.
    #[arg(long, value_name = "NAME")]
    scalar: Option<String>,
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
    /// `volbench ab`'s per-frame protocol (docs/ab.md): load, build, warm up,
    /// then render timed frames on command from stdin ("frame N", "quit").
    #[arg(long, hide = true, conflicts_with_all = ["png", "json", "reference", "diff_png", "count"])]
    serve: bool,
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
    /// beyond tolerance; exits non-zero on a regression. Frame-time ratios
    /// between methods that left their noise bands are notes, failures only
    /// when both summaries come from the same machine and sitting or with
    /// `--times`.
    #[arg(
        value_name = "SUMMARY",
        num_args = 2,
        conflicts_with_all = ["data", "methods", "out", "size", "frames", "warmup", "projection", "orbit_step", "zoom", "no_overlap", "fixed_frames", "tf", "cell_data", "integrator", "table_size", "sort", "interpolation"]
    )]
    summaries: Vec<PathBuf>,
    /// Tracking: compare counts and errors only, not times at all.
    #[arg(long, requires = "summaries")]
    no_times: bool,
    /// Tracking: a moved time fails the comparison even when the summaries
    /// are not from the same machine and sitting (speed decisions: `ab`).
    #[arg(long, requires = "summaries", conflicts_with = "no_times")]
    times: bool,
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
    /// Only these cases (repeat; default every case, see --describe).
    #[arg(long = "case", value_name = "NAME")]
    cases: Vec<String>,
    /// Write each case's reference and each render with its |image - reference| x10 as PNG into this directory.
    #[arg(long, value_name = "DIR")]
    images: Option<PathBuf>,
    /// Write {"cases": [...]} as JSON (rewritten as each row completes).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Print what each case is and its error allowances, and exit.
    #[arg(long)]
    describe: bool,
}

fn parse_cell_data(s: &str) -> Result<CellData, String> {
    s.parse::<CellData>().map_err(|e| e.to_string().trim_start_matches(&format!("--cell-data '{s}': ")).to_string())
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
            None => dataset.default_transfer_function(),
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
            fixed_frames: self.fixed_frames,
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
        outln!("device [{i}] {name} ({kind})");
    }
    let ctx = context(cli)?;
    outln!("selected: {}", serde_json::to_string_pretty(&ctx.info)?);
    Ok(())
}

fn list(registry: &Registry) -> Result<()> {
    outln!("Methods (spec: name:key=value,...; [b] = changes shader code, [r] = run-time parameter):");
    for m in registry.methods() {
        outln!("\n  {} ({} datasets): {}", m.name, m.data.name(), m.summary);
        if !m.features.is_empty() {
            let f: Vec<&str> = m.features.iter().map(|f| f.name()).collect();
            outln!("    needs: {}", f.join(", "));
        }
        for o in m.options {
            let unit = if o.unit.is_empty() { String::new() } else { format!(" ({})", o.unit) };
            outln!(
                "    {}={} [{}] {}{unit}: {}",
                o.name,
                o.default,
                if o.build_time { "b" } else { "r" },
                o.allowed(),
                o.help
            );
        }
    }
    outln!("\nDatasets (--data NAME, or a file path):");
    for d in datasets::NAMED {
        outln!("  {:<12} {:<9} {}", d.name, d.kind.name(), d.description);
    }
    Ok(())
}

/// Before any work: `dir` is a directory or can be made one, the files a
/// command writes there under fixed names can be written, and each of the
/// subdirectories it writes into is a directory that takes new files (or
/// does not exist yet).
fn check_out_dir(dir: &Path, files: &[&str], subdirs: &[&str]) -> Result<()> {
    match std::fs::metadata(dir) {
        Ok(m) if !m.is_dir() => bail!("--out {}: exists and is not a directory", dir.display()),
        Ok(_) => {
            let mut set = OutputSet::new();
            for f in files {
                set.add("--out", &dir.join(f))?;
            }
            for sub in subdirs {
                let sub = dir.join(sub);
                match std::fs::metadata(&sub) {
                    Ok(m) if !m.is_dir() => bail!("--out {}: {} exists and is not a directory", dir.display(), sub.display()),
                    Ok(_) => set.add("--out", &sub.join(".volbench-out-probe"))?,
                    Err(_) if std::fs::symlink_metadata(&sub).is_ok() => {
                        bail!("--out {}: {} is a dangling symbolic link", dir.display(), sub.display())
                    }
                    Err(_) => {}
                }
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
    let data = match &args.scalar {
        None => args.data.clone(),
        Some(name) => {
            let ext = std::path::Path::new(&args.data).extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
            if !ext.is_some_and(|e| volbench::mesh::datasets::VTK_EXTENSIONS.contains(&e.as_str())) {
                anyhow::bail!("--scalar {name}: only VTK unstructured grids (.vtk, .vtu, .pvtu) have named arrays, not '{}'", args.data);
            }
            format!("{}#{name}", args.data)
        }
    };
    let dataset = datasets::load_with(&data, args.frame.cell_data)
        .with_context(|| format!("--method {} renders {} datasets", spec.info.name, spec.info.data.name()))?;
    spec.check_renders(dataset.kind(), &args.data)?;
    let tf = args.frame.transfer_function(&dataset)?;
    // After the inputs are read, so that an output naming one is refused.
    let mut outputs = OutputSet::new();
    for (option, path) in [("--png", &args.png), ("--json", &args.json), ("--diff-png", &args.diff_png)] {
        if let Some(p) = path {
            outputs.add(option, p)?;
        }
    }
    cfg.check_framing(&dataset)?;
    let ctx = context(cli)?;
    cfg.check_device(&ctx.info)?;
    if args.serve {
        // One method, no reference: it takes the samples over, as below.
        let mut dataset = dataset;
        dataset.hand_over_samples();
        return volbench::harness::serve::serve_run(&ctx, &spec, &dataset, &tf, &cfg)
            .with_context(|| format!("serving {} on {}", spec.canonical(), args.data));
    }
    let with_reference = args.reference || args.diff_png.is_some();
    let cfg = RunConfig { diagnostics: with_reference, ..cfg };
    // A volume's reference comes first: nothing reads its samples after
    // the method's set-up, which takes them over and frees them as they
    // reach the device (docs/bad-input.md, "Memory").
    let camera = cfg.frame_camera(&dataset, &spec.info.family, 0);
    let early = match &dataset.data {
        DatasetData::Volume(_) if with_reference => Some(reference_image(&dataset, &tf, &camera, cfg.width, cfg.height)?),
        _ => None,
    };
    let mut dataset = dataset;
    dataset.hand_over_samples();
    let mut out = run_method(&ctx, &spec, &dataset, &tf, &cfg)
        .with_context(|| format!("running {} on {}", spec.canonical(), args.data))?;
    let mut diff = None;
    if with_reference && out.result.error.is_none() {
        let reference = match early {
            Some(r) => r,
            None => reference_image(&dataset, &tf, &out.result.image.camera, cfg.width, cfg.height)?,
        };
        diff = Some(out.attach_error(&reference)?);
    }
    let row = ComparisonRow { label: spec.label(), dataset: dataset.name.clone(), outcome: Ok(&out.result), rmse_vs_first: None };
    // The table goes to stderr when an output goes to stdout.
    let table = report::comparison_table(&[row], registry);
    let to_stdout = [&args.json, &args.png, &args.diff_png].iter().any(|p| p.as_deref().is_some_and(fsio::is_stdout));
    if to_stdout {
        {
            use std::io::Write as _;
            let _ = write!(std::io::stderr(), "{table}");
        }
    } else {
        out!("{table}");
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
    // The tracking options mean nothing to a comparison run: refuse them
    // rather than run for minutes and not write what was asked.
    for (option, given) in [("--no-times", args.no_times), ("--times", args.times), ("--bmf", args.bmf.is_some()), ("--gha", args.gha.is_some())] {
        if given {
            bail!("{option} applies only to benchmark tracking (`compare BASELINE NEW`, two summary.json files), not to a comparison run");
        }
    }
    let cfg = RunConfig { diagnostics: true, ..args.frame.config()? };
    // Load (and so validate) every dataset, transfer function and spec
    // before any output is written or Vulkan starts.
    let mut jobs = Vec::new();
    for name in &args.data {
        let dataset = datasets::load_with(name, args.frame.cell_data)?;
        let tf = args.frame.transfer_function(&dataset)?;
        let specs = sweep::specs_for(registry, &args.methods, dataset.kind(), &args.frame.method.pairs(), |m| m.compare)?;
        jobs.push(sweep::CompareJob { dataset, tf, specs });
    }
    sweep::check_compare_outputs(&jobs)?;
    if let Some(dir) = &args.out {
        check_out_dir(dir, &["comparison.md"], &[])?;
    }
    let ctx = context(cli)?;
    cfg.check_device(&ctx.info)?;
    let _lock = args.out.as_deref().map(|dir| fsio::lock_out_dir("--out", dir)).transpose()?;
    let rows = sweep::compare(&ctx, registry, &mut jobs, &cfg, args.out.as_deref())?;
    outln!("device: {} ({}, {})", ctx.info.name, ctx.info.driver_name, ctx.info.driver_info);
    out!("{}", sweep::comparison_markdown(&rows, registry)?);
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
    let times = match (args.no_times, args.times) {
        (true, _) => track::Times::Off,
        (false, true) => track::Times::Always,
        (false, false) => track::Times::Auto,
    };
    let tol = track::Tolerances { times, absolute_times: args.absolute_times, ..track::Tolerances::default() };
    let c = track::compare(&b, &n, &tol)?;
    // (The revisions are the summaries' text: printed escaped.)
    outln!(
        "baseline {} ({}), new {} ({})",
        baseline.display(),
        b.environment.git_sha.escape_debug(),
        new.display(),
        n.environment.git_sha.escape_debug()
    );
    out!("{}", c.table());
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
    let mut dataset = datasets::load_with(&args.data, args.frame.cell_data)?;
    let tf = args.frame.transfer_function(&dataset)?;
    let specs = sweep::pareto_specs(registry, &args.methods, dataset.kind(), &args.frame.method.pairs())?;
    let out_dir = args.out.clone().unwrap_or_else(|| PathBuf::from(format!("results/runs/pareto-{}", dataset.name)));
    check_out_dir(&out_dir, &["pareto.csv", "pareto.md", "pareto.json", "pareto.png"], &[])?;
    let ctx = context(cli)?;
    cfg.check_device(&ctx.info)?;
    let _lock = fsio::lock_out_dir("--out", &out_dir)?;
    let points = sweep::pareto(&ctx, &mut dataset, &tf, &specs, &cfg, &out_dir)?;
    out!("{}", volbench::harness::pareto::markdown(&dataset.name, &points));
    outln!("written: {}/pareto.{{csv,md,json,png}}", out_dir.display());
    let failed = points.iter().filter(|p| p.error.is_some() && !p.skipped).count();
    if failed > 0 {
        bail!("{failed} of {} sweep runs failed (see pareto.md)", points.len());
    }
    Ok(())
}

fn stress(cli: &Cli, registry: &Registry, args: &StressArgs) -> Result<()> {
    use volbench::harness::stress::{describe_cases, failures, run_cases_with_progress, stress_cases, stress_table, StressConfig, StressReport};
    if !(16..=2048).contains(&args.size) || !args.size.is_multiple_of(2) {
        bail!("--size must be even and within 16..=2048 (the f64 reference renders every pixel on the CPU), got {}", args.size);
    }
    if args.describe {
        out!("{}", describe_cases(args.size));
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
    let mut cases = stress_cases(args.size);
    if !args.cases.is_empty() {
        for c in &args.cases {
            anyhow::ensure!(cases.iter().any(|k| &k.name == c), "--case: no stress case '{c}' (see --describe)");
        }
        cases.retain(|k| args.cases.contains(&k.name));
    }
    let _images_lock = args.images.as_deref().map(|dir| fsio::lock_out_dir("--images", dir)).transpose()?;
    if let Some(dir) = &args.images {
        cfg.images = Some(dir.clone());
    }
    let ctx = context(cli)?;
    let mut done = Vec::new();
    // The JSON is rewritten as each row completes; a write that fails ends
    // the run at once (the path was probed up front, so this is rare).
    let rows = run_cases_with_progress(&ctx, &cases, &cfg, |row| {
        done.push(row.clone());
        if done.len() % 50 == 0 {
            volbench::progress!("volbench: stress: {} renders ({} ...)", done.len(), row.case);
        }
        match &args.json {
            Some(p) => report::write_json(p, &StressReport { cases: done.clone() }),
            None => Ok(()),
        }
    })?;
    out!("{}", stress_table(&rows));
    let failed = failures(&rows);
    let non_finite: usize = rows.iter().map(|r| r.nan_pixels + r.inf_pixels).sum();
    outln!("{} renders, {} NaN/Inf pixels, {} failed", rows.len(), non_finite, failed);
    if failed > 0 {
        bail!("{failed} stress renders failed or exceeded their bounds");
    }
    Ok(())
}

fn suite(cli: &Cli, registry: &Registry, args: &SuiteArgs) -> Result<()> {
    use volbench::harness::suite::{plan, run_suite, utc_now, SuiteSettings};
    let settings = SuiteSettings {
        peers: args.peers.clone(),
        rounds: if args.peers.is_empty() { 0 } else { args.rounds.map_or(SuiteSettings::default_rounds(args.quick), usize::from) },
        data: args.data.clone(),
        tf: args.tf.clone(),
        cell_data: args.cell_data,
        ..SuiteSettings::standard(args.quick, args.filter.clone())
    }
        .counted(count::child_dir(args.count)?);
    let plan = plan(registry, &settings)?;
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from(format!("results/{}", utc_now())));
    check_out_dir(&out, &["summary.json", "summary.csv", "report.md"], &["runs", "plots", "peers"])?;
    let ctx = context(cli)?;
    let _lock = fsio::lock_out_dir("--out", &out)?;
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
            volbench::progress!("volbench: suite: [{}/{}] {label}", i + 1, plan.len());
        }
    })?;
    bar.finish_and_clear();
    let failed = summary.runs.iter().filter(|r| r.status == "failed").count();
    let peers_failed = summary.peers.iter().filter(|r| r.status == "failed").count();
    outln!("results: {}", out.display());
    if failed > 0 {
        bail!("{failed} of {} suite runs failed (see report.md)", summary.runs.len());
    }
    if peers_failed > 0 {
        bail!("{peers_failed} of {} peer runs failed (see report.md)", summary.peers.len());
    }
    let rounds_failed = summary.matched.iter().filter(|m| m.message.is_some()).count();
    if rounds_failed > 0 {
        bail!("the rounds of {rounds_failed} of {} peer renderers failed (see report.md)", summary.matched.len());
    }
    Ok(())
}

fn ab(registry: &Registry, args: &AbArgs) -> Result<()> {
    use volbench::harness::ab;
    let seed = args.seed.unwrap_or_else(|| {
        std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos() as u64)
    });
    let mode = if args.per_run { ab::Mode::PerRun } else { ab::Mode::PerFrame };
    let settings = ab::AbSettings {
        mode,
        width: args.size.0,
        height: args.size.1,
        frames: args.frames,
        batch: args.batch,
        processes: args.processes,
        warmup: args.warmup,
        pairs: args.pairs.unwrap_or(if args.per_run { 10 } else { 300 }),
        timeout_s: args.timeout,
        build_timeout_s: args.build_timeout,
        threshold: args.threshold / 100.0,
        seed,
    };
    settings.validate()?;
    let benches = ab::benchmarks(registry, &args.filter, &args.spec)?;
    if let Some(dir) = &args.out {
        check_out_dir(dir, &["ab.json", "ab.md"], &[])?;
    }
    let target = args
        .target_dir
        .clone()
        .or_else(|| std::env::var_os("CARGO_TARGET_DIR").map(PathBuf::from))
        .unwrap_or_else(|| PathBuf::from("target"));
    let env = |option: &str, given: &[String]| -> Result<std::collections::BTreeMap<String, String>> {
        let mut env = std::collections::BTreeMap::new();
        for text in given {
            let (var, value) = ab::parse_env(option, text)?;
            anyhow::ensure!(env.insert(var.clone(), value).is_none(), "{option}: {var} given twice");
        }
        Ok(env)
    };
    let (base_env, new_env) = (env("--base-env", &args.base_env)?, env("--new-env", &args.new_env)?);
    let limit = std::time::Duration::from_secs_f64(settings.timeout_s);
    let build_limit = std::time::Duration::from_secs_f64(settings.build_timeout_s);
    let mut base = ab::resolve(&args.base, "BASE", &target, limit, build_limit)?;
    let mut new = ab::resolve(&args.new, "NEW", &target, limit, build_limit)?;
    base.env = base_env;
    new.env = new_env;
    let _lock = args.out.as_deref().map(|dir| fsio::lock_out_dir("--out", dir)).transpose()?;
    let report = ab::run(&base, &new, &benches, &settings, |b, p| {
        volbench::progress!("volbench: ab: [{}/{}] {} on {}, pair {}/{}", b + 1, benches.len(), benches[b].label, benches[b].dataset, p + 1, settings.pairs);
    }, |note| volbench::progress!("volbench: ab: {note}"))?;
    let table = ab::markdown(&report);
    out!("{table}");
    if let Some(dir) = &args.out {
        let (json, md) = (dir.join("ab.json"), dir.join("ab.md"));
        let json_bytes = report::json_bytes(&report)?;
        fsio::write_all(&[(json.as_path(), json_bytes.as_slice()), (md.as_path(), table.as_bytes())])?;
    }
    let (slower, failed) = (report.regressions(), report.failures());
    if failed > 0 {
        bail!("{failed} of {} benchmarks failed (see the table)", report.rows.len());
    }
    if slower > 0 {
        bail!("{slower} of {} benchmarks slower beyond the {} % threshold", report.rows.len(), args.threshold);
    }
    Ok(())
}

fn scale(registry: &Registry, args: &ScaleArgs) -> Result<()> {
    use volbench::algo::method::DataKind;
    use volbench::harness::scale;
    anyhow::ensure!(args.levels <= 4, "--levels {}: at most 4 (x8 tets per level: 4096 times the input)", args.levels);
    anyhow::ensure!(args.frames >= 1, "--frames must be at least 1");
    let specs = if args.methods.is_empty() {
        registry.for_kind(DataKind::TetMesh).map(|m| registry.parse_spec(m.name, &[])).collect::<Result<Vec<_>>>()?
    } else {
        args.methods.iter().map(|m| registry.parse_spec(m, &[]).with_context(|| format!("--method {m}"))).collect::<Result<Vec<_>>>()?
    };
    for s in &specs {
        s.check_renders(DataKind::TetMesh, &args.data)?;
    }
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from(format!("results/scale-{}", Path::new(&args.data).file_stem().map_or(args.data.clone(), |s| s.to_string_lossy().into_owned()))));
    let files = ["scale.json", "scale.csv", "scale.md", "scale_time.png", "scale_time.svg", "scale_memory.png", "scale_memory.svg"];
    check_out_dir(&out, &files, &["meshes"])?;
    let settings = scale::ScaleSettings {
        dataset: args.data.clone(),
        levels: args.levels,
        specs: specs.iter().map(|s| (s.canonical(), s.label())).collect(),
        width: args.size.0,
        height: args.size.1,
        frames: args.frames,
        warmup: args.warmup,
        reference_max_cells: args.reference_max_cells,
        peers: args.peers.clone(),
        cell_data: args.cell_data,
    };
    let exe = std::env::current_exe().context("locating this volbench binary")?;
    // The study checks its estimate first, creates `out` and writes the
    // results after every level (it takes the --out lock once the estimate fits).
    let report = scale::study(&exe, &settings, &out, |what| volbench::progress!("volbench: scale: {what}"))?;
    out!("{}", scale::markdown(&report));
    outln!("written: {}/scale.{{json,csv,md}}, scale_time.{{png,svg}}, scale_memory.{{png,svg}}, meshes/", out.display());
    let failed = report.rows.iter().filter(|r| r.error.is_some()).count();
    if failed > 0 {
        bail!("{failed} of {} scale runs failed (see scale.md)", report.rows.len());
    }
    Ok(())
}

/// Whether `e` comes from writing to a pipe whose reader has closed it.
fn broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| c.downcast_ref::<std::io::Error>().is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe))
}

/// `--help`, `--version` or a usage error: clap's text, through the one
/// stdout rule (`write_stdout`: a full device is an error, a closed pipe a
/// quiet exit), not clap's own printing, which ignores write errors.
fn parse_failure(e: &clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    if !matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) {
        // A usage error: to standard error, as clap does.
        let _ = e.print();
        return ExitCode::from(u8::try_from(e.exit_code()).unwrap_or(2));
    }
    exit_code(write_stdout(&e.render().to_string()))
}

/// A command's outcome as the process's: an error on standard error and
/// failure, except that a reader gone away (`volbench list | head -1`) is
/// a quiet success, as for a filter: what it wanted it has.
fn exit_code(result: Result<()>) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if broken_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => {
            volbench::progress!("volbench: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn main() -> ExitCode {
    fsio::occupy_closed_stdio();
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return parse_failure(&e),
    };
    // Every VOLBENCH_* switch is checked before any work (a bad value is
    // refused now, not after a suite has run), and the ones that change
    // what is measured are said (they are recorded in the results too).
    if let Err(e) = volbench::switches::check_environment() {
        volbench::progress!("volbench: error: {e}");
        return ExitCode::FAILURE;
    }
    // Said only for the test knobs (every switch is recorded in the results):
    // CI runs everything with VOLBENCH_VALIDATION=1, and serve mode's
    // standard error must stay quiet.
    let set: std::collections::BTreeMap<String, String> =
        volbench::switches::recorded().into_iter().filter(|(k, _)| k.starts_with(volbench::switches::TEST_PREFIX)).collect();
    if !set.is_empty() && !matches!(cli.command, Command::Info | Command::List) {
        let set: Vec<String> = set.iter().map(|(k, v)| format!("{k}={v}")).collect();
        volbench::progress!("volbench: note: set, and recorded in the results: {}", set.join(" "));
    }
    match volbench::mesh::HigherOrder::parse(&cli.higher_order) {
        Ok(m) => volbench::mesh::higher_order::set_mode(m),
        Err(e) => {
            volbench::progress!("volbench: error: {e:#}");
            return ExitCode::FAILURE;
        }
    }
    // `--count`: the same command again, under valgrind.
    let count = match &cli.command {
        Command::Run(a) => a.count,
        Command::Suite(a) => a.count,
        _ => false,
    };
    if count && cli.validation {
        volbench::progress!("volbench: error: --count with --validation: the layer's work would be counted as the method's; validate an uncounted run");
        return ExitCode::FAILURE;
    }
    match count::needs_reexec(count) {
        Ok(false) => {}
        Ok(true) => {
            return count::reexec().unwrap_or_else(|e| {
                volbench::progress!("volbench: error: {e:#}");
                ExitCode::FAILURE
            })
        }
        Err(e) => {
            volbench::progress!("volbench: error: {e:#}");
            return ExitCode::FAILURE;
        }
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
        Command::Ab(a) => ab(&registry, a),
        Command::Scale(a) => scale(&registry, a),
    };
    exit_code(result)
}
