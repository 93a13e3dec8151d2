//! The VTK XML file layer shared by the ImageData (`volume::vti`) and
//! UnstructuredGrid (`mesh::vtu`) readers: raw appended data cut off before
//! the XML is parsed, the root's `byte_order` / `header_type` /
//! `compressor`, and one `DataArray`'s binary payload (inline base64 or
//! appended raw/base64; uncompressed or zlib blocks).
//!
//! Binary data is a header then the bytes: uncompressed, one word with the
//! byte count; zlib-compressed, VTK's block header `[blocks, block size, last
//! block size (0: full), compressed size of each block]`, then each block as
//! its own zlib stream. Every count is checked against the size the caller
//! expects and the bytes present before any block is inflated, and each
//! block inflates to exactly its promised size.
//!
//! XML nesting: roxmltree overflows the stack on deeply nested input (200,000
//! levels abort the process), so the text is scanned first and more than
//! [`MAX_DEPTH`] levels of elements is an error (VTK files nest 6 deep).

use anyhow::{anyhow, bail, Result};

use crate::volume::decode::{base64_concat, inflate_exact, Endian, Wrapper};

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
    pub xml: String,
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
    let mut xml = std::str::from_utf8(xml_bytes)
        .map_err(|e| anyhow!("{name}: the XML is not UTF-8 text (invalid byte at offset {})", e.valid_up_to()))?
        .to_string();
    if appended.is_some() {
        xml.push_str("</VTKFile>");
    }
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

/// How binary arrays are laid out, from the `<VTKFile>` root.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Layout {
    pub endian: Endian,
    /// Bytes per header word (UInt32: 4, UInt64: 8).
    pub word: usize,
    pub zlib: bool,
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
    let zlib = match root.attribute("compressor") {
        None | Some("") => false,
        Some("vtkZLibDataCompressor") => true,
        Some(o) => bail!("{name}: unsupported compressor '{o}'; supported: none, vtkZLibDataCompressor"),
    };
    Ok(Layout { endian, word, zlib })
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

/// Reads header words of `word` bytes from a byte stream.
struct Words<'a> {
    b: &'a [u8],
    pos: usize,
    word: usize,
    endian: Endian,
}

impl Words<'_> {
    fn next(&mut self, name: &str, what: &str) -> Result<usize> {
        let c = self
            .b
            .get(self.pos..self.pos + self.word)
            .ok_or_else(|| anyhow!("{name}: truncated {what}: its header ends after {} bytes", self.b.len()))?;
        self.pos += self.word;
        let v = match (self.word, self.endian) {
            (4, Endian::Little) => u32::from_le_bytes([c[0], c[1], c[2], c[3]]) as u64,
            (4, Endian::Big) => u32::from_be_bytes([c[0], c[1], c[2], c[3]]) as u64,
            (_, e) => {
                let w: [u8; 8] = std::array::from_fn(|i| c[i]);
                if e == Endian::Little {
                    u64::from_le_bytes(w)
                } else {
                    u64::from_be_bytes(w)
                }
            }
        };
        usize::try_from(v).map_err(|_| anyhow!("{name}: header value {v} in {what} is too large"))
    }
}

/// The `expected` data bytes of one array from its binary stream (header +
/// data), compressed or not.
pub(crate) fn binary_payload(name: &str, what: &str, stream: &[u8], layout: Layout, expected: usize) -> Result<Vec<u8>> {
    let Layout { endian, word, zlib } = layout;
    let mut w = Words { b: stream, pos: 0, word, endian };
    if !zlib {
        let n = w.next(name, what)?;
        if n != expected {
            bail!("{name}: header/size mismatch: {what} declares {n} bytes, its size needs {expected}");
        }
        let body = stream
            .get(w.pos..)
            .filter(|b| b.len() >= n)
            .ok_or_else(|| anyhow!("{name}: truncated {what}: {n} bytes declared, {} present", stream.len() - w.pos))?;
        return Ok(body[..n].to_vec());
    }
    let blocks = w.next(name, what)?;
    let block = w.next(name, what)?;
    let last = w.next(name, what)?;
    // The per-block sizes must fit in what remains: bounds the vector.
    if blocks > (stream.len() - w.pos) / word {
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
    let sizes = (0..blocks).map(|_| w.next(name, what)).collect::<Result<Vec<usize>>>()?;
    let mut at = w.pos;
    let mut out = Vec::with_capacity(expected.min(stream.len().saturating_mul(1032)));
    for (i, &c) in sizes.iter().enumerate() {
        let end = at.checked_add(c).filter(|&e| e <= stream.len()).ok_or_else(|| {
            anyhow!("{name}: truncated {what}: compressed block {i} of {blocks} ({c} bytes) runs past the data")
        })?;
        let size = if i + 1 == blocks && last != 0 { last } else { block };
        out.extend(inflate_exact(name, &format!("{what}, block {i}"), Wrapper::Zlib, &stream[at..end], size)?);
        at = end;
    }
    Ok(out)
}

/// The `expected` bytes of a `binary` or `appended` `DataArray` (`None` for
/// an `ascii` one: its text is the caller's). `doc` is searched for the
/// next appended offset, where this array's bytes end.
pub(crate) fn array_payload(
    name: &str,
    what: &str,
    array: roxmltree::Node,
    doc: &roxmltree::Document,
    appended: Option<&(String, &[u8])>,
    layout: Layout,
    expected: usize,
) -> Result<Option<Vec<u8>>> {
    match array.attribute("format").unwrap_or("ascii") {
        "ascii" => Ok(None),
        "binary" => {
            let text = array.text().unwrap_or("");
            let stream = base64_concat(name, what, text.as_bytes())?;
            binary_payload(name, what, &stream, layout, expected).map(Some)
        }
        "appended" => {
            let (encoding, data) = appended.ok_or_else(|| anyhow!("{name}: {what} is appended but there is no <AppendedData>"))?;
            let off_text = array.attribute("offset").ok_or_else(|| anyhow!("{name}: appended {what} has no offset"))?;
            let offset: usize = off_text.trim().parse().map_err(|_| anyhow!("{name}: bad offset '{off_text}' of {what}"))?;
            // This array's bytes run to the next appended array's offset.
            let next = doc
                .descendants()
                .filter(|n| n.has_tag_name("DataArray") && n.attribute("format") == Some("appended"))
                .filter_map(|n| n.attribute("offset")?.trim().parse::<usize>().ok())
                .filter(|&o| o > offset && o <= data.len())
                .min()
                .unwrap_or(data.len());
            let tail = data.get(offset..next).ok_or_else(|| {
                anyhow!("{name}: offset {offset} of {what} is past the end of the {} bytes of appended data", data.len())
            })?;
            let stream = match encoding.as_str() {
                "raw" => std::borrow::Cow::Borrowed(tail),
                "base64" => std::borrow::Cow::Owned(base64_concat(name, what, tail)?),
                o => bail!("{name}: unsupported AppendedData encoding '{o}'; supported: raw, base64"),
            };
            binary_payload(name, what, &stream, layout, expected).map(Some)
        }
        o => bail!("{name}: {what} has format '{o}'; supported: ascii, binary, appended"),
    }
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
}
