//! Every file volbench reads or writes goes through here, so the rules hold
//! in one place (docs/bad-input.md states them for users):
//!
//! - **Inputs** must be regular files (a FIFO, a device or a directory is
//!   refused before anything is read: `--mesh fifo.vtk` would block forever,
//!   `--tf /dev/zero` never end) and no larger than a stated cap, checked
//!   from the file's metadata before reading (a 2 GiB sparse file is refused,
//!   not read whole). Each input read is remembered (device and inode) for
//!   the rest of the process.
//! - **Outputs** follow one rule for every path, decided by what the path
//!   is, not how it is spelled:
//!   - `-`, or any path that is the file this process's standard output
//!     (or error) already goes to (`/dev/stdout`, `/proc/self/fd/1`, the
//!     file a shell redirected it to): written to that stream.
//!   - a regular file (through symlinks) or a new name: replaced whole. The
//!     bytes go to a uniquely named temporary file beside the real target,
//!     which takes the replaced file's permission bits, and are renamed over
//!     it: a failure leaves the old file (or nothing), never a partial,
//!     mixed or widened one, and never a `*.tmp`.
//!   - a character device (`/dev/null`, `/dev/full`): written through; a
//!     failing device is a clean error.
//!   - a directory, a FIFO or socket (would block), a dangling symlink: refused.
//!   - a file that is (or links to) an input of this command: refused, so
//!     an input is never replaced by an output.
//! - `OutputSet` checks a run's outputs before any work starts: no two the
//!   same, each one's directory exists, none is a directory, and each can be
//!   written (a temporary file can be created beside it, a special file
//!   opened for writing).

use std::collections::HashSet;
use std::fs;
use std::io::{Read as _, Write as _};
use std::path::{Path, PathBuf};
use std::os::unix::fs::MetadataExt as _;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use anyhow::{bail, Context as _, Result};

/// Largest input file volbench reads: 1 GiB (a 1024^3 uint8 volume; the
/// largest shipped dataset is 9 MB). Checked from the file's metadata
/// before reading, so a huge or sparse file costs nothing; the readers' own
/// size checks come after this one.
pub const MAX_INPUT_BYTES: u64 = 1 << 30;

/// Puts `/dev/null` on standard input, output or error where the process
/// was started with one closed (`2>&-`), before anything else is opened:
/// otherwise the first file opened (an output, the pipeline cache) would
/// take descriptor 2 and receive the progress messages. Opening takes the
/// lowest free descriptor, so no descriptor is named and nothing is unsafe.
pub fn occupy_closed_stdio() {
    use std::os::fd::{AsRawFd as _, IntoRawFd as _};
    while let Ok(f) = fs::OpenOptions::new().read(true).write(true).open("/dev/null") {
        if f.as_raw_fd() > 2 {
            break;
        }
        // Kept open for the process's lifetime as the standard stream.
        let _ = f.into_raw_fd();
    }
}

/// Check that `path` can be read as an input: it exists, is a regular file
/// (after following symlinks) and holds at most `max_bytes`. Returns its size.
pub fn check_input(path: &Path, what: &str, max_bytes: u64) -> Result<u64> {
    let meta = fs::metadata(path).with_context(|| format!("{}: cannot read {what}", path.display()))?;
    remember_input(path, &meta);
    if meta.is_dir() {
        bail!("{}: is a directory, expected a {what} file", path.display());
    }
    if !meta.is_file() {
        bail!("{}: is not a regular file (a FIFO, socket or device?); {what} must be read from a regular file", path.display());
    }
    if meta.len() > max_bytes {
        bail!(
            "{}: {} bytes is larger than the {} bytes a {what} may have here",
            path.display(),
            meta.len(),
            max_bytes
        );
    }
    Ok(meta.len())
}

/// Read a whole input file after `check_input`. The read is bounded by the
/// size found there (plus one byte, to notice a file that grew meanwhile).
pub fn read_input(path: &Path, what: &str, max_bytes: u64) -> Result<Vec<u8>> {
    let len = check_input(path, what, max_bytes)?;
    let file = fs::File::open(path).with_context(|| format!("{}: cannot open {what}", path.display()))?;
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(max_bytes.saturating_add(1))
        .read_to_end(&mut bytes)
        .with_context(|| format!("{}: cannot read {what}", path.display()))?;
    if bytes.len() as u64 > max_bytes {
        bail!("{}: grew past the {} bytes a {what} may have while being read", path.display(), max_bytes);
    }
    Ok(bytes)
}

/// The first (at most) `max_bytes` of an input file, after the checks of
/// `check_input` (any size): for a header.
pub fn read_input_head(path: &Path, what: &str, max_bytes: u64) -> Result<Vec<u8>> {
    check_input(path, what, u64::MAX)?;
    let file = fs::File::open(path).with_context(|| format!("{}: cannot open {what}", path.display()))?;
    let mut bytes = Vec::new();
    file.take(max_bytes).read_to_end(&mut bytes).with_context(|| format!("{}: cannot read {what}", path.display()))?;
    Ok(bytes)
}

/// The inputs this process has read: (device, inode) and the path given.
static INPUTS: Mutex<Vec<(u64, u64, PathBuf)>> = Mutex::new(Vec::new());

fn remember_input(path: &Path, meta: &fs::Metadata) {
    if let Ok(mut inputs) = INPUTS.lock() {
        if !inputs.iter().any(|(d, i, _)| (*d, *i) == (meta.dev(), meta.ino())) {
            inputs.push((meta.dev(), meta.ino(), path.to_path_buf()));
        }
    }
}

/// The input of this process that `meta` is, if any.
fn input_named_by(meta: &fs::Metadata) -> Option<PathBuf> {
    let inputs = INPUTS.lock().ok()?;
    // The input's path must still name that file: an inode freed by a
    // removed input may be reused by an unrelated new file.
    let still = |p: &Path| fs::metadata(p).is_ok_and(|m| (m.dev(), m.ino()) == (meta.dev(), meta.ino()));
    inputs.iter().find(|(d, i, p)| (*d, *i) == (meta.dev(), meta.ino()) && still(p)).map(|(_, _, p)| p.clone())
}

/// `read_input` as UTF-8 text.
pub fn read_input_text(path: &Path, what: &str, max_bytes: u64) -> Result<String> {
    let bytes = read_input(path, what, max_bytes)?;
    String::from_utf8(bytes).map_err(|e| {
        anyhow::anyhow!("{}: {what} is not UTF-8 text (invalid byte at offset {})", path.display(), e.utf8_error().valid_up_to())
    })
}

/// A message about a file's content, shortened to at most 300 bytes (on a
/// character boundary): a bad token can be gigabytes of one "word", and an
/// error message must stay readable.
pub fn clip_message(text: &str) -> String {
    const MAX: usize = 300;
    if text.len() <= MAX {
        return text.to_string();
    }
    let mut end = MAX;
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    format!("{}… ({} more bytes)", &text[..end], text.len() - end)
}

/// Another process's error output, shortened to at most ~1,000 bytes by
/// cutting its middle: an error chain names what was being done first and
/// the root cause (often a path) last, so both ends are kept.
pub fn clip_child_output(text: &str) -> String {
    const KEEP: usize = 500;
    if text.len() <= 2 * KEEP {
        return text.to_string();
    }
    let mut head = KEEP;
    while !text.is_char_boundary(head) {
        head -= 1;
    }
    let mut tail = text.len() - KEEP;
    while !text.is_char_boundary(tail) {
        tail += 1;
    }
    format!("{} … ({} bytes) … {}", &text[..head], tail - head, &text[tail..])
}

/// A fresh scratch directory under the temporary directory (`TMPDIR`),
/// named `prefix` and random characters, created exclusively (mode 0700),
/// so no name can be guessed and planted beforehand (a symlink there is
/// never followed); removed with everything in it when dropped.
pub fn scratch_dir(prefix: &str) -> Result<tempfile::TempDir> {
    let base = std::env::temp_dir();
    use std::os::unix::fs::PermissionsExt as _;
    tempfile::Builder::new()
        .prefix(prefix)
        .permissions(fs::Permissions::from_mode(0o700))
        .tempdir_in(&base)
        .with_context(|| format!("creating a scratch directory in {} (TMPDIR)", base.display()))
}

/// The head and tail of another process's output stream, of any length,
/// in bounded memory: the first `keep` bytes and the last `keep` bytes,
/// and how many there were in all. Its text cuts the middle as
/// `clip_child_output` does (a stream that prints forever costs `2 * keep`
/// bytes, not gigabytes).
#[derive(Debug, Clone, Default)]
pub struct HeadTail {
    head: Vec<u8>,
    tail: std::collections::VecDeque<u8>,
    keep: usize,
    total: u64,
}

impl HeadTail {
    pub fn new(keep: usize) -> Self {
        HeadTail { head: Vec::new(), tail: std::collections::VecDeque::new(), keep, total: 0 }
    }

    /// Add the next bytes of the stream.
    pub fn push(&mut self, mut bytes: &[u8]) {
        self.total += bytes.len() as u64;
        let room = self.keep - self.head.len();
        let into_head = room.min(bytes.len());
        self.head.extend_from_slice(&bytes[..into_head]);
        bytes = &bytes[into_head..];
        if bytes.len() >= self.keep {
            self.tail.clear();
            bytes = &bytes[bytes.len() - self.keep..];
        }
        self.tail.extend(bytes);
        let over = self.tail.len().saturating_sub(self.keep);
        self.tail.drain(..over);
    }

    /// Bytes seen in all.
    pub fn total(&self) -> u64 {
        self.total
    }

    /// Whether bytes were dropped from the middle.
    pub fn clipped(&self) -> bool {
        self.total > (self.head.len() + self.tail.len()) as u64
    }

    /// The stream as (lossy UTF-8) text: whole if it fitted, else head and
    /// tail around the number of bytes left out.
    pub fn text(&self) -> String {
        let tail: Vec<u8> = self.tail.iter().copied().collect();
        if !self.clipped() {
            let mut all = self.head.clone();
            all.extend_from_slice(&tail);
            return String::from_utf8_lossy(&all).into_owned();
        }
        let gap = self.total - (self.head.len() + tail.len()) as u64;
        format!("{} … ({gap} bytes) … {}", String::from_utf8_lossy(&self.head), String::from_utf8_lossy(&tail))
    }
}

/// One line (without its end) of at most `max` bytes from `input`, `None`
/// at the end of input: a line that runs on past `max` bytes is an error
/// after reading `max + 1` of them (another process's endless line costs
/// `max` bytes, not gigabytes).
pub fn read_line_capped(input: &mut impl std::io::BufRead, max: usize) -> std::io::Result<Option<String>> {
    let mut line = Vec::new();
    loop {
        let buf = match input.fill_buf() {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        if buf.is_empty() {
            return Ok((!line.is_empty()).then(|| String::from_utf8_lossy(&line).into_owned()));
        }
        let (part, used, done) = match buf.iter().position(|&b| b == b'\n') {
            Some(i) => (&buf[..i], i + 1, true),
            None => (buf, buf.len(), false),
        };
        if line.len() + part.len() > max {
            return Err(std::io::Error::new(std::io::ErrorKind::InvalidData, format!("a line longer than {max} bytes")));
        }
        line.extend_from_slice(part);
        input.consume(used);
        if done {
            if line.last() == Some(&b'\r') {
                line.pop();
            }
            return Ok(Some(String::from_utf8_lossy(&line).into_owned()));
        }
    }
}

/// Where an output goes.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum OutputTarget {
    /// This process's standard output (`-`, `/dev/stdout`, ...).
    Stdout,
    /// This process's standard error (`/dev/stderr`, ...).
    Stderr,
    /// A path that does not exist yet, or a regular file (possibly through a
    /// symlink): replaced atomically.
    File(PathBuf),
    /// A character device: written through.
    Special(PathBuf),
}

/// (device, inode) of the file standard output (1) or error (2) goes to.
fn stream_identity(fd: i32) -> Option<(u64, u64)> {
    use std::os::fd::AsFd as _;
    let owned = match fd {
        1 => std::io::stdout().as_fd().try_clone_to_owned().ok()?,
        _ => std::io::stderr().as_fd().try_clone_to_owned().ok()?,
    };
    let m = fs::File::from(owned).metadata().ok()?;
    Some((m.dev(), m.ino()))
}

impl OutputTarget {
    /// Classify `path` (see the module note). Fails for a directory, a path
    /// ending in `/`, a parent directory that does not exist, a FIFO or
    /// socket, a dangling symlink, or an input of this process.
    pub fn of(path: &Path) -> Result<Self> {
        if path.as_os_str() == "-" {
            return Ok(OutputTarget::Stdout);
        }
        let text = path.as_os_str().to_string_lossy();
        if text.is_empty() {
            bail!("an output path is empty");
        }
        if text.ends_with('/') || text.ends_with("/.") || text.ends_with("/..") || text == "." || text == ".." {
            bail!("{}: names a directory, expected a file name", path.display());
        }
        match fs::metadata(path) {
            Ok(m) => {
                let id = Some((m.dev(), m.ino()));
                if id == stream_identity(1) {
                    return Ok(OutputTarget::Stdout);
                }
                if id == stream_identity(2) {
                    return Ok(OutputTarget::Stderr);
                }
                if m.is_dir() {
                    bail!("{}: is a directory, expected a file name", path.display());
                }
                if let Some(input) = input_named_by(&m) {
                    bail!("{}: is an input of this command ({}); refusing to overwrite it", path.display(), input.display());
                }
                if m.is_file() {
                    Ok(OutputTarget::File(path.to_path_buf()))
                } else if is_blocking_special(&m) {
                    // A FIFO without a reader would block the process forever.
                    bail!("{}: is a FIFO or socket; refusing to block on it (write to a regular file)", path.display())
                } else {
                    Ok(OutputTarget::Special(path.to_path_buf()))
                }
            }
            Err(_) => {
                if fs::symlink_metadata(path).is_ok() {
                    bail!("{}: is a dangling symbolic link; refusing to write through it", path.display());
                }
                let parent = parent_dir(path);
                match fs::metadata(&parent) {
                    Ok(m) if m.is_dir() => Ok(OutputTarget::File(path.to_path_buf())),
                    Ok(_) => bail!("{}: {} is not a directory", path.display(), parent.display()),
                    Err(_) => bail!("{}: directory {} does not exist", path.display(), parent.display()),
                }
            }
        }
    }

    /// Try, before any work, what writing will do: create (and remove) a
    /// temporary file beside a regular-file target, where the real one will
    /// be made (catches a read-only file system or directory), or open a
    /// special file for writing. Writes nothing to the target.
    pub fn probe(&self) -> Result<()> {
        match self {
            OutputTarget::Stdout | OutputTarget::Stderr => Ok(()),
            OutputTarget::Special(p) => fs::OpenOptions::new()
                .write(true)
                .open(p)
                .map(drop)
                .with_context(|| format!("{}: cannot be opened for writing", p.display())),
            OutputTarget::File(p) => Staged::new(p).map(drop),
        }
    }

    /// Write `bytes` to a target that cannot be staged (a stream or device).
    fn write_through(&self, bytes: &[u8]) -> Result<()> {
        match self {
            OutputTarget::Stdout => {
                let mut out = std::io::stdout().lock();
                out.write_all(bytes).and_then(|()| out.flush()).context("writing to standard output")
            }
            OutputTarget::Stderr => {
                let mut out = std::io::stderr().lock();
                out.write_all(bytes).and_then(|()| out.flush()).context("writing to standard error")
            }
            OutputTarget::Special(p) => {
                let mut f = fs::OpenOptions::new().write(true).open(p).with_context(|| format!("{}: cannot open for writing", p.display()))?;
                f.write_all(bytes).and_then(|()| f.flush()).with_context(|| format!("{}: write failed", p.display()))
            }
            OutputTarget::File(p) => Staged::new(p)?.commit_bytes(bytes),
        }
    }
}

/// Whether `path` names this process's standard output (`-`,
/// `/dev/stdout`, the file stdout is redirected to, ...).
pub fn is_stdout(path: &Path) -> bool {
    path.as_os_str() == "-"
        || fs::metadata(path).ok().is_some_and(|m| Some((m.dev(), m.ino())) == stream_identity(1))
}

fn is_blocking_special(m: &fs::Metadata) -> bool {
    use std::os::unix::fs::FileTypeExt as _;
    m.file_type().is_fifo() || m.file_type().is_socket()
}

fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A unique temporary name beside `target` (process id, a counter and the
/// time, so two processes or threads writing the same target never collide).
fn temp_path(target: &Path) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.subsec_nanos()).unwrap_or(0);
    let name = target.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
    parent_dir(target).join(format!(".{name}.{}.{n}.{nanos}.tmp", std::process::id()))
}

/// Remove the temporary files that process `pid` left in `dir` while
/// staging outputs (`temp_path`'s names; a process stopped by a signal runs
/// no destructor): what a command that stops itself, or a child it stopped,
/// would otherwise leave behind. Other files, and other processes'
/// temporaries, are left alone. Returns how many were removed.
pub fn remove_staged_by(dir: &Path, pid: u32) -> usize {
    let Ok(entries) = fs::read_dir(dir) else { return 0 };
    let pid = pid.to_string();
    let mut removed = 0;
    for entry in entries.flatten() {
        let name = entry.file_name();
        let name = name.to_string_lossy();
        // `.{name}.{pid}.{n}.{nanos}.tmp`
        let Some(stem) = name.strip_prefix('.').and_then(|n| n.strip_suffix(".tmp")) else { continue };
        let parts: Vec<&str> = stem.rsplitn(4, '.').collect();
        let numeric = |p: &str| !p.is_empty() && p.bytes().all(|b| b.is_ascii_digit());
        if parts.len() == 4 && numeric(parts[0]) && numeric(parts[1]) && parts[2] == pid {
            let is_file = entry.file_type().is_ok_and(|t| t.is_file());
            if is_file && fs::remove_file(entry.path()).is_ok() {
                removed += 1;
            }
        }
    }
    removed
}

/// A regular-file output being written: a temporary file beside the real
/// target (a symlink's target is replaced, not the link) with the replaced
/// file's permission bits; removed unless committed (any early return or
/// panic).
struct Staged {
    tmp: Option<PathBuf>,
    real: PathBuf,
    shown: PathBuf,
    file: Option<fs::File>,
}

impl Staged {
    fn new(p: &Path) -> Result<Self> {
        let real = fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
        let tmp = temp_path(&real);
        let file = fs::OpenOptions::new().write(true).create_new(true).open(&tmp).with_context(|| {
            format!("{}: cannot be written (no file can be created in {})", p.display(), parent_dir(&real).display())
        })?;
        let staged = Staged { tmp: Some(tmp), real, shown: p.to_path_buf(), file: Some(file) };
        if let Ok(m) = fs::metadata(&staged.real) {
            if let Some(f) = &staged.file {
                f.set_permissions(m.permissions()).with_context(|| format!("{}: cannot keep its permissions", p.display()))?;
            }
        }
        Ok(staged)
    }

    fn commit_bytes(mut self, bytes: &[u8]) -> Result<()> {
        if let Some(f) = &mut self.file {
            f.write_all(bytes).with_context(|| format!("{}: write failed", self.shown.display()))?;
        }
        self.commit()
    }

    fn commit(mut self) -> Result<()> {
        if let Some(f) = self.file.take() {
            f.sync_all().ok();
        }
        if let Some(tmp) = &self.tmp {
            fs::rename(tmp, &self.real).with_context(|| format!("{}: cannot replace it", self.shown.display()))?;
        }
        self.tmp = None;
        Ok(())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if let Some(p) = self.tmp.take() {
            let _ = fs::remove_file(p);
        }
    }
}

/// Write `bytes` to `path` all-or-nothing (see the module note).
pub fn write_output(path: &Path, bytes: &[u8]) -> Result<()> {
    write_output_with(path, |w| w.write_all(bytes).map_err(Into::into))
}

/// Write what `fill` produces to `path` all-or-nothing: nothing reaches the
/// target unless `fill` succeeds.
pub fn write_output_with(path: &Path, fill: impl FnOnce(&mut dyn std::io::Write) -> Result<()>) -> Result<()> {
    match OutputTarget::of(path)? {
        OutputTarget::File(p) => {
            let mut staged = Staged::new(&p)?;
            let file = staged.file.take().context("a staged output has its file")?;
            let mut w = std::io::BufWriter::new(file);
            fill(&mut w).with_context(|| format!("writing {}", p.display()))?;
            let file = w.into_inner().map_err(|e| anyhow::anyhow!("{}: write failed: {}", p.display(), e.error()))?;
            staged.file = Some(file);
            staged.commit()
        }
        other => {
            let mut buf = Vec::new();
            fill(&mut buf)?;
            other.write_through(&buf)
        }
    }
}

/// Write several outputs all-or-nothing together: every regular-file
/// target is first written to its own temporary file; only when all of
/// them are complete are they renamed into place (then the non-regular
/// targets and standard output are written through, which cannot be undone).
/// If any write fails, no target is touched and no temporary file is left.
pub fn write_all(outputs: &[(&Path, &[u8])]) -> Result<()> {
    let mut staged: Vec<Staged> = Vec::new();
    let mut later: Vec<(OutputTarget, &[u8])> = Vec::new();
    for &(path, bytes) in outputs {
        match OutputTarget::of(path)? {
            OutputTarget::File(p) => {
                let mut s = Staged::new(&p)?;
                if let Some(f) = &mut s.file {
                    f.write_all(bytes).with_context(|| format!("{}: write failed", p.display()))?;
                }
                staged.push(s);
            }
            other => later.push((other, bytes)),
        }
    }
    // What cannot be undone (devices, standard output) first: if it fails,
    // no regular target has been touched yet.
    for (target, bytes) in later {
        target.write_through(bytes)?;
    }
    for s in staged {
        s.commit()?;
    }
    Ok(())
}

/// The outputs one command will write, checked together before any work:
/// each is writable as `OutputTarget::of` says, and no two are the same file.
#[derive(Default)]
pub struct OutputSet {
    seen: HashSet<PathBuf>,
}

impl OutputSet {
    pub fn new() -> Self {
        Self::default()
    }

    /// Add an output named by `option` (for the message).
    pub fn add(&mut self, option: &str, path: &Path) -> Result<()> {
        let target = OutputTarget::of(path).with_context(|| option.to_string())?;
        target.probe().with_context(|| option.to_string())?;
        let key = match &target {
            OutputTarget::Stdout => PathBuf::from("-"),
            OutputTarget::Stderr => PathBuf::from("/dev/stderr"),
            OutputTarget::File(p) | OutputTarget::Special(p) => identity(p).unwrap_or_else(|| canonical_for_compare(p)),
        };
        if !self.seen.insert(key) {
            bail!("{option} {}: another output of this command writes the same file", path.display());
        }
        Ok(())
    }
}

/// An existing file's identity (device and inode), so that `-`,
/// `/dev/stdout` and the file standard output goes to are one output.
fn identity(p: &Path) -> Option<PathBuf> {
    use std::os::unix::fs::MetadataExt as _;
    let m = fs::metadata(p).ok()?;
    // Character devices such as /dev/null may be named twice harmlessly.
    if !m.is_file() && !is_blocking_special(&m) {
        return None;
    }
    Some(PathBuf::from(format!("inode:{}:{}", m.dev(), m.ino())))
}

/// A path's identity: canonical parent joined with the file name (the file
/// itself may not exist yet); a symlink resolves to its target.
fn canonical_for_compare(p: &Path) -> PathBuf {
    if let Ok(c) = fs::canonicalize(p) {
        return c;
    }
    let parent = fs::canonicalize(parent_dir(p)).unwrap_or_else(|_| parent_dir(p));
    match p.file_name() {
        Some(n) => parent.join(n),
        None => parent,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_child_output_keeps_both_ends() {
        assert_eq!(clip_child_output("short"), "short");
        let long = format!("context: {}: /the/root/cause/é.txt", "é".repeat(2_000));
        let clipped = clip_child_output(&long);
        assert!(clipped.len() < 1_100, "{}", clipped.len());
        assert!(clipped.starts_with("context: ") && clipped.ends_with("/the/root/cause/é.txt"), "{clipped}");
        assert!(clipped.contains(" bytes) … "), "{clipped}");
    }

    #[test]
    fn scratch_directories_are_fresh_private_and_unguessable() {
        use std::os::unix::fs::PermissionsExt as _;
        let (a, b) = (scratch_dir("volbench-t-").unwrap(), scratch_dir("volbench-t-").unwrap());
        assert_ne!(a.path(), b.path());
        let m = fs::symlink_metadata(a.path()).unwrap();
        assert!(m.is_dir() && m.permissions().mode() & 0o777 == 0o700);
        assert!(a.path().file_name().unwrap().to_str().unwrap().len() > "volbench-t-".len() + 5);
        let p = a.path().to_path_buf();
        drop(a);
        assert!(!p.exists());
    }

    #[test]
    fn a_stream_keeps_head_and_tail_in_bounded_memory() {
        let mut h = HeadTail::new(4);
        h.push(b"ab");
        h.push(b"cdef");
        assert_eq!((h.text(), h.clipped()), ("abcdef".to_string(), false));
        h.push(b"gh");
        h.push(b"0123456789");
        assert_eq!(h.total(), 18);
        assert_eq!(h.text(), "abcd … (10 bytes) … 6789");
        // A stream far past the cap keeps 2 * keep bytes.
        let mut big = HeadTail::new(1000);
        for _ in 0..10_000 {
            big.push(&[b'x'; 997]);
        }
        assert!(big.head.len() + big.tail.len() == 2000 && big.text().len() < 2100);
        assert!(big.text().contains("(9968000 bytes)"), "{}", &big.text()[990..1030]);
    }

    #[test]
    fn lines_are_capped() {
        let mut r = std::io::BufReader::with_capacity(3, &b"one\r\ntwo\nlast"[..]);
        assert_eq!(read_line_capped(&mut r, 4).unwrap().as_deref(), Some("one"));
        assert_eq!(read_line_capped(&mut r, 4).unwrap().as_deref(), Some("two"));
        assert_eq!(read_line_capped(&mut r, 4).unwrap().as_deref(), Some("last"));
        assert_eq!(read_line_capped(&mut r, 4).unwrap(), None);
        // Exactly the cap passes; one byte more is an error, at both sizes.
        for max in [8, 64 * 1024] {
            let ok = vec![b'y'; max];
            assert_eq!(read_line_capped(&mut &ok[..], max).unwrap().unwrap().len(), max);
            let long = vec![b'y'; max + 1];
            let e = read_line_capped(&mut &long[..], max).unwrap_err().to_string();
            assert!(e.contains(&format!("longer than {max} bytes")), "{e}");
        }
        // An endless line: stops after max + 1 bytes.
        let mut endless = std::io::BufReader::new(std::io::repeat(b'z'));
        assert!(read_line_capped(&mut endless, 1 << 20).is_err());
    }

    #[test]
    fn replaces_regular_files_atomically_and_leaves_no_temp() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("a.json");
        write_output(&p, b"one").unwrap();
        write_output(&p, b"two").unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"two");
        let err = write_output_with(&p, |_| bail!("boom")).unwrap_err();
        assert!(format!("{err:#}").contains("boom"));
        assert_eq!(fs::read(&p).unwrap(), b"two", "a failed write keeps the old file");
        let names: Vec<_> = fs::read_dir(d.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names.len(), 1, "{names:?}");
    }

    #[test]
    fn a_stopped_process_s_temporaries_are_found_by_its_id() {
        let d = tempfile::tempdir().unwrap();
        let mine = temp_path(&d.path().join("scale.json"));
        let other = temp_path(&d.path().join("a.b.json")).to_string_lossy().replace(&format!(".{}.", std::process::id()), ".4242.");
        for p in [mine.as_path(), Path::new(&other), &d.path().join("scale.json"), &d.path().join(".x.tmp")] {
            fs::write(p, b"x").unwrap();
        }
        assert_eq!(remove_staged_by(d.path(), 4242), 1);
        assert!(!Path::new(&other).exists() && mine.exists());
        assert_eq!(remove_staged_by(d.path(), std::process::id()), 1);
        assert!(!mine.exists());
        let mut left: Vec<_> = fs::read_dir(d.path()).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
        left.sort();
        assert_eq!(left, [".x.tmp", "scale.json"]);
        assert_eq!(remove_staged_by(&d.path().join("missing"), 1), 0);
    }

    #[test]
    fn never_replaces_what_is_not_a_regular_file() {
        let d = tempfile::tempdir().unwrap();
        // /dev/null is written through, not replaced by a regular file.
        write_output(Path::new("/dev/null"), b"x").unwrap();
        assert!(!fs::metadata("/dev/null").unwrap().is_file());
        // A symlink to a regular file: the target is replaced, the link stays.
        let target = d.path().join("t.txt");
        fs::write(&target, b"old").unwrap();
        let link = d.path().join("l.txt");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        write_output(&link, b"new").unwrap();
        assert!(fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        assert_eq!(fs::read(&target).unwrap(), b"new");
        // A directory, a trailing slash, a missing parent: clear errors.
        for bad in [d.path().to_path_buf(), d.path().join("x/"), d.path().join("nope/x.png")] {
            let e = write_output(&bad, b"x").unwrap_err().to_string();
            assert!(e.contains(bad.to_string_lossy().trim_end_matches('/')), "{e}");
        }
        assert_eq!(fs::read_dir(d.path()).unwrap().count(), 2);
    }

    #[test]
    fn inputs_must_be_regular_and_small_enough() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("m.vtk");
        fs::write(&p, b"0123456789").unwrap();
        assert_eq!(read_input(&p, "mesh", 10).unwrap().len(), 10);
        let e = read_input(&p, "mesh", 9).unwrap_err().to_string();
        assert!(e.contains("m.vtk") && e.contains("10 bytes"), "{e}");
        let e = read_input(Path::new("/dev/zero"), "transfer function", 100).unwrap_err().to_string();
        assert!(e.contains("/dev/zero") && e.contains("not a regular file"), "{e}");
        let e = read_input(d.path(), "mesh", 100).unwrap_err().to_string();
        assert!(e.contains("directory"), "{e}");
    }

    #[test]
    fn fifos_dot_paths_and_failing_devices_are_bounded_and_leave_nothing() {
        let d = tempfile::tempdir().unwrap();
        let fifo = d.path().join("f");
        assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
        let e = write_output(&fifo, b"x").unwrap_err().to_string();
        assert!(e.contains("FIFO"), "{e}");
        let dot = d.path().join("x.json/.");
        assert!(write_output(&dot, b"x").unwrap_err().to_string().contains("directory"));
        // A device that fails (/dev/full) is written before any rename.
        let a = d.path().join("a.png");
        assert!(write_all(&[(&a, b"png"), (Path::new("/dev/full"), b"json")]).is_err());
        assert!(!a.exists());
        assert_eq!(fs::read_dir(d.path()).unwrap().count(), 1, "only the FIFO");
        // Standard output named twice.
        let mut set = OutputSet::new();
        set.add("--json", Path::new("-")).unwrap();
        assert!(set.add("--png", Path::new("/dev/stdout")).is_err() || identity(Path::new("/dev/stdout")).is_none());
    }

    #[test]
    fn write_all_is_all_or_nothing() {
        let d = tempfile::tempdir().unwrap();
        let (a, b) = (d.path().join("a.png"), d.path().join("b.json"));
        fs::write(&a, b"old").unwrap();
        // The second target's directory does not exist: nothing is written.
        let bad = d.path().join("missing/c.json");
        assert!(write_all(&[(&a, b"new"), (&bad, b"x")]).is_err());
        assert_eq!(fs::read(&a).unwrap(), b"old");
        assert_eq!(fs::read_dir(d.path()).unwrap().count(), 1, "no temporary file left");
        write_all(&[(&a, b"new"), (&b, b"{}"), (Path::new("/dev/null"), b"x")]).unwrap();
        assert_eq!(fs::read(&a).unwrap(), b"new");
        assert_eq!(fs::read(&b).unwrap(), b"{}");
    }

    #[test]
    fn an_output_set_refuses_the_same_file_twice() {
        let d = tempfile::tempdir().unwrap();
        let mut set = OutputSet::new();
        set.add("--png", &d.path().join("a.png")).unwrap();
        set.add("--json", &d.path().join("a.json")).unwrap();
        let e = set.add("--diff-png", &d.path().join("./a.png")).unwrap_err().to_string();
        assert!(e.contains("--diff-png") && e.contains("same file"), "{e}");
    }

    #[test]
    fn an_output_never_replaces_an_input_by_any_name() {
        let d = tempfile::tempdir().unwrap();
        let input = d.path().join("in.vtk");
        fs::write(&input, b"mesh").unwrap();
        read_input(&input, "mesh", 100).unwrap();
        let link = d.path().join("link.json");
        std::os::unix::fs::symlink(&input, &link).unwrap();
        let hard = d.path().join("hard.json");
        fs::hard_link(&input, &hard).unwrap();
        for out in [input.clone(), link, hard, d.path().join("./in.vtk")] {
            let e = write_output(&out, b"json").unwrap_err().to_string();
            assert!(e.contains("is an input of this command"), "{e}");
            assert!(OutputSet::new().add("--json", &out).is_err());
        }
        assert_eq!(fs::read(&input).unwrap(), b"mesh");
    }

    #[test]
    fn a_replaced_file_keeps_its_mode_and_is_never_mixed() {
        use std::os::unix::fs::PermissionsExt as _;
        let d = tempfile::tempdir().unwrap();
        for mode in [0o600, 0o640, 0o755] {
            let p = d.path().join(format!("o{mode:o}.json"));
            fs::write(&p, vec![b'x'; 200_000]).unwrap();
            fs::set_permissions(&p, fs::Permissions::from_mode(mode)).unwrap();
            write_all(&[(&p, b"{}")]).unwrap();
            assert_eq!(fs::read(&p).unwrap(), b"{}");
            assert_eq!(fs::metadata(&p).unwrap().permissions().mode() & 0o777, mode);
            write_output(&p, b"[]").unwrap();
            assert_eq!(fs::metadata(&p).unwrap().permissions().mode() & 0o777, mode);
        }
        // A regular file under /dev/shm is a regular file like any other.
        if Path::new("/dev/shm").is_dir() {
            let f = tempfile::NamedTempFile::new_in("/dev/shm").unwrap();
            fs::write(f.path(), vec![b'x'; 200_000]).unwrap();
            write_output(f.path(), b"{}").unwrap();
            assert_eq!(fs::read(f.path()).unwrap(), b"{}");
        }
    }
}
