//! NRRD reader (`.nrrd` with attached data, `.nhdr` with a detached
//! `data file`), for 3-dimensional scalar volumes.
//!
//! Understood: `type` (uint8, int16, uint16, float and their NRRD synonyms
//! such as `unsigned char`, `short`, `ushort`; also int8 and int32, see
//! `decode`), `dimension` (3 only), `sizes`, `encoding` raw, gzip (`gz`) or
//! ascii (`text`, `txt`), `endian` (required for multi-byte raw or gzip
//! data), `spacings` or `space directions` (axis-aligned only; a negative
//! step is turned into positive spacing, see [`super::Volume`]), `space
//! origin`, `space`/`space dimension` (3D spaces only), `data file` (one file,
//! relative to the header), `line skip` and `byte skip` (-1 for raw data at
//! the end of its file). The other standard fields (`kinds`, `units`,
//! `labels`, ...) and `key:=value` pairs are accepted and ignored; an unknown
//! field is an error (a misspelt `spacing:` must not silently give 1).
//!
//! The data must hold exactly what the header promises (after the skips):
//! anything shorter or longer is a header/size mismatch. World coordinates
//! are the file's own (`space` is not converted between RAS and LPS).

use std::collections::HashMap;
use std::path::Path;

use anyhow::{anyhow, bail, Result};

use super::decode::{byte_len, decode_binary, parse_ascii, RawType, Tokens};
use crate::bytes::inflate::{inflate_after, Wrapper};
use crate::bytes::Endian;
use super::{check_dims, from_steps, stem_of, Samples, Volume, AXES};

/// Reads a NRRD file (`.nrrd` or `.nhdr`); a detached data file is read
/// from the header's directory.
pub fn read_nrrd(path: impl AsRef<Path>) -> Result<Volume> {
    let path = path.as_ref();
    let bytes = crate::fsio::read_input(path, "NRRD file", crate::fsio::MAX_INPUT_BYTES)?;
    parse_nrrd_bytes(&path.display().to_string(), &bytes, &mut data_file_loader(path))
}

/// What [`parse_nrrd_bytes`] calls to read a detached `data file` of the
/// header at `header`: see [`super::data_file_loader`].
pub fn data_file_loader(header: &Path) -> impl FnMut(&str) -> Result<Vec<u8>> {
    super::data_file_loader(header, "NRRD data file")
}

/// Fields accepted and ignored (after alias folding).
const IGNORED: [&str; 17] = [
    "content",
    "block size",
    "min",
    "max",
    "old min",
    "old max",
    "kinds",
    "centers",
    "units",
    "labels",
    "axis mins",
    "axis maxs",
    "thicknesses",
    "space units",
    "measurement frame",
    "sample units",
    "number",
];

const USED: [&str; 13] = [
    "type",
    "dimension",
    "sizes",
    "encoding",
    "endian",
    "spacings",
    "space directions",
    "space origin",
    "space",
    "space dimension",
    "data file",
    "line skip",
    "byte skip",
];

/// A NRRD field name in its canonical spelling.
fn canonical(field: &str) -> String {
    let f = field.trim().to_ascii_lowercase();
    match f.as_str() {
        "datafile" => "data file",
        "centerings" => "centers",
        "axismins" => "axis mins",
        "axismaxs" => "axis maxs",
        "oldmin" => "old min",
        "oldmax" => "old max",
        "lineskip" => "line skip",
        "byteskip" => "byte skip",
        "blocksize" => "block size",
        _ => return f,
    }
    .to_string()
}

fn parse_type(source: &str, v: &str) -> Result<RawType> {
    let t = v.split_whitespace().collect::<Vec<_>>().join(" ").to_ascii_lowercase();
    Ok(match t.as_str() {
        "signed char" | "int8" | "int8_t" => RawType::I8,
        "uchar" | "unsigned char" | "uint8" | "uint8_t" => RawType::U8,
        "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t" => RawType::I16,
        "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => RawType::U16,
        "int" | "signed int" | "int32" | "int32_t" => RawType::I32,
        "float" => RawType::F32,
        _ => bail!(
            "{source}: unsupported type '{v}'; supported: uint8 (uchar, unsigned char), int16 (short), \
             uint16 (ushort, unsigned short), float, and int8 (signed char), int32 (int)"
        ),
    })
}

/// `(a,b,c)` vectors or `none`, whitespace-separated.
fn parse_vectors(source: &str, field: &str, v: &str) -> Result<Vec<Option<Vec<f64>>>> {
    let mut out = Vec::new();
    let mut rest = v.trim();
    while !rest.is_empty() {
        if let Some(r) = rest.strip_prefix("none") {
            out.push(None);
            rest = r.trim_start();
            continue;
        }
        let bad = || anyhow!("{source}: bad {field} '{v}': expected vectors such as (1,0,0) or 'none'");
        let inner = rest.strip_prefix('(').ok_or_else(bad)?;
        let close = inner.find(')').ok_or_else(bad)?;
        let comps = inner[..close]
            .split(',')
            .map(|c| c.trim().parse::<f64>().map_err(|_| bad()))
            .collect::<Result<Vec<f64>>>()?;
        out.push(Some(comps));
        rest = inner[close + 1..].trim_start();
    }
    Ok(out)
}

/// Parses a NRRD from its header bytes (the whole `.nrrd` file, or a
/// `.nhdr`). A detached `data file` is obtained by calling `load_data` with
/// its name as written. `name` (the file path, or any label) starts every
/// error, and its stem names the volume. Never panics on malformed input;
/// sizes are checked before anything is allocated from them.
pub fn parse_nrrd_bytes(name: &str, bytes: &[u8], load_data: &mut dyn FnMut(&str) -> Result<Vec<u8>>) -> Result<Volume> {
    let (fields, data_start) = header_fields(name, bytes)?;
    let h = Header { name, fields };
    let ty = parse_type(name, h.need("type")?)?;
    let dims = grid(&h)?;
    let count = dims[0] * dims[1] * dims[2];
    let needed = byte_len(name, count, ty)?;
    let (steps, origin) = placement(&h)?;
    let enc = encoding(&h, ty)?;
    let loaded;
    let (data, what): (&[u8], String) = match h.get("data file") {
        Some(f) => {
            if f.starts_with("LIST") || f.split_whitespace().count() > 1 {
                bail!("{name}: multi-file 'data file: {f}' is not supported; give a single data file");
            }
            loaded = load_data(f).map_err(|e| anyhow!("{name}: data file '{f}': {e:#}"))?;
            (&loaded, format!("data file '{f}'"))
        }
        None => match data_start {
            Some(s) => (&bytes[s..], "the attached data".to_string()),
            None => bail!("{name}: no 'data file' field and no data after the header (a blank line ends the header)"),
        },
    };
    let shape = format!("sizes {} {} {} of {}", dims[0], dims[1], dims[2], ty.name());
    let body = Body { name, what: &what, shape: &shape, ty, count, needed };
    let samples = body.samples(&enc, data)?;
    from_steps(name, stem_of(name), dims, steps, origin, samples)
}

/// The header's fields (value and line) after the magic line, and where
/// attached data starts (after the blank line ending the header), if any.
/// A header's fields by name: (value, header line).
type Fields<'b> = HashMap<String, (&'b str, usize)>;

fn header_fields<'b>(name: &str, bytes: &'b [u8]) -> Result<(Fields<'b>, Option<usize>)> {
    let magic_end = bytes.iter().position(|&c| c == b'\n').unwrap_or(bytes.len());
    let magic = &bytes[..magic_end];
    let magic = magic.strip_suffix(b"\r").unwrap_or(magic);
    if !(magic.len() == 8 && magic.starts_with(b"NRRD000") && (b'1'..=b'5').contains(&magic[7])) {
        bail!(
            "{name}: not a NRRD file: the first line is '{}', expected NRRD0001 to NRRD0005",
            String::from_utf8_lossy(&magic[..magic.len().min(40)]).escape_debug()
        );
    }
    let mut pos = (magic_end + 1).min(bytes.len());
    let mut line_no = 1;
    let mut fields: HashMap<String, (&str, usize)> = HashMap::new();
    while pos < bytes.len() {
        line_no += 1;
        let end = bytes[pos..].iter().position(|&c| c == b'\n').map_or(bytes.len(), |e| pos + e);
        let raw = &bytes[pos..end];
        let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
        pos = (end + 1).min(bytes.len());
        if raw.is_empty() {
            return Ok((fields, Some(pos)));
        }
        let line = std::str::from_utf8(raw).map_err(|_| anyhow!("{name}: header line {line_no} holds non-text bytes"))?;
        if line.starts_with('#') {
            continue;
        }
        let Some(colon) = line.find(':') else {
            bail!("{name}: header line {line_no} '{}' is not a 'field: value' line", line.escape_debug());
        };
        if line[colon + 1..].starts_with('=') {
            continue; // key:=value
        }
        let field = canonical(&line[..colon]);
        let value = line[colon + 1..].trim();
        if !USED.contains(&field.as_str()) {
            if IGNORED.contains(&field.as_str()) {
                continue;
            }
            bail!("{name}: unknown field '{}' on header line {line_no}", line[..colon].escape_debug());
        }
        if let Some((_, first)) = fields.get(&field) {
            bail!("{name}: field '{field}' given twice (header lines {first} and {line_no})");
        }
        fields.insert(field, (value, line_no));
    }
    Ok((fields, None))
}

/// A header's fields, read by name (keys in their canonical spelling:
/// `canonical`).
type Header<'h> = super::Header<'h, String>;

/// The grid's dimensions (`dimension`, `sizes`).
fn grid(h: &Header) -> Result<[usize; 3]> {
    let name = h.name;
    let dim = h.need("dimension")?;
    if dim != "3" {
        bail!("{name}: dimension {dim}: only 3-dimensional volumes are supported");
    }
    let sizes: Vec<&str> = h.need("sizes")?.split_whitespace().collect();
    if sizes.len() != 3 {
        bail!("{name}: sizes has {} values for dimension 3", sizes.len());
    }
    let mut d = [0u64; 3];
    for a in 0..3 {
        d[a] = sizes[a].parse().map_err(|_| anyhow!("{name}: bad size '{}' along {}", sizes[a], AXES[a]))?;
    }
    check_dims(name, d)
}

/// The grid's steps and origin (`space`, `spacings` or `space directions`,
/// `space origin`).
fn placement(h: &Header) -> Result<([[f64; 3]; 3], [f64; 3])> {
    let name = h.name;
    if let Some(sd) = h.get("space dimension") {
        if sd != "3" {
            bail!("{name}: space dimension {sd}: only 3D spaces are supported");
        }
    }
    if let Some(space) = h.get("space") {
        let s = space.to_ascii_lowercase();
        if s.ends_with("-time") || ["rast", "last", "lpst"].contains(&s.as_str()) {
            bail!("{name}: space '{space}' has a time axis: only 3D spaces are supported");
        }
    }
    let steps = match (h.get("spacings"), h.get("space directions")) {
        (Some(_), Some(_)) => bail!("{name}: both 'spacings' and 'space directions' are given; NRRD allows one"),
        (Some(sp), None) => spacings(name, sp)?,
        (None, Some(dirs)) => space_directions(name, dirs)?,
        (None, None) => [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    };
    let mut origin = [0.0; 3];
    if let Some(o) = h.get("space origin") {
        match parse_vectors(name, "space origin", o)?.as_slice() {
            [Some(c)] if c.len() == 3 => origin = [c[0], c[1], c[2]],
            _ => bail!("{name}: space origin '{o}' must be one vector of 3 components"),
        }
    }
    Ok((steps, origin))
}

/// Axis-aligned steps from `spacings`.
fn spacings(name: &str, sp: &str) -> Result<[[f64; 3]; 3]> {
    let mut steps = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let v: Vec<&str> = sp.split_whitespace().collect();
    if v.len() != 3 {
        bail!("{name}: spacings has {} values for dimension 3", v.len());
    }
    for a in 0..3 {
        let s: f64 = v[a].parse().map_err(|_| anyhow!("{name}: bad spacing '{}' along {}", v[a], AXES[a]))?;
        if !s.is_finite() || s == 0.0 {
            bail!("{name}: spacing '{}' along {} must be a finite, non-zero number", v[a], AXES[a]);
        }
        steps[a][a] = s;
    }
    Ok(steps)
}

/// Steps from `space directions`, one vector per axis.
fn space_directions(name: &str, dirs: &str) -> Result<[[f64; 3]; 3]> {
    let mut steps = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let v = parse_vectors(name, "space directions", dirs)?;
    if v.len() != 3 {
        bail!("{name}: space directions has {} entries for dimension 3", v.len());
    }
    for (a, dir) in v.into_iter().enumerate() {
        match dir {
            None => bail!("{name}: axis {a} has no space direction ('none'); all 3 axes must be spatial"),
            Some(c) if c.len() == 3 => steps[a] = [c[0], c[1], c[2]],
            Some(c) => bail!("{name}: space direction {a} has {} components, not 3", c.len()),
        }
    }
    Ok(steps)
}

/// How the data is encoded.
#[derive(Clone, Copy)]
enum Enc {
    Raw,
    Gzip,
    Ascii,
}

/// The encoding, byte order and skips of the data.
struct Encoding {
    enc: Enc,
    endian: Endian,
    line_skip: usize,
    /// `byte skip`: bytes to skip, or -1 (the data is the file's end).
    byte_skip: i64,
}

fn encoding(h: &Header, ty: RawType) -> Result<Encoding> {
    let name = h.name;
    let enc_text = h.need("encoding")?;
    let enc = match enc_text.to_ascii_lowercase().as_str() {
        "raw" => Enc::Raw,
        "gzip" | "gz" => Enc::Gzip,
        "ascii" | "text" | "txt" => Enc::Ascii,
        _ => bail!("{name}: unsupported encoding '{enc_text}'; supported: raw, gzip (gz), ascii (text, txt)"),
    };
    let endian = match h.get("endian").map(str::to_ascii_lowercase).as_deref() {
        Some("little") => Endian::Little,
        Some("big") => Endian::Big,
        Some(other) => bail!("{name}: bad endian '{other}': expected little or big"),
        None if ty.size() > 1 && !matches!(enc, Enc::Ascii) => {
            bail!("{name}: the required field 'endian' is missing ({} data of more than one byte)", ty.name())
        }
        None => Endian::Little,
    };
    let line_skip: usize = match h.get("line skip") {
        Some(v) => v.parse().map_err(|_| anyhow!("{name}: bad line skip '{v}'"))?,
        None => 0,
    };
    let byte_skip: i64 = match h.get("byte skip") {
        Some(v) => v.parse().ok().filter(|&b: &i64| b >= -1).ok_or_else(|| anyhow!("{name}: bad byte skip '{v}'"))?,
        None => 0,
    };
    if byte_skip == -1 && !matches!(enc, Enc::Raw) {
        bail!("{name}: byte skip -1 (data at the end of the file) needs raw encoding, not {enc_text}");
    }
    Ok(Encoding { enc, endian, line_skip, byte_skip })
}

/// What the data must hold, for decoding it and naming it in errors.
struct Body<'a> {
    name: &'a str,
    /// The data's source ("data file 'x'", "the attached data").
    what: &'a str,
    /// "sizes x y z of type".
    shape: &'a str,
    ty: RawType,
    count: usize,
    needed: usize,
}

impl Body<'_> {
    /// The samples of `data` after its skipped lines and bytes.
    fn samples(&self, e: &Encoding, data: &[u8]) -> Result<Samples> {
        let (name, what, shape, needed, count) = (self.name, self.what, self.shape, self.needed, self.count);
        let mut data = data;
        for l in 0..e.line_skip {
            let nl = data
                .iter()
                .position(|&c| c == b'\n')
                .ok_or_else(|| anyhow!("{name}: line skip {} runs past the end of {what} (at line {l})", e.line_skip))?;
            data = &data[nl + 1..];
        }
        let byte_skip = e.byte_skip;
        let skip = usize::try_from(byte_skip.max(0)).map_err(|_| anyhow!("{name}: byte skip {byte_skip} is too large"))?;
        Ok(match e.enc {
            Enc::Raw => {
                let body = if byte_skip == -1 {
                    if data.len() < needed {
                        bail!("{name}: header/size mismatch: {shape} need {needed} bytes, {what} has only {}", data.len());
                    }
                    &data[data.len() - needed..]
                } else {
                    let total = skip.checked_add(needed).ok_or_else(|| anyhow!("{name}: byte skip {skip} overflows"))?;
                    if data.len() != total {
                        let sk = if skip > 0 { format!(" after a byte skip of {skip}") } else { String::new() };
                        bail!("{name}: header/size mismatch: {shape} need {needed} bytes{sk}, {what} has {}", data.len());
                    }
                    &data[skip..]
                };
                decode_binary(name, body.into(), self.ty, e.endian, count)?
            }
            Enc::Gzip => {
                let body = inflate_after(name, what, Wrapper::Gzip, data, skip, needed)?;
                decode_binary(name, body.into(), self.ty, e.endian, count)?
            }
            Enc::Ascii => {
                let text = data.get(skip..).ok_or_else(|| anyhow!("{name}: byte skip {skip} runs past the end of {what}"))?;
                let mut tokens = Tokens::new(text);
                let s = parse_ascii(name, what, &mut tokens, self.ty, self.ty.name(), count, 0)?;
                if let Some((t, _)) = tokens.next_token() {
                    bail!(
                        "{name}: header/size mismatch: {what} holds more than the {count} values of {shape} (next: '{}')",
                        String::from_utf8_lossy(&t[..t.len().min(20)])
                    );
                }
                s
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn no_file(f: &str) -> Result<Vec<u8>> {
        bail!("no file {f}")
    }

    #[test]
    fn attached_raw_and_synonyms() {
        let mut b = b"NRRD0004\n# comment\ntype: unsigned short\ndimension: 3\nsizes: 2 1 2\nendian: big\n\
                      encoding: raw\nspacings: 1 2 3\nkinds: domain domain domain\nk:=v\n\n"
            .to_vec();
        b.extend([0, 1, 0, 2, 1, 0, 255, 255]);
        let v = parse_nrrd_bytes("a.nrrd", &b, &mut no_file).unwrap();
        assert_eq!(v.samples(), &super::super::Samples::U16(vec![1, 2, 256, 65535]));
        assert_eq!(v.spacing(), [1.0, 2.0, 3.0]);
        assert_eq!(v.name, "a");
    }

    #[test]
    fn header_errors() {
        let base = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n\x01\x02\x03\x04\x05\x06\x07\x08";
        assert!(parse_nrrd_bytes("h", base.as_bytes(), &mut no_file).is_ok());
        for (from, to, what) in [
            ("NRRD0004", "NRRD9", "not a NRRD file"),
            ("dimension: 3", "dimension: 4", "dimension 4: only 3-dimensional"),
            ("type: uint8", "type: double", "unsupported type 'double'"),
            ("type: uint8", "type: int16", "'endian' is missing"),
            ("encoding: raw", "encoding: bzip2", "unsupported encoding 'bzip2'"),
            ("encoding: raw", "encoding: raw\nspacing: 1 1 1", "unknown field 'spacing'"),
            ("encoding: raw", "encoding: raw\nsizes: 2 2 2", "given twice"),
            ("sizes: 2 2 2", "sizes: 2 2", "sizes has 2 values"),
            ("sizes: 2 2 2", "sizes: 2 0 2", "size 0 along y"),
            ("sizes: 2 2 2", "sizes: 2 -1 2", "bad size '-1' along y"),
            ("sizes: 2 2 2", "sizes: 100000 2 2", "absurd size 100000"),
            ("sizes: 2 2 2", "sizes: 4 2 2", "header/size mismatch: sizes 4 2 2 of uint8 need 16 bytes, the attached data has 8"),
            ("encoding: raw", "encoding: raw\nspacings: 1 nan 1", "spacing 'nan' along y"),
            ("encoding: raw", "encoding: raw\nspace directions: (1,0,0) (0,1,0.5) (0,0,1)", "axis-aligned"),
            ("encoding: raw", "encoding: raw\nspace directions: (1,0,0) none (0,0,1)", "no space direction"),
            ("encoding: raw", "encoding: raw\nspace directions: (1,0) (0,1,0) (0,0,1)", "2 components"),
            ("encoding: raw", "encoding: raw\nspace directions: (1,0,0 (0,1,0) (0,0,1)", "bad space directions"),
            ("encoding: raw", "encoding: raw\ndata file: LIST", "multi-file"),
            ("encoding: raw", "encoding: raw\ndata file: x.raw", "data file 'x.raw': no file x.raw"),
            ("encoding: raw\n\n", "encoding: raw\n", "'field: value' line"),
        ] {
            let t = base.replacen(from, to, 1);
            let e = format!("{:#}", parse_nrrd_bytes("h.nrrd", t.as_bytes(), &mut no_file).unwrap_err());
            assert!(e.starts_with("h.nrrd: ") && e.contains(what), "{from} -> {to}: expected '{what}' in: {e}");
        }
        let e = parse_nrrd_bytes("h.nhdr", b"NRRD0004\ntype: uint8\n", &mut no_file).unwrap_err().to_string();
        assert!(e.contains("'dimension' is missing"), "{e}");
    }

    #[test]
    fn skips_and_origin() {
        let hdr = b"NRRD0005\ntype: int8\ndimension: 3\nsizes: 1 1 2\nencoding: raw\nline skip: 1\nbyte skip: 2\n\
                    space: left-posterior-superior\nspace directions: (0.5,0,0) (0,0.5,0) (0,0,-2)\n\
                    space origin: (1,2,3)\ndata file: d.raw\n";
        let mut load = |f: &str| -> Result<Vec<u8>> {
            assert_eq!(f, "d.raw");
            Ok(b"junk line\nXX\x05\xfb".to_vec())
        };
        let v = parse_nrrd_bytes("s.nhdr", hdr, &mut load).unwrap();
        // z was flipped: sample 0 is the file's last (-5), at z = 3 - 2.
        assert_eq!(v.samples(), &super::super::Samples::I16(vec![-5, 5]));
        assert_eq!((v.origin(), v.spacing()), ([1.0, 2.0, 1.0], [0.5, 0.5, 2.0]));
        let tail = String::from_utf8_lossy(hdr).replace("line skip: 1\nbyte skip: 2", "byte skip: -1");
        let v = parse_nrrd_bytes("s.nhdr", tail.as_bytes(), &mut load).unwrap();
        assert_eq!(v.samples(), &super::super::Samples::I16(vec![-5, 5]));
    }
}
