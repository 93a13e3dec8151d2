//! VTK XML ImageData (`.vti`) reader.
//!
//! One `Piece` covering the `WholeExtent`; `Origin`, `Spacing` and an
//! axis-aligned `Direction`; `byte_order` little or big; `header_type`
//! UInt32 or UInt64; `compressor` none or `vtkZLibDataCompressor`. The point
//! data array read is the one named by the caller, else the `PointData`'s
//! active `Scalars`, else the first one-component array. Its data may be
//! `ascii`, inline `binary` (base64) or `appended` (raw or base64), of type
//! UInt8, Int16, UInt16, Float32 (Int8 and Int32 convert, see `decode`).
//!
//! Binary data is a header then the bytes: uncompressed, one word with the
//! byte count; zlib-compressed, VTK's block header `[blocks, block size, last
//! block size (0: full), compressed size of each block]`, then each block as
//! its own zlib stream. Every count is checked against the extent and the
//! bytes present before any block is inflated, and each block inflates to
//! exactly its promised size.
//!
//! Raw appended data is not XML text, so the file is cut at `<AppendedData`:
//! the XML before it is parsed (closed with `</VTKFile>`), the bytes after
//! its `_` marker are the appended data.

use anyhow::{anyhow, bail, Result};
use std::path::Path;

use super::decode::{
    base64_concat, byte_len, decode_binary, inflate_exact, parse_ascii, Endian, RawType, Tokens, Wrapper,
};
use super::{check_dims, from_steps, stem_of, Volume};

/// Reads a `.vti` file's point array `array` (`None`: see the module note).
pub fn read_vti(path: impl AsRef<Path>, array: Option<&str>) -> Result<Volume> {
    let path = path.as_ref();
    let bytes = crate::fsio::read_input(path, "VTK XML ImageData file", crate::fsio::MAX_INPUT_BYTES)?;
    parse_vti_bytes(&path.display().to_string(), &bytes, array)
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

fn rfind(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).rposition(|w| w == needle)
}

/// The numbers of an attribute, exactly `n` of them.
fn numbers<T: std::str::FromStr>(name: &str, node: roxmltree::Node, attr: &str, n: usize) -> Result<Option<Vec<T>>> {
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

fn raw_type(name: &str, t: &str) -> Result<RawType> {
    Ok(match t {
        "Int8" => RawType::I8,
        "UInt8" => RawType::U8,
        "Int16" => RawType::I16,
        "UInt16" => RawType::U16,
        "Int32" => RawType::I32,
        "Float32" => RawType::F32,
        _ => bail!("{name}: unsupported DataArray type '{t}'; supported: UInt8, Int16, UInt16, Float32, Int8, Int32"),
    })
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
fn binary_payload(name: &str, what: &str, stream: &[u8], word: usize, endian: Endian, zlib: bool, expected: usize) -> Result<Vec<u8>> {
    let mut w = Words { b: stream, pos: 0, word, endian };
    if !zlib {
        let n = w.next(name, what)?;
        if n != expected {
            bail!("{name}: header/size mismatch: {what} declares {n} bytes, its extent needs {expected}");
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
             {last}) does not make the {expected} bytes its extent needs"
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

/// Parses a VTK XML ImageData file from its bytes, reading the point array
/// `array` (`None`: the active scalars, else the first one-component array).
/// `name` starts every error and its stem names the volume. Never panics on
/// malformed input.
pub fn parse_vti_bytes(name: &str, bytes: &[u8], array: Option<&str>) -> Result<Volume> {
    let body = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let first = body.iter().position(|c| !c.is_ascii_whitespace()).unwrap_or(body.len());
    if !(body[first..].starts_with(b"<?xml") || body[first..].starts_with(b"<VTKFile")) {
        bail!("{name}: not a VTK XML file (it does not start with '<?xml' or '<VTKFile')");
    }

    // ---- split off appended data
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
    super::decode::check_xml_depth(name, &xml)?;
    let doc = roxmltree::Document::parse(&xml).map_err(|e| anyhow!("{name}: bad XML: {e}"))?;
    let root = doc.root_element();
    if root.tag_name().name() != "VTKFile" {
        bail!("{name}: the root element is <{}>, not <VTKFile>", root.tag_name().name());
    }
    match root.attribute("type") {
        Some("ImageData") => {}
        other => bail!("{name}: VTK XML type '{}' is not ImageData", other.unwrap_or("(missing)")),
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

    // ---- grid
    let image = root
        .children()
        .find(|n| n.has_tag_name("ImageData"))
        .ok_or_else(|| anyhow!("{name}: no <ImageData> element"))?;
    let whole: Vec<i64> = numbers(name, image, "WholeExtent", 6)?.ok_or_else(|| anyhow!("{name}: <ImageData> has no WholeExtent"))?;
    let mut d = [0u64; 3];
    for a in 0..3 {
        let (lo, hi) = (whole[2 * a], whole[2 * a + 1]);
        if hi < lo {
            bail!("{name}: WholeExtent axis {a} runs from {lo} down to {hi}: size 0");
        }
        d[a] = hi.abs_diff(lo).saturating_add(1);
    }
    let dims = check_dims(name, d)?;
    let count = dims[0] * dims[1] * dims[2];
    let origin: Vec<f64> = numbers(name, image, "Origin", 3)?.unwrap_or(vec![0.0; 3]);
    let spacing: Vec<f64> = numbers(name, image, "Spacing", 3)?.unwrap_or(vec![1.0; 3]);
    let dir: Vec<f64> = numbers(name, image, "Direction", 9)?.unwrap_or(vec![1., 0., 0., 0., 1., 0., 0., 0., 1.]);
    // Direction is row-major; column a is index axis a's world direction.
    let steps: [[f64; 3]; 3] = std::array::from_fn(|a| std::array::from_fn(|w| dir[3 * w + a] * spacing[a]));
    // World position of the extent's first point (VTK's Origin is index 0).
    let first: [f64; 3] =
        std::array::from_fn(|w| origin[w] + (0..3).map(|a| whole[2 * a] as f64 * steps[a][w]).sum::<f64>());

    let pieces: Vec<_> = image.children().filter(|n| n.has_tag_name("Piece")).collect();
    let piece = match pieces.as_slice() {
        [p] => *p,
        [] => bail!("{name}: <ImageData> has no <Piece>"),
        _ => bail!("{name}: {} pieces: only single-piece files are supported", pieces.len()),
    };
    let extent: Vec<i64> = numbers(name, piece, "Extent", 6)?.ok_or_else(|| anyhow!("{name}: <Piece> has no Extent"))?;
    if extent != whole {
        bail!("{name}: the piece's Extent {extent:?} is not the WholeExtent {whole:?}");
    }
    let point_data = piece
        .children()
        .find(|n| n.has_tag_name("PointData"))
        .ok_or_else(|| anyhow!("{name}: the piece has no <PointData>"))?;
    let arrays: Vec<_> = point_data.children().filter(|n| n.has_tag_name("DataArray")).collect();
    let comps = |n: &roxmltree::Node| n.attribute("NumberOfComponents").unwrap_or("1").trim() == "1";
    let listing = || {
        arrays
            .iter()
            .map(|a| format!("'{}' ({} components)", a.attribute("Name").unwrap_or("?"), a.attribute("NumberOfComponents").unwrap_or("1")))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let chosen = match array.or(point_data.attribute("Scalars")) {
        Some(want) => arrays
            .iter()
            .find(|a| a.attribute("Name") == Some(want))
            .ok_or_else(|| anyhow!("{name}: no point data array named '{want}'; found: {}", listing()))?,
        None => arrays
            .iter()
            .find(|a| comps(a))
            .ok_or_else(|| anyhow!("{name}: no one-component point data array; found: {}", listing()))?,
    };
    let aname = chosen.attribute("Name").unwrap_or("(unnamed)");
    let what = format!("DataArray '{aname}'");
    if !comps(chosen) {
        bail!("{name}: {what} has {} components; a volume needs one", chosen.attribute("NumberOfComponents").unwrap_or("?"));
    }
    let ty_name = chosen.attribute("type").ok_or_else(|| anyhow!("{name}: {what} has no type"))?;
    let ty = raw_type(name, ty_name)?;
    let expected = byte_len(name, count, ty)?;

    // ---- the data
    let samples = match chosen.attribute("format").unwrap_or("ascii") {
        "ascii" => {
            let text = chosen.text().unwrap_or("");
            let mut tokens = Tokens::new(text.as_bytes());
            let s = parse_ascii(name, &what, &mut tokens, ty, ty_name, count, 0)?;
            if tokens.next_token().is_some() {
                bail!("{name}: header/size mismatch: {what} holds more than the {count} values its extent needs");
            }
            s
        }
        "binary" => {
            let text = chosen.text().unwrap_or("");
            let stream = base64_concat(name, &what, text.as_bytes())?;
            let data = binary_payload(name, &what, &stream, word, endian, zlib, expected)?;
            decode_binary(name, &data, ty, endian, count)?
        }
        "appended" => {
            let (encoding, data) = appended.as_ref().ok_or_else(|| anyhow!("{name}: {what} is appended but there is no <AppendedData>"))?;
            let off_text = chosen.attribute("offset").ok_or_else(|| anyhow!("{name}: appended {what} has no offset"))?;
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
                "base64" => std::borrow::Cow::Owned(base64_concat(name, &what, tail)?),
                o => bail!("{name}: unsupported AppendedData encoding '{o}'; supported: raw, base64"),
            };
            let bytes = binary_payload(name, &what, &stream, word, endian, zlib, expected)?;
            decode_binary(name, &bytes, ty, endian, count)?
        }
        o => bail!("{name}: {what} has format '{o}'; supported: ascii, binary, appended"),
    };
    from_steps(name, stem_of(name), dims, steps, first, samples)
}
