//! Bounded decompression: each stream or block inflates to exactly the
//! size its header promises, or is an error, and never costs more than
//! that promise (plus a byte) in memory. gzip and zlib (deflate: NRRD,
//! NIfTI, MetaImage, VTK's zlib blocks), LZ4 blocks and `.xz` streams
//! (VTK's other compressors).

use std::io::Read;

use anyhow::{anyhow, bail, Result};

/// Deflate never expands more than about 1032:1, so no stream of `n` bytes
/// can need more room than this: caps what a header's promise reserves.
fn max_inflated(n: usize) -> usize {
    max_inflated_at(DEFLATE_RATIO, n)
}

/// Which wrapper a deflate stream has.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Wrapper {
    /// gzip (RFC 1952), possibly several members back to back.
    Gzip,
    /// zlib (RFC 1950), one stream.
    Zlib,
}

/// Decompresses `input` to exactly `expected` bytes (what the header
/// promises): reading stops one byte past it, so a bomb costs at most that,
/// and a stream that is corrupt, ends early or holds more is an error.
pub(crate) fn inflate_exact(source: &str, what: &str, wrapper: Wrapper, input: &[u8], expected: usize) -> Result<Vec<u8>> {
    inflate_after(source, what, wrapper, input, 0, expected)
}

/// Decompresses `input`, whose first `skip` bytes (a header offset) are
/// read and dropped, to exactly `expected` bytes after them. Memory is
/// bounded by `expected` alone, whatever the offset; a promise the stream
/// cannot hold (deflate expands at most ~1032:1) is refused before any
/// inflating.
pub(crate) fn inflate_after(source: &str, what: &str, wrapper: Wrapper, input: &[u8], skip: usize, expected: usize) -> Result<Vec<u8>> {
    let kind = match wrapper {
        Wrapper::Gzip => "gzip",
        Wrapper::Zlib => "zlib",
    };
    let promised = skip.saturating_add(expected);
    if promised > max_inflated(input.len()) {
        bail!(
            "{source}: {kind} data in {what}: {} compressed bytes cannot hold the {promised} bytes the header promises \
             ({skip} skipped + {expected} of data)",
            input.len()
        );
    }
    let mut reader: Box<dyn Read> = match wrapper {
        Wrapper::Gzip => Box::new(flate2::read::MultiGzDecoder::new(input)),
        Wrapper::Zlib => Box::new(flate2::read::ZlibDecoder::new(input)),
    };
    let skipped = std::io::copy(&mut (&mut reader).take(skip as u64), &mut std::io::sink());
    let skipped = skipped.map_err(|e| anyhow!("{source}: corrupt {kind} data in {what}: {e}"))?;
    if skipped < skip as u64 {
        bail!("{source}: {kind} data in {what} decompresses to {skipped} bytes, shorter than the {skip}-byte offset before the data");
    }
    let mut out = Vec::with_capacity(expected.min(max_inflated(input.len())));
    if let Err(e) = reader.take(expected as u64 + 1).read_to_end(&mut out) {
        bail!("{source}: corrupt {kind} data in {what}: {e}");
    }
    if out.len() > expected {
        bail!("{source}: {kind} data in {what} decompresses to more than the {promised} bytes the header promises");
    }
    if out.len() < expected {
        bail!(
            "{source}: {kind} data in {what} decompresses to {} bytes, {promised} expected (truncated or corrupt stream)",
            out.len() + skip
        );
    }
    Ok(out)
}

/// The first `n` decompressed bytes of a gzip stream (a header inside it).
pub(crate) fn gunzip_prefix(source: &str, what: &str, input: &[u8], n: usize) -> Result<Vec<u8>> {
    let mut out = Vec::with_capacity(n.min(max_inflated(input.len())));
    flate2::read::MultiGzDecoder::new(input)
        .take(n as u64)
        .read_to_end(&mut out)
        .map_err(|e| anyhow!("{source}: corrupt gzip data in {what}: {e}"))?;
    if out.len() < n {
        bail!("{source}: gzip data decompresses to only {} bytes, shorter than the {n}-byte {what}", out.len());
    }
    Ok(out)
}

/// Deflate's, an LZ4 block's and an `.xz` stream's bound on how many times
/// its compressed size a block can inflate to: deflate at most ~1032:1, an
/// LZ4 block 255:1 (a match length byte per 255 bytes); an `.xz` stream has
/// no such bound, so 65536:1 (VTK's 32 KiB blocks of zeros are ~100 bytes
/// of xz: 330:1). A header promising more is refused before anything is
/// inflated.
pub(crate) const DEFLATE_RATIO: usize = 1032;
pub(crate) const LZ4_RATIO: usize = 256;
pub(crate) const XZ_RATIO: usize = 65536;

/// The most bytes `c` compressed bytes can hold at `ratio` (above), with
/// room for a header's worth.
pub(crate) fn max_inflated_at(ratio: usize, c: usize) -> usize {
    c.saturating_mul(ratio).saturating_add(64)
}

/// Decompresses the LZ4 block `input` into `out` (resized to `size`):
/// exactly `size` bytes, or an error; never more.
pub(crate) fn lz4_block_exact(source: &str, what: &str, input: &[u8], size: usize, out: &mut Vec<u8>) -> Result<()> {
    out.clear();
    out.resize(size, 0);
    let n = lz4_flex::block::decompress_into(input, out).map_err(|e| match e {
        lz4_flex::block::DecompressError::OutputTooSmall { .. } => {
            anyhow!("{source}: LZ4 data in {what} decompresses to more than the {size} bytes the header promises")
        }
        e => anyhow!("{source}: corrupt LZ4 data in {what}: {e}"),
    })?;
    if n != size {
        bail!("{source}: LZ4 data in {what} decompresses to {n} bytes, {size} expected (truncated or corrupt block)");
    }
    Ok(())
}

/// A writer that refuses bytes past `limit` (an `.xz` block inflating past
/// its promised size stops there).
struct Capped<'v> {
    out: &'v mut Vec<u8>,
    limit: usize,
}

impl std::io::Write for Capped<'_> {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        if self.out.len() + b.len() > self.limit {
            return Err(std::io::Error::other("inflates past its promised size"));
        }
        self.out.extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Decompresses the `.xz` stream `input` into `out` (cleared first):
/// exactly `size` bytes, or an error; never more.
pub(crate) fn xz_exact(source: &str, what: &str, input: &[u8], size: usize, out: &mut Vec<u8>) -> Result<()> {
    out.clear();
    let mut w = Capped { out, limit: size };
    if let Err(e) = lzma_rs::xz_decompress(&mut &input[..], &mut w) {
        let over = matches!(&e, lzma_rs::error::Error::IoError(io) if io.kind() == std::io::ErrorKind::Other);
        if over {
            bail!("{source}: LZMA data in {what} decompresses to more than the {size} bytes the header promises");
        }
        bail!("{source}: corrupt LZMA data in {what}: {e}");
    }
    if out.len() != size {
        bail!(
            "{source}: LZMA data in {what} decompresses to {} bytes, {size} expected (truncated or corrupt block)",
            out.len()
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write as _;

    fn zlib(b: &[u8]) -> Vec<u8> {
        let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        e.write_all(b).unwrap();
        e.finish().unwrap()
    }


    #[test]
    fn inflate_is_exact_and_bounded() {
        let data: Vec<u8> = (0..5000u32).map(|i| (i % 251) as u8).collect();
        let z = zlib(&data);
        assert_eq!(inflate_exact("f", "b", Wrapper::Zlib, &z, data.len()).unwrap(), data);
        let e = inflate_exact("f", "b", Wrapper::Zlib, &z, 4999).unwrap_err().to_string();
        assert!(e.contains("more than the 4999 bytes"), "{e}");
        let e = inflate_exact("f", "b", Wrapper::Zlib, &z, 5001).unwrap_err().to_string();
        assert!(e.contains("5000 bytes, 5001 expected"), "{e}");
        let e = inflate_exact("f", "b", Wrapper::Zlib, &z[..z.len() / 2], data.len()).unwrap_err().to_string();
        assert!(e.starts_with("f: ") && e.contains("zlib"), "{e}");
        let mut bad = z.clone();
        bad[0] ^= 0xff;
        assert!(inflate_exact("f", "b", Wrapper::Zlib, &bad, data.len()).unwrap_err().to_string().contains("corrupt zlib"));
        let e = inflate_exact("f", "b", Wrapper::Gzip, &z, data.len()).unwrap_err().to_string();
        assert!(e.contains("corrupt gzip"), "{e}");
    }
}
