//! Other programs `ab` and `--count` start and read, with every wait and
//! every byte bounded: a binary's `--version`, a per-run `volbench run`,
//! git, `valgrind --version`. Each child runs in a process group of its
//! own with a deadline; at the deadline (or when it prints more than its
//! caller allows) the whole group is killed, and when it exits, whatever it
//! left running in its group is killed too. Its output is read on threads
//! into `fsio::HeadTail`s (head and tail kept, the middle counted), so a
//! child that prints forever costs a few kilobytes, not gigabytes.
//!
//! Two children write to the terminal instead ([`run_attached`]): `ab`'s
//! `cargo build` of a revision and `--count`'s valgrind. They stay in
//! volbench's process group, so a Ctrl-C stops them with it as before, and
//! at their deadline they and every process they started are stopped and
//! killed (found as descendants in `/proc`).

use std::os::unix::process::CommandExt as _;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::Receiver;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{bail, Context as _, Result};

use crate::fsio::HeadTail;

/// Bytes kept of each end of a child's output stream.
pub const KEEP: usize = 16 * 1024;

/// How long the readers may take to see the end of a stream once the
/// child and its group are gone (a grandchild that left the group may hold
/// the stream open: its output is then taken as it stands).
const DRAIN_GRACE: Duration = Duration::from_secs(2);

/// A stream being read on a thread into a `HeadTail`.
pub struct Drain {
    pub seen: Arc<Mutex<HeadTail>>,
    done: Receiver<()>,
}

impl Drain {
    /// Read `stream` to its end on a thread, keeping `keep` bytes of each end.
    pub fn start(stream: Option<impl std::io::Read + Send + 'static>, keep: usize) -> Drain {
        let seen = Arc::new(Mutex::new(HeadTail::new(keep)));
        let (tx, done) = std::sync::mpsc::channel();
        let shared = Arc::clone(&seen);
        std::thread::spawn(move || {
            if let Some(mut stream) = stream {
                let mut buf = vec![0u8; 64 * 1024];
                loop {
                    match stream.read(&mut buf) {
                        Ok(0) => break,
                        Ok(n) => match shared.lock() {
                            Ok(mut s) => s.push(&buf[..n]),
                            Err(_) => break,
                        },
                        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                        Err(_) => break,
                    }
                }
            }
            let _ = tx.send(());
        });
        Drain { seen, done }
    }

    /// Bytes read so far.
    pub fn total(&self) -> u64 {
        self.seen.lock().map_or(0, |s| s.total())
    }

    /// What was read, after waiting up to `grace` for the end of the stream.
    pub fn finish(&self, grace: Duration) -> HeadTail {
        let _ = self.done.recv_timeout(grace);
        self.seen.lock().map(|s| s.clone()).unwrap_or_default()
    }
}

/// A finished child: its exit status and its output streams.
#[derive(Debug)]
pub struct Finished {
    pub status: ExitStatus,
    pub stdout: HeadTail,
    pub stderr: HeadTail,
}

impl Finished {
    /// Its standard error, trimmed and clipped for a message.
    pub fn stderr_text(&self) -> String {
        crate::fsio::clip_child_output(self.stderr.text().trim())
    }
}

/// Start `cmd` in a process group of its own (stdin from /dev/null).
/// `what` names it in errors; a file that is not executable says so.
pub fn spawn_in_group(cmd: &mut Command, what: &str) -> Result<Child> {
    cmd.process_group(0).spawn().map_err(|e| match e.kind() {
        std::io::ErrorKind::PermissionDenied => anyhow::anyhow!("{what}: not executable ({e})"),
        _ => anyhow::anyhow!("{what}: cannot be started ({e})"),
    })
}

/// Send SIGKILL to process group `group` (a child and all it started).
/// Through kill(1): signals need `unsafe` outside `src/vk/`. A group
/// already gone is not an error.
pub(crate) fn kill_group_id(group: u32) {
    let _ = Command::new("kill").arg("-KILL").arg("--").arg(format!("-{group}")).stderr(Stdio::null()).status();
}

/// Kill the process group `child` leads (its leader, when still running,
/// and whatever it started and left in the group), then reap the leader.
pub fn kill_group(child: &mut Child) {
    kill_group_id(child.id());
    let _ = child.wait();
}

/// Run `cmd` to its end within `deadline`, its output kept head and tail
/// (`KEEP` bytes of each end of each stream). `max_stdout`: more standard
/// output than this is an error too (a `--version` that prints megabytes is
/// not one). Either way the child's process group is killed and the error
/// says which limit (`limit_name`, the option that sets the deadline) it hit.
pub fn run(cmd: &mut Command, what: &str, deadline: Duration, limit_name: &str, max_stdout: Option<u64>) -> Result<Finished> {
    let mut child = spawn_in_group(cmd.stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped()), what)?;
    let out = Drain::start(child.stdout.take(), KEEP);
    let err = Drain::start(child.stderr.take(), KEEP);
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().with_context(|| format!("{what}: waiting for it"))? {
            break status;
        }
        if start.elapsed() > deadline {
            kill_group(&mut child);
            bail!("{what}: still running after {} s ({limit_name}); killed its process group", deadline.as_secs_f64());
        }
        if let Some(max) = max_stdout {
            if out.total() > max {
                kill_group(&mut child);
                bail!("{what}: printed more than {max} bytes; killed its process group");
            }
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    // What it left running (holding its output open, or just running).
    kill_group_id(child.id());
    Ok(Finished { status, stdout: out.finish(DRAIN_GRACE), stderr: err.finish(DRAIN_GRACE) })
}

/// Poll interval of [`run_attached`] (its children run for minutes).
const ATTACHED_POLL: Duration = Duration::from_millis(50);

/// Run `cmd` to its end within `deadline`, its standard streams the
/// terminal's (what it prints is the user's to see). It stays in our
/// process group; at the deadline it and its descendants are killed and
/// the error names the limit (`limit_name`).
pub fn run_attached(cmd: &mut Command, what: &str, deadline: Duration, limit_name: &str) -> Result<ExitStatus> {
    let mut child = cmd.spawn().map_err(|e| match e.kind() {
        std::io::ErrorKind::PermissionDenied => anyhow::anyhow!("{what}: not executable ({e})"),
        _ => anyhow::anyhow!("{what}: cannot be started ({e})"),
    })?;
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().with_context(|| format!("{what}: waiting for it"))? {
            return Ok(status);
        }
        if start.elapsed() > deadline {
            kill_tree(&mut child);
            bail!("{what}: still running after {} s ({limit_name}); killed it and the processes it started", deadline.as_secs_f64());
        }
        std::thread::sleep(ATTACHED_POLL);
    }
}

/// The processes below `root` (children, their children, ...), from the
/// parent ids in `/proc/<pid>/stat`.
fn descendants(root: u32) -> Vec<u32> {
    let mut parent_of = Vec::new();
    if let Ok(dir) = std::fs::read_dir("/proc") {
        for entry in dir.flatten() {
            let Some(pid) = entry.file_name().to_str().and_then(|n| n.parse::<u32>().ok()) else { continue };
            if let Some((_, ppid)) = state_and_parent(pid) {
                parent_of.push((pid, ppid));
            }
        }
    }
    let mut found = vec![root];
    let mut i = 0;
    while i < found.len() {
        let p = found[i];
        found.extend(parent_of.iter().filter(|&&(_, pp)| pp == p).map(|&(c, _)| c));
        i += 1;
    }
    found.remove(0);
    found
}

/// Kill `child` and every process below it: stopped first (so none forks
/// or is handed to init while the tree is read), then killed, then reaped.
fn kill_tree(child: &mut Child) {
    use rustix::process::{kill_process, Pid, Signal};
    let signal = |pid: u32, sig: Signal| {
        if let Some(pid) = i32::try_from(pid).ok().and_then(Pid::from_raw) {
            let _ = kill_process(pid, sig);
        }
    };
    let mut tree = vec![child.id()];
    for _ in 0..3 {
        for &p in &tree {
            signal(p, Signal::STOP);
        }
        tree = std::iter::once(child.id()).chain(descendants(child.id())).collect();
    }
    for &p in &tree {
        signal(p, Signal::KILL);
    }
    let _ = child.wait();
    // A SIGKILL lands when the process next runs: on a loaded machine that
    // is milliseconds later. Return only when none of them runs any more
    // (what they were writing, e.g. a worktree `ab` removes next, is still).
    let until = Instant::now() + KILL_GRACE;
    while tree.iter().any(|&p| runs(p)) && Instant::now() < until {
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// How long [`kill_tree`] waits for killed processes to be gone.
const KILL_GRACE: Duration = Duration::from_secs(10);

/// Whether process `pid` exists and is not a zombie (dead, waiting for its
/// parent or init to reap it).
fn runs(pid: u32) -> bool {
    state_and_parent(pid).is_some_and(|(state, _)| state != 'Z' && state != 'X')
}

/// A process's state letter and parent id, from `/proc/<pid>/stat` (the
/// fields after the parenthesised command name); None when it is gone.
fn state_and_parent(pid: u32) -> Option<(char, u32)> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    let mut fields = stat.rsplit_once(") ")?.1.split_whitespace();
    let state = fields.next()?.chars().next()?;
    Some((state, fields.next()?.parse().ok()?))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sh(script: &str) -> Command {
        let mut c = Command::new("sh");
        c.args(["-c", script]);
        c
    }

    #[test]
    fn output_is_kept_whole_when_small_and_clipped_when_large() {
        let f = run(&mut sh("echo out; echo err >&2; exit 3"), "t", Duration::from_secs(20), "--timeout", None).unwrap();
        assert_eq!((f.status.code(), f.stdout.text().as_str(), f.stderr.text().as_str()), (Some(3), "out\n", "err\n"));
        // 4 MB of output: the head and tail, the middle counted.
        let f = run(&mut sh("head -c 4000000 /dev/zero | tr '\\0' x; echo END"), "t", Duration::from_secs(20), "--timeout", None).unwrap();
        assert_eq!(f.stdout.total(), 4_000_004);
        let text = f.stdout.text();
        assert!(text.len() < 2 * KEEP + 100 && text.ends_with("END\n") && text.contains("bytes) …"), "{}", text.len());
    }

    #[test]
    fn deadlines_and_output_limits_kill_the_group() {
        let t = Instant::now();
        let e = run(&mut sh("sleep 300 & sleep 300"), "hang", Duration::from_millis(300), "--timeout", None).unwrap_err().to_string();
        assert!(e.contains("hang: still running after 0.3 s (--timeout); killed its process group"), "{e}");
        // The output limit at two sizes: exactly the limit passes, beyond it
        // (or without end) is killed.
        for max in [1_000u64, 100_000] {
            let exact = run(&mut sh(&format!("head -c {max} /dev/zero")), "t", Duration::from_secs(20), "--timeout", Some(max)).unwrap();
            assert_eq!(exact.stdout.total(), max);
            let e = run(&mut sh("yes"), "spew", Duration::from_secs(60), "--timeout", Some(max)).unwrap_err().to_string();
            assert!(e.contains(&format!("spew: printed more than {max} bytes")), "{e}");
        }
        assert!(t.elapsed() < Duration::from_secs(30), "{:?}", t.elapsed());
        // A grandchild that holds the output open is killed with the group
        // when the child exits: the run ends at once.
        let t = Instant::now();
        let f = run(&mut sh("sleep 300 & echo started"), "leave", Duration::from_secs(60), "--timeout", None).unwrap();
        assert!(f.status.success() && f.stdout.text() == "started\n");
        assert!(t.elapsed() < Duration::from_secs(30), "{:?}", t.elapsed());
    }

    #[test]
    fn attached_children_and_what_they_started_are_killed_at_the_deadline() {
        let f = run_attached(&mut sh("exit 4"), "t", Duration::from_secs(20), "--build-timeout").unwrap();
        assert_eq!(f.code(), Some(4));
        let d = tempfile::tempdir().unwrap();
        let pids = d.path().join("pids");
        // A child that starts a grandchild (as cargo starts rustc) and hangs.
        let script = format!("sleep 300 & echo $! > {0}; sh -c 'sleep 300' & echo $! >> {0}; wait", pids.display());
        let t = Instant::now();
        let e = run_attached(&mut sh(&script), "build", Duration::from_millis(500), "--build-timeout").unwrap_err().to_string();
        assert!(e.contains("build: still running after 0.5 s (--build-timeout); killed it and the processes it started"), "{e}");
        assert!(t.elapsed() < Duration::from_secs(30), "{:?}", t.elapsed());
        for pid in std::fs::read_to_string(&pids).unwrap().split_whitespace() {
            // Gone, or a zombie waiting for init to reap it, when run_attached returns.
            assert!(!runs(pid.parse().unwrap()), "process {pid} still runs");
        }
    }

    #[test]
    fn a_file_without_execute_permission_is_named_not_executable() {
        use std::os::unix::fs::PermissionsExt as _;
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("x");
        std::fs::write(&p, "#!/bin/sh\n").unwrap();
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o644)).unwrap();
        let e = run(&mut Command::new(&p), "x", Duration::from_secs(5), "--timeout", None).err().unwrap().to_string();
        assert!(e.contains("x: not executable"), "{e}");
    }
}
