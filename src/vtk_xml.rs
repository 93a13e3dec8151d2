//! The VTK XML file layer shared by the ImageData (`volume::vti`) and
//! UnstructuredGrid (`mesh::vtu`) readers: raw appended data cut off before
//! the XML is parsed, the root's `byte_order` / `header_type` /
//! `compressor`, and one `DataArray`'s binary payload (inline base64 or
//! appended raw/base64; uncompressed, or zlib, LZ4 or LZMA blocks).
//!
//! Binary data is a header then the bytes: uncompressed, one word with the
//! byte count; compressed, VTK's block header `[blocks, block size, last
//! block size (0: full), compressed size of each block]`, then each block
//! compressed on its own (a zlib stream, an LZ4 block or an `.xz` stream:
//! [`Compressor`]). Every count is checked against the size the caller
//! expects and the bytes present, and each block's promise against what its
//! compressed bytes can hold, before any block is inflated
//! ([`Payload::open`]); each block inflates to exactly its promised size.
//! The data is then handed on a block (or 64 KiB) at a time
//! ([`Payload::for_each_chunk`]), base64 text decoded as it is read
//! ([`Stream`]), so a reader can decode straight into its final arrays
//! without holding the whole inflated array.
//!
//! XML nesting: roxmltree overflows the stack on deeply nested input (200,000
//! levels abort the process), so the text is scanned first and more than
//! [`MAX_DEPTH`] levels of elements is an error (VTK files nest 6 deep).

use anyhow::{anyhow, bail, Result};

use crate::bytes::inflate::{inflate_exact, lz4_block_exact, max_inflated_at, xz_exact, Wrapper, DEFLATE_RATIO, LZ4_RATIO, XZ_RATIO};
use crate::bytes::stream::{Stream, CHUNK};
use crate::bytes::Endian;

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

fn rfind(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).rposition(|w| w == needle)
}

/// A VTK XML file cut in two: the XML text (closed with `</VTKFile>` when
/// appended data was cut off) and the appended data's encoding and bytes
/// (after the `_` marker).
pub(crate) struct XmlParts<'a> {
    /// Borrowed from the file when nothing was cut off.
    pub xml: std::borrow::Cow<'a, str>,
    pub appended: Option<(String, &'a [u8])>,
}

/// Splits off raw appended data (it is not XML text) and checks the file
/// starts like VTK XML.
pub(crate) fn split_appended<'a>(name: &str, bytes: &'a [u8]) -> Result<XmlParts<'a>> {
    let body = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let first = body.iter().position(|c| !c.is_ascii_whitespace()).unwrap_or(body.len());
    if !(body[first..].starts_with(b"<?xml") || body[first..].starts_with(b"<VTKFile")) {
        bail!("{name}: not a VTK XML file (it does not start with '<?xml' or '<VTKFile')");
    }
    let (xml_bytes, appended) = match find(body, b"<AppendedData") {
        None => (body, None),
        Some(at) => {
            let tag_end = body[at..]
                .iter()
                .position(|&c| c == b'>')
                .map(|e| at + e)
                .ok_or_else(|| anyhow!("{name}: truncated <AppendedData> tag"))?;
            let tag = std::str::from_utf8(&body[at..=tag_end]).map_err(|_| anyhow!("{name}: non-text bytes in <AppendedData>"))?;
            let tag_doc = format!("{}/>", tag.trim_end_matches('>').trim_end_matches('/'));
            let tag_xml = roxmltree::Document::parse(&tag_doc).map_err(|e| anyhow!("{name}: bad <AppendedData> tag: {e}"))?;
            let encoding = tag_xml.root_element().attribute("encoding").unwrap_or("raw").to_string();
            let rest = &body[tag_end + 1..];
            let us = rest
                .iter()
                .position(|c| !c.is_ascii_whitespace())
                .filter(|&i| rest[i] == b'_')
                .ok_or_else(|| anyhow!("{name}: appended data does not start with the '_' marker"))?;
            let data = &rest[us + 1..];
            let data = match rfind(data, b"</AppendedData>") {
                Some(e) => &data[..e],
                None => data,
            };
            (&body[..at], Some((encoding, data)))
        }
    };
    let text = std::str::from_utf8(xml_bytes)
        .map_err(|e| anyhow!("{name}: the XML is not UTF-8 text (invalid byte at offset {})", e.valid_up_to()))?;
    let xml = match appended {
        Some(_) => std::borrow::Cow::Owned(format!("{text}</VTKFile>")),
        None => std::borrow::Cow::Borrowed(text),
    };
    check_depth(name, &xml)?;
    Ok(XmlParts { xml, appended })
}

/// Deepest element nesting an XML input may have: VTK files nest five
/// levels; a parser walking 20,000 levels overflows the stack.
pub(crate) const MAX_DEPTH: usize = 64;

/// Refuse XML nested deeper than [`MAX_DEPTH`] before it is parsed
/// (a scan of the tags: comments, CDATA, declarations and quoted
/// attribute values are skipped).
pub(crate) fn check_depth(source: &str, text: &str) -> Result<()> {
    let b = text.as_bytes();
    let skip_to = |from: usize, end: &[u8]| find_from(b, from, end).map_or(b.len(), |e| e + end.len());
    let (mut depth, mut i) = (0usize, 0usize);
    while let Some(off) = b[i..].iter().position(|&c| c == b'<') {
        let at = i + off;
        let rest = &b[at..];
        if rest.starts_with(b"<!--") {
            i = skip_to(at, b"-->");
            continue;
        }
        if rest.starts_with(b"<![CDATA[") {
            i = skip_to(at, b"]]>");
            continue;
        }
        // The tag's end, outside quoted attribute values.
        let (mut j, mut quote) = (at + 1, None);
        while j < b.len() {
            match (quote, b[j]) {
                (Some(q), c) if c == q => quote = None,
                (None, c @ (b'"' | b'\'')) => quote = Some(c),
                (None, b'>') => break,
                _ => {}
            }
            j += 1;
        }
        if rest.starts_with(b"</") {
            depth = depth.saturating_sub(1);
        } else if !(rest.starts_with(b"<?") || rest.starts_with(b"<!") || b[j.saturating_sub(1)] == b'/') {
            depth += 1;
            if depth > MAX_DEPTH {
                bail!("{source}: XML elements nested more than {MAX_DEPTH} deep (at byte {at}); not a VTK file");
            }
        }
        i = j + 1;
        if i >= b.len() {
            break;
        }
    }
    Ok(())
}

fn find_from(hay: &[u8], from: usize, needle: &[u8]) -> Option<usize> {
    hay.get(from..)?.windows(needle.len()).position(|w| w == needle).map(|p| p + from)
}

/// A `compressor` of the `<VTKFile>` root. VTK writes the same block
/// header for each (`[blocks, block size, last block size, compressed size
/// of each block]`); the blocks differ: a zlib stream each
/// (`vtkZLibDataCompressor`), an LZ4 *block* (`vtkLZ4DataCompressor`:
/// `LZ4_compress_fast`, no frame) or an `.xz` stream
/// (`vtkLZMADataCompressor`: `lzma_easy_buffer_encode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Compressor {
    None,
    Zlib,
    Lz4,
    Lzma,
}

impl Compressor {
    fn kind(self) -> &'static str {
        match self {
            Compressor::None => "uncompressed",
            Compressor::Zlib => "zlib",
            Compressor::Lz4 => "LZ4",
            Compressor::Lzma => "LZMA",
        }
    }

    /// The most bytes `c` compressed bytes of one block can hold
    /// (`bytes::inflate::DEFLATE_RATIO` and the others). A header
    /// promising more is refused before anything is inflated.
    fn max_inflated(self, c: usize) -> usize {
        let ratio = match self {
            Compressor::None => 1,
            Compressor::Zlib => DEFLATE_RATIO,
            Compressor::Lz4 => LZ4_RATIO,
            Compressor::Lzma => XZ_RATIO,
        };
        max_inflated_at(ratio, c)
    }
}

/// How binary arrays are laid out, from the `<VTKFile>` root.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Layout {
    pub endian: Endian,
    /// Bytes per header word (UInt32: 4, UInt64: 8).
    pub word: usize,
    pub compressor: Compressor,
}

/// Checks the root is `<VTKFile type="{kind}">` and reads its layout.
pub(crate) fn root_layout(name: &str, root: roxmltree::Node, kind: &str) -> Result<Layout> {
    if root.tag_name().name() != "VTKFile" {
        bail!("{name}: the root element is <{}>, not <VTKFile>", root.tag_name().name());
    }
    match root.attribute("type") {
        Some(t) if t == kind => {}
        other => bail!("{name}: VTK XML type '{}' is not {kind}", other.unwrap_or("(missing)")),
    }
    let endian = match root.attribute("byte_order").unwrap_or("LittleEndian") {
        "LittleEndian" => Endian::Little,
        "BigEndian" => Endian::Big,
        o => bail!("{name}: bad byte_order '{o}': expected LittleEndian or BigEndian"),
    };
    let word = match root.attribute("header_type").unwrap_or("UInt32") {
        "UInt32" => 4,
        "UInt64" => 8,
        o => bail!("{name}: bad header_type '{o}': expected UInt32 or UInt64"),
    };
    let compressor = match root.attribute("compressor") {
        None | Some("") => Compressor::None,
        Some("vtkZLibDataCompressor") => Compressor::Zlib,
        Some("vtkLZ4DataCompressor") => Compressor::Lz4,
        Some("vtkLZMADataCompressor") => Compressor::Lzma,
        Some(o) => bail!(
            "{name}: unsupported compressor '{o}'; supported: none, vtkZLibDataCompressor, vtkLZ4DataCompressor, \
             vtkLZMADataCompressor"
        ),
    };
    Ok(Layout { endian, word, compressor })
}

/// The numbers of an attribute, exactly `n` of them.
pub(crate) fn numbers<T: std::str::FromStr>(name: &str, node: roxmltree::Node, attr: &str, n: usize) -> Result<Option<Vec<T>>> {
    let Some(text) = node.attribute(attr) else { return Ok(None) };
    let v = text
        .split_ascii_whitespace()
        .map(|t| t.parse::<T>().map_err(|_| anyhow!("{name}: bad number '{t}' in {attr}=\"{text}\"")))
        .collect::<Result<Vec<T>>>()?;
    if v.len() != n {
        bail!("{name}: {attr}=\"{text}\" has {} numbers, expected {n}", v.len());
    }
    Ok(Some(v))
}

/// One array's binary data, its header read and checked: the data bytes
/// (`expected`, what its count and type need) and, compressed, each
/// block's compressed and inflated size. Nothing is inflated yet, and
/// nothing the size of the data is allocated.
pub(crate) struct Payload<'a> {
    stream: Stream<'a>,
    compressor: Compressor,
    /// Compressed: (compressed bytes, inflated bytes) per block.
    blocks: Vec<(usize, usize)>,
    expected: usize,
}

impl<'a> Payload<'a> {
    /// Reads and checks the header: uncompressed, one word equal to
    /// `expected` and that many bytes present; compressed, VTK's block
    /// header whose sizes make exactly `expected` bytes, whose blocks are
    /// all present, and none of which promises more than its compressed
    /// bytes can hold.
    pub(crate) fn open(name: &str, what: &str, mut stream: Stream<'a>, layout: Layout, expected: usize) -> Result<Payload<'a>> {
        let compressor = layout.compressor;
        if compressor == Compressor::None {
            let n = stream.word(name, what, layout.word, layout.endian)?;
            if n != expected {
                bail!("{name}: header/size mismatch: {what} declares {n} bytes, its size needs {expected}");
            }
            if stream.left() < n {
                bail!("{name}: truncated {what}: {n} bytes declared, {} present", stream.left());
            }
            return Ok(Payload { stream, compressor, blocks: Vec::new(), expected });
        }
        let blocks = stream.word(name, what, layout.word, layout.endian)?;
        let block = stream.word(name, what, layout.word, layout.endian)?;
        let last = stream.word(name, what, layout.word, layout.endian)?;
        // The per-block sizes must fit in what remains: bounds the vector.
        if blocks > stream.left() / layout.word {
            bail!("{name}: truncated {what}: {blocks} compressed blocks declared, the header ends first");
        }
        if last > block {
            bail!("{name}: {what}: last block size {last} is larger than the block size {block}");
        }
        let total = match (blocks, last) {
            (0, _) => Some(0),
            (b, 0) => b.checked_mul(block),
            (b, l) => (b - 1).checked_mul(block).and_then(|t| t.checked_add(l)),
        };
        if total != Some(expected) {
            bail!(
                "{name}: header/size mismatch: the block header of {what} ({blocks} blocks of {block} bytes, last \
                 {last}) does not make the {expected} bytes its size needs"
            );
        }
        let kind = compressor.kind();
        let mut sizes = Vec::with_capacity(blocks);
        let mut present = 0usize;
        for i in 0..blocks {
            let c = stream.word(name, what, layout.word, layout.endian)?;
            let size = if i + 1 == blocks && last != 0 { last } else { block };
            if size > compressor.max_inflated(c) {
                bail!(
                    "{name}: {kind} data in {what}: block {i} of {blocks} has {c} compressed bytes, which cannot hold \
                     the {size} bytes the header promises"
                );
            }
            present = present.saturating_add(c);
            sizes.push((c, size));
        }
        if present > stream.left() {
            bail!(
                "{name}: truncated {what}: its {blocks} compressed blocks need {present} bytes, {} present",
                stream.left()
            );
        }
        Ok(Payload { stream, compressor, blocks: sizes, expected })
    }

    /// The data's byte count (what the header promised and `open` checked).
    pub(crate) fn len(&self) -> usize {
        self.expected
    }

    /// Hands the data to `sink` in order, in pieces (a block, or 64 KiB of
    /// uncompressed data), each block inflated to exactly its promised size.
    pub(crate) fn for_each_chunk(mut self, name: &str, what: &str, sink: &mut dyn FnMut(&[u8]) -> Result<()>) -> Result<()> {
        let mut buf = Vec::new();
        if self.compressor == Compressor::None {
            let mut left = self.expected;
            while left > 0 {
                let n = left.min(CHUNK);
                sink(self.stream.take(name, what, n, &mut buf)?)?;
                left -= n;
            }
            return Ok(());
        }
        let mut out = Vec::new();
        let count = self.blocks.len();
        for (i, &(c, size)) in self.blocks.iter().enumerate() {
            let input = self.stream.take(name, what, c, &mut buf)?;
            inflate_block(name, &format!("{what}, block {i} of {count}"), self.compressor, input, size, &mut out)?;
            sink(&out)?;
        }
        Ok(())
    }

    /// The whole data in one vector (`expected` bytes).
    pub(crate) fn into_vec(self, name: &str, what: &str) -> Result<Vec<u8>> {
        let mut v = Vec::with_capacity(self.expected);
        self.for_each_chunk(name, what, &mut |c| {
            v.extend_from_slice(c);
            Ok(())
        })?;
        Ok(v)
    }
}

/// Inflates one compressed block into `out`: exactly `size` bytes, or an
/// error; never more than `size` (+1 for zlib) bytes are produced.
fn inflate_block(name: &str, what: &str, compressor: Compressor, input: &[u8], size: usize, out: &mut Vec<u8>) -> Result<()> {
    match compressor {
        Compressor::None => {
            out.clear();
            out.extend_from_slice(input);
        }
        Compressor::Zlib => *out = inflate_exact(name, what, Wrapper::Zlib, input, size)?,
        Compressor::Lz4 => lz4_block_exact(name, what, input, size, out)?,
        Compressor::Lzma => xz_exact(name, what, input, size, out)?,
    }
    Ok(())
}

#[cfg(test)]
thread_local! {
    /// XML nodes the readers have stepped over (this thread): a count that
    /// shows how reading grows with the file (`visit`).
    pub(crate) static NODE_VISITS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// Counts one XML node stepped over (tests only: `NODE_VISITS`).
#[inline]
pub(crate) fn visit() {
    #[cfg(test)]
    NODE_VISITS.with(|c| c.set(c.get() + 1));
}

/// The `<AppendedData>` of a file: its encoding, its bytes, and the sorted
/// offsets of every appended `DataArray` (one array's bytes run to the next
/// offset), gathered once per document.
pub(crate) struct Appended<'a> {
    encoding: String,
    data: &'a [u8],
    offsets: Vec<usize>,
}

impl<'a> Appended<'a> {
    pub(crate) fn new(doc: &roxmltree::Document, parts: Option<&(String, &'a [u8])>) -> Option<Appended<'a>> {
        let (encoding, data) = parts?;
        let mut offsets: Vec<usize> = doc
            .descendants()
            .inspect(|_| visit())
            .filter(|n| n.has_tag_name("DataArray") && n.attribute("format") == Some("appended"))
            .filter_map(|n| n.attribute("offset")?.trim().parse::<usize>().ok())
            .filter(|&o| o <= data.len())
            .collect();
        offsets.sort_unstable();
        offsets.dedup();
        Some(Appended { encoding: encoding.clone(), data, offsets })
    }
}

/// A `binary` or `appended` `DataArray`'s payload, header checked
/// ([`Payload::open`]), for `expected` data bytes; `None` for an `ascii`
/// one (its text is the caller's).
pub(crate) fn array_payload<'a>(
    name: &str,
    what: &str,
    array: roxmltree::Node<'a, '_>,
    appended: Option<&Appended<'a>>,
    layout: Layout,
    expected: usize,
) -> Result<Option<Payload<'a>>> {
    let stream = match array.attribute("format").unwrap_or("ascii") {
        "ascii" => return Ok(None),
        "binary" => Stream::base64(name, what, array.text().unwrap_or("").as_bytes())?,
        "appended" => {
            let app = appended.ok_or_else(|| anyhow!("{name}: {what} is appended but there is no <AppendedData>"))?;
            let off_text = array.attribute("offset").ok_or_else(|| anyhow!("{name}: appended {what} has no offset"))?;
            let offset: usize = off_text.trim().parse().map_err(|_| anyhow!("{name}: bad offset '{off_text}' of {what}"))?;
            // This array's bytes run to the next appended array's offset.
            let next = match app.offsets.binary_search(&offset) {
                Ok(i) => i + 1,
                Err(i) => i,
            };
            let end = app.offsets.get(next).copied().unwrap_or(app.data.len());
            let tail = app.data.get(offset..end).ok_or_else(|| {
                anyhow!("{name}: offset {offset} of {what} is past the end of the {} bytes of appended data", app.data.len())
            })?;
            match app.encoding.as_str() {
                "raw" => Stream::raw(tail),
                "base64" => Stream::base64(name, what, tail)?,
                o => bail!("{name}: unsupported AppendedData encoding '{o}'; supported: raw, base64"),
            }
        }
        o => bail!("{name}: {what} has format '{o}'; supported: ascii, binary, appended"),
    };
    Payload::open(name, what, stream, layout, expected).map(Some)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deep_nesting_is_refused_before_parsing() {
        let depth = 200_000;
        let xml = format!("<VTKFile>{}{}</VTKFile>", "<a>".repeat(depth), "</a>".repeat(depth));
        let e = split_appended("deep.vtu", xml.as_bytes()).err().map(|e| e.to_string()).unwrap_or_default();
        assert!(e.contains("deep.vtu") && e.contains("nested more than"), "{e}");
        // A normal depth with comments, self-closing tags and a '/>' pair passes.
        let ok = format!("<?xml version=\"1.0\"?><!-- c --><VTKFile>{}<b/>{}</VTKFile>", "<a x=\"1\">".repeat(50), "</a>".repeat(50));
        split_appended("ok.vtu", ok.as_bytes()).unwrap();
    }

    #[test]
    fn xml_nesting_is_bounded_before_parsing() {
        let ok = "<?xml version=\"1.0\"?><!-- <a><a><a> --><VTKFile a='<x>'><ImageData><Piece/></ImageData></VTKFile>";
        check_depth("f", ok).unwrap();
        for n in [MAX_DEPTH + 1, 20_000] {
            let deep = format!("{}{}", "<a>".repeat(n), "</a>".repeat(n));
            let e = check_depth("f.vti", &deep).unwrap_err().to_string();
            assert!(e.contains("f.vti") && e.contains("nested more than"), "{e}");
        }
        let flat = "<a></a>".repeat(100_000);
        check_depth("f", &flat).unwrap();
    }

    fn compress(c: Compressor, data: &[u8]) -> Vec<u8> {
        use std::io::Write as _;
        match c {
            Compressor::None => data.to_vec(),
            Compressor::Zlib => {
                let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
                e.write_all(data).unwrap();
                e.finish().unwrap()
            }
            Compressor::Lz4 => lz4_flex::block::compress(data),
            Compressor::Lzma => {
                let mut out = Vec::new();
                lzma_rs::xz_compress(&mut &data[..], &mut out).unwrap();
                out
            }
        }
    }

    /// VTK's layout: `[blocks, block, last, sizes...]` then the blocks, each
    /// compressed from `chunk` bytes of `data` but declared as `declared`.
    fn blocks(c: Compressor, data: &[u8], chunk: usize, declared: usize) -> Vec<u8> {
        let comp: Vec<Vec<u8>> = data.chunks(chunk).map(|b| compress(c, b)).collect();
        let last = if data.len().is_multiple_of(chunk) { 0 } else { declared - (chunk - data.len() % chunk) };
        let mut out: Vec<u8> = [comp.len() as u32, declared as u32, last as u32].iter().flat_map(|w| w.to_le_bytes()).collect();
        for b in &comp {
            out.extend((b.len() as u32).to_le_bytes());
        }
        for b in comp {
            out.extend(b);
        }
        out
    }

    fn read(c: Compressor, stream: &[u8], expected: usize) -> Result<Vec<u8>> {
        let layout = Layout { endian: Endian::Little, word: 4, compressor: c };
        Payload::open("f.vtu", "the array", Stream::raw(stream), layout, expected)?.into_vec("f.vtu", "the array")
    }

    /// Every compressor: honest blocks read back; blocks that inflate past
    /// or short of their declared size, truncated blocks, corrupt bytes and
    /// impossible ratios are errors naming the file, at two block sizes.
    #[test]
    fn compressed_blocks_are_exact_and_bounded() {
        let data: Vec<u8> = (0..5000u32).map(|i| (i * 7 % 251) as u8).collect();
        for c in [Compressor::Zlib, Compressor::Lz4, Compressor::Lzma] {
            for chunk in [100, 1024] {
                let what = format!("{c:?} blocks of {chunk}");
                assert_eq!(read(c, &blocks(c, &data, chunk, chunk), data.len()).unwrap(), data, "{what}");
                // Declared 10 bytes smaller: each block inflates past it.
                let n = data.len().div_ceil(chunk);
                let lying = blocks(c, &data, chunk, chunk - 10);
                let e = format!("{:#}", read(c, &lying, data.len() - 10 * n).unwrap_err());
                assert!(e.starts_with("f.vtu: ") && e.contains("more than the"), "{what}: {e}");
                // Declared 10 bytes larger: each block ends early.
                let e = format!("{:#}", read(c, &blocks(c, &data, chunk, chunk + 10), data.len() + 10 * n).unwrap_err());
                assert!(e.contains("expected"), "{what}: {e}");
                // Truncated: the blocks' declared sizes run past the data, refused before inflating.
                let honest = blocks(c, &data, chunk, chunk);
                for cut in [honest.len() - 1, honest.len() / 2, 13] {
                    let e = format!("{:#}", read(c, &honest[..cut], data.len()).unwrap_err());
                    assert!(e.starts_with("f.vtu: ") && e.contains("truncated"), "{what} cut at {cut}: {e}");
                }
                // Corrupt bytes in the last block: never a panic; an error where the
                // format has a checksum (zlib's Adler-32, xz's CRC), while an LZ4 block
                // has none (VTK's reader cannot tell either).
                let mut bad = honest.clone();
                let k = bad.len() - 3;
                bad[k] ^= 0x5a;
                bad[k - 1] ^= 0xa5;
                let r = read(c, &bad, data.len());
                assert!(c == Compressor::Lz4 || r.is_err(), "{what}: corrupt block accepted");
            }
            // A block of a few bytes promising a gigabyte: refused from the header.
            let mut bomb: Vec<u8> = [1u32, 1 << 30, 0, 8].iter().flat_map(|w| w.to_le_bytes()).collect();
            bomb.extend([0u8; 8]);
            let e = format!("{:#}", read(c, &bomb, 1 << 30).unwrap_err());
            assert!(e.contains("cannot hold the 1073741824 bytes"), "{c:?}: {e}");
        }
    }
}
