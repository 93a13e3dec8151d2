//! Paired A/B timing (`volbench ab BASE NEW`): two volbench binaries (or two
//! git revisions, built here) run the same benchmarks alternately in one
//! sitting, so whatever else loads the machine hits both alike.
//!
//! Two ways to alternate. **Per frame** (the default): each binary serves
//! each benchmark from one long-lived process (`run --serve`,
//! `harness::serve`) that has loaded the data, built its pipelines and
//! warmed up; both are resident at once and `ab` asks them in turn for one
//! frame (or a small batch), in an order drawn per pair from a seeded
//! generator, so the two samples of a pair are taken milliseconds apart and
//! see the same camera. **Per run** (`--per-run`, and the fallback for a
//! binary without serve mode): a pair is one fresh `volbench run` process
//! of each, the sample the median of its timed frames.
//!
//! The estimate is a t interval on the pairs' log ratios
//! `ln(new_i / base_i)`: ratio `exp(mean)`, 95 % interval
//! `exp(mean ± t(0.975, b-1)·sd_b/√b)` over `b` non-overlapping batch means
//! of consecutive log ratios (batch means, because consecutive frames of
//! one sitting are correlated: a load spike spans several; per run, every
//! pair is its own batch). The verdict holds the interval against a
//! slowdown threshold `T`: wholly above `1+T` slower (a regression: the
//! command fails), wholly below `1/(1+T)` faster, wholly inside both
//! "same", and otherwise undecided: the machine was too noisy for this many
//! pairs.

use std::collections::BTreeMap;
use std::os::unix::fs::PermissionsExt as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use anyhow::{bail, ensure, Context as _, Result};
use serde::{Deserialize, Serialize};

use super::child;
use super::datasets::NAMED;
use super::serve::{Server, StartError};
use crate::algo::registry::Registry;

/// The shipped dataset each kind's benchmarks run on by default: the
/// cheapest of its kind (seconds per pair, not minutes).
pub const CHEAP_DATASETS: &[&str] = &["post-small", "headsq", "jacksboro"];

/// One benchmark: a method spec on a shipped dataset.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Benchmark {
    pub dataset: String,
    /// The spec each binary is given: the method and the options that
    /// differ from its defaults (`name:key=value,...`). Each build applies
    /// its own defaults to the rest, so a build that adds an option can be
    /// compared with one that lacks it, and a changed default is part of
    /// what is compared.
    pub spec: String,
    /// How tables name it (the spec's label).
    pub label: String,
}

/// The benchmarks of `volbench ab`: every registered method at its
/// defaults (or each of `specs` instead) on the cheapest shipped dataset of
/// its kind and on every shipped dataset `filter` names, keeping those
/// whose method or dataset `filter` names (suite semantics; empty keeps all).
pub fn benchmarks(registry: &Registry, filter: &[String], specs: &[String]) -> Result<Vec<Benchmark>> {
    for f in filter {
        let known = NAMED.iter().any(|d| d.name == f) || registry.names().contains(&f.as_str());
        ensure!(known, "--filter {f}: neither a registered method nor a shipped dataset (see `volbench list`)");
    }
    let parsed = if specs.is_empty() {
        registry.methods().iter().map(|m| registry.parse_spec(m.name, &[])).collect::<Result<Vec<_>>>()?
    } else {
        specs.iter().map(|s| registry.parse_spec(s, &[]).with_context(|| format!("--spec {s}"))).collect::<Result<Vec<_>>>()?
    };
    let keep = |name: &str| filter.is_empty() || filter.iter().any(|f| f == name);
    let mut out = Vec::new();
    for d in NAMED.iter().filter(|d| CHEAP_DATASETS.contains(&d.name) || filter.iter().any(|f| f == d.name)) {
        for spec in parsed.iter().filter(|s| s.info.data == d.kind) {
            if keep(d.name) || keep(spec.info.name) {
                out.push(Benchmark { dataset: d.name.to_string(), spec: spec.label(), label: spec.label() });
            }
        }
    }
    ensure!(!out.is_empty(), "--filter {filter:?} with --spec {specs:?} leaves no benchmark to run");
    Ok(out)
}

/// A volbench binary taking part, and where it came from.
#[derive(Debug, Clone, Serialize)]
pub struct Binary {
    pub path: PathBuf,
    /// `volbench --version` of it.
    pub version: String,
    /// The git revision it was built from, when `ab` built it.
    pub revision: Option<String>,
    /// Environment variables set for this side's processes only
    /// (`--base-env`, `--new-env`): e.g. a driver setting measured with the
    /// same binary on both sides.
    pub env: BTreeMap<String, String>,
}

/// `arg` (BASE or NEW, named `role` in errors) as a binary: an existing
/// path is a file to run (relative to the working directory, never looked
/// up in `PATH`), which must be executable; anything else a git revision
/// of the repository around the working directory, built with
/// `cargo build --release` in a temporary worktree with `target_dir` as
/// the target directory (so the second build reuses the first's
/// dependencies). Built binaries are kept as
/// `target_dir/ab/volbench-<commit>` and reused. Every child (the binary's
/// `--version`, git) must finish within `timeout` (`--timeout`), the build
/// within `build_timeout` (`--build-timeout`).
pub fn resolve(arg: &str, role: &str, target_dir: &Path, timeout: Duration, build_timeout: Duration) -> Result<Binary> {
    let path = Path::new(arg);
    if path.exists() {
        ensure!(path.is_file(), "{role} {arg}: is not a file (give a volbench binary or a git revision)");
        let mode = std::fs::metadata(path).with_context(|| format!("{role} {arg}"))?.permissions().mode();
        ensure!(mode & 0o111 != 0, "{role} {arg}: not executable (a file without execute permission, mode {:o})", mode & 0o7777);
        // Absolute, so that `vb` is this file and not a `vb` in PATH.
        let path = path.canonicalize().with_context(|| format!("{role} {arg}"))?;
        let version = version_of(&path, timeout).with_context(|| format!("{role} {arg}"))?;
        return Ok(Binary { path, version, revision: None, env: BTreeMap::new() });
    }
    let commit = git(&["rev-parse", "--verify", "--quiet", &format!("{arg}^{{commit}}")], timeout)
        .ok()
        .filter(|s| !s.is_empty())
        .with_context(|| format!("{role} {arg}: neither an existing file nor a git revision of this repository"))?;
    let binary = build_revision(&commit, target_dir, timeout, build_timeout).with_context(|| format!("{role} {arg}: building revision {commit}"))?;
    let version = version_of(&binary, timeout).with_context(|| format!("{role} {arg}: the binary built from {commit}"))?;
    Ok(Binary { path: binary, version, revision: Some(commit), env: BTreeMap::new() })
}

/// The most a `--version` may print: volbench prints one short line.
const MAX_VERSION_BYTES: u64 = 64 * 1024;

/// `volbench --version` of `path`, or an error if it is not volbench (or
/// does not finish within `timeout`, or prints more than a version).
fn version_of(path: &Path, timeout: Duration) -> Result<String> {
    let out = child::run(Command::new(path).arg("--version"), "`--version`", timeout, "--timeout", Some(MAX_VERSION_BYTES))?;
    let stdout = out.stdout.text();
    let text = crate::fsio::clip_message(stdout.lines().next().unwrap_or("").trim());
    ensure!(out.status.success() && text.starts_with("volbench "), "is not a volbench binary (`--version` printed {text:?})");
    Ok(text)
}

fn git(args: &[&str], timeout: Duration) -> Result<String> {
    let what = format!("git {}", args.join(" "));
    let out = child::run(Command::new("git").args(args), &what, timeout, "--timeout", None)?;
    ensure!(out.status.success(), "{what}: {}", out.stderr_text());
    ensure!(!out.stdout.clipped(), "{what}: printed {} bytes, more than expected", out.stdout.total());
    Ok(out.stdout.text().trim().to_string())
}

fn build_revision(commit: &str, target_dir: &Path, timeout: Duration, build_timeout: Duration) -> Result<PathBuf> {
    let dir = target_dir.join("ab");
    let binary = dir.join(format!("volbench-{commit}"));
    if binary.is_file() {
        return Ok(binary);
    }
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    // Absolute: cargo runs in the temporary worktree.
    let target_dir = &target_dir.canonicalize().with_context(|| format!("target directory {}", target_dir.display()))?;
    let dir = target_dir.join("ab");
    let binary = dir.join(format!("volbench-{commit}"));
    let tree = dir.join(format!("src-{commit}"));
    let tree_s = tree.to_string_lossy().to_string();
    if tree.exists() {
        // A worktree an interrupted build left behind.
        let _ = git(&["worktree", "remove", "--force", &tree_s], timeout);
    }
    git(&["worktree", "add", "--detach", &tree_s, commit], timeout)?;
    crate::progress!("volbench: ab: building {commit} (cargo build --release, target dir {})", target_dir.display());
    // Its progress goes to the terminal; it stays in our process group
    // (a Ctrl-C stops it too) and is killed with its rustc jobs at the deadline.
    let status = child::run_attached(
        Command::new(std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into()))
            .args(["build", "--release", "--locked", "--bin", "volbench"])
            .current_dir(&tree)
            .env("CARGO_TARGET_DIR", target_dir)
            .stdin(std::process::Stdio::null()),
        "cargo build --release",
        build_timeout,
        "--build-timeout",
    );
    let built = target_dir.join("release").join("volbench");
    let copied = match status {
        Ok(s) if s.success() => std::fs::copy(&built, &binary).with_context(|| format!("copying {} to {}", built.display(), binary.display())),
        Ok(s) => Err(anyhow::anyhow!("cargo build --release failed ({s})")),
        Err(e) => Err(e),
    };
    // The worktree goes either way; the binary reads data from VOLBENCH_DATA.
    let removed = git(&["worktree", "remove", "--force", &tree_s], timeout);
    copied?;
    removed?;
    Ok(binary)
}

/// How the two binaries alternate.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Mode {
    /// Resident serve processes, one per binary, started afresh for each of
    /// several rounds; pairs of single frames (or batches) within a round.
    PerFrame,
    /// One fresh process per sample.
    PerRun,
}

/// How the runs are made.
#[derive(Debug, Clone, Serialize)]
pub struct AbSettings {
    pub mode: Mode,
    pub width: u32,
    pub height: u32,
    /// Per run: timed frames per run (the sample is their median).
    pub frames: usize,
    /// Per frame: frames per alternation step (the sample is their median).
    pub batch: usize,
    /// Untimed frames first (per run: in every run; per frame: once per server).
    pub warmup: usize,
    /// Samples per binary and benchmark.
    pub pairs: usize,
    /// Per frame: rounds of fresh serve processes the pairs are shared out
    /// over. Two processes of one binary can differ by several per cent for
    /// their whole life (measured: the same build against itself, 1.09 over
    /// 300 frame pairs in one pair of processes), so the interval is over
    /// the rounds' mean log ratios, not over frames of one pair of processes.
    pub processes: usize,
    /// How long a serve process may take to answer (its handshake included)
    /// before it is killed.
    pub timeout_s: f64,
    /// How long building a revision (`cargo build --release`) may take.
    pub build_timeout_s: f64,
    /// The slowdown threshold, as a fraction (0.03: 3 %).
    pub threshold: f64,
    /// Seeds the per-pair order (recorded so a sitting can be repeated).
    pub seed: u64,
}

impl AbSettings {
    pub fn validate(&self) -> Result<()> {
        ensure!(self.pairs >= 2, "--pairs must be at least 2 (an interval needs two pairs), got {}", self.pairs);
        ensure!(self.pairs <= 10_000, "--pairs {} is more than 10000", self.pairs);
        ensure!(self.frames >= 1, "--frames must be at least 1");
        if self.mode == Mode::PerFrame {
            ensure!(
                (2..=self.pairs).contains(&self.processes),
                "--processes must be from 2 to --pairs ({}), got {}",
                self.pairs,
                self.processes
            );
        }
        ensure!(
            (1..=super::serve::MAX_BATCH).contains(&self.batch),
            "--batch must be from 1 to {}, got {}",
            super::serve::MAX_BATCH,
            self.batch
        );
        ensure!(
            self.timeout_s.is_finite() && self.timeout_s >= 0.1 && self.timeout_s <= 86_400.0,
            "--timeout must be from 0.1 to 86400 seconds, got {}",
            self.timeout_s
        );
        ensure!(
            self.build_timeout_s.is_finite() && self.build_timeout_s >= 1.0 && self.build_timeout_s <= 86_400.0,
            "--build-timeout must be from 1 to 86400 seconds, got {}",
            self.build_timeout_s
        );
        ensure!(
            self.threshold.is_finite() && self.threshold > 0.0 && self.threshold < 10.0,
            "--threshold must be a percentage above 0 and below 1000, got {}",
            self.threshold * 100.0
        );
        Ok(())
    }
}

/// One pair's samples (ms: the median frame time of each run, or of each
/// batch per frame).
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct Pair {
    pub base_ms: f64,
    pub new_ms: f64,
    /// NEW ran first in this pair.
    pub new_first: bool,
}

/// The paired estimate of NEW/BASE.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct Estimate {
    pub pairs: usize,
    /// Batches of consecutive pairs whose mean log ratios the interval is on.
    pub batches: usize,
    /// Lag-1 autocorrelation of the pairs' log ratios in sitting order (how
    /// much consecutive pairs share; none below 3 pairs or without spread).
    pub lag1_autocorrelation: Option<f64>,
    /// exp(mean log ratio): the geometric mean of the pairs' ratios.
    pub ratio: f64,
    pub ci_low: f64,
    pub ci_high: f64,
    pub mean_log_ratio: f64,
    /// Standard deviation of the batch means of the log ratios.
    pub sd_log_ratio: f64,
    /// Standard deviation of the pairs' own log ratios (the spread of one
    /// pair: 0.05 is about ±5 %).
    pub sd_pair_log_ratio: f64,
}

/// What an interval says against the threshold.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    Slower,
    Faster,
    Same,
    Undecided,
}

impl Verdict {
    pub fn describe(self, threshold: f64) -> String {
        let t = threshold * 100.0;
        match self {
            Verdict::Slower => format!("SLOWER: beyond the {t:.1} % threshold"),
            Verdict::Faster => format!("faster: beyond {t:.1} %"),
            Verdict::Same => format!("same: within ±{t:.1} %"),
            Verdict::Undecided => format!("undecided: too noisy to decide at {t:.1} % (more --pairs or a quieter machine)"),
        }
    }
}

/// t quantile (0.975) for `df` degrees of freedom: the table below to 30,
/// the Cornish-Fisher expansion in 1/df beyond (within 1e-4 there).
pub fn t_975(df: usize) -> f64 {
    const TABLE: [f64; 30] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160, 2.145, 2.131, 2.120, 2.110,
        2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042,
    ];
    if (1..=30).contains(&df) {
        return TABLE[df - 1];
    }
    let (z, v) = (1.959_963_984_540_054_f64, df.max(1) as f64);
    let (z3, z5, z7) = (z.powi(3), z.powi(5), z.powi(7));
    z + (z3 + z) / (4.0 * v) + (5.0 * z5 + 16.0 * z3 + 3.0 * z) / (96.0 * v * v)
        + (3.0 * z7 + 19.0 * z5 + 17.0 * z3 - 15.0 * z) / (384.0 * v * v * v)
}

/// The paired estimate from `pairs` (at least two, every sample positive)
/// over `batches` batches of consecutive pairs (2 ≤ batches ≤ pairs; equal
/// to `pairs`: every pair its own).
pub fn estimate(pairs: &[Pair], batches: usize) -> Result<Estimate> {
    ensure!(pairs.len() >= 2, "{} pair(s): an interval needs at least two", pairs.len());
    ensure!((2..=pairs.len()).contains(&batches), "{batches} batches of {} pairs", pairs.len());
    let mut logs = Vec::with_capacity(pairs.len());
    for p in pairs {
        ensure!(
            p.base_ms.is_finite() && p.new_ms.is_finite() && p.base_ms > 0.0 && p.new_ms > 0.0,
            "a sample is not a positive time (base {} ms, new {} ms)",
            p.base_ms,
            p.new_ms
        );
        logs.push((p.new_ms / p.base_ms).ln());
    }
    // Batch j holds pairs [j·n/b, (j+1)·n/b): sizes differ by at most one.
    let n = logs.len();
    let means: Vec<f64> = (0..batches)
        .map(|j| {
            let part = &logs[j * n / batches..(j + 1) * n / batches];
            part.iter().sum::<f64>() / part.len() as f64
        })
        .collect();
    let sd_pair = {
        let m = logs.iter().sum::<f64>() / n as f64;
        (logs.iter().map(|l| (l - m).powi(2)).sum::<f64>() / (n as f64 - 1.0)).sqrt()
    };
    let b = batches as f64;
    let mean = means.iter().sum::<f64>() / b;
    let sd = (means.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / (b - 1.0)).sqrt();
    let half = t_975(batches - 1) * sd / b.sqrt();
    Ok(Estimate {
        pairs: n,
        batches,
        lag1_autocorrelation: lag1(&logs),
        ratio: mean.exp(),
        ci_low: (mean - half).exp(),
        ci_high: (mean + half).exp(),
        mean_log_ratio: mean,
        sd_log_ratio: sd,
        sd_pair_log_ratio: sd_pair,
    })
}

/// Lag-1 autocorrelation of `x` (none below 3 values or without spread).
pub fn lag1(x: &[f64]) -> Option<f64> {
    if x.len() < 3 {
        return None;
    }
    let m = x.iter().sum::<f64>() / x.len() as f64;
    let var: f64 = x.iter().map(|v| (v - m).powi(2)).sum();
    let cov: f64 = x.windows(2).map(|w| (w[0] - m) * (w[1] - m)).sum();
    (var > 0.0).then(|| cov / var)
}

/// The interval held against a slowdown `threshold` (fraction).
pub fn decide(e: &Estimate, threshold: f64) -> Verdict {
    let (up, down) = (1.0 + threshold, 1.0 / (1.0 + threshold));
    if e.ci_low > up {
        Verdict::Slower
    } else if e.ci_high < down {
        Verdict::Faster
    } else if e.ci_low >= down && e.ci_high <= up {
        Verdict::Same
    } else {
        Verdict::Undecided
    }
}

/// The pair orders: a splitmix64 stream from the seed, one bit per pair.
pub struct Order(u64);

impl Order {
    pub fn new(seed: u64) -> Self {
        Order(seed)
    }

    pub fn new_first(&mut self) -> bool {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        (z ^ (z >> 31)) & 1 == 1
    }
}

/// One benchmark's outcome.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct AbRow {
    #[serde(flatten)]
    pub benchmark: Benchmark,
    /// How this benchmark alternated (per run after a fallback).
    pub mode: Mode,
    /// Why per-frame alternation fell back to per run.
    pub fallback: Option<String>,
    pub samples: Vec<Pair>,
    pub estimate: Option<Estimate>,
    pub verdict: Option<Verdict>,
    /// Why the benchmark has no estimate (a run failed).
    pub error: Option<String>,
}

/// `ab.json`.
#[derive(Debug, Clone, Serialize)]
pub struct AbReport {
    pub schema: &'static str,
    pub base: Binary,
    pub new: Binary,
    pub settings: AbSettings,
    /// How the interval is computed (the module note, in short).
    pub statistic: String,
    pub rows: Vec<AbRow>,
}

/// The statistic of `mode`, as reports state it.
pub fn statistic(mode: Mode) -> String {
    match mode {
        Mode::PerFrame => "per frame: in each of several rounds a fresh resident serve process per binary, single frames (or batches) alternated \
                           in random pair order; 95 % t interval on ln(new/base) over the rounds' means (a process's own bias is in the spread)"
            .into(),
        Mode::PerRun => "per run: one fresh process per sample (median of its frames), pair order randomised; \
                         paired 95 % t interval on ln(new/base)"
            .into(),
    }
}

impl AbReport {
    pub fn regressions(&self) -> usize {
        self.rows.iter().filter(|r| r.verdict == Some(Verdict::Slower)).count()
    }

    pub fn failures(&self) -> usize {
        self.rows.iter().filter(|r| r.error.is_some()).count()
    }
}

/// `VAR=VALUE` (an `--base-env` / `--new-env` value) as a pair; `option`
/// names it in the error.
pub fn parse_env(option: &str, text: &str) -> Result<(String, String)> {
    let (var, value) = text.split_once('=').with_context(|| format!("{option} {text}: expected VAR=VALUE"))?;
    ensure!(!var.is_empty() && !var.contains('\0') && !value.contains('\0'), "{option} {text}: expected VAR=VALUE with a non-empty name and no NUL");
    Ok((var.to_string(), value.to_string()))
}

/// The largest run JSON `ab` reads back (a run of 10,000 frames writes
/// about 2 MB).
const MAX_RUN_JSON_BYTES: u64 = 64 << 20;

/// The median frame time (ms) of one `volbench run` of `bench` by `binary`,
/// which must finish within `--timeout`; its output is kept head and tail.
fn sample(binary: &Binary, bench: &Benchmark, s: &AbSettings, scratch: &Path) -> Result<f64> {
    let json = scratch.join("run.json");
    let _ = std::fs::remove_file(&json);
    let what = format!("{} run", binary.path.display());
    let mut cmd = Command::new(&binary.path);
    cmd.args(["run", "--data", &bench.dataset, "--method", &bench.spec])
        .args(["--size", &format!("{}x{}", s.width, s.height)])
        .args(["--frames", &s.frames.to_string(), "--warmup", &s.warmup.to_string(), "--json"])
        .arg(&json)
        .env("VOLBENCH_DATA", super::datasets::data_dir())
        .envs(&binary.env);
    let out = child::run(&mut cmd, &what, Duration::from_secs_f64(s.timeout_s), "--timeout", None)?;
    if !out.status.success() {
        bail!("{what} failed ({}): {}", out.status, out.stderr_text());
    }
    let text = crate::fsio::read_input_text(&json, "run JSON", MAX_RUN_JSON_BYTES)?;
    let v: serde_json::Value = serde_json::from_str(&text).with_context(|| format!("{}: not JSON", json.display()))?;
    let frames: Vec<f64> = v
        .pointer("/time_ms/samples/frame")
        .and_then(|f| f.as_array())
        .context("the run's JSON has no time_ms.samples.frame")?
        .iter()
        .filter_map(|x| x.as_f64())
        .collect();
    ensure!(!frames.is_empty(), "the run's JSON has no frame samples");
    Ok(super::stats::Summary::of(&frames).median)
}

/// The arguments of `run --serve` for `bench`.
fn serve_args(bench: &Benchmark, s: &AbSettings) -> Vec<String> {
    [
        "--data",
        &bench.dataset,
        "--method",
        &bench.spec,
        "--size",
        &format!("{}x{}", s.width, s.height),
        "--warmup",
        &s.warmup.to_string(),
        "--fixed-frames",
        "0",
    ]
    .iter()
    .map(|a| a.to_string())
    .collect()
}

/// Per frame: `processes` rounds, each with a fresh server per binary
/// (started in seeded order) and its share of the `pairs` batches of each in
/// seeded order; the pairs come back round after round, so the estimate's
/// batches are the rounds. `Err(Ok(reason))`: a binary has no serve mode
/// (fall back).
fn frame_pairs(
    base: &Binary,
    new: &Binary,
    bench: &Benchmark,
    s: &AbSettings,
    order: &mut Order,
    mut progress: impl FnMut(usize),
) -> std::result::Result<Vec<Pair>, std::result::Result<String, anyhow::Error>> {
    let timeout = Duration::from_secs_f64(s.timeout_s);
    let args = serve_args(bench, s);
    let start = |b: &Binary| match Server::start(&b.path, &b.env, &args, timeout) {
        Ok(server) => Ok(server),
        Err(StartError::Unsupported(why)) => Err(Ok(why)),
        Err(StartError::Failed(e)) => Err(Err(e)),
    };
    let median = |v: Vec<f64>| super::stats::Summary::of(&v).median;
    let mut pairs = Vec::with_capacity(s.pairs);
    for round in 0..s.processes {
        // Both resident before the round's first timed frame.
        let (mut base_server, mut new_server) = if order.new_first() {
            let n = start(new)?;
            (start(base)?, n)
        } else {
            let b = start(base)?;
            (b, start(new)?)
        };
        for _ in round * s.pairs / s.processes..(round + 1) * s.pairs / s.processes {
            progress(pairs.len());
            let new_first = order.new_first();
            let (first, second) = if new_first { (&mut new_server, &mut base_server) } else { (&mut base_server, &mut new_server) };
            let a = median(first.frames(s.batch).map_err(Err)?);
            let b = median(second.frames(s.batch).map_err(Err)?);
            let (new_ms, base_ms) = if new_first { (a, b) } else { (b, a) };
            pairs.push(Pair { base_ms, new_ms, new_first });
        }
        base_server.quit().map_err(Err)?;
        new_server.quit().map_err(Err)?;
    }
    Ok(pairs)
}

/// Per run: `pairs` fresh runs of each binary, in seeded order.
fn run_pairs(
    base: &Binary,
    new: &Binary,
    bench: &Benchmark,
    s: &AbSettings,
    order: &mut Order,
    scratch: &Path,
    mut progress: impl FnMut(usize),
) -> Result<Vec<Pair>> {
    let mut pairs = Vec::with_capacity(s.pairs);
    for p in 0..s.pairs {
        progress(p);
        let new_first = order.new_first();
        let pair = if new_first {
            let new_ms = sample(new, bench, s, scratch)?;
            Pair { new_ms, base_ms: sample(base, bench, s, scratch)?, new_first }
        } else {
            let base_ms = sample(base, bench, s, scratch)?;
            Pair { base_ms, new_ms: sample(new, bench, s, scratch)?, new_first }
        };
        pairs.push(pair);
    }
    Ok(pairs)
}

/// Every benchmark, `pairs` samples per binary, alternating; `progress`
/// gets (benchmark index, pair index) now and then, and `note` the
/// fallbacks.
pub fn run(
    base: &Binary,
    new: &Binary,
    benches: &[Benchmark],
    settings: &AbSettings,
    mut progress: impl FnMut(usize, usize),
    mut note: impl FnMut(&str),
) -> Result<AbReport> {
    settings.validate()?;
    // Per run's JSON goes here: a fresh directory of ours (created
    // exclusively under a random name, mode 0700), removed when dropped.
    let scratch_dir = crate::fsio::scratch_dir("volbench-ab-")?;
    let scratch = scratch_dir.path();
    let mut order = Order::new(settings.seed);
    let every = (settings.pairs / 10).max(1);
    let mut rows = Vec::new();
    for (b, bench) in benches.iter().enumerate() {
        let mut tick = |p: usize| {
            if p.is_multiple_of(every) {
                progress(b, p)
            }
        };
        let (mut mode, mut fallback) = (settings.mode, None);
        let mut sampled = match settings.mode {
            Mode::PerRun => None,
            Mode::PerFrame => match frame_pairs(base, new, bench, settings, &mut order, &mut tick) {
                Ok(pairs) => Some(Ok(pairs)),
                Err(Err(e)) => Some(Err(e)),
                Err(Ok(why)) => {
                    note(&format!("{why}: falling back to per-run alternation ({} frames per run) for {} on {}", settings.frames, bench.label, bench.dataset));
                    (mode, fallback) = (Mode::PerRun, Some(why));
                    None
                }
            },
        };
        if sampled.is_none() {
            sampled = Some(run_pairs(base, new, bench, settings, &mut order, scratch, &mut tick));
        }
        // Per frame the batches are the rounds (`frame_pairs` shares the
        // pairs out over them as `estimate` splits them).
        let batches = |n: usize| if mode == Mode::PerRun { n } else { settings.processes };
        let (samples, estimate) = match sampled {
            Some(Ok(samples)) => {
                let e = estimate(&samples, batches(samples.len()));
                (samples, e)
            }
            Some(Err(e)) => (Vec::new(), Err(e)),
            None => (Vec::new(), Err(anyhow::anyhow!("no samples"))),
        };
        let (estimate, error) = match estimate {
            Ok(e) => (Some(e), None),
            Err(e) => (None, Some(format!("{e:#}"))),
        };
        let verdict = estimate.as_ref().map(|e| decide(e, settings.threshold));
        rows.push(AbRow { benchmark: bench.clone(), mode, fallback, samples, estimate, verdict, error });
    }
    drop(scratch_dir);
    Ok(AbReport {
        schema: "volbench-ab/2",
        base: base.clone(),
        new: new.clone(),
        settings: settings.clone(),
        statistic: statistic(settings.mode),
        rows,
    })
}

/// The report as a Markdown table (also what stdout shows).
pub fn markdown(r: &AbReport) -> String {
    let s = &r.settings;
    let env = |b: &Binary| b.env.iter().map(|(k, v)| format!(" {k}={v}")).collect::<String>();
    let mut out = format!(
        "BASE {} ({}){}\nNEW  {} ({}){}\n{} pairs per benchmark at {}x{}, {}, seed {}\n{}; threshold {:.1} %\n\n",
        r.base.path.display(),
        r.base.revision.as_deref().unwrap_or(&r.base.version),
        env(&r.base),
        r.new.path.display(),
        r.new.revision.as_deref().unwrap_or(&r.new.version),
        env(&r.new),
        s.pairs,
        s.width,
        s.height,
        match s.mode {
            Mode::PerFrame => format!("{} frame(s) per sample after {} warm-up frame(s) per server", s.batch, s.warmup),
            Mode::PerRun => format!("{} timed frames (+{} warm-up) per run", s.frames, s.warmup),
        },
        s.seed,
        r.statistic,
        s.threshold * 100.0
    );
    out += "| dataset | benchmark | alternation | pairs | batches | pair spread | lag-1 | BASE median ms | NEW median ms | NEW/BASE | 95 % interval | verdict |\n";
    out += "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|---|\n";
    for row in &r.rows {
        let med = |f: fn(&Pair) -> f64| {
            let v: Vec<f64> = row.samples.iter().map(f).collect();
            if v.is_empty() {
                "-".to_string()
            } else {
                format!("{:.2}", super::stats::Summary::of(&v).median)
            }
        };
        let (ratio, ci, verdict) = match (&row.estimate, row.verdict, &row.error) {
            (Some(e), Some(v), _) => {
                (format!("{:.3}", e.ratio), format!("[{:.3}, {:.3}]", e.ci_low, e.ci_high), v.describe(s.threshold))
            }
            (_, _, Some(err)) => ("-".into(), "-".into(), format!("failed: {}", super::report::md_cell(err))),
            _ => ("-".into(), "-".into(), "-".into()),
        };
        let (batches, spread, lag) = match &row.estimate {
            Some(e) => (
                e.batches.to_string(),
                format!("±{:.1} %", e.sd_pair_log_ratio * 100.0),
                e.lag1_autocorrelation.map_or("-".into(), |r| format!("{r:.2}")),
            ),
            None => ("-".into(), "-".into(), "-".into()),
        };
        let mode = match (row.mode, &row.fallback) {
            (Mode::PerFrame, _) => "per frame",
            (Mode::PerRun, None) => "per run",
            (Mode::PerRun, Some(_)) => "per run (fallback: no serve mode)",
        };
        out += &format!(
            "| {} | {} | {mode} | {} | {batches} | {spread} | {lag} | {} | {} | {ratio} | {ci} | {verdict} |\n",
            row.benchmark.dataset,
            row.benchmark.label,
            row.samples.len(),
            med(|p| p.base_ms),
            med(|p| p.new_ms)
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pairs(ratios: &[f64]) -> Vec<Pair> {
        ratios.iter().enumerate().map(|(i, r)| Pair { base_ms: 10.0 + i as f64, new_ms: (10.0 + i as f64) * r, new_first: i % 2 == 0 }).collect()
    }

    #[test]
    fn t_quantiles_match_the_tables() {
        assert_eq!(t_975(1), 12.706);
        assert_eq!(t_975(9), 2.262);
        // Beyond the table: 40 -> 2.0211, 60 -> 2.0003, 120 -> 1.9799.
        for (df, t) in [(40, 2.0211), (60, 2.0003), (120, 1.9799), (31, 2.0395)] {
            assert!((t_975(df) - t).abs() < 2e-4, "df {df}: {}", t_975(df));
        }
    }

    #[test]
    fn identical_samples_are_the_same() {
        let e = estimate(&pairs(&[1.0; 5]), 5).unwrap();
        assert_eq!((e.ratio, e.ci_low, e.ci_high), (1.0, 1.0, 1.0));
        assert_eq!(decide(&e, 0.03), Verdict::Same);
    }

    #[test]
    fn interval_is_the_paired_t_interval_of_the_log_ratios() {
        // Log ratios ln 1.1 ± 0.01: mean ln 1.1, sd 0.01 (n = 4: the two
        // deviations +-0.01 twice), half width t(3) * 0.01 / 2.
        let l = 1.1f64.ln();
        let r: Vec<f64> = [l + 0.01, l - 0.01, l + 0.01, l - 0.01].iter().map(|x: &f64| x.exp()).collect();
        let e = estimate(&pairs(&r), 4).unwrap();
        let sd = (4.0 * 0.01f64.powi(2) / 3.0).sqrt();
        assert!((e.sd_log_ratio - sd).abs() < 1e-12);
        assert!((e.ratio - 1.1).abs() < 1e-12);
        let half = 3.182 * sd / 2.0;
        assert!((e.ci_low - (l - half).exp()).abs() < 1e-12 && (e.ci_high - (l + half).exp()).abs() < 1e-12);
        assert_eq!(decide(&e, 0.03), Verdict::Slower);
        assert_eq!(decide(&e, 0.15), Verdict::Same);
    }

    #[test]
    fn verdicts() {
        // 5 % slower with 0.5 % noise over 10 pairs: slower at 3 %.
        let noise = [0.005, -0.004, 0.003, -0.005, 0.001, -0.002, 0.004, -0.003, 0.002, -0.001];
        let slow: Vec<f64> = noise.iter().map(|n| 1.05 * (1.0 + n)).collect();
        assert_eq!(decide(&estimate(&pairs(&slow), 10).unwrap(), 0.03), Verdict::Slower);
        let fast: Vec<f64> = noise.iter().map(|n| 0.9 * (1.0 + n)).collect();
        assert_eq!(decide(&estimate(&pairs(&fast), 10).unwrap(), 0.03), Verdict::Faster);
        let same: Vec<f64> = noise.iter().map(|n| 1.0 + n).collect();
        assert_eq!(decide(&estimate(&pairs(&same), 10).unwrap(), 0.03), Verdict::Same);
        // The same mean slowdown with 20 % noise: too noisy to say.
        let noisy: Vec<f64> = noise.iter().map(|n| 1.05 * (1.0 + 40.0 * n)).collect();
        assert_eq!(decide(&estimate(&pairs(&noisy), 10).unwrap(), 0.03), Verdict::Undecided);
        // A narrow interval that straddles the threshold is undecided too.
        let edge: Vec<f64> = noise.iter().map(|n| 1.03 * (1.0 + n)).collect();
        assert_eq!(decide(&estimate(&pairs(&edge), 10).unwrap(), 0.03), Verdict::Undecided);
    }

    #[test]
    fn bad_samples_are_errors() {
        assert!(estimate(&pairs(&[1.0]), 1).is_err());
        assert!(estimate(&[Pair { base_ms: 0.0, new_ms: 1.0, new_first: false }; 3], 3).is_err());
        assert!(estimate(&[Pair { base_ms: 1.0, new_ms: f64::NAN, new_first: false }; 3], 3).is_err());
    }

    #[test]
    fn per_frame_intervals_are_on_batch_means() {
        // 16 pairs in 4 runs of 4 alike (a load spike spans several frames):
        // log ratios ln 1.05 ± 0.02 by run. The batch means are those four
        // values, so the interval is the t interval (3 df) of them, wider
        // than the per-pair one that treats 16 correlated pairs as independent.
        let l = 1.05f64.ln();
        let r: Vec<f64> = (0..16).map(|i| (l + if (i / 4) % 2 == 0 { 0.02 } else { -0.02 }).exp()).collect();
        let e = estimate(&pairs(&r), 4).unwrap();
        assert_eq!((e.pairs, e.batches), (16, 4));
        let sd = (4.0 * 0.02f64.powi(2) / 3.0).sqrt();
        assert!((e.mean_log_ratio - l).abs() < 1e-12 && (e.sd_log_ratio - sd).abs() < 1e-12, "{e:?}");
        let half = 3.182 * sd / 2.0;
        assert!((e.ci_low - (l - half).exp()).abs() < 1e-12 && (e.ci_high - (l + half).exp()).abs() < 1e-12);
        let naive = estimate(&pairs(&r), 16).unwrap();
        assert!(naive.ci_high - naive.ci_low < e.ci_high - e.ci_low);
        assert!(e.lag1_autocorrelation.unwrap() > 0.5, "{e:?}");
        assert!((e.sd_pair_log_ratio - 0.02 * (16.0f64 / 15.0).sqrt()).abs() < 1e-12);
        // Unequal batches: 5 pairs in 2 batches of 2 and 3.
        let r5: Vec<f64> = [0.1, 0.3, 0.0, 0.0, 0.3].iter().map(|x: &f64| x.exp()).collect();
        let e5 = estimate(&pairs(&r5), 2).unwrap();
        assert!((e5.mean_log_ratio - 0.15).abs() < 1e-12, "{e5:?}");
        // Alternating log ratios are negatively correlated; too few have none.
        assert!(lag1(&[1.0, -1.0, 1.0, -1.0]).unwrap() < -0.5);
        assert_eq!(lag1(&[1.0, 2.0]), None);
        assert_eq!(lag1(&[1.0, 1.0, 1.0]), None);
        assert!(estimate(&pairs(&[1.0; 4]), 1).is_err() && estimate(&pairs(&[1.0; 4]), 5).is_err());
    }

    #[test]
    fn order_is_seeded_and_mixed() {
        let a: Vec<bool> = { let mut o = Order::new(7); (0..64).map(|_| o.new_first()).collect() };
        let b: Vec<bool> = { let mut o = Order::new(7); (0..64).map(|_| o.new_first()).collect() };
        assert_eq!(a, b);
        let firsts = a.iter().filter(|x| **x).count();
        assert!((16..=48).contains(&firsts), "{firsts}");
    }

    #[test]
    fn default_benchmarks_run_each_method_on_the_cheap_dataset_of_its_kind() {
        let reg = crate::algo::registry::builtin();
        let all = benchmarks(&reg, &[], &[]).unwrap();
        assert_eq!(all.len(), reg.methods().len());
        assert!(all.iter().all(|b| CHEAP_DATASETS.contains(&b.dataset.as_str())));
        let one = benchmarks(&reg, &["balanced".into()], &[]).unwrap();
        assert_eq!(one.len(), 1);
        assert_eq!(one[0].dataset, "post-small");
        let data = benchmarks(&reg, &["bluntfin".into()], &["balanced:sort=mpvo".into()]).unwrap();
        assert_eq!(data.len(), 1);
        assert_eq!((data[0].dataset.as_str(), data[0].label.as_str()), ("bluntfin", "balanced:sort=mpvo"));
        // Defaults are left to each binary (an option new in NEW is not
        // forced on BASE); options given stay, written out as the default
        // ones are not.
        assert_eq!(data[0].spec, "balanced:sort=mpvo");
        assert_eq!(one[0].spec, "balanced");
        let default_given = benchmarks(&reg, &[], &["balanced:sort=centroid".into()]).unwrap();
        assert_eq!(default_given[0].spec, "balanced");
        let spec = benchmarks(&reg, &[], &["balanced:sort=mpvo".into()]).unwrap();
        assert_eq!(spec.len(), 1);
        assert!(benchmarks(&reg, &["nope".into()], &[]).unwrap_err().to_string().contains("--filter nope"));
        assert!(benchmarks(&reg, &[], &["nope".into()]).unwrap_err().to_string().contains("--spec nope"));
    }
}
