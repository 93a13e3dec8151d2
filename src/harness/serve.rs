//! The serve protocol of `volbench ab`'s per-frame alternation: a
//! long-lived `volbench run … --serve` process that has loaded its dataset,
//! built its pipelines and warmed up, and renders timed frames on command.
//! `ab` starts one per binary and benchmark, both resident at once, and
//! alternates single frames (or small batches) between them.
//!
//! The server's side (`serve`) and the client's (`Server`) live here
//! together so the two cannot drift apart. Lines on stdin and stdout:
//!
//! - server, once ready: `{"protocol":"volbench-serve/1","version":…,"git_sha":…,"spec":…,"dataset":…}`
//! - `frame N` (1 ≤ N ≤ `MAX_BATCH`): renders the next N frames of the
//!   run's camera path, each prepared, submitted and waited for in turn,
//!   and answers `{"frame_ms":[…],"gpu_ms":[…]}`
//! - `quit`, or end of input: the server exits 0
//! - anything else: `{"error":"…"}` and the server keeps serving; a frame
//!   that fails answers `{"error":"…"}` and the server exits 1.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::Duration;

use anyhow::{bail, ensure, Context as _, Result};
use serde::{Deserialize, Serialize};

/// The protocol this build speaks (the handshake's `protocol`).
pub const PROTOCOL: &str = "volbench-serve/1";

/// The most frames one `frame N` command renders.
pub const MAX_BATCH: usize = 10_000;

/// The longest line `ab` reads from a server: an answer to `frame
/// MAX_BATCH` is some 400 KB. A longer line is an error (and a server that
/// prints one endless line costs this much, not gigabytes).
pub const MAX_LINE_BYTES: usize = 1 << 20;

/// The server's first line: it is ready.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct Hello {
    pub protocol: String,
    pub version: String,
    pub git_sha: String,
    pub spec: String,
    pub dataset: String,
}

/// The answer to `frame N`: each frame's wall time (prepare to fence) and
/// device time, ms.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Frames {
    pub frame_ms: Vec<f64>,
    pub gpu_ms: Vec<f64>,
}

/// A command the server understood.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request {
    Frames(usize),
    Quit,
}

/// One input line as a command, or why it is not one.
pub fn parse_request(line: &str) -> Result<Request> {
    let words: Vec<&str> = line.split_whitespace().collect();
    match words.as_slice() {
        ["quit"] => Ok(Request::Quit),
        ["frame", n] => {
            let n: usize = n.parse().ok().filter(|n| (1..=MAX_BATCH).contains(n)).with_context(|| {
                format!("'frame {n}': the frame count must be a whole number from 1 to {MAX_BATCH}")
            })?;
            Ok(Request::Frames(n))
        }
        _ => bail!("unknown command {line:?} (expected 'frame N' or 'quit')"),
    }
}

fn send(output: &mut impl Write, value: &impl Serialize) -> Result<()> {
    let line = serde_json::to_string(value)?;
    writeln!(output, "{line}").and_then(|()| output.flush()).context("writing to standard output")
}

fn send_error(output: &mut impl Write, message: &str) -> Result<()> {
    send(output, &serde_json::json!({ "error": message }))
}

/// The server's loop: greet with `hello`, then answer commands from
/// `input` until `quit` or its end. `render(n)` renders the next `n`
/// frames; its error is answered and then returned (the server stops).
pub fn serve(
    input: impl BufRead,
    mut output: impl Write,
    hello: &Hello,
    mut render: impl FnMut(usize) -> Result<Frames>,
) -> Result<()> {
    send(&mut output, hello)?;
    for line in input.lines() {
        let line = line.context("reading standard input")?;
        if line.trim().is_empty() {
            continue;
        }
        match parse_request(&line) {
            Ok(Request::Quit) => return Ok(()),
            Ok(Request::Frames(n)) => match render(n) {
                Ok(frames) => send(&mut output, &frames)?,
                Err(e) => {
                    send_error(&mut output, &format!("{e:#}"))?;
                    return Err(e);
                }
            },
            Err(e) => send_error(&mut output, &format!("{e:#}"))?,
        }
    }
    Ok(())
}

/// Serve `spec` on `dataset` as `cfg` says (size, warm-up, camera path)
/// over stdin and stdout: the body of `volbench run … --serve`. The
/// warm-up frames run before the handshake; each `frame N` then renders the
/// next N frames of the camera path without CPU/device overlap (one frame
/// is its own sample), and the validation layer is checked after each.
pub fn serve_run(
    ctx: &std::sync::Arc<crate::vk::Context>,
    spec: &crate::algo::registry::MethodSpec,
    dataset: &super::datasets::Dataset,
    tf: &crate::scene::TransferFunction,
    cfg: &super::run::RunConfig,
) -> Result<()> {
    let mut session = super::run::MethodSession::new(ctx, spec, dataset, tf, cfg)?;
    session.set_statistics(false);
    let mut counter = crate::vk::UploadCounter::default();
    let mut next = 0usize;
    let mut render = |n: usize| -> Result<Frames> {
        let cameras: Vec<_> = (next..next + n).map(|f| cfg.frame_camera(dataset, &spec.info.family, f)).collect();
        let timings = session.run_frames(&cameras, false, &mut counter).with_context(|| format!("frames {next}..{}", next + n))?;
        next += n;
        ctx.check_validation().context("Vulkan validation")?;
        Ok(Frames { frame_ms: timings.iter().map(|(t, _)| t.frame).collect(), gpu_ms: timings.iter().map(|(t, _)| t.gpu).collect() })
    };
    if cfg.warmup > 0 {
        render(cfg.warmup).context("warm-up frames")?;
    }
    let hello = Hello {
        protocol: PROTOCOL.into(),
        version: format!("volbench {}", env!("CARGO_PKG_VERSION")),
        git_sha: env!("VOLBENCH_GIT_SHA").into(),
        spec: spec.canonical(),
        dataset: dataset.name.clone(),
    };
    serve(std::io::stdin().lock(), std::io::stdout().lock(), &hello, render)
}

/// Why a server could not be started.
#[derive(Debug)]
pub enum StartError {
    /// The binary has no serve mode (an older build) or speaks another
    /// protocol: `ab` falls back to one process per run.
    Unsupported(String),
    /// It has one, and failed or stopped answering.
    Failed(anyhow::Error),
}

/// A running server, seen from `ab`. Dropping it (and `quit`) ends the
/// process group: nothing it started outlives it.
pub struct Server {
    child: Child,
    stdin: Option<ChildStdin>,
    lines: Receiver<std::io::Result<String>>,
    /// Its standard error, head and tail.
    errors: super::child::Drain,
    /// Its process group has been killed.
    ended: bool,
    timeout: Duration,
    name: String,
    pub hello: Hello,
}

impl Server {
    /// Start `binary run --serve` with `args` (dataset, method, size,
    /// warm-up) and `env` added to its environment, in a process group of
    /// its own, and wait up to `timeout` for its handshake.
    pub fn start(binary: &Path, env: &BTreeMap<String, String>, args: &[String], timeout: Duration) -> std::result::Result<Server, StartError> {
        let name = binary.display().to_string();
        let mut cmd = Command::new(binary);
        cmd.arg("run")
            .args(args)
            .arg("--serve")
            .env("VOLBENCH_DATA", super::datasets::data_dir())
            .envs(env)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        let mut child = super::child::spawn_in_group(&mut cmd, &format!("{name} run --serve")).map_err(StartError::Failed)?;
        // Readers on threads, so every wait is bounded by the time-out; each
        // line is bounded by MAX_LINE_BYTES, standard error kept head and tail.
        let (stdout, stderr) = (child.stdout.take(), child.stderr.take());
        let (line_tx, lines) = std::sync::mpsc::sync_channel(16);
        std::thread::spawn(move || {
            if let Some(out) = stdout {
                let mut out = BufReader::new(out);
                loop {
                    let line = match crate::fsio::read_line_capped(&mut out, MAX_LINE_BYTES) {
                        Ok(Some(line)) => Ok(line),
                        Ok(None) => break,
                        Err(e) => Err(e),
                    };
                    let stop = line.is_err();
                    if line_tx.send(line).is_err() || stop {
                        break;
                    }
                }
            }
        });
        let errors = super::child::Drain::start(stderr, super::child::KEEP);
        let stdin = child.stdin.take();
        let mut server = Server { child, stdin, lines, errors, ended: false, timeout, name, hello: Hello::default() };
        let first = match server.next_line("its handshake") {
            Ok(line) => line,
            Err(e) => {
                let lines = server.stderr_lines();
                let stderr = tail(&lines);
                let status = server.child.try_wait().ok().flatten();
                // clap's usage error (exit 2) naming the flag: a build from before serve mode.
                let unknown_flag = lines.iter().any(|l| l.contains("unexpected argument '--serve'"));
                if status.is_some_and(|s| s.code() == Some(2)) && unknown_flag {
                    return Err(StartError::Unsupported(format!("{} has no serve mode (`run --serve` is an unknown argument to it)", server.name)));
                }
                return Err(StartError::Failed(if stderr.is_empty() { e } else { anyhow::anyhow!("{e:#}; its stderr: {stderr}") }));
            }
        };
        let hello: Hello = match serde_json::from_str(&first) {
            Ok(h) => h,
            Err(_) => return Err(StartError::Unsupported(format!("{}: `run --serve` answered {first:?}, not a handshake", server.name))),
        };
        if hello.protocol != PROTOCOL {
            return Err(StartError::Unsupported(format!("{} speaks {}, this ab speaks {PROTOCOL}", server.name, hello.protocol)));
        }
        server.hello = hello;
        Ok(server)
    }

    /// Send one command line and read the one-line answer.
    fn ask(&mut self, command: &str) -> Result<String> {
        let stdin = self.stdin.as_mut().context("the server's input is closed")?;
        writeln!(stdin, "{command}").and_then(|()| stdin.flush()).with_context(|| format!("{}: sending {command:?}", self.name))?;
        self.next_line(&format!("'{command}'"))
    }

    /// Render the next `n` frames: their wall times, ms.
    pub fn frames(&mut self, n: usize) -> Result<Vec<f64>> {
        let line = self.ask(&format!("frame {n}"))?;
        if let Ok(v) = serde_json::from_str::<serde_json::Value>(&line) {
            if let Some(e) = v.get("error").and_then(|e| e.as_str()) {
                bail!("{}: frame failed: {e}", self.name);
            }
        }
        let frames: Frames = serde_json::from_str(&line).with_context(|| format!("{}: answered {line:?} to 'frame {n}'", self.name))?;
        ensure!(frames.frame_ms.len() == n, "{}: answered {} frame times to 'frame {n}'", self.name, frames.frame_ms.len());
        Ok(frames.frame_ms)
    }

    /// Send a raw command line (tests: how a server refuses one).
    pub fn raw(&mut self, command: &str) -> Result<String> {
        self.ask(command)
    }

    /// The next stdout line within the time-out; on silence or a closed
    /// output the process group is killed and the error says so.
    fn next_line(&mut self, waiting_for: &str) -> Result<String> {
        match self.lines.recv_timeout(self.timeout) {
            Ok(Ok(line)) => Ok(line),
            Ok(Err(e)) => {
                self.kill();
                Err(e).with_context(|| format!("{}: reading its answer to {waiting_for}", self.name))
            }
            Err(RecvTimeoutError::Timeout) => {
                self.kill();
                bail!(
                    "{}: no answer to {waiting_for} within {} s (--timeout); killed its process group",
                    self.name,
                    self.timeout.as_secs_f64()
                )
            }
            Err(RecvTimeoutError::Disconnected) => {
                // Give the exit status a moment to arrive.
                let status = (0..50).find_map(|_| {
                    let s = self.child.try_wait().ok().flatten();
                    if s.is_none() {
                        std::thread::sleep(Duration::from_millis(20));
                    }
                    s
                });
                self.kill();
                let how = status.map_or("closed its output".to_string(), |s| format!("exited ({s})"));
                bail!("{}: {how} before answering {waiting_for}", self.name)
            }
        }
    }

    /// The non-empty lines the server wrote to stderr so far (its head and
    /// tail, when it wrote much).
    fn stderr_lines(&self) -> Vec<String> {
        // The stderr thread may still be draining: a short grace period.
        self.errors.finish(Duration::from_millis(200)).text().lines().filter(|l| !l.trim().is_empty()).map(str::to_string).collect()
    }

    /// The last lines the server wrote to stderr (why it failed).
    fn stderr_tail(&self) -> String {
        tail(&self.stderr_lines())
    }

    fn kill(&mut self) {
        if !self.ended {
            super::child::kill_group(&mut self.child);
            self.ended = true;
        }
    }

    /// `quit`, then wait (bounded) for a clean exit; an error if it was not.
    /// Either way its process group is killed: whatever it started and
    /// left running goes with it.
    pub fn quit(mut self) -> Result<()> {
        if let Some(mut stdin) = self.stdin.take() {
            let _ = writeln!(stdin, "quit");
        }
        let start = std::time::Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().context("waiting for the server")? {
                self.kill();
                ensure!(status.success(), "{}: exited with {status} after quit: {}", self.name, self.stderr_tail());
                return Ok(());
            }
            if start.elapsed() > self.timeout {
                self.kill();
                bail!("{}: still running {} s after quit (--timeout); killed its process group", self.name, self.timeout.as_secs_f64());
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }
}

/// The last three of `lines`, on one line.
fn tail(lines: &[String]) -> String {
    crate::fsio::clip_child_output(lines[lines.len().saturating_sub(3)..].join(" / ").trim())
}

impl Drop for Server {
    fn drop(&mut self) {
        self.kill();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hello() -> Hello {
        Hello { protocol: PROTOCOL.into(), version: "volbench 0".into(), git_sha: "x".into(), spec: "m".into(), dataset: "d".into() }
    }

    fn talk(input: &str, fail_at: Option<usize>) -> (Result<()>, Vec<serde_json::Value>, usize) {
        let mut out = Vec::new();
        let mut rendered = 0;
        let r = serve(input.as_bytes(), &mut out, &hello(), |n| {
            if fail_at == Some(rendered) {
                bail!("device lost");
            }
            rendered += n;
            Ok(Frames { frame_ms: vec![1.5; n], gpu_ms: vec![1.0; n] })
        });
        let lines = String::from_utf8(out).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
        (r, lines, rendered)
    }

    #[test]
    fn commands_parse_and_bad_ones_are_refused() {
        assert_eq!(parse_request("frame 3").unwrap(), Request::Frames(3));
        assert_eq!(parse_request("  quit ").unwrap(), Request::Quit);
        for bad in ["frame 0", "frame -1", "frame x", "frame 10001", "frame", "frames 2", "render", "frame 1 2"] {
            assert!(parse_request(bad).is_err(), "{bad}");
        }
        assert!(parse_request("frame 0").unwrap_err().to_string().contains("from 1 to"));
        assert!(parse_request("jump").unwrap_err().to_string().contains("expected 'frame N' or 'quit'"));
    }

    #[test]
    fn the_server_greets_answers_refuses_and_stops() {
        let (r, lines, rendered) = talk("frame 2\nbogus\n\nframe 1\nquit\nframe 5\n", None);
        r.unwrap();
        assert_eq!(rendered, 3, "nothing after quit");
        assert_eq!(lines.len(), 4);
        assert_eq!(lines[0]["protocol"], PROTOCOL);
        assert_eq!(lines[1]["frame_ms"].as_array().unwrap().len(), 2);
        assert!(lines[2]["error"].as_str().unwrap().contains("unknown command"));
        assert_eq!(lines[3]["gpu_ms"].as_array().unwrap().len(), 1);
        // End of input stops it as quit does.
        let (r, lines, _) = talk("frame 1\n", None);
        r.unwrap();
        assert_eq!(lines.len(), 2);
        // A failed frame is answered, then the server stops with the error.
        let (r, lines, _) = talk("frame 1\nframe 1\nframe 1\n", Some(1));
        assert!(r.unwrap_err().to_string().contains("device lost"));
        assert_eq!(lines.len(), 3);
        assert!(lines[2]["error"].as_str().unwrap().contains("device lost"));
    }
}
