//! Paired A/B timing (`volbench ab BASE NEW`): two volbench binaries (or two
//! git revisions, built here) run the same benchmarks alternately in one
//! sitting, so whatever else loads the machine hits both alike.
//!
//! Each benchmark runs `pairs` times per binary, each run a fresh process
//! (`volbench run … --json`), the two runs of a pair back to back in an
//! order drawn per pair from a seeded generator (no position bias). A run's
//! sample is the median of its timed frames' `frame` times (process start,
//! dataset loading and pipeline compilation are outside it). The estimate
//! is a paired t interval on the log ratios `ln(new_i / base_i)` of the
//! pairs: ratio `exp(mean)`, 95 % interval `exp(mean ± t(0.975, n-1)·sd/√n)`.
//! The verdict holds the interval against a slowdown threshold `T`:
//! wholly above `1+T` slower (a regression: the command fails), wholly
//! below `1/(1+T)` faster, wholly inside both "same", and otherwise
//! undecided: the machine was too noisy for this many pairs.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, ensure, Context as _, Result};
use serde::{Deserialize, Serialize};

use super::datasets::NAMED;
use crate::algo::registry::Registry;

/// The shipped dataset each kind's benchmarks run on by default: the
/// cheapest of its kind (seconds per pair, not minutes).
pub const CHEAP_DATASETS: &[&str] = &["post-small", "headsq", "jacksboro"];

/// One benchmark: a method spec on a shipped dataset.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Benchmark {
    pub dataset: String,
    /// The canonical spec (`name:key=value,...`, every option written out).
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
                out.push(Benchmark { dataset: d.name.to_string(), spec: spec.canonical(), label: spec.label() });
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
}

/// `arg` (BASE or NEW, named `role` in errors) as a binary: an executable
/// file, or else a git revision of the repository around the working
/// directory, built with `cargo build --release` in a temporary worktree
/// with `target_dir` as the target directory (so the second build reuses
/// the first's dependencies). Built binaries are kept as
/// `target_dir/ab/volbench-<commit>` and reused.
pub fn resolve(arg: &str, role: &str, target_dir: &Path) -> Result<Binary> {
    let path = Path::new(arg);
    if path.exists() {
        ensure!(path.is_file(), "{role} {arg}: is not a file (give a volbench binary or a git revision)");
        let version = version_of(path).with_context(|| format!("{role} {arg}"))?;
        let path = path.canonicalize().with_context(|| format!("{role} {arg}"))?;
        return Ok(Binary { path, version, revision: None });
    }
    let commit = git(&["rev-parse", "--verify", "--quiet", &format!("{arg}^{{commit}}")])
        .ok()
        .filter(|s| !s.is_empty())
        .with_context(|| format!("{role} {arg}: neither an existing file nor a git revision of this repository"))?;
    let binary = build_revision(&commit, target_dir).with_context(|| format!("{role} {arg}: building revision {commit}"))?;
    let version = version_of(&binary).with_context(|| format!("{role} {arg}: the binary built from {commit}"))?;
    Ok(Binary { path: binary, version, revision: Some(commit) })
}

/// `volbench --version` of `path`, or an error if it is not volbench.
fn version_of(path: &Path) -> Result<String> {
    let out = Command::new(path).arg("--version").output().context("cannot be executed")?;
    let text = String::from_utf8_lossy(&out.stdout).lines().next().unwrap_or("").trim().to_string();
    ensure!(out.status.success() && text.starts_with("volbench "), "is not a volbench binary (`--version` printed {text:?})");
    Ok(text)
}

fn git(args: &[&str]) -> Result<String> {
    let out = Command::new("git").args(args).output().context("running git")?;
    ensure!(out.status.success(), "git {}: {}", args.join(" "), String::from_utf8_lossy(&out.stderr).trim());
    Ok(String::from_utf8_lossy(&out.stdout).trim().to_string())
}

fn build_revision(commit: &str, target_dir: &Path) -> Result<PathBuf> {
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
        let _ = git(&["worktree", "remove", "--force", &tree_s]);
    }
    git(&["worktree", "add", "--detach", &tree_s, commit])?;
    crate::progress!("volbench: ab: building {commit} (cargo build --release, target dir {})", target_dir.display());
    let status = Command::new(std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into()))
        .args(["build", "--release", "--locked", "--bin", "volbench"])
        .current_dir(&tree)
        .env("CARGO_TARGET_DIR", target_dir)
        .status()
        .context("running cargo");
    let built = target_dir.join("release").join("volbench");
    let copied = match status {
        Ok(s) if s.success() => std::fs::copy(&built, &binary).with_context(|| format!("copying {} to {}", built.display(), binary.display())),
        Ok(s) => Err(anyhow::anyhow!("cargo build --release failed ({s})")),
        Err(e) => Err(e),
    };
    // The worktree goes either way; the binary reads data from VOLBENCH_DATA.
    let removed = git(&["worktree", "remove", "--force", &tree_s]);
    copied?;
    removed?;
    Ok(binary)
}

/// How the runs are made.
#[derive(Debug, Clone, Serialize)]
pub struct AbSettings {
    pub width: u32,
    pub height: u32,
    pub frames: usize,
    pub warmup: usize,
    /// Runs per binary and benchmark.
    pub pairs: usize,
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
        ensure!(
            self.threshold.is_finite() && self.threshold > 0.0 && self.threshold < 10.0,
            "--threshold must be a percentage above 0 and below 1000, got {}",
            self.threshold * 100.0
        );
        Ok(())
    }
}

/// One pair's samples (ms: median frame time of each run).
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
    /// exp(mean log ratio): the geometric mean of the pairs' ratios.
    pub ratio: f64,
    pub ci_low: f64,
    pub ci_high: f64,
    pub mean_log_ratio: f64,
    pub sd_log_ratio: f64,
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

/// The paired estimate from `pairs` (at least two, every sample positive).
pub fn estimate(pairs: &[Pair]) -> Result<Estimate> {
    ensure!(pairs.len() >= 2, "{} pair(s): an interval needs at least two", pairs.len());
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
    let n = logs.len() as f64;
    let mean = logs.iter().sum::<f64>() / n;
    let sd = (logs.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    let half = t_975(pairs.len() - 1) * sd / n.sqrt();
    Ok(Estimate {
        pairs: pairs.len(),
        ratio: mean.exp(),
        ci_low: (mean - half).exp(),
        ci_high: (mean + half).exp(),
        mean_log_ratio: mean,
        sd_log_ratio: sd,
    })
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
    pub statistic: &'static str,
    pub rows: Vec<AbRow>,
}

pub const STATISTIC: &str = "paired t interval (95 %) on ln(new/base) of per-run median frame times, one fresh process per run, pair order randomised";

impl AbReport {
    pub fn regressions(&self) -> usize {
        self.rows.iter().filter(|r| r.verdict == Some(Verdict::Slower)).count()
    }

    pub fn failures(&self) -> usize {
        self.rows.iter().filter(|r| r.error.is_some()).count()
    }
}

/// The median frame time (ms) of one `volbench run` of `bench` by `binary`.
fn sample(binary: &Path, bench: &Benchmark, s: &AbSettings, scratch: &Path) -> Result<f64> {
    let json = scratch.join("run.json");
    let _ = std::fs::remove_file(&json);
    let out = Command::new(binary)
        .args(["run", "--data", &bench.dataset, "--method", &bench.spec])
        .args(["--size", &format!("{}x{}", s.width, s.height)])
        .args(["--frames", &s.frames.to_string(), "--warmup", &s.warmup.to_string(), "--json"])
        .arg(&json)
        .env("VOLBENCH_DATA", super::datasets::data_dir())
        .output()
        .with_context(|| format!("running {}", binary.display()))?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        bail!("{} run failed ({}): {}", binary.display(), out.status, crate::fsio::clip_message(err.trim()));
    }
    let text = std::fs::read_to_string(&json).with_context(|| format!("reading {}", json.display()))?;
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

/// Every benchmark, `pairs` times per binary, alternating; `progress` gets
/// (benchmark index, pair index) before each pair.
pub fn run(
    base: &Binary,
    new: &Binary,
    benches: &[Benchmark],
    settings: &AbSettings,
    mut progress: impl FnMut(usize, usize),
) -> Result<AbReport> {
    settings.validate()?;
    let scratch = std::env::temp_dir().join(format!("volbench-ab-{}", std::process::id()));
    std::fs::create_dir_all(&scratch).with_context(|| format!("creating {}", scratch.display()))?;
    let mut order = Order::new(settings.seed);
    let mut rows = Vec::new();
    for (b, bench) in benches.iter().enumerate() {
        let mut samples = Vec::new();
        let mut error = None;
        for p in 0..settings.pairs {
            progress(b, p);
            let new_first = order.new_first();
            let pair = if new_first {
                sample(&new.path, bench, settings, &scratch)
                    .and_then(|n| Ok(Pair { new_ms: n, base_ms: sample(&base.path, bench, settings, &scratch)?, new_first }))
            } else {
                sample(&base.path, bench, settings, &scratch)
                    .and_then(|b| Ok(Pair { base_ms: b, new_ms: sample(&new.path, bench, settings, &scratch)?, new_first }))
            };
            match pair {
                Ok(pair) => samples.push(pair),
                Err(e) => {
                    error = Some(format!("{e:#}"));
                    break;
                }
            }
        }
        let estimate = if error.is_none() {
            match estimate(&samples) {
                Ok(e) => Some(e),
                Err(e) => {
                    error = Some(format!("{e:#}"));
                    None
                }
            }
        } else {
            None
        };
        let verdict = estimate.as_ref().map(|e| decide(e, settings.threshold));
        rows.push(AbRow { benchmark: bench.clone(), samples, estimate, verdict, error });
    }
    let _ = std::fs::remove_dir_all(&scratch);
    Ok(AbReport {
        schema: "volbench-ab/1",
        base: base.clone(),
        new: new.clone(),
        settings: settings.clone(),
        statistic: STATISTIC,
        rows,
    })
}

/// The report as a Markdown table (also what stdout shows).
pub fn markdown(r: &AbReport) -> String {
    let s = &r.settings;
    let mut out = format!(
        "BASE {} ({})\nNEW  {} ({})\n{} pairs per benchmark at {}x{}, {} timed frames (+{} warm-up) per run, seed {}\n{}; threshold {:.1} %\n\n",
        r.base.path.display(),
        r.base.revision.as_deref().unwrap_or(&r.base.version),
        r.new.path.display(),
        r.new.revision.as_deref().unwrap_or(&r.new.version),
        s.pairs,
        s.width,
        s.height,
        s.frames,
        s.warmup,
        s.seed,
        r.statistic,
        s.threshold * 100.0
    );
    out += "| dataset | benchmark | pairs | BASE median ms | NEW median ms | NEW/BASE | 95 % interval | verdict |\n";
    out += "|---|---|---:|---:|---:|---:|---|---|\n";
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
            (_, _, Some(err)) => ("-".into(), "-".into(), format!("failed: {}", err.replace('|', "/").replace('\n', " "))),
            _ => ("-".into(), "-".into(), "-".into()),
        };
        out += &format!(
            "| {} | {} | {} | {} | {} | {ratio} | {ci} | {verdict} |\n",
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
        let e = estimate(&pairs(&[1.0; 5])).unwrap();
        assert_eq!((e.ratio, e.ci_low, e.ci_high), (1.0, 1.0, 1.0));
        assert_eq!(decide(&e, 0.03), Verdict::Same);
    }

    #[test]
    fn interval_is_the_paired_t_interval_of_the_log_ratios() {
        // Log ratios ln 1.1 ± 0.01: mean ln 1.1, sd 0.01 (n = 4: the two
        // deviations +-0.01 twice), half width t(3) * 0.01 / 2.
        let l = 1.1f64.ln();
        let r: Vec<f64> = [l + 0.01, l - 0.01, l + 0.01, l - 0.01].iter().map(|x: &f64| x.exp()).collect();
        let e = estimate(&pairs(&r)).unwrap();
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
        assert_eq!(decide(&estimate(&pairs(&slow)).unwrap(), 0.03), Verdict::Slower);
        let fast: Vec<f64> = noise.iter().map(|n| 0.9 * (1.0 + n)).collect();
        assert_eq!(decide(&estimate(&pairs(&fast)).unwrap(), 0.03), Verdict::Faster);
        let same: Vec<f64> = noise.iter().map(|n| 1.0 + n).collect();
        assert_eq!(decide(&estimate(&pairs(&same)).unwrap(), 0.03), Verdict::Same);
        // The same mean slowdown with 20 % noise: too noisy to say.
        let noisy: Vec<f64> = noise.iter().map(|n| 1.05 * (1.0 + 40.0 * n)).collect();
        assert_eq!(decide(&estimate(&pairs(&noisy)).unwrap(), 0.03), Verdict::Undecided);
        // A narrow interval that straddles the threshold is undecided too.
        let edge: Vec<f64> = noise.iter().map(|n| 1.03 * (1.0 + n)).collect();
        assert_eq!(decide(&estimate(&pairs(&edge)).unwrap(), 0.03), Verdict::Undecided);
    }

    #[test]
    fn bad_samples_are_errors() {
        assert!(estimate(&pairs(&[1.0])).is_err());
        assert!(estimate(&[Pair { base_ms: 0.0, new_ms: 1.0, new_first: false }; 3]).is_err());
        assert!(estimate(&[Pair { base_ms: 1.0, new_ms: f64::NAN, new_first: false }; 3]).is_err());
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
        let spec = benchmarks(&reg, &[], &["balanced:sort=mpvo".into()]).unwrap();
        assert_eq!(spec.len(), 1);
        assert!(benchmarks(&reg, &["nope".into()], &[]).unwrap_err().to_string().contains("--filter nope"));
        assert!(benchmarks(&reg, &[], &["nope".into()]).unwrap_err().to_string().contains("--spec nope"));
    }
}
