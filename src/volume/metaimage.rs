//! MetaImage reader (ITK's MetaIO format): `.mhd` headers with a separate
//! data file, and `.mha` files with the data after the header
//! (`ElementDataFile = LOCAL`), for 3-dimensional scalar volumes.
//!
//! The header is `Key = Value` lines (keys case-insensitive), ended by
//! `ElementDataFile`, which must come last. Understood: `ObjectType`
//! (`Image`), `NDims` (3 only), `DimSize`, `ElementType` (`MET_UCHAR`,
//! `MET_CHAR`, `MET_USHORT`, `MET_SHORT`, `MET_UINT`, `MET_INT`,
//! `MET_FLOAT`, `MET_DOUBLE`; char, int, uint and double convert as
//! described in `decode`), `ElementNumberOfChannels` (1 only: a volume is
//! one scalar per sample, as for the other readers), `BinaryData` (MetaIO's
//! default False means ASCII values), `BinaryDataByteOrderMSB` or
//! `ElementByteOrderMSB`, `CompressedData` (zlib, or gzip found by its magic)
//! with `CompressedDataSize` (optional: else the rest of the data), `HeaderSize`
//! (bytes skipped before the data; -1: raw data at the end of its file),
//! `ElementSpacing` (else `ElementSize`, else 1), `Offset` (or its synonyms
//! `Position`, `Origin`), `TransformMatrix` (or `Rotation`, `Orientation`:
//! row `a` is index axis `a`'s direction; axis-aligned only, a negative
//! direction is turned into positive spacing as for NRRD, anything else is
//! refused). `ElementDataFile` is `LOCAL`, one file name (relative to the
//! header), `LIST` followed by one file name per line, or a printf-style
//! pattern `name%03d.raw first last step`; a list or pattern must name one
//! file per z slice (none twice), each holding one uncompressed slice, and
//! together at most [`crate::fsio::MAX_INPUT_BYTES`]. MetaIO's
//! descriptive fields (`Comment`, `CenterOfRotation`,
//! `AnatomicalOrientation`, `ElementMin`, ...) and ITK's own `ITK_*` keys are
//! accepted and ignored; any other field is an error (a misspelt
//! `ElementSpacings` must not silently give 1).
//!
//! The header must end (its `ElementDataFile` line) within
//! [`MAX_HEADER_BYTES`]; the data must hold exactly what the header
//! promises after the header size: anything shorter or longer is a
//! header/size mismatch, and compressed data inflates to exactly that, the
//! inflation bounded as for every reader.

use std::collections::HashMap;
use std::path::Path;

use anyhow::{anyhow, bail, Result};

use super::decode::{byte_len, decode_binary, parse_ascii, RawType, Tokens};
use crate::bytes::inflate::{inflate_exact, Wrapper};
use crate::bytes::Endian;
use super::{check_dims, from_steps, stem_of, Samples, Volume, AXES};

/// Longest header read: a MetaImage header is a few hundred bytes; one
/// whose `ElementDataFile` line does not come within this is refused.
pub const MAX_HEADER_BYTES: usize = 1 << 16;

/// Reads a MetaImage file (`.mhd` or `.mha`); a separate data file is read
/// from the header's directory.
pub fn read_metaimage(path: impl AsRef<Path>) -> Result<Volume> {
    let path = path.as_ref();
    let bytes = crate::fsio::read_input(path, "MetaImage file", crate::fsio::MAX_INPUT_BYTES)?;
    parse_metaimage_bytes(&path.display().to_string(), &bytes, &mut super::data_file_loader(path, "MetaImage data file"))
}

/// Fields used, in their canonical spelling.
const USED: [&str; 20] = [
    "ObjectType",
    "NDims",
    "DimSize",
    "ElementType",
    "ElementNumberOfChannels",
    "ElementSpacing",
    "ElementSize",
    "Offset",
    "Position",
    "Origin",
    "TransformMatrix",
    "Rotation",
    "Orientation",
    "BinaryData",
    "BinaryDataByteOrderMSB",
    "ElementByteOrderMSB",
    "CompressedData",
    "CompressedDataSize",
    "HeaderSize",
    "ElementDataFile",
];

/// MetaIO's descriptive fields, accepted and ignored.
const IGNORED: [&str; 14] = [
    "Comment",
    "ObjectSubType",
    "TransformType",
    "Name",
    "ID",
    "ParentID",
    "Color",
    "AcquisitionDate",
    "Modality",
    "CenterOfRotation",
    "AnatomicalOrientation",
    "DistanceUnits",
    "ElementMin",
    "ElementMax",
];

/// Whether `bytes` start like a MetaImage header: the first line is
/// `Key = ...` with a key MetaIO writers put first.
pub fn is_metaimage(bytes: &[u8]) -> bool {
    let start = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let line = start.split(|&c| c == b'\n').next().unwrap_or_default();
    let Some(eq) = line.iter().position(|&c| c == b'=') else { return false };
    let key = String::from_utf8_lossy(&line[..eq]).trim().to_ascii_lowercase();
    ["objecttype", "ndims", "comment", "objectsubtype"].contains(&key.as_str())
}

fn element_type(source: &str, v: &str) -> Result<RawType> {
    Ok(match v.to_ascii_uppercase().as_str() {
        "MET_UCHAR" => RawType::U8,
        "MET_CHAR" => RawType::I8,
        "MET_USHORT" => RawType::U16,
        "MET_SHORT" => RawType::I16,
        "MET_UINT" => RawType::U32,
        "MET_INT" => RawType::I32,
        "MET_FLOAT" => RawType::F32,
        "MET_DOUBLE" => RawType::F64,
        _ => bail!(
            "{source}: unsupported ElementType '{v}'; supported: MET_UCHAR, MET_CHAR, MET_USHORT, MET_SHORT, \
             MET_UINT, MET_INT, MET_FLOAT, MET_DOUBLE"
        ),
    })
}

/// Where the samples are.
enum DataFiles {
    Local,
    /// One file per z slice (one name: the whole volume).
    Files(Vec<String>),
}

/// Parses a MetaImage from its header bytes (a whole `.mha`, or a `.mhd`).
/// Data files are obtained by calling `load_data` with their names as
/// written. `name` (the file path, or any label) starts every error and its
/// stem names the volume. Never panics on malformed input; sizes are checked
/// before anything is allocated from them.
pub fn parse_metaimage_bytes(
    name: &str,
    bytes: &[u8],
    load_data: &mut dyn FnMut(&str) -> Result<Vec<u8>>,
) -> Result<Volume> {
    let (fields, data_start) = header_fields(name, bytes)?;
    let h = Header { name, fields };
    let grid = grid(&h)?;
    let (steps, origin) = placement(&h)?;
    let enc = encoding(&h)?;
    let files = data_files(name, h.need("ElementDataFile")?, &bytes[data_start..], grid.dims[2])?;
    let samples = match &files {
        DataFiles::Files(list) if list.len() != 1 => slice_files(&h, &grid, &enc, list, load_data)?,
        DataFiles::Local => samples(&h, &grid, &enc, &bytes[data_start..], "the data after the header".to_string())?,
        DataFiles::Files(list) => {
            let f = &list[0];
            let loaded = load_data(f).map_err(|e| anyhow!("{name}: data file '{f}': {e:#}"))?;
            samples(&h, &grid, &enc, &loaded, format!("data file '{f}'"))?
        }
    };
    from_steps(name, stem_of(name), grid.dims, steps, origin, samples)
}

/// The header's fields (value and line), up to and including
/// ElementDataFile, and where the bytes after that line start.
/// A header's fields by name: (value, header line).
type Fields<'b> = HashMap<&'static str, (&'b str, usize)>;

fn header_fields<'b>(name: &str, bytes: &'b [u8]) -> Result<(Fields<'b>, usize)> {
    let mut fields: HashMap<&'static str, (&str, usize)> = HashMap::new();
    let mut pos = if bytes.starts_with(b"\xEF\xBB\xBF") { 3 } else { 0 };
    let mut line_no = 0;
    loop {
        if pos >= bytes.len() {
            bail!("{name}: the header ends without an 'ElementDataFile' line (it must be the last field)");
        }
        if pos > MAX_HEADER_BYTES {
            bail!("{name}: no 'ElementDataFile' line within the first {MAX_HEADER_BYTES} bytes: not a MetaImage header");
        }
        line_no += 1;
        let end = bytes[pos..].iter().position(|&c| c == b'\n').map_or(bytes.len(), |e| pos + e);
        let raw = &bytes[pos..end];
        let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
        pos = (end + 1).min(bytes.len());
        if raw.iter().all(u8::is_ascii_whitespace) {
            continue;
        }
        let line = std::str::from_utf8(raw).map_err(|_| anyhow!("{name}: header line {line_no} holds non-text bytes"))?;
        let Some(eq) = line.find('=') else {
            bail!("{name}: header line {line_no} '{}' is not a 'Key = Value' line", crate::fsio::clip_message(line).escape_debug());
        };
        let key = line[..eq].trim();
        let value = line[eq + 1..].trim();
        let Some(&field) = USED.iter().find(|f| f.eq_ignore_ascii_case(key)) else {
            if IGNORED.iter().any(|f| f.eq_ignore_ascii_case(key)) || key.starts_with("ITK_") {
                continue;
            }
            bail!("{name}: unknown field '{}' on header line {line_no}", crate::fsio::clip_message(key).escape_debug());
        };
        if let Some((_, first)) = fields.get(field) {
            bail!("{name}: field '{field}' given twice (header lines {first} and {line_no})");
        }
        fields.insert(field, (value, line_no));
        if field == "ElementDataFile" {
            return Ok((fields, pos));
        }
    }
}

/// A header's fields, read by name (`get`, `need`: `super::Header`).
type Header<'h> = super::Header<'h, &'static str>;

impl<'h> Header<'h> {
    /// At most one of a group of synonyms.
    fn one_of(&self, group: &[&'static str]) -> Result<Option<(&'static str, &'h str)>> {
        let given: Vec<_> = group.iter().filter_map(|&f| self.get(f).map(|v| (f, v))).collect();
        if given.len() > 1 {
            bail!("{}: both '{}' and '{}' are given; they are synonyms, give one", self.name, given[0].0, given[1].0);
        }
        Ok(given.first().copied())
    }

    fn numbers(&self, field: &str, v: &str, n: usize) -> Result<Vec<f64>> {
        let name = self.name;
        let t: Vec<&str> = v.split_whitespace().take(n + 1).collect();
        if t.len() != n {
            bail!("{name}: {field} has {} values, expected {n}", if t.len() > n { "more than ".to_string() + &n.to_string() } else { t.len().to_string() });
        }
        t.iter()
            .map(|s| s.parse::<f64>().ok().filter(|x| x.is_finite()))
            .collect::<Option<Vec<f64>>>()
            .ok_or_else(|| anyhow!("{name}: bad {field} '{}': expected {n} finite numbers", crate::fsio::clip_message(v)))
    }

    fn boolean(&self, field: &str) -> Result<Option<bool>> {
        match self.get(field).map(str::to_ascii_lowercase).as_deref() {
            None => Ok(None),
            Some("true" | "1") => Ok(Some(true)),
            Some("false" | "0") => Ok(Some(false)),
            Some(_) => bail!("{}: bad {field} '{}': expected True or False", self.name, self.get(field).unwrap_or_default()),
        }
    }
}

/// The grid and its samples' type, as the header declares them.
struct Grid<'h> {
    dims: [usize; 3],
    count: usize,
    ty: RawType,
    ty_text: &'h str,
    /// The data's byte count (`count` samples of `ty`).
    needed: usize,
    /// "DimSize x y z of type", for errors.
    shape: String,
}

fn grid<'h>(h: &Header<'h>) -> Result<Grid<'h>> {
    let name = h.name;
    if let Some(t) = h.get("ObjectType") {
        if !t.eq_ignore_ascii_case("Image") {
            bail!("{name}: ObjectType '{t}': only Image objects are volumes");
        }
    }
    let ndims = h.need("NDims")?;
    if ndims != "3" {
        bail!("{name}: NDims {ndims}: only 3-dimensional volumes are supported");
    }
    let sizes: Vec<&str> = h.need("DimSize")?.split_whitespace().take(4).collect();
    if sizes.len() != 3 {
        bail!("{name}: DimSize has {} values for NDims 3", if sizes.len() > 3 { "more than 3".to_string() } else { sizes.len().to_string() });
    }
    let mut d = [0u64; 3];
    for a in 0..3 {
        d[a] = sizes[a].parse().map_err(|_| anyhow!("{name}: bad DimSize '{}' along {}", sizes[a], AXES[a]))?;
    }
    let dims = check_dims(name, d)?;
    let count = dims[0] * dims[1] * dims[2];
    let ty_text = h.need("ElementType")?;
    let ty = element_type(name, ty_text)?;
    let needed = byte_len(name, count, ty)?;
    if let Some(c) = h.get("ElementNumberOfChannels") {
        match c.parse::<u64>() {
            Ok(1) => {}
            Ok(n) if n > 1 => bail!("{name}: ElementNumberOfChannels {n}: a volume needs one scalar per sample"),
            _ => bail!("{name}: bad ElementNumberOfChannels '{c}'"),
        }
    }
    let shape = format!("DimSize {} {} {} of {}", dims[0], dims[1], dims[2], ty_text);
    Ok(Grid { dims, count, ty, ty_text, needed, shape })
}

/// The grid's steps (spacing along each direction) and origin.
fn placement(h: &Header) -> Result<([[f64; 3]; 3], [f64; 3])> {
    let spacing = match (h.get("ElementSpacing"), h.get("ElementSize")) {
        (Some(s), _) => h.numbers("ElementSpacing", s, 3)?,
        (None, Some(s)) => h.numbers("ElementSize", s, 3)?,
        (None, None) => vec![1.0; 3],
    };
    for (a, &s) in spacing.iter().enumerate() {
        if s == 0.0 {
            bail!("{}: element spacing 0 along {}: it must be non-zero", h.name, AXES[a]);
        }
    }
    let origin = match h.one_of(&["Offset", "Position", "Origin"])? {
        Some((f, v)) => h.numbers(f, v, 3)?,
        None => vec![0.0; 3],
    };
    let directions = match h.one_of(&["TransformMatrix", "Rotation", "Orientation"])? {
        Some((f, v)) => h.numbers(f, v, 9)?,
        None => vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
    };
    let steps: [[f64; 3]; 3] = std::array::from_fn(|a| std::array::from_fn(|b| spacing[a] * directions[3 * a + b]));
    Ok((steps, [origin[0], origin[1], origin[2]]))
}

/// How the data is stored.
struct Encoding {
    binary: bool,
    endian: Endian,
    compressed: bool,
    compressed_size: Option<usize>,
    /// HeaderSize: bytes to skip, or -1 (the data is the file's end).
    header_size: i64,
    /// `header_size`, at least 0.
    skip: usize,
}

fn encoding(h: &Header) -> Result<Encoding> {
    let name = h.name;
    let binary = h.boolean("BinaryData")?.unwrap_or(false);
    let msb = match (h.boolean("BinaryDataByteOrderMSB")?, h.boolean("ElementByteOrderMSB")?) {
        (Some(a), Some(b)) if a != b => {
            bail!("{name}: BinaryDataByteOrderMSB and ElementByteOrderMSB disagree; they are synonyms")
        }
        (a, b) => a.or(b).unwrap_or(false),
    };
    let endian = if msb { Endian::Big } else { Endian::Little };
    let compressed = h.boolean("CompressedData")?.unwrap_or(false);
    let compressed_size: Option<usize> = match h.get("CompressedDataSize") {
        Some(v) => Some(v.parse().map_err(|_| anyhow!("{name}: bad CompressedDataSize '{v}'"))?),
        None => None,
    };
    let header_size: i64 = match h.get("HeaderSize") {
        Some(v) => v.parse().ok().filter(|&b: &i64| b >= -1).ok_or_else(|| anyhow!("{name}: bad HeaderSize '{v}'"))?,
        None => 0,
    };
    if compressed && !binary {
        bail!("{name}: CompressedData needs BinaryData = True (compressed ASCII values are not MetaImage)");
    }
    if header_size == -1 && (compressed || !binary) {
        bail!("{name}: HeaderSize -1 (data at the end of the file) needs uncompressed binary data");
    }
    let skip = usize::try_from(header_size.max(0)).map_err(|_| anyhow!("{name}: HeaderSize {header_size} is too large"))?;
    Ok(Encoding { binary, endian, compressed, compressed_size, header_size, skip })
}

/// The samples of a list of slice files (uncompressed binary, one slice each).
fn slice_files(
    h: &Header,
    g: &Grid,
    enc: &Encoding,
    list: &[String],
    load_data: &mut dyn FnMut(&str) -> Result<Vec<u8>>,
) -> Result<Samples> {
    let (name, needed, shape) = (h.name, g.needed, &g.shape);
    if enc.compressed || !enc.binary {
        bail!("{name}: a list of slice files needs uncompressed binary data");
    }
    // Bounded as one input file is: a header cannot make a few
    // small files stand for more.
    if needed as u64 > crate::fsio::MAX_INPUT_BYTES {
        bail!(
            "{name}: {shape} make {needed} bytes of slice files, more than the {} bytes an input may hold",
            crate::fsio::MAX_INPUT_BYTES
        );
    }
    let slice = needed / g.dims[2];
    // Grown by what the files really hold, not reserved from the header.
    let mut all = Vec::new();
    for f in list {
        let b = load_data(f).map_err(|e| anyhow!("{name}: data file '{f}': {e:#}"))?;
        all.extend_from_slice(raw_body(name, &b, enc.header_size, enc.skip, slice, &format!("data file '{f}'"), "one slice")?);
    }
    decode_binary(name, all.into(), g.ty, enc.endian, g.count)
}

/// The samples of one body of data (`what` names it in errors): compressed,
/// raw binary or ASCII values.
fn samples(h: &Header, g: &Grid, enc: &Encoding, data: &[u8], what: String) -> Result<Samples> {
    let (name, skip, count, shape) = (h.name, enc.skip, g.count, &g.shape);
    Ok(if enc.compressed {
        let body = data.get(skip..).ok_or_else(|| anyhow!("{name}: HeaderSize {skip} runs past the end of {what}"))?;
        let stream = match enc.compressed_size {
            Some(n) if n != body.len() => bail!(
                "{name}: header/size mismatch: CompressedDataSize {n}, {what} has {} bytes{}",
                body.len(),
                if skip > 0 { format!(" after a HeaderSize of {skip}") } else { String::new() }
            ),
            _ => body,
        };
        let wrapper = if stream.starts_with(&[0x1f, 0x8b]) { Wrapper::Gzip } else { Wrapper::Zlib };
        let inflated = inflate_exact(name, &what, wrapper, stream, g.needed)?;
        decode_binary(name, inflated.into(), g.ty, enc.endian, count)?
    } else if enc.binary {
        let body = raw_body(name, data, enc.header_size, skip, g.needed, &what, shape)?;
        decode_binary(name, body.into(), g.ty, enc.endian, count)?
    } else {
        let text = data.get(skip..).ok_or_else(|| anyhow!("{name}: HeaderSize {skip} runs past the end of {what}"))?;
        let mut tokens = Tokens::new(text);
        let what = format!("{what} (ASCII values: BinaryData is {})", h.get("BinaryData").unwrap_or("not given, so False"));
        let s: Samples = parse_ascii(name, &what, &mut tokens, g.ty, g.ty_text, count, skip)?;
        if let Some((t, _)) = tokens.next_token() {
            bail!(
                "{name}: header/size mismatch: {what} holds more than the {count} values of {shape} (next: '{}')",
                String::from_utf8_lossy(&t[..t.len().min(20)])
            );
        }
        s
    })
}

/// The `needed` raw bytes of `data` after `skip` (`header_size` -1: its
/// last `needed` bytes); `data` must hold exactly that.
fn raw_body<'a>(
    name: &str,
    data: &'a [u8],
    header_size: i64,
    skip: usize,
    needed: usize,
    what: &str,
    shape: &str,
) -> Result<&'a [u8]> {
    if header_size == -1 {
        if data.len() < needed {
            bail!("{name}: header/size mismatch: {shape} need {needed} bytes, {what} has only {}", data.len());
        }
        return Ok(&data[data.len() - needed..]);
    }
    let total = skip.checked_add(needed).ok_or_else(|| anyhow!("{name}: HeaderSize {skip} overflows"))?;
    if data.len() != total {
        let sk = if skip > 0 { format!(" after a HeaderSize of {skip}") } else { String::new() };
        bail!("{name}: header/size mismatch: {shape} need {needed} bytes{sk}, {what} has {}", data.len());
    }
    Ok(&data[skip..])
}

/// The data files `ElementDataFile = value` names (`rest`: the header file
/// after that line, where a `LIST` is); a list or pattern must name `nz`
/// files.
fn data_files(name: &str, value: &str, rest: &[u8], nz: usize) -> Result<DataFiles> {
    if value.is_empty() {
        bail!("{name}: ElementDataFile is empty: expected LOCAL, a file name, LIST or a file pattern");
    }
    if value.eq_ignore_ascii_case("LOCAL") {
        return Ok(DataFiles::Local);
    }
    let words: Vec<&str> = value.split_whitespace().take(6).collect();
    if words[0].eq_ignore_ascii_case("LIST") {
        if words.len() > 1 && !["2d", "2D"].contains(&words[1]) {
            bail!("{name}: ElementDataFile '{value}': only lists of 2D slice files are supported");
        }
        let mut list = Vec::new();
        for line in rest.split(|&c| c == b'\n') {
            let line = line.strip_suffix(b"\r").unwrap_or(line);
            let f = std::str::from_utf8(line).map_err(|_| anyhow!("{name}: the LIST of data files holds non-text bytes"))?;
            if f.trim().is_empty() {
                continue;
            }
            if list.len() == nz {
                bail!("{name}: the LIST names more than the {nz} files of DimSize's z (one per slice)");
            }
            if list.iter().any(|l| l == f.trim()) {
                bail!("{name}: the LIST names '{}' twice; each slice has its own file", crate::fsio::clip_message(f.trim()));
            }
            list.push(f.trim().to_string());
        }
        if list.len() != nz {
            bail!("{name}: the LIST names {} files; DimSize's z needs {nz} (one per slice)", list.len());
        }
        return Ok(DataFiles::Files(list));
    }
    if value.contains('%') && (4..=5).contains(&words.len()) {
        let bad = || anyhow!("{name}: bad ElementDataFile pattern '{value}': expected 'name%03d.raw first last step'");
        // i128: no overflow from any i64 values.
        let n = |s: &str| s.parse::<i64>().map(i128::from).map_err(|_| bad());
        let (first, last, step) = (n(words[1])?, n(words[2])?, n(words[3])?);
        if step == 0 || (last - first).signum() * step.signum() < 0 {
            return Err(bad());
        }
        let files = (last - first) / step + 1;
        if files != nz as i128 {
            bail!("{name}: the ElementDataFile pattern '{value}' names {files} files; DimSize's z needs {nz} (one per slice)");
        }
        let pat = words[0];
        let at = pat.find('%').ok_or_else(bad)?;
        let spec = &pat[at + 1..];
        let d = spec.find('d').ok_or_else(bad)?;
        let flags = &spec[..d];
        let (zero, width) = match flags.strip_prefix('0') {
            Some(w) => (true, w),
            None => (false, flags),
        };
        let width: usize = if width.is_empty() { 0 } else { width.parse().map_err(|_| bad())? };
        let (head, tail) = (&pat[..at], &spec[d + 1..]);
        if tail.contains('%') || width > 20 {
            return Err(bad());
        }
        let list = (0..files)
            .map(|k| {
                let i = first + k * step;
                if zero { format!("{head}{i:0width$}{tail}") } else { format!("{head}{i:width$}{tail}") }
            })
            .collect();
        return Ok(DataFiles::Files(list));
    }
    Ok(DataFiles::Files(vec![value.to_string()]))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn no_file(f: &str) -> Result<Vec<u8>> {
        bail!("no file {f}")
    }

    const BASE: &str = "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n\
                        CompressedData = False\nTransformMatrix = 1 0 0 0 1 0 0 0 1\nOffset = 1 2 3\n\
                        ElementSpacing = 0.5 1 2\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n\
                        \x01\x02\x03\x04\x05\x06\x07\x08";

    #[test]
    fn local_raw() {
        assert!(is_metaimage(BASE.as_bytes()));
        let v = parse_metaimage_bytes("a.mha", BASE.as_bytes(), &mut no_file).unwrap();
        assert_eq!(v.samples(), &Samples::U8(vec![1, 2, 3, 4, 5, 6, 7, 8]));
        assert_eq!((v.spacing(), v.origin(), v.name.as_str()), ([0.5, 1.0, 2.0], [1.0, 2.0, 3.0], "a"));
    }

    #[test]
    fn header_errors() {
        for (from, to, what) in [
            ("NDims = 3", "NDims = 2", "NDims 2: only 3-dimensional"),
            ("NDims = 3", "NDims = 4", "NDims 4: only 3-dimensional"),
            ("MET_UCHAR", "MET_LONG", "unsupported ElementType 'MET_LONG'"),
            ("DimSize = 2 2 2", "DimSize = 2 2", "DimSize has 2 values"),
            ("DimSize = 2 2 2", "DimSize = 2 2 2 1", "DimSize has more than 3"),
            ("DimSize = 2 2 2", "DimSize = 2 0 2", "size 0 along y"),
            ("DimSize = 2 2 2", "DimSize = 100000 2 2", "absurd size 100000"),
            ("DimSize = 2 2 2", "DimSize = 4 2 2", "header/size mismatch: DimSize 4 2 2 of MET_UCHAR need 16 bytes"),
            ("DimSize = 2 2 2", "DimSize = 1 2 2", "need 4 bytes, the data after the header has 8"),
            ("ElementSpacing = 0.5 1 2", "ElementSpacings = 1 1 1", "unknown field 'ElementSpacings'"),
            ("ElementSpacing = 0.5 1 2", "ElementSpacing = 1 nan 1", "bad ElementSpacing"),
            ("ElementSpacing = 0.5 1 2", "ElementSpacing = 1 0 1", "spacing 0 along y"),
            ("Offset = 1 2 3", "Offset = 1 2 3\nOrigin = 1 2 3", "both 'Offset' and 'Origin'"),
            ("NDims = 3", "NDims = 3\nNDims = 3", "given twice"),
            ("1 0 0 0 1 0 0 0 1", "1 0 0 0 0.7 0.7 0 0 1", "axis-aligned"),
            ("1 0 0 0 1 0 0 0 1", "1 0 0 0 1 0", "TransformMatrix has 6 values"),
            ("BinaryData = True", "BinaryData = Maybe", "bad BinaryData 'Maybe'"),
            ("ObjectType = Image", "ObjectType = Tube", "ObjectType 'Tube'"),
            ("NDims = 3", "NDims = 3\nElementNumberOfChannels = 3", "ElementNumberOfChannels 3"),
            ("NDims = 3", "NDims = 3\nElementByteOrderMSB = True", "disagree"),
            ("NDims = 3", "NDims = 3\nHeaderSize = -2", "bad HeaderSize"),
            ("CompressedData = False", "CompressedData = True", "zlib data"),
            ("CompressedData = False", "CompressedData = True\nCompressedDataSize = 7", "CompressedDataSize 7, the data after"),
            ("ElementDataFile = LOCAL", "ElementDataFile = x.raw", "data file 'x.raw': no file x.raw"),
            ("ElementDataFile = LOCAL", "ElementDataFile = LIST 3D", "only lists of 2D"),
            ("ElementDataFile = LOCAL", "ElementDataFile = LIST", "the LIST names"),
            ("ElementDataFile = LOCAL", "ElementDataFile = s%d.raw 1 3 1", "names 3 files; DimSize's z needs 2"),
            ("ElementDataFile = LOCAL", "ElementDataFile = s%d.raw 1 2 0", "bad ElementDataFile pattern"),
            ("ElementDataFile = LOCAL", "ElementDataFile = s%d.raw 2 1 1", "bad ElementDataFile pattern"),
            (
                "ElementDataFile = LOCAL",
                "ElementDataFile = s%d.raw -9223372036854775808 9223372036854775807 1",
                "names 18446744073709551616 files",
            ),
            ("ElementDataFile = LOCAL", "ElementDataFile = s%d.raw 1 2 1", "data file 's1.raw'"),
            ("ElementDataFile = LOCAL\n", "Nonsense\n", "not a 'Key = Value' line"),
        ] {
            let t = BASE.replacen(from, to, 1);
            let e = format!("{:#}", parse_metaimage_bytes("h.mha", t.as_bytes(), &mut no_file).unwrap_err());
            assert!(e.starts_with("h.mha: ") && e.contains(what), "{from} -> {to}: expected '{what}' in: {e}");
        }
        let e = parse_metaimage_bytes("h.mhd", b"NDims = 3\n", &mut no_file).unwrap_err().to_string();
        assert!(e.contains("ends without"), "{e}");
    }

    #[test]
    fn header_bound_at_two_sizes() {
        // Comment lines before ElementDataFile: within the bound they are
        // read; past it the header is refused.
        let with = |n: usize| format!("Comment = {}\n{BASE}", "x".repeat(n));
        assert!(parse_metaimage_bytes("h.mha", with(MAX_HEADER_BYTES - 400).as_bytes(), &mut no_file).is_ok());
        let e = parse_metaimage_bytes("h.mha", with(MAX_HEADER_BYTES).as_bytes(), &mut no_file).unwrap_err().to_string();
        assert!(e.contains("no 'ElementDataFile' line within the first 65536 bytes"), "{e}");
    }

    #[test]
    fn lists_patterns_skips_and_ascii() {
        let hdr = BASE.split("ElementDataFile").next().unwrap().replace("MET_UCHAR", "MET_SHORT");
        let mut load = |f: &str| -> Result<Vec<u8>> {
            match f {
                "s01.raw" | "a" => Ok(vec![9, 9, 1, 0, 2, 0, 3, 0, 4, 0]),
                "s03.raw" | "b" => Ok(vec![9, 9, 5, 0, 6, 0, 7, 0, 8, 0]),
                _ => bail!("no file {f}"),
            }
        };
        let want = Samples::I16(vec![1, 2, 3, 4, 5, 6, 7, 8]);
        for tail in ["ElementDataFile = s%02d.raw 1 3 2\n", "ElementDataFile = LIST\na\n\nb\n"] {
            let t = format!("{hdr}HeaderSize = 2\n{tail}");
            assert_eq!(parse_metaimage_bytes("l.mhd", t.as_bytes(), &mut load).unwrap().samples(), &want, "{tail}");
            let t = format!("{hdr}HeaderSize = -1\n{tail}");
            assert_eq!(parse_metaimage_bytes("l.mhd", t.as_bytes(), &mut load).unwrap().samples(), &want, "{tail}");
        }
        let t = format!("{hdr}ElementDataFile = LIST\na\nb\nc\n");
        let e = parse_metaimage_bytes("l.mhd", t.as_bytes(), &mut load).unwrap_err().to_string();
        assert!(e.contains("more than the 2 files"), "{e}");
        let t = format!("{hdr}ElementDataFile = LIST\na\na\n");
        let e = parse_metaimage_bytes("l.mhd", t.as_bytes(), &mut load).unwrap_err().to_string();
        assert!(e.contains("names 'a' twice"), "{e}");
        // The slice files' total is bounded as one input is (two sizes: 1 GiB of
        // uint8 reads its files, one byte more is refused before any).
        let big = |y: usize| BASE.replace("DimSize = 2 2 2", &format!("DimSize = 65536 {y} 2")).replace("LOCAL", "s%d.raw 0 1 1");
        let e = parse_metaimage_bytes("l.mhd", big(8192).as_bytes(), &mut no_file).unwrap_err().to_string();
        assert!(e.contains("data file 's0.raw'"), "{e}");
        let e = parse_metaimage_bytes("l.mhd", big(8193).as_bytes(), &mut no_file).unwrap_err().to_string();
        assert!(e.contains("more than the 1073741824 bytes an input may hold"), "{e}");
        let ascii = hdr.replace("BinaryData = True", "BinaryData = False") + "ElementDataFile = LOCAL\n1 2 3\n4 5 6 7 8\n";
        assert_eq!(parse_metaimage_bytes("t.mha", ascii.as_bytes(), &mut no_file).unwrap().samples(), &want);
        let e = parse_metaimage_bytes("t.mha", (ascii + "9").as_bytes(), &mut no_file).unwrap_err().to_string();
        assert!(e.contains("more than the 8 values"), "{e}");
    }
}
