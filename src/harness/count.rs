//! Counted work: `volbench run … --count` and `volbench suite … --count`
//! run themselves again under callgrind and report, per timed frame and per
//! phase, the instructions executed (by every thread), instead of the time.
//! Unlike time, a count repeats to a few parts in a million from run to run
//! and from a quiet machine to a loaded one (docs/tracking.md).
//!
//! How it is made deterministic:
//! - callgrind starts with instrumentation off (`--instr-atstart=no`): file
//!   loading, the CPU reference, pipeline creation and the warm-up frames
//!   (llvmpipe compiles its shader variants at the first draw, LLVM's JIT)
//!   are not counted. The runner opens the counted section after the
//!   warm-up (`vk::valgrind::start`) and closes it after the last timed
//!   frame.
//! - At each phase boundary the runner (and a method, through
//!   `Phases::ended`) dumps the counts since the previous boundary under the
//!   phase's name (`vk::valgrind::mark`); this module reads the dumps back.
//! - Frames run without CPU/device overlap, so phases never interleave.
//! - Waits count no work: valgrind runs one thread at a time, and a thread
//!   blocked on a futex (lavapipe's fence wait, its queue thread) executes
//!   nothing. Spinning is what would not repeat, so nothing spins:
//!   `LP_NUM_THREADS=0` (lavapipe rasterises and runs compute on its own
//!   queue thread, no worker pool) and rayon's pool is the main thread alone
//!   (no idle worker spins between jobs).
//! - What changes code paths is pinned and recorded in the result:
//!   `LP_NUM_THREADS`, `LP_NATIVE_VECTOR_WIDTH`, Mesa's shader disk cache
//!   off, rayon's thread count, one malloc arena without thread caches and
//!   with a fixed mmap threshold (lavapipe's per-draw-piece mallocs cost the
//!   same whatever the heap's history),
//!   valgrind's fair scheduling, no overlap. The validation layer is off (its
//!   work would count as the method's; `--validation` with `--count` is an
//!   error).
//! - The C allocator is left out of every phase and reported on its own
//!   (`count.allocator`): even with the pins, which free-list a malloc
//!   searches depends on the heap's history and on how the queue thread and
//!   the host interleaved, and moved the strip variant's `device` by 3 %.
//!
//! The device's work: lavapipe executes a submission on its queue thread
//! while the host waits on the fence. The `device` phase is every thread's
//! instructions from vkQueueSubmit until the fence has signalled: the
//! submission call itself, the rasteriser and shaders, and the host's
//! return from the wait. vkQueueSubmit is inside it because lavapipe's queue
//! thread may start on the work before the call returns, and where that
//! split falls depends on the scheduler.

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

use anyhow::{bail, ensure, Context as _, Result};
use serde::Serialize;

use crate::vk::valgrind;

/// Set by the parent for the counted child: the directory callgrind dumps
/// into. It also marks the child: a process that has it set but does not
/// run under valgrind refuses to re-execute itself (a `valgrind` that does
/// not instrument would otherwise start volbench again without end).
pub const DIR_VAR: &str = "VOLBENCH_COUNT_DIR";
/// The child's receipt in the count directory: its process id and how many
/// callgrind dumps it has read, so the parent can check that callgrind's
/// final output covers the run (`verify`).
const RECEIPT: &str = "volbench-count-receipt";
/// How long `valgrind --version` may take.
const VERSION_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(60);
/// What the counted child runs with (also recorded in `count.pinned`).
pub const PINNED_ENV: &[(&str, &str)] = &[
    ("LP_NUM_THREADS", "0"),
    ("LP_NATIVE_VECTOR_WIDTH", "128"),
    ("MESA_SHADER_CACHE_DISABLE", "true"),
    ("RAYON_NUM_THREADS", "1"),
    // One malloc arena (the host and lavapipe's queue thread share it, in
    // every run alike), no per-thread caches, and a fixed mmap threshold of
    // 1 KiB. lavapipe's draw module mallocs and frees for every piece of a
    // draw: the strip variant draws one piece per tet, split at each
    // primitive restart, some 22,600 mallocs a frame. With glibc's default,
    // self-adjusting threshold, what those mallocs cost depended on the
    // heap's history, i.e. on the runs before in the same process: the
    // strip variant's `device` moved by up to 2.5 % (docs/tracking.md).
    ("GLIBC_TUNABLES", "glibc.malloc.arena_max=1:glibc.malloc.tcache_count=0:glibc.malloc.mmap_threshold=1024"),
];
/// valgrind's options besides the output file.
const VALGRIND_ARGS: &[&str] = &[
    "--tool=callgrind",
    "-q",
    "--instr-atstart=no",
    // llvmpipe writes code at run time (LLVM's JIT) into anonymous memory.
    "--smc-check=all-non-file",
    // Threads take valgrind's lock in the order they ask for it.
    "--fair-sched=yes",
];
/// The fence time-out of a counted run, seconds, unless the user set one.
const COUNTED_FENCE_TIMEOUT_S: &str = "3600";

/// How long the whole counted run may take unless `VOLBENCH_COUNT_TIMEOUT_S`
/// says otherwise: a counted suite runs for tens of minutes, a hung one
/// (every fence wait is bounded too) is stopped within a day.
const DEFAULT_COUNTED_TIMEOUT_S: f64 = 86_400.0;
/// Optional: a directory the counted child copies callgrind's dumps into
/// before reading them (to see where a count moved with
/// `callgrind_annotate`; docs/tracking.md). Unset: the dumps are deleted.
pub const KEEP_VAR: &str = "VOLBENCH_COUNT_KEEP_DUMPS";
/// The prefix of test-only switches; a counted run records any that is set.
const TEST_SWITCH_PREFIX: &str = "VOLBENCH_TEST_";
/// The dump files' prefix inside the count directory.
const DUMP_PREFIX: &str = "callgrind.out";
/// The harness's boundary between frames; what precedes it is not counted.
const BETWEEN: &str = "between-frames";

/// The phases the runner itself marks, in frame order (a method's own CPU
/// phases come before `prepare`).
pub const RUNNER_PHASES: &[&str] = &["prepare", "upload", "record", "device", "finish"];

/// The counted child: `--count` given and running under valgrind with the
/// dump directory set. `None` when `--count` was not given.
pub fn child_dir(count: bool) -> Result<Option<PathBuf>> {
    if !count {
        return Ok(None);
    }
    ensure!(valgrind::running_on_valgrind(), "--count: internal error: not running under valgrind");
    let dir = std::env::var_os(DIR_VAR).with_context(|| format!("--count under valgrind needs {DIR_VAR} (set by volbench itself)"))?;
    write_receipt(Path::new(&dir))?;
    // rayon's pool is this thread alone: no idle worker spins.
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .use_current_thread()
        .build_global()
        .context("--count: making rayon's pool the main thread alone")?;
    Ok(Some(PathBuf::from(dir)))
}

/// Whether `--count` must re-execute this process under valgrind: not
/// when it already runs under valgrind, and never a second time: a process
/// volbench started under `valgrind` to be counted ({DIR_VAR} set) that
/// finds itself not under valgrind is an error, so a `valgrind` that just
/// runs its program stops at depth one.
pub fn needs_reexec(count: bool) -> Result<bool> {
    if !count || valgrind::running_on_valgrind() {
        return Ok(false);
    }
    ensure!(
        std::env::var_os(DIR_VAR).is_none(),
        "--count: volbench was started under `valgrind` to be counted, but is not running under valgrind \
         (valgrind's client request says so): the `valgrind` on PATH ({}) does not instrument; refusing to start itself again",
        which("valgrind").map_or("not found".into(), |p| p.display().to_string())
    );
    Ok(true)
}

/// Where `PATH` finds `program`.
fn which(program: &str) -> Option<PathBuf> {
    std::env::split_paths(&std::env::var_os("PATH")?).map(|d| d.join(program)).find(|p| p.is_file())
}

/// Dumps the counted child has read (and removed) so far.
static DUMPS_READ: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// The child's receipt: its process id and the dumps read so far.
fn write_receipt(dir: &Path) -> Result<()> {
    let text = format!("{} {}\n", std::process::id(), DUMPS_READ.load(std::sync::atomic::Ordering::SeqCst));
    crate::fsio::write_output(&dir.join(RECEIPT), text.as_bytes()).context("--count: writing the count receipt")
}

/// Check, after valgrind exited (`status`), that callgrind really ran the
/// counted child over the whole run in `dir`: its final output (written at
/// the program's end) exists, is callgrind's, is of the process that wrote
/// the receipt, and its part number is one past every dump, read by the
/// child or left over (none lost, none foreign).
pub fn verify(dir: &Path, status: std::process::ExitStatus) -> Result<()> {
    let final_out = dir.join(DUMP_PREFIX);
    let valgrind = which("valgrind").map_or("valgrind".into(), |p| p.display().to_string());
    if !final_out.exists() {
        bail!(
            "--count: {valgrind} exited ({status}) without callgrind's output ({} missing): it did not run volbench under callgrind",
            final_out.display()
        );
    }
    let head = crate::fsio::read_input_head(&final_out, "callgrind output", 64 * 1024)?;
    let head = String::from_utf8_lossy(&head);
    let field = |name: &str| head.lines().find_map(|l| l.strip_prefix(name)).map(str::trim);
    let bad = |why: &str| anyhow::anyhow!("--count: {}: {why}: not callgrind's output of the counted run", final_out.display());
    ensure!(field("creator:").is_some_and(|c| c.starts_with("callgrind")), bad("no `creator: callgrind` line"));
    ensure!(field("desc: Trigger:") == Some("Program termination"), bad("not the dump at the program's end"));
    let pid: u64 = field("pid:").and_then(|p| p.parse().ok()).ok_or_else(|| bad("no process id"))?;
    let part: u64 = field("part:").and_then(|p| p.parse().ok()).ok_or_else(|| bad("no part number"))?;
    let receipt = dir.join(RECEIPT);
    if !receipt.exists() {
        bail!("--count: {valgrind} exited ({status}) and callgrind wrote output, but the counted volbench never started (no {RECEIPT})");
    }
    let text = crate::fsio::read_input_text(&receipt, "count receipt", 1024)?;
    let mut words = text.split_whitespace().map(str::parse::<u64>);
    let (Some(Ok(child)), Some(Ok(read))) = (words.next(), words.next()) else {
        bail!("--count: {}: not a count receipt ({:?})", receipt.display(), crate::fsio::clip_message(&text));
    };
    ensure!(pid == child, bad(&format!("of process {pid}, the counted volbench was {child}")));
    let left = std::fs::read_dir(dir)
        .with_context(|| format!("reading the count directory {}", dir.display()))?
        .filter_map(|e| e.ok())
        .filter(|e| dump_number(&e.path()).is_some())
        .count() as u64;
    ensure!(
        part == read + left + 1,
        bad(&format!("its part {part} is not one past the {} dumps of the run ({read} read, {left} left over)", read + left))
    );
    Ok(())
}

/// Run this command again under callgrind, with what changes code paths
/// pinned; its exit status is ours.
pub fn reexec() -> Result<ExitCode> {
    ensure!(valgrind::SUPPORTED, "--count needs x86_64 (valgrind client requests)");
    ensure!(
        which("valgrind").is_some(),
        "--count runs volbench under valgrind, which was not found in PATH; scripts/setup.sh installs it"
    );
    let version = super::child::run(Command::new("valgrind").arg("--version"), "--count: `valgrind --version`", VERSION_TIMEOUT, "60 s", Some(64 * 1024))?;
    ensure!(version.status.success(), "--count: `valgrind --version` failed ({}): {}", version.status, version.stderr_text());
    let exe = std::env::current_exe().context("--count: locating the volbench binary to run under valgrind")?;
    // Callgrind's dumps go here: a fresh directory of ours (random name,
    // mode 0700), removed when dropped.
    let scratch = crate::fsio::scratch_dir("volbench-count-").context("--count")?;
    let dir = scratch.path();
    let args: Vec<OsString> = std::env::args_os().skip(1).collect();
    let mut cmd = Command::new("valgrind");
    cmd.args(VALGRIND_ARGS)
    .arg(format!("--callgrind-out-file={}", dir.join(DUMP_PREFIX).display()))
    .arg(&exe)
    .args(&args)
    .env(DIR_VAR, dir)
    .envs(PINNED_ENV.iter().copied())
    // The validation layer's own work would be counted as the method's
    // (the same frames are validated in the uncounted runs).
    .env_remove(crate::vk::VALIDATION_VAR)
    .env_remove("VK_LAYER_ENABLES")
    .env_remove("VK_INSTANCE_LAYERS");
    // Under valgrind a warm-up frame (llvmpipe compiling its variants) can
    // take minutes on a loaded machine: not a hung device.
    if std::env::var_os(crate::vk::FENCE_TIMEOUT_VAR).is_none() {
        cmd.env(crate::vk::FENCE_TIMEOUT_VAR, COUNTED_FENCE_TIMEOUT_S);
    }
    let limit = crate::switches::seconds(crate::switches::COUNT_TIMEOUT_S)?.unwrap_or(DEFAULT_COUNTED_TIMEOUT_S);
    let status = super::child::run_attached(&mut cmd, "--count: valgrind", std::time::Duration::from_secs_f64(limit), crate::switches::COUNT_TIMEOUT_S)?;
    // A valgrind that failed with its output written: the counted process
    // said why (its exit status is ours); one that wrote nothing, or
    // claimed success without the output of the whole run, is an error here.
    let wrote_nothing = !dir.join(DUMP_PREFIX).exists();
    let checked = verify(dir, status);
    drop(scratch);
    match status.code() {
        Some(0) => checked.map(|()| ExitCode::SUCCESS),
        Some(c) if wrote_nothing => checked.map(|()| ExitCode::from(u8::try_from(c).unwrap_or(1))),
        Some(c) => Ok(ExitCode::from(u8::try_from(c).unwrap_or(1))),
        None => bail!("--count: volbench under valgrind was killed by a signal ({status})"),
    }
}

/// Instructions of one phase: the timed frames' total and each frame's.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct PhaseCount {
    pub total: u64,
    pub per_frame: Vec<u64>,
}

/// The counted work of a run's timed frames (`count` in the result).
#[derive(Debug, Clone, Serialize)]
pub struct CountReport {
    /// `callgrind` and the event counted (`Ir`: instructions executed).
    pub tool: String,
    pub event: String,
    pub frames: usize,
    /// Instructions per phase over the timed frames: the method's own CPU
    /// phases, then `prepare` (the rest of the method's CPU half), `upload`,
    /// `record`, `device` and `finish` (query results, the method's
    /// after-frame work).
    pub phases: BTreeMap<String, PhaseCount>,
    /// Every phase of each frame together.
    pub frame: PhaseCount,
    /// The C allocator's instructions over every phase of each frame,
    /// left out of `phases` and `frame`: what a malloc costs depends on the
    /// heap's history and on how threads interleaved, not on the work
    /// (lavapipe's per-draw-piece mallocs moved the strip variant's `device`
    /// by 3 %; docs/tracking.md). Reported, not compared.
    pub allocator: PhaseCount,
    /// How the device's work is attributed.
    pub device_attribution: String,
    /// What was pinned because it changes code paths.
    pub pinned: BTreeMap<String, String>,
}

/// One dump: its label, the instructions since the previous one outside
/// the allocator, and the allocator's own.
#[derive(Debug, Clone, PartialEq)]
pub struct Dump {
    pub label: String,
    pub instructions: u64,
    pub allocator: u64,
}

/// Whether a function is the C allocator's (its self cost is not the
/// work's): glibc's malloc.c (libc6-dbg, a dependency of Debian's
/// valgrind, names its internal functions and file) or, without debug
/// information, its exported entry points.
fn is_allocator(file: &str, function: &str) -> bool {
    file.ends_with("malloc/malloc.c")
        || matches!(function, "malloc" | "free" | "calloc" | "realloc" | "reallocarray" | "posix_memalign" | "aligned_alloc" | "memalign")
}

/// A compressed name of callgrind's format: `(id) name` defines id, `(id)`
/// refers back to it, a bare name is itself.
fn name<'a>(spec: &'a str, table: &mut std::collections::HashMap<&'a str, &'a str>) -> &'a str {
    let spec = spec.trim();
    match spec.strip_prefix('(').and_then(|r| r.split_once(')')) {
        Some((id, rest)) if rest.trim().is_empty() => table.get(id).copied().unwrap_or(""),
        Some((id, rest)) => {
            table.insert(id, rest.trim());
            rest.trim()
        }
        None => spec,
    }
}

/// The allocator's self cost in one dump (callgrind's format with
/// `positions: line`): the cost lines of its functions, not counting the
/// inclusive cost line that follows each `calls=` line.
fn allocator_cost(text: &str, what: &str) -> Result<u64> {
    let (mut files, mut fns) = (std::collections::HashMap::new(), std::collections::HashMap::new());
    let (mut file, mut in_alloc, mut call_cost_next) = ("", false, false);
    let mut total = 0u64;
    for line in text.lines() {
        let first = line.as_bytes().first().copied().unwrap_or(b' ');
        if first.is_ascii_digit() || matches!(first, b'+' | b'-' | b'*') {
            if std::mem::take(&mut call_cost_next) || !in_alloc {
                continue;
            }
            let ir = line.split_whitespace().nth(1).unwrap_or("0");
            total += ir.parse::<u64>().with_context(|| format!("{what}: cost line '{line}' has no instruction count"))?;
        } else if let Some(spec) = line.strip_prefix("fl=") {
            file = name(spec, &mut files);
        } else if let Some(spec) = line.strip_prefix("fi=").or_else(|| line.strip_prefix("fe=")).or_else(|| line.strip_prefix("cfi=")).or_else(|| line.strip_prefix("cfl=")) {
            name(spec, &mut files);
        } else if let Some(spec) = line.strip_prefix("fn=") {
            in_alloc = is_allocator(file, name(spec, &mut fns));
        } else if let Some(spec) = line.strip_prefix("cfn=") {
            name(spec, &mut fns);
        } else if line.starts_with("calls=") {
            call_cost_next = true;
        }
    }
    Ok(total)
}

/// Parse one callgrind dump: the trigger's label, the `totals:` line
/// (callgrind with its default event set: `Ir` first) and the allocator's
/// part of it.
pub fn parse_dump(text: &str, what: &str) -> Result<Dump> {
    let label = text
        .lines()
        .find_map(|l| l.strip_prefix("desc: Trigger: Client Request: "))
        .with_context(|| format!("{what}: no client-request trigger line"))?;
    let totals = text
        .lines()
        .find_map(|l| l.strip_prefix("totals:").or_else(|| l.strip_prefix("summary:")))
        .with_context(|| format!("{what}: no totals line"))?;
    let all: u64 = totals
        .split_whitespace()
        .next()
        .and_then(|v| v.parse().ok())
        .with_context(|| format!("{what}: totals line '{totals}' has no instruction count"))?;
    let allocator = allocator_cost(text, what)?;
    ensure!(allocator <= all, "{what}: the allocator's {allocator} instructions exceed the dump's total {all}");
    Ok(Dump { label: label.trim().to_string(), instructions: all - allocator, allocator })
}

/// Read (and remove) the dumps written into `dir` so far, in order.
pub fn take_dumps(dir: &Path) -> Result<Vec<Dump>> {
    let mut files = Vec::new();
    for e in std::fs::read_dir(dir).with_context(|| format!("reading the count directory {}", dir.display()))? {
        let path = e?.path();
        if let Some(n) = dump_number(&path) {
            files.push((n, path));
        }
    }
    files.sort();
    let keep = std::env::var_os(KEEP_VAR).map(PathBuf::from);
    let mut out = Vec::with_capacity(files.len());
    for (_, path) in files {
        let text = std::fs::read_to_string(&path).with_context(|| format!("reading callgrind dump {}", path.display()))?;
        if let (Some(keep), Some(name)) = (&keep, path.file_name()) {
            let to = keep.join(name);
            std::fs::write(&to, &text).with_context(|| format!("{KEEP_VAR}: copying callgrind dump to {}", to.display()))?;
        }
        out.push(parse_dump(&text, &path.display().to_string())?);
        std::fs::remove_file(&path).with_context(|| format!("removing {}", path.display()))?;
        DUMPS_READ.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
    }
    write_receipt(dir)?;
    Ok(out)
}

/// The part number of a dump file (`callgrind.out.N`), `None` for any other.
fn dump_number(path: &Path) -> Option<u64> {
    path.file_name()?.to_str()?.strip_prefix(DUMP_PREFIX)?.strip_prefix('.')?.parse().ok()
}

/// The boundary at the start of each counted frame.
pub fn frame_start() {
    valgrind::mark(BETWEEN);
}

/// The end of one of the runner's phases.
pub fn phase_end(name: &'static str) {
    valgrind::mark(name);
}

/// Group the dumps of `frames` counted frames into the report.
pub fn report(dumps: &[Dump], frames: usize) -> Result<CountReport> {
    let mut per_frame: Vec<BTreeMap<String, u64>> = Vec::new();
    let mut allocator: Vec<u64> = Vec::new();
    for d in dumps {
        if d.label == BETWEEN {
            per_frame.push(BTreeMap::new());
            allocator.push(0);
        } else if let (Some(f), Some(a)) = (per_frame.last_mut(), allocator.last_mut()) {
            *f.entry(d.label.clone()).or_default() += d.instructions;
            *a += d.allocator;
        }
    }
    ensure!(
        per_frame.len() == frames,
        "--count: {} counted frames in callgrind's dumps, expected {frames} (is the binary run under callgrind?)",
        per_frame.len()
    );
    let names: std::collections::BTreeSet<&String> = per_frame.iter().flat_map(|f| f.keys()).collect();
    let phases: BTreeMap<String, PhaseCount> = names
        .into_iter()
        .map(|n| {
            let v: Vec<u64> = per_frame.iter().map(|f| f.get(n).copied().unwrap_or(0)).collect();
            (n.clone(), PhaseCount { total: v.iter().sum(), per_frame: v })
        })
        .collect();
    let frame_v: Vec<u64> = per_frame.iter().map(|f| f.values().sum()).collect();
    let mut pinned: BTreeMap<String, String> = PINNED_ENV.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect();
    pinned.insert("overlap".into(), "off".into());
    pinned.insert("rayon_pool".into(), "the main thread alone".into());
    pinned.insert("valgrind".into(), VALGRIND_ARGS.join(" "));
    // A test-only switch (`VOLBENCH_TEST_*`, e.g. the deliberate slowdown of
    // docs/tracking.md) is recorded, so that a count made with one shows it.
    pinned.extend(crate::switches::utf8_vars().filter(|(k, _)| k.starts_with(TEST_SWITCH_PREFIX)));
    Ok(CountReport {
        tool: "callgrind".into(),
        event: "Ir".into(),
        frames,
        phases,
        frame: PhaseCount { total: frame_v.iter().sum(), per_frame: frame_v },
        allocator: PhaseCount { total: allocator.iter().sum(), per_frame: allocator },
        device_attribution: "every thread's instructions from vkQueueSubmit until the frame's fence signalled \
                             (the submission, lavapipe's queue thread, the host's return from the wait)"
            .into(),
        pinned,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_a_dump() {
        let text = "version: 1\ncreator: callgrind-3.19.0\npid: 1\ncmd: x\npart: 3\n\ndesc: I1 cache:\ndesc: Timerange: Basic block 1 - 2\n\
                    desc: Trigger: Client Request: sort\n\npositions: line\nevents: Ir\nsummary: 12345\n\nfn=(1) main\n0 3\n\ntotals: 12345\n";
        assert_eq!(parse_dump(text, "t").unwrap(), Dump { label: "sort".into(), instructions: 12345, allocator: 0 });
        assert!(parse_dump("events: Ir\n", "t").unwrap_err().to_string().contains("trigger"));
    }

    #[test]
    fn groups_frames_and_phases() {
        let d = |l: &str, n| Dump { label: l.into(), instructions: n, allocator: 1 };
        let dumps = [d(BETWEEN, 7), d("sort", 10), d("device", 100), d(BETWEEN, 3), d("sort", 11), d("device", 101), d("device", 1)];
        let r = report(&dumps, 2).unwrap();
        assert_eq!(r.phases["sort"].per_frame, vec![10, 11]);
        assert_eq!(r.phases["device"].total, 202);
        assert_eq!(r.frame.per_frame, vec![110, 113]);
        assert_eq!(r.allocator.per_frame, vec![2, 3]);
        assert!(report(&dumps, 3).is_err());
    }

    #[test]
    fn the_final_output_must_cover_the_counted_run() {
        use std::os::unix::process::ExitStatusExt as _;
        let ok = std::process::ExitStatus::from_raw(0);
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let check = || verify(d, ok).map_err(|e| format!("{e:#}"));
        // Nothing written: valgrind did not run volbench under callgrind.
        assert!(check().unwrap_err().contains("without callgrind's output"));
        let final_dump = |pid: u64, part: u64, creator: &str| {
            let text = format!("# callgrind format\nversion: 1\ncreator: {creator}\npid: {pid}\ncmd:  volbench\npart: {part}\n\ndesc: Trigger: Program termination\n\ntotals: 0\n");
            std::fs::write(d.join(DUMP_PREFIX), text).unwrap();
        };
        final_dump(7, 3, "fake");
        assert!(check().unwrap_err().contains("no `creator: callgrind` line"));
        final_dump(7, 3, "callgrind-3.19.0");
        assert!(check().unwrap_err().contains("never started"));
        std::fs::write(d.join(RECEIPT), "8 2\n").unwrap();
        assert!(check().unwrap_err().contains("of process 7, the counted volbench was 8"));
        std::fs::write(d.join(RECEIPT), "7 1\n").unwrap();
        assert!(check().unwrap_err().contains("part 3 is not one past the 1 dumps"), "{:?}", check());
        // Two dumps read, or one read and one left over: covered.
        std::fs::write(d.join(RECEIPT), "7 2\n").unwrap();
        check().unwrap();
        std::fs::write(d.join(RECEIPT), "7 1\n").unwrap();
        std::fs::write(d.join(format!("{DUMP_PREFIX}.2")), "").unwrap();
        check().unwrap();
        std::fs::write(d.join(RECEIPT), "seven").unwrap();
        assert!(check().unwrap_err().contains("not a count receipt"));
    }

    #[test]
    fn leaves_out_the_allocators_self_cost() {
        // malloc.c's functions by file (named once, then by id), `free` by
        // name; the cost line after `calls=` is the callee's inclusive cost.
        let text = "desc: Trigger: Client Request: device\npositions: line\nevents: Ir\n\
                    fl=(1) ./malloc/./malloc/malloc.c\nfn=(1) _int_malloc\n10 100\n+2 5\n\
                    fl=(2) lvp.c\nfn=(2) draw\n3 1000\ncfl=(1)\ncfn=(1)\ncalls=1 10\n* 105\n\
                    fl=(1)\nfn=(1)\n11 7\nfl=(3) ???\nfn=(3) free\n0 20\ncfn=(2)\ncalls=1 3\n* 1000\n\
                    totals: 1132\n";
        let d = parse_dump(text, "t").unwrap();
        assert_eq!((d.instructions, d.allocator), (1000, 132));
    }
}
