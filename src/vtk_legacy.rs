//! The line and token layer of VTK legacy files, shared by the unstructured
//! grid reader (`mesh::vtk`) and the structured-points reader
//! (`volume::vtk_sp`): one set of rules for lines (LF or CRLF; CR-only
//! endings named), keywords, counts and binary spans. Each reader adds its
//! own value parsing in an `impl` of its own.

use anyhow::{anyhow, Result};

/// A legacy file being read: its label (quoted in every error), bytes,
/// position, and whether its data are BINARY.
pub(crate) struct Lines<'a> {
    pub(crate) name: &'a str,
    pub(crate) b: &'a [u8],
    pub(crate) pos: usize,
    pub(crate) binary: bool,
}

impl<'a> Lines<'a> {
    pub(crate) fn err(&self, msg: impl std::fmt::Display) -> anyhow::Error {
        anyhow!("{}: {} (at byte {})", self.name, crate::fsio::clip_message(&msg.to_string()), self.pos)
    }

    pub(crate) fn skip_ws(&mut self) {
        while self.pos < self.b.len() && self.b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
    }

    pub(crate) fn at_end(&mut self) -> bool {
        self.skip_ws();
        self.pos >= self.b.len()
    }

    /// The rest of the current line (without `\r\n`), consuming the newline.
    pub(crate) fn raw_line(&mut self, what: &str) -> Result<&'a str> {
        if self.pos >= self.b.len() {
            return Err(self.err(format!("truncated file: expected {what}, found end of file")));
        }
        let start = self.pos;
        let end = self.b[start..].iter().position(|&c| c == b'\n').map_or(self.b.len(), |e| start + e);
        self.pos = (end + 1).min(self.b.len());
        let line = &self.b[start..end];
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        if line.contains(&b'\r') {
            self.pos = start;
            return Err(self.err(format!(
                "expected {what}, found a line broken by a bare carriage return (CR-only line endings, as \
                 classic Mac OS wrote them); VTK legacy files need LF or CRLF line endings"
            )));
        }
        std::str::from_utf8(line).map_err(|_| {
            self.pos = start;
            self.err(format!("expected {what}, found non-text bytes"))
        })
    }

    /// Next non-blank line split into words (never empty). Splits on ASCII
    /// whitespace only, the same set `skip_ws` skips: Unicode-whitespace
    /// splitting would turn a line starting with e.g. a vertical tab into no
    /// words at all.
    pub(crate) fn keyword_line(&mut self, what: &str) -> Result<Vec<&'a str>> {
        self.skip_ws();
        let words: Vec<&'a str> = self.raw_line(what)?.split_ascii_whitespace().collect();
        if words.is_empty() {
            return Err(self.err(format!("truncated file: expected {what}, found end of file")));
        }
        Ok(words)
    }

    /// `n` binary values of `size` bytes, checked against what remains.
    pub(crate) fn binary_bytes(&mut self, n: usize, size: usize, what: &str) -> Result<&'a [u8]> {
        let remain = self.b.len() - self.pos;
        let len = n.checked_mul(size).filter(|&l| l <= remain).ok_or_else(|| {
            self.err(format!("truncated file: {what} needs {n} values of {size} bytes, only {remain} bytes remain"))
        })?;
        let s = &self.b[self.pos..self.pos + len];
        self.pos += len;
        Ok(s)
    }

    /// `n * k` values, or an error (a header's counts are untrusted).
    pub(crate) fn product(&self, n: usize, k: usize, what: &str) -> Result<usize> {
        n.checked_mul(k).ok_or_else(|| self.err(format!("{what} size {n} x {k} overflows")))
    }

    pub(crate) fn count(&self, s: Option<&&str>, what: &str) -> Result<usize> {
        let s = s.ok_or_else(|| self.err(format!("missing {what}")))?;
        s.parse::<usize>().map_err(|_| self.err(format!("bad {what} '{s}'")))
    }

    /// Skips a METADATA block (it ends at an empty line or the end of file).
    pub(crate) fn skip_metadata(&mut self) -> Result<()> {
        while self.pos < self.b.len() {
            if self.raw_line("METADATA")?.trim().is_empty() {
                break;
            }
        }
        Ok(())
    }
}
