//! What a suite wrote: the structure of `summary.json` (the environment,
//! every run's row, the peers' rows, the culling checks) and its flat form
//! `summary.csv`.

use std::fmt::Write as _;

use serde::Serialize;

use super::plan::{Scene, SuiteSettings};
use crate::harness::peers::PeerRow;
use crate::harness::run::RunResult;
use crate::vk::{Context, DeviceInfo};

/// The machine a suite ran on.
#[derive(Debug, Clone, Serialize)]
pub struct Environment {
    pub device: DeviceInfo,
    pub cpu_model: String,
    pub cores: usize,
    /// lavapipe's thread count (`LP_NUM_THREADS`), when set.
    pub lp_num_threads: Option<String>,
    pub git_sha: &'static str,
    pub volbench_version: &'static str,
    pub started_utc: String,
    /// Which machine and boot ran the suite, without naming either: the
    /// first 16 bytes of SHA-256 over `/etc/machine-id` and
    /// `/proc/sys/kernel/random/boot_id` (`compare` decides "same machine
    /// and sitting" from it, `track::same_sitting`). Absent when either
    /// cannot be read.
    pub machine_boot_id: Option<String>,
    /// The environment switches set that change what is measured
    /// (`crate::switches::recorded`); empty in an ordinary suite.
    pub env_switches: std::collections::BTreeMap<String, String>,
}

impl Environment {
    pub fn of(ctx: &Context) -> Self {
        let cpu_model = std::fs::read_to_string("/proc/cpuinfo")
            .ok()
            .and_then(|t| t.lines().find(|l| l.starts_with("model name")).and_then(|l| l.split_once(':')).map(|(_, v)| v.trim().to_string()))
            .unwrap_or_else(|| "unknown".into());
        Environment {
            device: ctx.info.clone(),
            cpu_model,
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            lp_num_threads: std::env::var("LP_NUM_THREADS").ok(),
            git_sha: env!("VOLBENCH_GIT_SHA"),
            volbench_version: env!("CARGO_PKG_VERSION"),
            started_utc: utc_now(),
            machine_boot_id: machine_boot_id(),
            env_switches: crate::switches::recorded(),
        }
    }
}

/// See [`Environment::machine_boot_id`].
pub fn machine_boot_id() -> Option<String> {
    use sha2::{Digest as _, Sha256};
    let read = |p: &str| std::fs::read_to_string(p).ok().map(|t| t.trim().to_string()).filter(|t| !t.is_empty());
    let machine = read("/etc/machine-id").or_else(|| read("/var/lib/dbus/machine-id"))?;
    let boot = read("/proc/sys/kernel/random/boot_id")?;
    let digest = Sha256::digest(format!("volbench machine {machine} boot {boot}").as_bytes());
    Some(crate::harness::datasets::hex(&digest[..16]))
}

/// Seconds since 1970 of a `YYYYMMDDTHHMMSSZ` time ([`utc_now`]'s form);
/// `None` for anything else.
pub fn parse_utc(text: &str) -> Option<i64> {
    let b = text.as_bytes();
    if b.len() != 16 || b[8] != b'T' || b[15] != b'Z' || !b[..8].iter().chain(&b[9..15]).all(u8::is_ascii_digit) {
        return None;
    }
    let num = |r: std::ops::Range<usize>| text[r].parse::<i64>().ok();
    let (y, m, d) = (num(0..4)?, num(4..6)?, num(6..8)?);
    let (hh, mm, ss) = (num(9..11)?, num(11..13)?, num(13..15)?);
    if !(1..=12).contains(&m) || !(1..=31).contains(&d) || hh > 23 || mm > 59 || ss > 60 {
        return None;
    }
    // Days from civil (Howard Hinnant's algorithm, the inverse of utc_now's).
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = if m > 2 { m - 3 } else { m + 9 };
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    let days = era * 146_097 + doe - 719_468;
    Some(days * 86_400 + hh * 3600 + mm * 60 + ss)
}

/// The current UTC time as `YYYYMMDDTHHMMSSZ` (for run ids).
pub fn utc_now() -> String {
    let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let (days, rem) = (secs / 86400, secs % 86400);
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}{m:02}{d:02}T{:02}{:02}{:02}Z", rem / 3600, (rem / 60) % 60, rem % 60)
}

/// One row of the suite: the run's record, or why it failed or was skipped.
#[derive(Debug, Clone, Serialize)]
pub struct SuiteRow {
    pub dataset: String,
    pub method: String,
    /// The method and its non-default options (`balanced:integrator=average`).
    pub label: String,
    pub status: &'static str,
    pub message: Option<String>,
    /// The view and transfer function (`standard`, or a culling scene).
    pub scene: Scene,
    /// Position in the suite's run order (peers' runs counted too).
    pub sequence: usize,
    pub result: Option<RunResult>,
    /// The work the method's family shares with other placements of it
    /// (`Family::placement`; the placement report groups by it).
    #[serde(skip)]
    pub placement: Option<&'static str>,
}

/// A dataset as the suite ran it: where it came from, the transfer
/// function its standard scene was shown with, and what its peers read.
#[derive(Debug, Clone, Serialize)]
pub struct SuiteDatasetRow {
    pub name: String,
    /// The shipped name, or the user's file as `--data` gave it.
    pub source: String,
    pub kind: crate::algo::method::DataKind,
    /// A user's file (`--data FILE`), not a shipped dataset.
    pub user: bool,
    /// The transfer function's name (`None`: it could not be made; the
    /// dataset's rows say why).
    pub transfer_function: Option<String>,
    /// Where it came from: the `--tf` file, the shipped preset, or volbench's
    /// generic ramp over the scalar range (a user's file without `--tf`).
    pub transfer_function_from: String,
    /// The scalar array named by `FILE#SCALAR` or recorded by the reader
    /// (`scalar_array` in the dataset's statistics), when known.
    pub scalar_array: Option<String>,
}

impl SuiteDatasetRow {
    pub(super) fn of(d: &super::plan::SuiteDataset, loaded: &crate::harness::datasets::Dataset, tf: Option<&crate::scene::TransferFunction>, tf_file: Option<&std::path::Path>) -> Self {
        let from = match tf_file {
            Some(p) => format!("--tf {}", p.display()),
            None if d.user => "volbench's generic ramp over the scalar range".into(),
            None => "the dataset's preset".into(),
        };
        let named = d.source.rsplit_once('#').filter(|_| d.user && std::fs::symlink_metadata(&d.source).is_err()).map(|(_, a)| a.to_string());
        let recorded = loaded.summary().stats.get("scalar_array").and_then(|v| v.as_str()).map(str::to_string);
        SuiteDatasetRow {
            name: d.name.clone(),
            source: d.source.clone(),
            kind: d.kind,
            user: d.user,
            transfer_function: tf.map(|t| t.name.clone()),
            transfer_function_from: from,
            scalar_array: named.or(recorded),
        }
    }
}

/// What `summary.json` holds.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    pub environment: Environment,
    pub settings: SuiteSettings,
    /// Each dataset run, in order: source, transfer function, scalar.
    pub datasets: Vec<SuiteDatasetRow>,
    pub runs: Vec<SuiteRow>,
    /// Peers' runs (`--peers`), apart from volbench's: other programs'
    /// renderers on the same data, view and transfer function.
    pub peers: Vec<PeerRow>,
    /// Each culling scene's culled image against the unculled one.
    pub cull_checks: Vec<CullCheck>,
    /// Each peer renderer against its matched run, in alternating rounds
    /// (`--rounds`, `suite::rounds`).
    pub matched: Vec<MatchedRounds>,
}

impl Summary {
    /// The runs a peer row may be matched with, fastest first: volbench's
    /// runs of the standard scene on its dataset whose image error against
    /// the f64 reference is no larger than the peer's (a faster but less
    /// accurate run would not be a like-for-like comparison); each with its
    /// median frame time and RMSE.
    pub fn matched_runs(&self, p: &crate::harness::peers::PeerRow) -> Vec<(&SuiteRow, f64, f64)> {
        use crate::harness::run::ErrorKind;
        let Some(pe) = p.error.as_ref() else { return Vec::new() };
        let mut runs: Vec<_> = self
            .runs
            .iter()
            .filter(|r| r.dataset == p.dataset && r.scene == super::plan::Scene::Standard)
            .filter_map(|r| {
                let x = r.result.as_ref()?;
                let e = x.error.as_ref().filter(|e| e.compared == ErrorKind::Image && e.rmse <= pe.rmse)?;
                Some((r, x.time_ms.phase("frame").median, e.rmse))
            })
            .filter(|(_, ms, _)| *ms > 0.0)
            .collect();
        runs.sort_by(|a, b| a.1.total_cmp(&b.1));
        runs
    }

    /// The run a peer row is matched with in the first pass: the fastest
    /// of `matched_runs`.
    pub fn matched_run(&self, p: &crate::harness::peers::PeerRow) -> Option<(&SuiteRow, f64, f64)> {
        self.matched_runs(p).into_iter().next()
    }
}

/// One peer renderer run again with the volbench runs it may be matched
/// with, in alternating rounds (`suite::rounds`).
#[derive(Debug, Clone, Serialize)]
pub struct MatchedRounds {
    pub dataset: String,
    pub peer: String,
    pub renderer: String,
    /// The volbench runs (`PlannedRun::label`): the fastest of the first
    /// pass whose RMSE against the f64 reference is no larger than the
    /// peer's (`Summary::matched_runs`), fastest first, at most two.
    pub labels: Vec<String>,
    pub rounds: Vec<Round>,
    /// Per label, its rounds' speed ratios (peer ms / its ms): median, min,
    /// max.
    pub ratios: Vec<crate::harness::stats::Summary>,
    /// The label whose median ratio is higher: the one quoted (a maximum of
    /// two estimates, so the report gives the other beside it).
    pub best: Option<usize>,
    /// Why the rounds did not all complete (those before are kept).
    pub message: Option<String>,
}

impl MatchedRounds {
    /// The quoted run and its ratios.
    pub fn quoted(&self) -> Option<(&str, &crate::harness::stats::Summary)> {
        let b = self.best?;
        Some((self.labels.get(b)?.as_str(), self.ratios.get(b)?))
    }

    /// The other run and its ratios, when there are two.
    pub fn other(&self) -> Option<(&str, &crate::harness::stats::Summary)> {
        let o = 1 - self.best.filter(|&b| b < 2)?;
        Some((self.labels.get(o)?.as_str(), self.ratios.get(o)?))
    }
}

/// One round: the peer's median frame time and each label's, in the order
/// they ran (the first label, the peer, the second; `reversed`: the other
/// way round).
#[derive(Debug, Clone, Serialize)]
pub struct Round {
    pub peer_ms: f64,
    pub volbench_ms: Vec<f64>,
    pub reversed: bool,
}

/// The unchanged-image check of one culling scene: the reference-view image
/// of a method with its culling option on against the same with it off.
#[derive(Debug, Clone, Serialize)]
pub struct CullCheck {
    pub dataset: String,
    pub scene: Scene,
    pub method: String,
    /// The option toggled (`Family::culling_option`).
    #[serde(skip)]
    pub option: &'static str,
    pub rmse: f64,
    pub max_abs: f64,
}

/// One line per run, volbench's and the peers' (`source`), with the
/// figures a spreadsheet wants; a peer has no bytes or GPU time to report.
pub fn csv(s: &Summary) -> String {
    let mut t = String::from(
        "source,dataset,method,label,status,frame_ms_median,gpu_ms_median,bytes_per_frame,bytes_per_cell,static_bytes,cells_per_second,rmse,max_abs,message\n",
    );
    let q = |x: &str| format!("\"{}\"", x.replace('"', "\"\""));
    for r in &s.runs {
        let (f, g, b, bc, st, cps, rmse, max) = match &r.result {
            Some(x) => (
                format!("{:.3}", x.time_ms.phase("frame").median),
                format!("{:.3}", x.time_ms.phase("gpu").median),
                x.upload.bytes_per_frame.to_string(),
                x.upload.bytes_per_cell.map_or(String::new(), |v| format!("{v}")),
                x.upload.static_bytes.to_string(),
                format!("{:.0}", x.cells_per_second),
                x.error.as_ref().map_or(String::new(), |e| format!("{:.6e}", e.rmse)),
                x.error.as_ref().map_or(String::new(), |e| format!("{:.6e}", e.max_abs)),
            ),
            None => Default::default(),
        };
        let _ = writeln!(
            t,
            "volbench,{},{},{},{},{f},{g},{b},{bc},{st},{cps},{rmse},{max},{}",
            r.dataset,
            r.method,
            q(&r.label),
            r.status,
            q(r.message.as_deref().unwrap_or(""))
        );
    }
    for p in &s.peers {
        let f = p.frame_ms.as_ref().map_or(String::new(), |f| format!("{:.3}", f.median));
        let rmse = p.error.as_ref().map_or(String::new(), |e| format!("{:.6e}", e.rmse));
        let max = p.error.as_ref().map_or(String::new(), |e| format!("{:.6e}", e.max_abs));
        let _ = writeln!(
            t,
            "{},{},{},{},{},{f},,,,,,{rmse},{max},{}",
            p.peer,
            p.dataset,
            q(&p.renderer),
            q(&format!("{} {} ({})", p.peer, p.renderer, p.class)),
            p.status,
            q(p.message.as_deref().unwrap_or(""))
        );
    }
    t
}
