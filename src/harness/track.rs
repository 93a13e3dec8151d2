//! `volbench compare BASELINE NEW`: benchmark tracking between two suite
//! summaries (`summary.json`), as CI needs it.
//!
//! Three kinds of figure, three rules:
//! - **counts** (bytes uploaded per frame and per cell, static bytes,
//!   pipeline statistics, work counts such as samples per ray, covered
//!   pixels) are deterministic on one device and must match exactly
//!   (vertex-shader invocations depend on the index order too, which device
//!   atomics may change from run to run: they get the relative tolerance). Counts
//!   that depend on shader arithmetic or rasterisation may differ in the last
//!   digits on another device (another CPU behind lavapipe); there they get
//!   [`Tolerances::count_rel_other_device`] and the line says why.
//! - **errors** (RMSE against the f64 reference) must not grow by more than
//!   `max(rmse_abs, rmse_rel × baseline)`; non-finite pixels must stay zero.
//! - **instruction counts** (`count`, from `suite --count`: instructions per
//!   phase of the timed frames under callgrind, see `harness::count`) repeat
//!   to a few parts in a million; each phase and the frame total is its own
//!   figure, and regresses when it grows by more than `count_rel` (1 %).
//! - **times** are compared as ratios between methods on one dataset inside
//!   each run, each with a distribution-free 95 % confidence band of its
//!   medians; absolute frame times only when asked (`--absolute-times`)
//!   and the device, driver and CPU match. A time moves when the bands do
//!   not overlap and the change exceeds `time_margin`. Times are not
//!   deterministic, and ratios between methods are not machine-independent
//!   either (fragment and compute paths use the CPU differently, and the
//!   runs of a suite are not alternated): a moved time **fails the compare
//!   only when both summaries come from the same machine and sitting**
//!   ([`same_sitting`]) **or the user asks** (`--times`, [`Times::Always`]);
//!   otherwise it is a note. Speed decisions belong to `volbench ab`.
//!
//! The summaries' text (run labels, phase names, messages) is escaped in
//! the table ([`report::md_cell`]); summaries whose count phases collide
//! as export names are refused ([`validate`]).
//!
//! It also exports the new summary in Bencher Metric Format and as
//! github-action-benchmark's `customSmallerIsBetter` JSON.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use anyhow::{bail, ensure, Context as _, Result};
use serde::Deserialize;
use serde_json::{json, Value};

use crate::fsio;
use crate::harness::report;

/// Whether moved times fail a comparison.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Times {
    /// Not compared at all (`--no-times`).
    Off,
    /// Compared; a moved time fails only when both summaries come from the
    /// same machine and sitting ([`same_sitting`]), else it is a note (the default).
    Auto,
    /// Compared, and a moved time fails wherever the summaries come from (`--times`).
    Always,
}

/// The thresholds `compare` applies.
#[derive(Debug, Clone, Copy)]
pub struct Tolerances {
    /// An RMSE may grow by this much in absolute terms...
    pub rmse_abs: f64,
    /// ...or by this fraction of the baseline's, whichever is larger.
    pub rmse_rel: f64,
    /// Relative tolerance of arithmetic-dependent counts across devices.
    pub count_rel_other_device: f64,
    /// A time (ratio or absolute) must move by more than this fraction,
    /// outside both noise bands, to count.
    pub time_margin: f64,
    /// An instruction count (per phase, per frame) may move by this
    /// fraction either way...
    pub count_rel: f64,
    /// ...or by this many instructions (a phase of a few thousand, such as
    /// reading the query results, jitters by a few hundred).
    pub count_abs: f64,
    /// Whether times are compared, and whether a moved one fails.
    pub times: Times,
    /// Compare absolute frame times too (same device, driver and CPU only).
    pub absolute_times: bool,
}

impl Default for Tolerances {
    fn default() -> Self {
        Tolerances { rmse_abs: 1e-4, rmse_rel: 0.05, count_rel_other_device: 1e-3, time_margin: 0.10, count_rel: 0.01, count_abs: 10_000.0, times: Times::Auto, absolute_times: false }
    }
}

/// The part of `summary.json` tracking reads (other fields are ignored, so
/// older and newer summaries of schema 2 both load).
#[derive(Debug, Deserialize)]
pub struct SummaryFile {
    /// Absent in the summaries written so far (the version is per result);
    /// when present it must be one this build reads.
    #[serde(default)]
    pub schema_version: Option<u32>,
    pub environment: EnvironmentFile,
    pub settings: SettingsFile,
    pub runs: Vec<RowFile>,
}

#[derive(Debug, Deserialize)]
pub struct EnvironmentFile {
    pub device: DeviceFile,
    #[serde(default)]
    pub cpu_model: String,
    #[serde(default)]
    pub git_sha: String,
    /// `YYYYMMDDTHHMMSSZ` (absent or empty: unknown).
    #[serde(default)]
    pub started_utc: String,
    /// A hash of the machine's id and its boot's (absent in summaries
    /// written before it was recorded: then no sitting is known).
    #[serde(default)]
    pub machine_boot_id: Option<String>,
}

#[derive(Debug, Deserialize)]
pub struct DeviceFile {
    pub name: String,
    pub driver_info: String,
}

#[derive(Debug, Deserialize, PartialEq)]
pub struct SettingsFile {
    pub width: u32,
    pub height: u32,
    pub orbit_step_deg: f64,
    pub quick: bool,
    /// A counted suite (`--count`; absent before counting existed).
    #[serde(default)]
    pub counted: bool,
}

#[derive(Debug, Deserialize)]
pub struct RowFile {
    pub dataset: String,
    pub method: String,
    /// The method and its non-default options (absent in early summaries).
    #[serde(default)]
    pub label: Option<String>,
    pub status: String,
    #[serde(default)]
    pub message: Option<String>,
    #[serde(default)]
    pub result: Option<ResultFile>,
}

#[derive(Debug, Deserialize)]
pub struct ResultFile {
    pub schema_version: u32,
    pub spec: String,
    pub upload: UploadFile,
    #[serde(default)]
    pub stats: Option<BTreeMap<String, u64>>,
    pub work: BTreeMap<String, Value>,
    pub time_ms: TimesFile,
    pub image: ImageFile,
    #[serde(default)]
    pub error: Option<ErrorFile>,
    #[serde(default)]
    pub count: Option<CountFile>,
}

/// A counted run's instructions (`harness::count::CountReport`).
#[derive(Debug, Deserialize)]
pub struct CountFile {
    pub frames: usize,
    pub phases: BTreeMap<String, CountTotal>,
    pub frame: CountTotal,
}

#[derive(Debug, Deserialize)]
pub struct CountTotal {
    pub total: u64,
}

impl CountFile {
    /// Instructions per frame by figure (`instructions.<phase>`, and
    /// `instructions.frame` for every phase together).
    fn per_frame(&self) -> BTreeMap<String, f64> {
        let n = self.frames.max(1) as f64;
        let mut m: BTreeMap<String, f64> = self.phases.iter().map(|(k, v)| (format!("instructions.{k}"), v.total as f64 / n)).collect();
        m.insert("instructions.frame".into(), self.frame.total as f64 / n);
        m
    }
}

#[derive(Debug, Deserialize)]
pub struct UploadFile {
    pub bytes_per_frame: u64,
    pub cell_bytes_per_frame: u64,
    pub constant_bytes_per_frame: u64,
    pub static_bytes: u64,
    #[serde(default)]
    pub bytes_per_cell: Option<f64>,
}

#[derive(Debug, Deserialize)]
pub struct TimesFile {
    pub samples: BTreeMap<String, Vec<f64>>,
}

#[derive(Debug, Deserialize)]
pub struct ImageFile {
    pub covered_pixels: u64,
    pub non_finite_pixels: u64,
}

#[derive(Debug, Deserialize)]
pub struct ErrorFile {
    pub rmse: f64,
}

/// Read and parse a suite summary, naming the file in every error.
pub fn load(path: &Path) -> Result<SummaryFile> {
    let text = fsio::read_input_text(path, "suite summary", 256 << 20)?;
    let s: SummaryFile = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a volbench suite summary.json (schema 2)", path.display()))?;
    validate(&s).with_context(|| format!("{}: not a valid volbench suite summary", path.display()))?;
    Ok(s)
}

/// Largest frame or phase time a summary may hold, in milliseconds (a
/// day): far above any frame, and small enough that every figure derived
/// from it (nanoseconds, ratios, bands) stays finite.
pub const MAX_TIME_MS: f64 = 86_400_000.0;

/// Refuse what no run writes: another schema version, two rows with one
/// name, negative or non-finite errors and times.
fn validate(s: &SummaryFile) -> Result<()> {
    let supported = crate::harness::run::SCHEMA_VERSION;
    if let Some(v) = s.schema_version {
        ensure!(v == supported, "schema_version {v} is not supported (this build reads schema_version {supported})");
    }
    let mut seen = std::collections::BTreeSet::new();
    for r in &s.runs {
        let k = key(r);
        ensure!(seen.insert(k.clone()), "two rows for {k}");
        let Some(x) = &r.result else { continue };
        ensure!(
            x.schema_version == supported,
            "{k}: schema_version {} is not supported (this build reads schema_version {supported})",
            x.schema_version
        );
        if let Some(e) = &x.error {
            ensure!(e.rmse.is_finite() && e.rmse >= 0.0, "{k}: error.rmse {} is not a finite non-negative number", e.rmse);
        }
        if let Some(b) = x.upload.bytes_per_cell {
            ensure!(b.is_finite() && b >= 0.0, "{k}: upload.bytes_per_cell {b} is not a finite non-negative number");
        }
        if let Some(cf) = &x.count {
            // Each phase is its own exported measure (`instructions-<phase>`,
            // lower case, punctuation as `-`): two phases that differ only in
            // case or punctuation would be one measure and two equal names.
            let mut measures: BTreeMap<String, String> = BTreeMap::new();
            measures.insert(measure_name("instructions.frame"), "the frame total".into());
            for phase in cf.phases.keys() {
                let m = measure_name(&format!("instructions.{phase}"));
                if let Some(other) = measures.insert(m.clone(), format!("phase {phase:?}")) {
                    bail!(
                        "{k:?}: count {other} and phase {phase:?} are both exported as the measure {m:?} \
                         (names must differ in more than case and punctuation)"
                    );
                }
            }
        }
        for (phase, samples) in &x.time_ms.samples {
            for t in samples {
                ensure!(
                    t.is_finite() && (0.0..=MAX_TIME_MS).contains(t),
                    "{k}: time_ms.samples.{phase} holds {t}, expected milliseconds in [0, {MAX_TIME_MS}]"
                );
            }
        }
    }
    Ok(())
}

/// A figure's name as an exported measure: lower case, every character but
/// ASCII letters and digits as `-` (BMF measure names are kebab-case).
fn measure_name(figure: &str) -> String {
    figure.chars().map(|c| if c.is_ascii_alphanumeric() { c.to_ascii_lowercase() } else { '-' }).collect()
}

/// A row's name: `dataset/method` or `dataset/method:options`.
fn key(r: &RowFile) -> String {
    format!("{}/{}", r.dataset, r.label.as_deref().unwrap_or(&r.method))
}

/// What one line of the comparison found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Verdict {
    Regression,
    Improved,
    Ok,
    Info,
}

impl Verdict {
    fn word(self) -> &'static str {
        match self {
            Verdict::Regression => "REGRESSION",
            Verdict::Improved => "improved",
            Verdict::Ok => "ok",
            Verdict::Info => "note",
        }
    }
}

/// One compared figure.
#[derive(Debug, Clone)]
pub struct Line {
    pub verdict: Verdict,
    pub benchmark: String,
    pub figure: String,
    pub baseline: String,
    pub new: String,
    pub why: String,
}

/// Every line of a comparison.
#[derive(Debug, Default)]
pub struct Comparison {
    pub lines: Vec<Line>,
}

impl Comparison {
    pub fn regressions(&self) -> usize {
        self.count(Verdict::Regression)
    }

    /// The lines with verdict `v`.
    pub fn count(&self, v: Verdict) -> usize {
        self.lines.iter().filter(|l| l.verdict == v).count()
    }

    fn push(&mut self, verdict: Verdict, benchmark: &str, figure: &str, baseline: String, new: String, why: impl Into<String>) {
        self.lines.push(Line { verdict, benchmark: benchmark.into(), figure: figure.into(), baseline, new, why: why.into() });
    }

    /// The printed table: regressions first, one clear line each (every
    /// cell escaped: the text comes from the summaries); then a count of
    /// the figures that matched.
    pub fn table(&self) -> String {
        let mut lines: Vec<&Line> = self.lines.iter().filter(|l| l.verdict != Verdict::Ok).collect();
        lines.sort_by_key(|l| l.verdict);
        let ok = self.lines.len() - lines.len();
        let mut t = String::from("| verdict | benchmark | figure | baseline | new | why |\n|---|---|---|---:|---:|---|\n");
        for l in lines {
            let cells = [l.verdict.word(), &l.benchmark, &l.figure, &l.baseline, &l.new, &l.why].map(report::md_cell);
            let _ = writeln!(t, "| {} |", cells.join(" | "));
        }
        let _ = writeln!(
            t,
            "\n{} figures compared: {} regressions, {} improved, {} notes, {ok} unchanged within tolerance.",
            self.lines.len(),
            self.regressions(),
            self.count(Verdict::Improved),
            self.count(Verdict::Info)
        );
        t
    }
}

/// Whether two summaries come from the same device, driver and CPU.
fn same_device(a: &SummaryFile, b: &SummaryFile) -> bool {
    let (x, y) = (&a.environment, &b.environment);
    x.device.name == y.device.name && x.device.driver_info == y.device.driver_info && x.cpu_model == y.cpu_model
}

/// How far apart two suites may have started and still be one sitting.
pub const SITTING_WINDOW_S: i64 = 3600;

/// Whether two summaries come from the same machine and sitting: both
/// record the same `machine_boot_id` (a hash of the machine's
/// `/etc/machine-id` and of this boot's id, so another machine, a clone of
/// the same image or a reboot differ), the same device, driver and CPU
/// model, and started at most [`SITTING_WINDOW_S`] apart. `Ok` says so,
/// `Err` says what differs.
pub fn same_sitting(a: &SummaryFile, b: &SummaryFile) -> std::result::Result<String, String> {
    use crate::harness::suite::parse_utc;
    let (x, y) = (&a.environment, &b.environment);
    let (Some(mx), Some(my)) = (&x.machine_boot_id, &y.machine_boot_id) else {
        return Err("a summary does not record its machine and boot".into());
    };
    if mx != my {
        return Err("another machine, or the same one rebooted".into());
    }
    if !same_device(a, b) {
        return Err("another device, driver or CPU".into());
    }
    let (Some(tx), Some(ty)) = (parse_utc(&x.started_utc), parse_utc(&y.started_utc)) else {
        return Err("a summary does not record when it started".into());
    };
    let apart = (tx - ty).abs();
    if apart > SITTING_WINDOW_S {
        return Err(format!("started {:.1} h apart, more than {} h", apart as f64 / 3600.0, SITTING_WINDOW_S / 3600));
    }
    Ok(format!("one machine and boot, started {apart} s apart"))
}

/// Compare `new` against `base`.
pub fn compare(base: &SummaryFile, new: &SummaryFile, tol: &Tolerances) -> Result<Comparison> {
    if base.settings != new.settings {
        bail!(
            "the two summaries were run with different settings (baseline {:?}, new {:?}): their counts and errors are not comparable; \
             run the suite with the baseline's settings",
            base.settings,
            new.settings
        );
    }
    let same = same_device(base, new);
    let mut c = Comparison::default();
    if !same {
        c.push(
            Verdict::Info,
            "environment",
            "device",
            format!("{} / {} / {}", base.environment.device.name, base.environment.device.driver_info, base.environment.cpu_model),
            format!("{} / {} / {}", new.environment.device.name, new.environment.device.driver_info, new.environment.cpu_model),
            format!(
                "different device: arithmetic-dependent counts within {:e} relative, absolute times not compared",
                tol.count_rel_other_device
            ),
        );
    }
    // Whether a moved time fails (else it is a note), and why.
    let sitting = same_sitting(base, new);
    let enforce = match tol.times {
        Times::Off => false,
        Times::Always => true,
        Times::Auto => sitting.is_ok(),
    };
    if tol.times != Times::Off {
        let why = match (&sitting, tol.times) {
            (_, Times::Always) => "--times: moved times fail the comparison".to_string(),
            (Ok(how), _) => format!("same machine and sitting ({how}): moved times fail the comparison"),
            (Err(what), _) => format!(
                "not the same machine and sitting ({what}): moved times are notes, not failures \
                 (--times to fail on them; speed decisions: volbench ab)"
            ),
        };
        c.push(Verdict::Info, "environment", "times", base.environment.started_utc.clone(), new.environment.started_utc.clone(), why);
    }
    let new_rows: BTreeMap<String, &RowFile> = new.runs.iter().map(|r| (key(r), r)).collect();
    for b in &base.runs {
        let k = key(b);
        let Some(n) = new_rows.get(&k) else {
            c.push(Verdict::Regression, &k, "row", b.status.clone(), "missing".into(), "the baseline has this run; the new summary does not");
            continue;
        };
        match (&b.result, &n.result) {
            (Some(br), Some(nr)) => compare_row(&mut c, &k, br, nr, same, enforce, tol),
            (Some(_), None) => c.push(
                Verdict::Regression,
                &k,
                "status",
                b.status.clone(),
                n.status.clone(),
                n.message.clone().unwrap_or_default(),
            ),
            (None, Some(_)) => c.push(Verdict::Improved, &k, "status", b.status.clone(), n.status.clone(), "runs now"),
            (None, None) => c.push(Verdict::Ok, &k, "status", b.status.clone(), n.status.clone(), ""),
        }
    }
    let base_keys: std::collections::BTreeSet<String> = base.runs.iter().map(key).collect();
    for n in &new.runs {
        if !base_keys.contains(&key(n)) {
            c.push(Verdict::Info, &key(n), "row", "absent".into(), n.status.clone(), "new run, not in the baseline");
        }
    }
    if tol.times != Times::Off {
        compare_ratios(&mut c, base, new, enforce, tol);
    }
    Ok(c)
}

/// Counts that depend only on the data and the method (exact on any
/// device); every other count may move with the device's arithmetic.
fn device_independent(figure: &str) -> bool {
    figure.starts_with("upload.") || matches!(figure, "stats.input_vertices" | "stats.input_primitives" | "work.cells")
}

/// Counts that depend on the order of the indices as well: vertex-shader
/// invocations are what a post-transform cache misses, and a method whose
/// index order comes from device atomics (hm-compute) draws the same
/// triangles in another order each run. Held to the relative tolerance even
/// on the same device.
fn order_dependent(figure: &str) -> bool {
    figure == "stats.vertex_invocations"
}

fn compare_row(c: &mut Comparison, k: &str, b: &ResultFile, n: &ResultFile, same_device: bool, enforce_times: bool, tol: &Tolerances) {
    let verdict = |ok: bool| if ok { Verdict::Ok } else { Verdict::Regression };
    c.push(verdict(b.spec == n.spec), k, "spec", b.spec.clone(), n.spec.clone(), if b.spec == n.spec { "" } else { "the method's default options changed" });
    for (figure, bv, nv) in counts(b, n) {
        let exact = (same_device || device_independent(&figure)) && !order_dependent(&figure);
        let ok = match (bv, nv) {
            (Some(x), Some(y)) if exact => x == y,
            (Some(x), Some(y)) => (x - y).abs() <= tol.count_rel_other_device * x.abs().max(y.abs()),
            (None, None) => true,
            _ => false,
        };
        let why = if ok {
            String::new()
        } else if exact {
            "a deterministic count changed".into()
        } else {
            format!("changed by more than {:e} (relative) on another device", tol.count_rel_other_device)
        };
        let show = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v}"));
        c.push(verdict(ok), k, &figure, show(bv), show(nv), why);
    }
    let (be, ne) = (b.error.as_ref().map(|e| e.rmse), n.error.as_ref().map(|e| e.rmse));
    match (be, ne) {
        (Some(x), Some(y)) => {
            let allowed = x + tol.rmse_abs.max(tol.rmse_rel * x);
            let v = if y > allowed || !y.is_finite() {
                Verdict::Regression
            } else if y < x - tol.rmse_abs.max(tol.rmse_rel * x) {
                Verdict::Improved
            } else {
                Verdict::Ok
            };
            let why = match v {
                Verdict::Regression => format!("grew beyond the allowed {allowed:.3e} (+max({:e}, {}×baseline))", tol.rmse_abs, tol.rmse_rel),
                Verdict::Improved => "smaller error".into(),
                _ => String::new(),
            };
            c.push(v, k, "error.rmse", format!("{x:.4e}"), format!("{y:.4e}"), why);
        }
        (Some(x), None) => c.push(Verdict::Regression, k, "error.rmse", format!("{x:.4e}"), "-".into(), "no reference comparison in the new run"),
        _ => {}
    }
    let nf = (b.image.non_finite_pixels, n.image.non_finite_pixels);
    c.push(verdict(nf.1 <= nf.0), k, "image.non_finite_pixels", nf.0.to_string(), nf.1.to_string(), if nf.1 > nf.0 { "NaN/Inf pixels appeared" } else { "" });
    compare_instructions(c, k, b, n, tol);
    if tol.times != Times::Off && tol.absolute_times && same_device {
        if let (Some(bs), Some(ns)) = (b.time_ms.samples.get("frame"), n.time_ms.samples.get("frame")) {
            if let (Some(bb), Some(nb)) = (median_band(bs), median_band(ns)) {
                let v = time_verdict(bb, nb, tol.time_margin);
                let (v, why) = time_note(v, time_why(v, tol.time_margin), enforce_times);
                c.push(v, k, "time_ms.frame (same device)", bb.show(), nb.show(), why);
            }
        }
    }
}

/// Instructions per frame of each phase (counted runs): within
/// `count_rel` either way, a regression beyond it naming the phase and the
/// change in instructions.
fn compare_instructions(c: &mut Comparison, k: &str, b: &ResultFile, n: &ResultFile, tol: &Tolerances) {
    let (bc, nc) = match (&b.count, &n.count) {
        (None, None) => return,
        (Some(_), None) => {
            c.push(Verdict::Regression, k, "instructions", "counted".into(), "-".into(), "the baseline is counted, the new run is not (suite --count)");
            return;
        }
        (None, Some(_)) => {
            c.push(Verdict::Info, k, "instructions", "-".into(), "counted".into(), "the baseline has no counts");
            return;
        }
        (Some(x), Some(y)) => (x.per_frame(), y.per_frame()),
    };
    let names: std::collections::BTreeSet<&String> = bc.keys().chain(nc.keys()).collect();
    for name in names {
        let (x, y) = (bc.get(name).copied().unwrap_or(0.0), nc.get(name).copied().unwrap_or(0.0));
        let (v, why) = instruction_verdict(x, y, tol);
        c.push(v, k, &format!("{name} (per frame)"), format!("{x:.0}"), format!("{y:.0}"), why);
    }
}

fn instruction_verdict(base: f64, new: f64, tol: &Tolerances) -> (Verdict, String) {
    let change = new - base;
    let pct = if base > 0.0 { format!("{:+.2} %", 100.0 * change / base) } else { "new phase".into() };
    let allowed = (tol.count_rel * base).max(tol.count_abs);
    if change > allowed {
        (
            Verdict::Regression,
            format!("{change:+.0} instructions ({pct}), beyond the tolerance (max({:.0} %, {:.0} instructions))", tol.count_rel * 100.0, tol.count_abs),
        )
    } else if -change > allowed {
        (Verdict::Improved, format!("{change:+.0} instructions ({pct})"))
    } else {
        (Verdict::Ok, String::new())
    }
}

/// Every count of a run, as (figure name, value) pairs aligned between the two.
fn counts(b: &ResultFile, n: &ResultFile) -> Vec<(String, Option<f64>, Option<f64>)> {
    let flat = |r: &ResultFile| {
        let mut m: BTreeMap<String, f64> = BTreeMap::new();
        let u = &r.upload;
        m.insert("upload.bytes_per_frame".into(), u.bytes_per_frame as f64);
        m.insert("upload.cell_bytes_per_frame".into(), u.cell_bytes_per_frame as f64);
        m.insert("upload.constant_bytes_per_frame".into(), u.constant_bytes_per_frame as f64);
        m.insert("upload.static_bytes".into(), u.static_bytes as f64);
        if let Some(v) = u.bytes_per_cell {
            m.insert("upload.bytes_per_cell".into(), v);
        }
        for (s, v) in r.stats.iter().flatten() {
            m.insert(format!("stats.{s}"), *v as f64);
        }
        for (w, v) in &r.work {
            if let Some(v) = v.as_u64() {
                m.insert(format!("work.{w}"), v as f64);
            }
        }
        m.insert("image.covered_pixels".into(), r.image.covered_pixels as f64);
        m
    };
    let (fb, fnew) = (flat(b), flat(n));
    let names: std::collections::BTreeSet<&String> = fb.keys().chain(fnew.keys()).collect();
    names.into_iter().map(|k| (k.clone(), fb.get(k).copied(), fnew.get(k).copied())).collect()
}

/// A median with its distribution-free 95 % confidence band (order
/// statistics of the binomial(n, ½); [min, max] below 6 samples).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Band {
    pub median: f64,
    pub lo: f64,
    pub hi: f64,
}

impl Band {
    fn show(&self) -> String {
        format!("{:.3} [{:.3}, {:.3}]", self.median, self.lo, self.hi)
    }
}

pub fn median_band(samples: &[f64]) -> Option<Band> {
    let mut s: Vec<f64> = samples.iter().copied().filter(|v| v.is_finite()).collect();
    if s.is_empty() {
        return None;
    }
    s.sort_by(f64::total_cmp);
    let n = s.len();
    let median = super::stats::Summary::of(&s).median;
    // Largest k with P(Binomial(n, 1/2) < k) <= 0.025: the band is
    // [x_(k), x_(n+1-k)] (1-based), which covers the median with >= 95 %.
    // The pmf is carried as its logarithm: 0.5^n underflows from n = 1075.
    let mut k = 0usize;
    let mut cdf = 0.0f64;
    let mut ln_pmf = -(n as f64) * std::f64::consts::LN_2;
    for j in 0..n / 2 {
        let pmf = ln_pmf.exp();
        if cdf + pmf > 0.025 {
            break;
        }
        cdf += pmf;
        k = j + 1;
        ln_pmf += ((n - j) as f64).ln() - ((j + 1) as f64).ln();
    }
    let (lo, hi) = if k == 0 { (s[0], s[n - 1]) } else { (s[k - 1], s[n - k]) };
    Some(Band { median, lo, hi })
}

/// The band of a ratio of two medians (interval arithmetic on their bands).
fn ratio_band(a: Band, b: Band) -> Option<Band> {
    (b.lo > 0.0).then(|| Band { median: a.median / b.median, lo: a.lo / b.hi, hi: a.hi / b.lo })
}

fn time_verdict(base: Band, new: Band, margin: f64) -> Verdict {
    if new.lo > base.hi && new.median > base.median * (1.0 + margin) {
        Verdict::Regression
    } else if new.hi < base.lo && new.median < base.median * (1.0 - margin) {
        Verdict::Improved
    } else {
        Verdict::Ok
    }
}

/// A time regression as a note when times do not fail the comparison.
fn time_note(v: Verdict, why: String, enforce: bool) -> (Verdict, String) {
    if v == Verdict::Regression && !enforce {
        (Verdict::Info, format!("{why} (a note: not the same machine and sitting)"))
    } else {
        (v, why)
    }
}

fn time_why(v: Verdict, margin: f64) -> String {
    match v {
        Verdict::Regression => format!("slower by more than {:.0} %, outside both noise bands", margin * 100.0),
        Verdict::Improved => format!("faster by more than {:.0} %, outside both noise bands", margin * 100.0),
        _ => String::new(),
    }
}

/// Frame-time ratios on each dataset, within each summary, compared across
/// the two: every run against the dataset's reference run (the first by
/// name that both summaries time), so the lines grow linearly with the runs
/// (every pair made 4.5 million lines of 3,000 runs).
fn compare_ratios(c: &mut Comparison, base: &SummaryFile, new: &SummaryFile, enforce: bool, tol: &Tolerances) {
    let bands = |s: &SummaryFile| -> BTreeMap<(String, String), Band> {
        s.runs
            .iter()
            .filter_map(|r| {
                let b = median_band(r.result.as_ref()?.time_ms.samples.get("frame")?)?;
                Some(((r.dataset.clone(), r.label.clone().unwrap_or_else(|| r.method.clone())), b))
            })
            .collect()
    };
    let (bb, nb) = (bands(base), bands(new));
    // Runs timed in both, by dataset, in name order.
    let mut by_dataset: BTreeMap<&str, Vec<(&str, Band, Band)>> = BTreeMap::new();
    for ((d, m), b) in &bb {
        if let Some(n) = nb.get(&(d.clone(), m.clone())) {
            by_dataset.entry(d).or_default().push((m, *b, *n));
        }
    }
    for (d, runs) in by_dataset {
        let Some(((m0, b0, n0), rest)) = runs.split_first() else { continue };
        for (m, b, n) in rest {
            let (Some(rb), Some(rn)) = (ratio_band(*b, *b0), ratio_band(*n, *n0)) else { continue };
            let v = time_verdict(rb, rn, tol.time_margin);
            // A ratio moving either way means one method changed relative to
            // the other; which one, only absolute times on one device can say.
            let v = if v == Verdict::Improved { Verdict::Regression } else { v };
            let why = if v == Verdict::Regression {
                format!("the ratio moved by more than {:.0} %, outside both noise bands: one of the two methods changed speed", tol.time_margin * 100.0)
            } else {
                String::new()
            };
            let (v, why) = time_note(v, why, enforce);
            c.push(v, &format!("{d}/{m} ÷ {d}/{m0}"), "frame-time ratio", rb.show(), rn.show(), why);
        }
    }
}

/// One exported measure: name, value, and its band when it has one.
type Measure = (String, f64, Option<(f64, f64)>);

/// The run's figures by benchmark name (`dataset/method`): frame and GPU
/// latency in nanoseconds with their bands, bytes, RMSE.
fn metrics(s: &SummaryFile) -> Vec<(String, Vec<Measure>)> {
    let mut out = Vec::new();
    for r in &s.runs {
        let Some(x) = &r.result else { continue };
        let mut m = Vec::new();
        for (phase, name) in [("frame", "latency"), ("gpu", "gpu-latency")] {
            if let Some(b) = x.time_ms.samples.get(phase).and_then(|v| median_band(v)) {
                m.push((name.into(), b.median * 1e6, Some((b.lo * 1e6, b.hi * 1e6))));
            }
        }
        m.push(("bytes-per-frame".into(), x.upload.bytes_per_frame as f64, None));
        if let Some(v) = x.upload.bytes_per_cell {
            m.push(("bytes-per-cell".into(), v, None));
        }
        if let Some(e) = &x.error {
            m.push(("rmse".into(), e.rmse, None));
        }
        // Instructions per frame, each phase its own measure
        // (`instructions-<phase>`: BMF measure names are kebab-case).
        // (`validate` refused phases that would share a measure name.)
        if let Some(cf) = &x.count {
            m.extend(cf.per_frame().into_iter().map(|(name, v)| (measure_name(&name), v, None)));
        }
        out.push((key(r), m));
    }
    out
}

/// Bencher Metric Format: `{benchmark: {measure: {value, lower_value, upper_value}}}`.
pub fn bmf(s: &SummaryFile) -> Value {
    let mut root = serde_json::Map::new();
    for (bench, ms) in metrics(s) {
        let mut measures = serde_json::Map::new();
        for (name, v, band) in ms {
            let mut o = json!({ "value": v });
            if let Some((lo, hi)) = band {
                o["lower_value"] = json!(lo);
                o["upper_value"] = json!(hi);
            }
            measures.insert(name, o);
        }
        root.insert(bench, Value::Object(measures));
    }
    Value::Object(root)
}

/// github-action-benchmark's `customSmallerIsBetter`: `[{name, unit, value, range?, extra?}]`.
pub fn gha(s: &SummaryFile) -> Value {
    let mut out = Vec::new();
    for (bench, ms) in metrics(s) {
        for (name, v, band) in ms {
            let (unit, value, range) = match name.as_str() {
                "latency" | "gpu-latency" => ("ms", v / 1e6, band.map(|(lo, hi)| format!("[{:.3}, {:.3}]", lo / 1e6, hi / 1e6))),
                "rmse" => ("rmse", v, None),
                n if n.starts_with("instructions-") => ("instructions", v, None),
                _ => ("bytes", v, None),
            };
            let mut o = json!({ "name": format!("{bench} {name}"), "unit": unit, "value": value });
            if let Some(r) = range {
                o["range"] = json!(r);
                o["extra"] = json!("95 % confidence band of the median frame");
            }
            out.push(o);
        }
    }
    Value::Array(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_band_is_order_statistics() {
        let b = median_band(&[5.0, 1.0, 3.0]).unwrap();
        assert_eq!((b.median, b.lo, b.hi), (3.0, 1.0, 5.0));
        // n = 10: P(Bin(10, .5) <= 1) = 0.0107, <= 2 is 0.0547: k = 2.
        let s: Vec<f64> = (1..=10).map(f64::from).collect();
        let b = median_band(&s).unwrap();
        assert_eq!((b.median, b.lo, b.hi), (5.5, 2.0, 9.0));
        // n = 20: P(<= 5) = 0.0207, P(<= 6) = 0.0577: k = 6.
        let s: Vec<f64> = (1..=20).map(f64::from).collect();
        let b = median_band(&s).unwrap();
        assert_eq!((b.lo, b.hi), (6.0, 15.0));
        assert!(median_band(&[]).is_none());
    }

    #[test]
    fn times_regress_only_outside_both_bands_and_the_margin() {
        let b = Band { median: 100.0, lo: 95.0, hi: 105.0 };
        assert_eq!(time_verdict(b, Band { median: 130.0, lo: 120.0, hi: 140.0 }, 0.1), Verdict::Regression);
        assert_eq!(time_verdict(b, Band { median: 108.0, lo: 106.0, hi: 110.0 }, 0.1), Verdict::Ok);
        assert_eq!(time_verdict(b, Band { median: 130.0, lo: 100.0, hi: 140.0 }, 0.1), Verdict::Ok);
        assert_eq!(time_verdict(b, Band { median: 70.0, lo: 60.0, hi: 80.0 }, 0.1), Verdict::Improved);
    }

    /// A summary of `runs` rows on one dataset, each with `samples` frame times.
    fn summary(runs: usize, samples: &[f64], schema: u32, rmse: f64) -> SummaryFile {
        let rows: Vec<Value> = (0..runs)
            .map(|i| {
                json!({"dataset": "d", "method": format!("m{i:05}"), "status": "ok", "result": {
                    "schema_version": schema, "spec": "m", "work": {},
                    "upload": {"bytes_per_frame": 1, "cell_bytes_per_frame": 1, "constant_bytes_per_frame": 0, "static_bytes": 1},
                    "time_ms": {"samples": {"frame": samples}},
                    "image": {"covered_pixels": 1, "non_finite_pixels": 0},
                    "error": {"rmse": rmse}}})
            })
            .collect();
        let v = json!({"environment": {"device": {"name": "x", "driver_info": "y"}},
            "settings": {"width": 1, "height": 1, "orbit_step_deg": 5.0, "quick": true}, "runs": rows});
        serde_json::from_value(v).unwrap()
    }

    #[test]
    fn bands_stay_finite_and_ordered_at_any_sample_count_and_size() {
        for n in [1usize, 7, 1074, 1075, 5000] {
            for scale in [1.0, 1e-300, 8e7] {
                let s: Vec<f64> = (0..n).map(|i| scale * (1.0 + (i * 7919 % n) as f64)).collect();
                let b = median_band(&s).unwrap();
                assert!(b.lo <= b.median && b.median <= b.hi, "n={n} scale={scale}: {b:?}");
            }
        }
        let s = summary(2, &vec![80_000_000.0; 1100], 2, 0.1);
        validate(&s).unwrap();
        for v in [bmf(&s), gha(&s)] {
            let text = serde_json::to_string(&v).unwrap();
            assert!(!text.contains("null"), "{text}");
        }
        let lat = &bmf(&s)["d/m00000"]["latency"];
        assert!(lat["lower_value"].as_f64() <= lat["value"].as_f64() && lat["value"].as_f64() <= lat["upper_value"].as_f64());
    }

    #[test]
    fn summaries_no_run_writes_are_refused() {
        let e = format!("{:#}", validate(&summary(1, &[1.0], 99, 0.1)).unwrap_err());
        assert!(e.contains("schema_version 99") && e.contains("reads schema_version 2"), "{e}");
        let mut s = summary(1, &[1.0], 2, 0.1);
        s.schema_version = Some(3);
        assert!(validate(&s).is_err());
        let e = format!("{:#}", validate(&summary(1, &[1.0], 2, -0.5)).unwrap_err());
        assert!(e.contains("error.rmse -0.5"), "{e}");
        for t in [-1.0, 1e308] {
            let e = format!("{:#}", validate(&summary(1, &[1.0, t], 2, 0.1)).unwrap_err());
            assert!(e.contains("time_ms.samples.frame"), "{e}");
        }
    }

    #[test]
    fn a_comparison_grows_linearly_with_the_runs() {
        for runs in [30usize, 3000] {
            let s = summary(runs, &[1.0, 2.0, 3.0], 2, 0.1);
            let c = compare(&s, &s, &Tolerances::default()).unwrap();
            let ratios = c.lines.iter().filter(|l| l.figure == "frame-time ratio").count();
            assert_eq!(ratios, runs - 1);
            assert_eq!(c.regressions(), 0);
        }
    }

    /// `summary(2, ..)` with the second run's frames `slower` times slower,
    /// its covered pixels `+pixels`, started at `started` on `machine`.
    fn sitting(slower: f64, pixels: u64, machine: Option<&str>, started: &str) -> SummaryFile {
        let mut s = summary(2, &[10.0, 10.5, 11.0, 10.2, 10.8, 10.4, 10.6], 2, 0.1);
        let x = s.runs[1].result.as_mut().unwrap();
        for t in x.time_ms.samples.get_mut("frame").unwrap() {
            *t *= slower;
        }
        x.image.covered_pixels += pixels;
        s.environment.machine_boot_id = machine.map(String::from);
        s.environment.started_utc = started.into();
        s
    }

    #[test]
    fn moved_times_fail_only_in_one_sitting_or_when_asked() {
        let base = sitting(1.0, 0, Some("m1"), "20261206T010000Z");
        let auto = Tolerances::default();
        let always = Tolerances { times: Times::Always, ..auto };
        let off = Tolerances { times: Times::Off, ..auto };
        let ratio = |c: &Comparison| c.lines.iter().find(|l| l.figure == "frame-time ratio").map(|l| l.verdict);
        // Only times moved, another machine, or the same one hours later, or
        // one that records no machine: notes, no failure.
        for new in [
            sitting(2.0, 0, Some("m2"), "20261206T010500Z"),
            sitting(2.0, 0, Some("m1"), "20261206T030000Z"),
            sitting(2.0, 0, None, "20261206T010500Z"),
        ] {
            let c = compare(&base, &new, &auto).unwrap();
            assert_eq!(c.regressions(), 0, "{}", c.table());
            assert_eq!(ratio(&c), Some(Verdict::Info), "{}", c.table());
            assert!(c.table().contains("moved times are notes"), "{}", c.table());
            // --times: a failure; --no-times: not compared.
            assert_eq!(compare(&base, &new, &always).unwrap().regressions(), 1);
            assert_eq!(ratio(&compare(&base, &new, &off).unwrap()), None);
        }
        // A count that moved fails however the times are treated.
        let c = compare(&base, &sitting(1.0, 1, Some("m2"), "20261206T010500Z"), &auto).unwrap();
        assert_eq!(c.regressions(), 1, "{}", c.table());
        assert!(c.lines.iter().any(|l| l.verdict == Verdict::Regression && l.figure == "image.covered_pixels"));
        // The same machine and boot, 50 minutes apart: one sitting, the moved ratio fails.
        let c = compare(&base, &sitting(2.0, 0, Some("m1"), "20261206T015000Z"), &auto).unwrap();
        assert_eq!(c.regressions(), 1, "{}", c.table());
        assert_eq!(ratio(&c), Some(Verdict::Regression));
        assert!(c.table().contains("same machine and sitting (one machine and boot, started 3000 s apart)"), "{}", c.table());
        // Unchanged times in one sitting pass.
        assert_eq!(compare(&base, &sitting(1.0, 0, Some("m1"), "20261206T015000Z"), &auto).unwrap().regressions(), 0);
    }

    #[test]
    fn suite_start_times_parse_back() {
        use crate::harness::suite::{parse_utc, utc_now};
        let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_secs() as i64;
        assert!((parse_utc(&utc_now()).unwrap() - now).abs() <= 2);
        assert_eq!(parse_utc("19700101T000000Z"), Some(0));
        assert_eq!(parse_utc("20000301T000001Z"), Some(951_868_801));
        for bad in ["", "2026-12-06T01:00:00Z", "20261306T010000Z", "20261206T250000Z", "20261206T010000", "2026120６T01000Z"] {
            assert_eq!(parse_utc(bad), None, "{bad}");
        }
    }

    #[test]
    fn summary_text_cannot_forge_table_rows() {
        let mut s = summary(2, &[1.0], 2, 0.1);
        s.runs[1].label = Some("m | ok\n| REGRESSION | forged | row | 1 | 2 | x |\r\u{1b}[31m<b>".into());
        s.runs[1].status = "failed".into();
        s.runs[1].message = Some("oom\n| REGRESSION | forged |".into());
        s.runs[1].result = None;
        let base = summary(2, &[1.0], 2, 0.1);
        let mut new = summary(2, &[1.0], 2, 0.1);
        new.runs[1].label = s.runs[1].label.clone();
        let c = compare(&base, &s, &Tolerances::default()).unwrap();
        let c2 = compare(&base, &new, &Tolerances::default()).unwrap();
        for t in [c.table(), c2.table()] {
            // Every table line is one row of six cells: `|` only as separators.
            for line in t.lines().filter(|l| l.starts_with('|')) {
                let separators = line.replace("\\|", "").matches('|').count();
                assert_eq!(separators, 7, "{line}");
            }
            assert!(!t.contains('\u{1b}') && !t.contains('\r') && !t.contains("<b>"), "{t}");
            assert!(!t.lines().any(|l| l.starts_with("| REGRESSION | forged")), "{t}");
        }
        assert!(c.table().contains("m \\| ok\\n\\| REGRESSION \\| forged"), "{}", c.table());
        assert_eq!(report::md_cell("a|b\\c\nd\te\u{7f}"), "a\\|b\\\\c\\nd e\\u{7f}");
    }

    #[test]
    fn phases_that_collide_as_measures_are_refused_naming_both() {
        let with_phases = |names: &[&str]| {
            let mut s = summary(1, &[1.0], 2, 0.1);
            let phases: BTreeMap<String, Value> = names.iter().map(|n| (n.to_string(), json!({"total": 10}))).collect();
            s.runs[0].result.as_mut().unwrap().count =
                Some(serde_json::from_value(json!({"frames": 1, "phases": phases, "frame": {"total": 10}})).unwrap());
            s
        };
        validate(&with_phases(&["device", "sort", "cull_gpu"])).unwrap();
        for (a, b) in [("Device", "device"), ("sort.gpu", "sort_gpu"), ("frame", "sort")] {
            let e = format!("{:#}", validate(&with_phases(&[a, b])).unwrap_err());
            let first = if a == "frame" { "the frame total".to_string() } else { format!("{a:?}") };
            assert!(e.contains(&first) && e.contains(&format!("{:?}", if a == "frame" { a } else { b })), "{e}");
            assert!(e.contains("instructions-"), "{e}");
        }
        // What is accepted exports unique names.
        let s = with_phases(&["device", "sort"]);
        let names: Vec<String> = gha(&s).as_array().unwrap().iter().map(|e| e["name"].as_str().unwrap().to_string()).collect();
        let unique: std::collections::BTreeSet<&String> = names.iter().collect();
        assert_eq!(unique.len(), names.len(), "{names:?}");
    }

    #[test]
    fn instructions_regress_beyond_the_tolerance() {
        let tol = Tolerances::default();
        assert_eq!(instruction_verdict(1e6, 1.009e6, &tol).0, Verdict::Ok);
        assert_eq!(instruction_verdict(1e6, 0.991e6, &tol).0, Verdict::Ok);
        let (v, why) = instruction_verdict(1e6, 1.05e6, &tol);
        assert_eq!(v, Verdict::Regression);
        assert!(why.contains("+50000 instructions (+5.00 %)"), "{why}");
        assert_eq!(instruction_verdict(1e6, 0.9e6, &tol).0, Verdict::Improved);
        // A small phase's jitter stays under the absolute floor.
        assert_eq!(instruction_verdict(7_000.0, 7_500.0, &tol).0, Verdict::Ok);
    }
}
