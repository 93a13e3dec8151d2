//! An array's bytes read front to back without holding them whole: raw
//! bytes borrowed from the file, or base64 text decoded a chunk at a time
//! (VTK XML's `binary` arrays and base64 appended data).

use anyhow::{anyhow, bail, Result};

use super::Endian;

/// Bytes handed to a sink at a time when an uncompressed array is streamed.
pub(crate) const CHUNK: usize = 1 << 16;

/// An array's binary stream read front to back without holding it whole:
/// raw bytes (borrowed), or base64 text decoded a chunk at a time. Padding
/// may end any 4-character group, not only the last: VTK encodes a data
/// array's header and its data as two base64 streams written back to back.
pub(crate) struct Stream<'a> {
    text: &'a [u8],
    pos: usize,
    base64: bool,
    /// Decoded bytes not yet read (exact: counted before reading).
    left: usize,
    /// Base64 only: decoded bytes not yet handed out, and where they start.
    pending: Vec<u8>,
    at: usize,
}

impl<'a> Stream<'a> {
    pub(crate) fn raw(bytes: &'a [u8]) -> Stream<'a> {
        Stream { text: bytes, pos: 0, base64: false, left: bytes.len(), pending: Vec::new(), at: 0 }
    }

    /// Base64 text (ASCII whitespace ignored); its length is checked and its
    /// decoded size counted here, its characters as they are decoded.
    pub(crate) fn base64(name: &str, what: &str, text: &'a [u8]) -> Result<Stream<'a>> {
        let (mut chars, mut pads) = (0usize, 0usize);
        for &c in text {
            if !c.is_ascii_whitespace() {
                chars += 1;
                pads += usize::from(c == b'=');
            }
        }
        if !chars.is_multiple_of(4) {
            bail!("{name}: base64 data in {what} has {chars} characters, not a multiple of 4");
        }
        let left = (chars / 4 * 3).saturating_sub(pads);
        Ok(Stream { text, pos: 0, base64: true, left, pending: Vec::new(), at: 0 })
    }

    /// Decoded bytes not yet read.
    pub(crate) fn left(&self) -> usize {
        self.left
    }

    /// Decodes the next base64 groups (up to 64 KiB of text, or up to a
    /// group ending in padding) into `pending`.
    fn refill(&mut self, name: &str, what: &str) -> Result<()> {
        use base64::Engine as _;
        let mut clean: Vec<u8> = Vec::with_capacity(CHUNK.min(self.text.len() - self.pos));
        let start = self.pos;
        while self.pos < self.text.len() && clean.len() < CHUNK {
            let c = self.text[self.pos];
            self.pos += 1;
            if c.is_ascii_whitespace() {
                continue;
            }
            clean.push(c);
            if clean.len().is_multiple_of(4) && c == b'=' {
                break;
            }
        }
        // Only whole groups: hand a partial one back (the length was checked).
        while !clean.len().is_multiple_of(4) {
            self.pos -= 1;
            if !self.text[self.pos].is_ascii_whitespace() {
                clean.pop();
            }
        }
        self.pending.clear();
        self.at = 0;
        base64::engine::general_purpose::STANDARD
            .decode_vec(&clean, &mut self.pending)
            .map_err(|e| anyhow!("{name}: bad base64 data in {what} (from character {start}): {e}"))?;
        Ok(())
    }

    /// The next `n` bytes: borrowed from raw data; decoded into `buf` from base64.
    pub(crate) fn take<'s>(&'s mut self, name: &str, what: &str, n: usize, buf: &'s mut Vec<u8>) -> Result<&'s [u8]> {
        if n > self.left {
            bail!("{name}: truncated {what}: {n} more bytes needed, {} present", self.left);
        }
        self.left -= n;
        if !self.base64 {
            let s = &self.text[self.pos..self.pos + n];
            self.pos += n;
            return Ok(s);
        }
        buf.clear();
        buf.reserve(n);
        while buf.len() < n {
            if self.at == self.pending.len() {
                self.refill(name, what)?;
                if self.pending.is_empty() {
                    bail!("{name}: truncated {what}: its base64 text ends early");
                }
            }
            let k = (n - buf.len()).min(self.pending.len() - self.at);
            buf.extend_from_slice(&self.pending[self.at..self.at + k]);
            self.at += k;
        }
        Ok(&buf[..])
    }

    /// One header word: an unsigned integer of `width` bytes (4 or 8) in
    /// `endian` order.
    pub(crate) fn word(&mut self, name: &str, what: &str, width: usize, endian: Endian) -> Result<usize> {
        if self.left < width {
            bail!("{name}: truncated {what}: its header ends after {} bytes", self.left);
        }
        let mut buf = Vec::new();
        let c = self.take(name, what, width, &mut buf)?;
        let v = match width {
            4 => endian.read::<u32>(c) as u64,
            _ => endian.read::<u64>(c),
        };
        usize::try_from(v).map_err(|_| anyhow!("{name}: header value {v} in {what} is too large"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Base64 streams back to back (VTK writes the header and the data as
    /// two), read in pieces across the 64 KiB refills.
    #[test]
    fn base64_streams_back_to_back() {
        use base64::Engine as _;
        let mut buf = Vec::new();
        let mut s = Stream::base64("f", "a", b" AQI=\n AwQF ").unwrap();
        assert_eq!(s.left(), 5);
        assert_eq!(s.take("f", "a", 5, &mut buf).unwrap(), [1, 2, 3, 4, 5]);
        assert!(Stream::base64("f", "a", b"AQI").err().unwrap().to_string().contains("multiple of 4"));
        let mut s = Stream::base64("f", "a", b"A*I=").unwrap();
        assert!(s.take("f", "a", 2, &mut buf).unwrap_err().to_string().contains("bad base64"));
        let data: Vec<u8> = (0..200_001u32).map(|i| (i % 253) as u8).collect();
        let b64 = base64::engine::general_purpose::STANDARD;
        let text = format!("{}\n  {}", b64.encode([9u8]), b64.encode(&data));
        let mut s = Stream::base64("f", "a", text.as_bytes()).unwrap();
        assert_eq!(s.left(), data.len() + 1);
        assert_eq!(s.take("f", "a", 1, &mut buf).unwrap(), [9]);
        let mut got = Vec::new();
        for n in [7, 70_000, 65_536, 64_458 - 1, 1] {
            got.extend_from_slice(s.take("f", "a", n, &mut buf).unwrap());
        }
        assert_eq!(got, data);
        assert!(s.take("f", "a", 1, &mut buf).unwrap_err().to_string().contains("truncated"));
    }
}
