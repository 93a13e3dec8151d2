//! Volume readers (issue 9, point 1): the shipped volumes load with the right
//! grid, spacing, type and values; synthetic files in every variant each
//! format allows (NRRD attached/detached, raw/gzip/ascii, every type and
//! byte order; VTI ascii/binary/appended, zlib or not, 32/64-bit headers;
//! legacy STRUCTURED_POINTS ASCII/BINARY; NIfTI-1 .nii/.nii.gz in both byte
//! orders) round-trip to the same samples; malformed files give an error
//! naming the file and the problem; and thousands of truncations and byte
//! flips of every synthetic file never panic (the stable stand-in for the
//! `volume_*` fuzz targets).

use std::io::Write as _;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

use anyhow::Result;
use base64::Engine as _;
use volbench::volume::nifti::parse_nifti_bytes;
use volbench::volume::nrrd::parse_nrrd_bytes;
use volbench::volume::vti::{parse_vti_bytes, read_vti};
use volbench::volume::vtk_sp::parse_structured_points_bytes;
use volbench::volume::{datasets, load_volume, SampleType, Samples, Volume};

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data")
}

// ------------------------------------------------------------ shipped data

#[test]
fn shipped_volumes_load_with_their_grids_and_values() {
    let d = data_dir();
    assert_eq!(datasets::NAMES, ["chest-ct", "headsq", "hydrogen"]);

    let ct = datasets::load_named("chest-ct", &d).unwrap();
    assert_eq!(ct.name, "chest-ct");
    assert_eq!(ct.dims(), [256, 256, 133]);
    assert_eq!(ct.spacing(), [1.40625, 1.40625, 2.5]);
    assert_eq!(ct.spacing()[2] / ct.spacing()[0], 1.7777777777777777, "z is 1.8x thicker");
    assert_eq!(ct.origin(), [0.0; 3]);
    assert_eq!(ct.sample_type(), SampleType::U8);
    assert_eq!(ct.range(), (0.0, 255.0));
    let raw = std::fs::read(d.join("volumes/lidc2_chest_ct_256x256x133_uint8.raw")).unwrap();
    assert_eq!(ct.value(128, 128, 66), raw[128 + 256 * (128 + 256 * 66)] as f64);
    let Samples::U8(s) = ct.samples() else { panic!() };
    assert_eq!(s.iter().map(|&v| v as u64).sum::<u64>(), 61_489_178);
    let b = ct.bounds();
    assert_eq!((b.min, b.max), ([0.0; 3], [255.0 * 1.40625, 255.0 * 1.40625, 132.0 * 2.5]));

    let head = datasets::load_named("headsq", &d).unwrap();
    assert_eq!((head.dims(), head.spacing()), ([64, 64, 93], [3.2, 3.2, 1.5]));
    assert_eq!(head.sample_type(), SampleType::I16);
    assert_eq!(head.range(), (0.0, 3926.0));
    assert_eq!(head.value(10, 20, 40), 271.0);
    let Samples::I16(s) = head.samples() else { panic!() };
    assert_eq!(s.iter().map(|&v| v as i64).sum::<i64>(), 193_392_317);

    let h = datasets::load_named("hydrogen", &d).unwrap();
    assert_eq!((h.dims(), h.spacing(), h.origin()), ([64; 3], [1.0; 3], [0.0; 3]));
    assert_eq!(h.sample_type(), SampleType::F32);
    assert_eq!(h.range(), (0.0, 1.0));
    assert_eq!(h.value(31, 31, 21), 1.0);
    assert_eq!(h.value(10, 20, 30), 0.015506000258028507);
    let sum: f64 = h.to_f32().iter().map(|&v| v as f64).sum();
    assert!((sum - 4856.008970333924).abs() < 1e-6, "{sum}");
    // The same file by its array name, and by path through the dispatcher.
    let by_name = read_vti(d.join(datasets::HYDROGEN), Some("probability_density")).unwrap();
    assert_eq!(by_name.samples(), h.samples());
    assert_eq!(load_volume(d.join(datasets::HYDROGEN)).unwrap().name, "hydrogen");

    let e = datasets::load_named("bunny", &d).unwrap_err().to_string();
    assert!(e.contains("bunny") && e.contains("chest-ct, headsq, hydrogen"), "{e}");
}

// ------------------------------------------------------- synthetic volumes

const DIMS: [usize; 3] = [3, 4, 5];
const N: usize = 60;
const SPACING: [f64; 3] = [0.5, 1.25, 2.25];
const ORIGIN: [f64; 3] = [-1.0, 2.0, 3.5];
const TYPES: [SampleType; 4] = [SampleType::U8, SampleType::I16, SampleType::U16, SampleType::F32];

fn samples_of(t: SampleType) -> Samples {
    match t {
        SampleType::U8 => Samples::U8((0..N).map(|i| ((i * 37 + 11) % 256) as u8).collect()),
        SampleType::I16 => Samples::I16((0..N).map(|i| (i as i32 * 1031 - 30000) as i16).collect()),
        SampleType::U16 => Samples::U16((0..N).map(|i| (i * 1100 + 7) as u16).collect()),
        SampleType::F32 => Samples::F32((0..N).map(|i| i as f32 * 0.37 - 5.5).collect()),
    }
}

fn sample_bytes(s: &Samples, big: bool) -> Vec<u8> {
    macro_rules! b {
        ($v:expr) => {
            $v.iter().flat_map(|x| if big { x.to_be_bytes().to_vec() } else { x.to_le_bytes().to_vec() }).collect()
        };
    }
    match s {
        Samples::U8(v) => v.clone(),
        Samples::I16(v) => b!(v),
        Samples::U16(v) => b!(v),
        Samples::F32(v) => b!(v),
    }
}

fn ascii_values(s: &Samples) -> String {
    let v: Vec<String> = match s {
        Samples::U8(v) => v.iter().map(|x| x.to_string()).collect(),
        Samples::I16(v) => v.iter().map(|x| x.to_string()).collect(),
        Samples::U16(v) => v.iter().map(|x| x.to_string()).collect(),
        Samples::F32(v) => v.iter().map(|x| x.to_string()).collect(),
    };
    v.chunks(7).map(|c| c.join(" ")).collect::<Vec<_>>().join("\n")
}

fn gzip(b: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(b).unwrap();
    e.finish().unwrap()
}

fn zlib(b: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(b).unwrap();
    e.finish().unwrap()
}

fn b64(b: &[u8]) -> String {
    base64::engine::general_purpose::STANDARD.encode(b)
}

fn check(v: &Volume, expect: &Samples, origin: [f64; 3], what: &str) {
    assert_eq!(v.dims(), DIMS, "{what}");
    assert_eq!(v.spacing(), SPACING, "{what}");
    assert_eq!(v.origin(), origin, "{what}");
    assert_eq!(v.samples(), expect, "{what}");
    let f = expect.to_f32();
    let lo = f.iter().fold(f32::MAX, |a, &b| a.min(b)) as f64;
    let hi = f.iter().fold(f32::MIN, |a, &b| a.max(b)) as f64;
    assert_eq!(v.range(), (lo, hi), "{what}");
}

/// One synthetic file: its name, bytes, a detached data file if any, the
/// samples and origin it must load as.
struct Case {
    file: String,
    bytes: Vec<u8>,
    data: Option<(String, Vec<u8>)>,
    expect: Samples,
    origin: [f64; 3],
}

impl Case {
    fn parse(&self, name: &str, bytes: &[u8], data: Option<&[u8]>) -> Result<Volume> {
        let lower = self.file.to_ascii_lowercase();
        if lower.ends_with(".nrrd") || lower.ends_with(".nhdr") {
            let mut load = |f: &str| -> Result<Vec<u8>> {
                match (&self.data, data) {
                    (Some((n, _)), Some(d)) if n == f => Ok(d.to_vec()),
                    _ => anyhow::bail!("no such file {f}"),
                }
            };
            parse_nrrd_bytes(name, bytes, &mut load)
        } else if lower.ends_with(".vti") {
            parse_vti_bytes(name, bytes, None)
        } else if lower.ends_with(".vtk") {
            parse_structured_points_bytes(name, bytes)
        } else {
            parse_nifti_bytes(name, bytes)
        }
    }
}

// ---- NRRD

#[derive(Clone, Copy, Debug, PartialEq)]
enum Enc {
    Raw,
    Gzip,
    Ascii,
}

fn nrrd_type(t: SampleType, synonym: bool) -> &'static str {
    match (t, synonym) {
        (SampleType::U8, false) => "uint8",
        (SampleType::U8, true) => "unsigned char",
        (SampleType::I16, false) => "int16",
        (SampleType::I16, true) => "short",
        (SampleType::U16, false) => "uint16",
        (SampleType::U16, true) => "ushort",
        (SampleType::F32, _) => "float",
    }
}

/// A NRRD of `t`; `synonym` also switches `space directions` + `space
/// origin` to plain `spacings` (origin 0).
fn nrrd_case(t: SampleType, enc: Enc, big: bool, detached: bool, synonym: bool) -> Case {
    let s = samples_of(t);
    let mut h = format!("NRRD0004\n# synthetic\ntype: {}\ndimension: 3\nsizes: 3 4 5\n", nrrd_type(t, synonym));
    let origin = if synonym {
        h += "spacings: 0.5 1.25 2.25\n";
        [0.0; 3]
    } else {
        h += "space: left-posterior-superior\nspace directions: (0.5,0,0) (0,1.25,0) (0,0,2.25)\nspace origin: (-1,2,3.5)\n";
        ORIGIN
    };
    h += &format!("endian: {}\n", if big { "big" } else { "little" });
    h += match enc {
        Enc::Raw => "encoding: raw\n",
        Enc::Gzip if synonym => "encoding: gz\n",
        Enc::Gzip => "encoding: gzip\n",
        Enc::Ascii => "encoding: text\n",
    };
    h += "kinds: domain domain domain\nmodality:=synthetic\n";
    let payload = match enc {
        Enc::Raw => sample_bytes(&s, big),
        Enc::Gzip => gzip(&sample_bytes(&s, big)),
        Enc::Ascii => (ascii_values(&s) + "\n").into_bytes(),
    };
    let ext = match enc {
        Enc::Raw => "raw",
        Enc::Gzip => "raw.gz",
        Enc::Ascii => "txt",
    };
    let tag = format!("{}_{enc:?}_{}_{}", t.name(), if big { "be" } else { "le" }, if synonym { "syn" } else { "dir" });
    if detached {
        let data_name = format!("vol_{tag}.{ext}");
        h += &format!("data file: {data_name}\n");
        Case { file: format!("vol_{tag}.nhdr"), bytes: h.into_bytes(), data: Some((data_name, payload)), expect: s, origin }
    } else {
        let mut b = (h + "\n").into_bytes();
        b.extend(payload);
        Case { file: format!("vol_{tag}.nrrd"), bytes: b, data: None, expect: s, origin }
    }
}

fn nrrd_cases() -> Vec<Case> {
    let mut out = Vec::new();
    for t in TYPES {
        for enc in [Enc::Raw, Enc::Gzip, Enc::Ascii] {
            for big in [false, true] {
                for detached in [false, true] {
                    out.push(nrrd_case(t, enc, big, detached, big == detached));
                }
            }
        }
    }
    out
}

// ---- VTI

#[derive(Clone, Copy, Debug, PartialEq)]
enum Fmt {
    Ascii,
    /// Header and data as two base64 streams (as VTK writes them).
    Binary,
    /// Header and data as one base64 stream.
    BinaryJoined,
    AppendedRaw,
    AppendedBase64,
}

fn vti_type(t: SampleType) -> &'static str {
    match t {
        SampleType::U8 => "UInt8",
        SampleType::I16 => "Int16",
        SampleType::U16 => "UInt16",
        SampleType::F32 => "Float32",
    }
}

/// Header + data of a binary array: VTK's block layout when compressed
/// (blocks of 64 bytes, so several and a partial last one).
fn vtk_binary(raw: &[u8], zlib_blocks: bool, word64: bool, big: bool) -> (Vec<u8>, Vec<u8>) {
    let word = |v: usize| -> Vec<u8> {
        match (word64, big) {
            (false, false) => (v as u32).to_le_bytes().to_vec(),
            (false, true) => (v as u32).to_be_bytes().to_vec(),
            (true, false) => (v as u64).to_le_bytes().to_vec(),
            (true, true) => (v as u64).to_be_bytes().to_vec(),
        }
    };
    if !zlib_blocks {
        return (word(raw.len()), raw.to_vec());
    }
    const BLOCK: usize = 64;
    let blocks: Vec<Vec<u8>> = raw.chunks(BLOCK).map(zlib).collect();
    let mut h = word(blocks.len());
    h.extend(word(BLOCK));
    h.extend(word(raw.len() % BLOCK));
    for b in &blocks {
        h.extend(word(b.len()));
    }
    (h, blocks.concat())
}

fn vti_case(t: SampleType, fmt: Fmt, zlib_blocks: bool, word64: bool, big: bool) -> Case {
    let s = samples_of(t);
    let raw = sample_bytes(&s, big);
    let (head, data) = vtk_binary(&raw, zlib_blocks, word64, big);
    // The extent starts at (2, 0, -1): VTK's Origin is index 0's position.
    let origin_attr = [ORIGIN[0] - 2.0 * SPACING[0], ORIGIN[1], ORIGIN[2] + SPACING[2]];
    let mut x = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" version=\"1.0\" byte_order=\"{}\" header_type=\"{}\"{}>\n\
         <ImageData WholeExtent=\"2 4 0 3 -1 3\" Origin=\"{} {} {}\" Spacing=\"0.5 1.25 2.25\" Direction=\"1 0 0 0 1 0 0 0 1\">\n\
         <Piece Extent=\"2 4 0 3 -1 3\">\n<PointData>\n\
         <DataArray type=\"Float32\" Name=\"velocity\" NumberOfComponents=\"3\" format=\"ascii\">{}</DataArray>\n",
        if big { "BigEndian" } else { "LittleEndian" },
        if word64 { "UInt64" } else { "UInt32" },
        if zlib_blocks { " compressor=\"vtkZLibDataCompressor\"" } else { "" },
        origin_attr[0],
        origin_attr[1],
        origin_attr[2],
        vec!["0"; 3 * N].join(" "),
    );
    let mut appended: Vec<u8> = Vec::new();
    // A cell array first in the appended section, so ours is at an offset.
    let (ph, pd) = vtk_binary(&[9u8; 12], zlib_blocks, word64, big);
    let pad = [ph, pd];
    let (ours, other) = {
        let (oh, od) = vtk_binary(&[7u8; N], zlib_blocks, word64, big);
        ([head.clone(), data.clone()], [oh, od])
    };
    let encode = |parts: &[Vec<u8>; 2]| -> Vec<u8> {
        if fmt == Fmt::AppendedBase64 {
            (b64(&parts[0]) + &b64(&parts[1])).into_bytes()
        } else {
            parts.concat()
        }
    };
    let name_attr = format!("type=\"{}\" Name=\"density\"", vti_type(t));
    match fmt {
        Fmt::Ascii => x += &format!("<DataArray {name_attr} format=\"ascii\">\n{}\n</DataArray>\n", ascii_values(&s)),
        Fmt::Binary => x += &format!("<DataArray {name_attr} format=\"binary\">\n  {}{}\n</DataArray>\n", b64(&head), b64(&data)),
        Fmt::BinaryJoined => x += &format!("<DataArray {name_attr} format=\"binary\">{}</DataArray>\n", b64(&[head, data].concat())),
        Fmt::AppendedRaw | Fmt::AppendedBase64 => {
            appended.extend(encode(&pad));
            x += &format!("<DataArray {name_attr} format=\"appended\" offset=\"{}\"/>\n", appended.len());
            appended.extend(encode(&ours));
            x += &format!("<DataArray type=\"UInt8\" Name=\"other\" format=\"appended\" offset=\"{}\"/>\n", appended.len());
            appended.extend(encode(&other));
        }
    }
    if !matches!(fmt, Fmt::AppendedRaw | Fmt::AppendedBase64) {
        x += &format!("<DataArray type=\"UInt8\" Name=\"other\" format=\"ascii\">{}</DataArray>\n", vec!["7"; N].join(" "));
    }
    x += "</PointData>\n<CellData>\n";
    if !appended.is_empty() {
        x += "<DataArray type=\"UInt8\" Name=\"pad\" format=\"appended\" offset=\"0\"/>\n";
    }
    x += "</CellData>\n</Piece>\n</ImageData>\n";
    let mut b = x.into_bytes();
    if !appended.is_empty() {
        let enc = if fmt == Fmt::AppendedBase64 { "base64" } else { "raw" };
        b.extend(format!("<AppendedData encoding=\"{enc}\">\n   _").bytes());
        b.extend(appended);
        b.extend(b"\n</AppendedData>\n");
    }
    b.extend(b"</VTKFile>\n");
    let file = format!(
        "img_{}_{fmt:?}_{}_{}_{}.vti",
        t.name(),
        if zlib_blocks { "zlib" } else { "none" },
        if word64 { "u64" } else { "u32" },
        if big { "be" } else { "le" }
    );
    Case { file, bytes: b, data: None, expect: s, origin: ORIGIN }
}

fn vti_cases() -> Vec<Case> {
    let mut out = Vec::new();
    let mut k = 0;
    for t in TYPES {
        for fmt in [Fmt::Ascii, Fmt::Binary, Fmt::BinaryJoined, Fmt::AppendedRaw, Fmt::AppendedBase64] {
            for zlib_blocks in [false, true] {
                if fmt == Fmt::Ascii && zlib_blocks {
                    continue;
                }
                k += 1;
                out.push(vti_case(t, fmt, zlib_blocks, k % 3 == 0, k % 5 < 2));
            }
        }
    }
    out
}

// ---- legacy STRUCTURED_POINTS

fn legacy_type(t: SampleType) -> &'static str {
    match t {
        SampleType::U8 => "unsigned_char",
        SampleType::I16 => "short",
        SampleType::U16 => "unsigned_short",
        SampleType::F32 => "float",
    }
}

/// `extras` adds a VECTORS array before the scalars and a FIELD after, and
/// says ASPECT_RATIO for SPACING.
fn legacy_case(t: SampleType, binary: bool, extras: bool) -> Case {
    let s = samples_of(t);
    let mut b = format!(
        "# vtk DataFile Version 3.0\nsynthetic volume\n{}\nDATASET STRUCTURED_POINTS\nDIMENSIONS 3 4 5\n{} 0.5 1.25 2.25\nORIGIN -1 2 3.5\nPOINT_DATA 60\n",
        if binary { "BINARY" } else { "ASCII" },
        if extras { "ASPECT_RATIO" } else { "SPACING" }
    )
    .into_bytes();
    let values = |b: &mut Vec<u8>, s: &Samples| {
        if binary {
            b.extend(sample_bytes(s, true));
        } else {
            b.extend(ascii_values(s).bytes());
        }
        b.push(b'\n');
    };
    if extras {
        b.extend(b"VECTORS v float\n");
        values(&mut b, &Samples::F32(vec![0.25; 3 * N]));
    }
    b.extend(format!("SCALARS density {} 1\nLOOKUP_TABLE default\n", legacy_type(t)).bytes());
    values(&mut b, &s);
    if extras {
        b.extend(b"FIELD FieldData 1\nextra 1 60 short\n");
        values(&mut b, &Samples::I16(vec![-3; N]));
    }
    let file = format!("sp_{}_{}_{}.vtk", t.name(), if binary { "bin" } else { "ascii" }, if extras { "extras" } else { "plain" });
    Case { file, bytes: b, data: None, expect: s, origin: ORIGIN }
}

fn legacy_cases() -> Vec<Case> {
    let mut out = Vec::new();
    for t in TYPES {
        for binary in [false, true] {
            for extras in [false, true] {
                out.push(legacy_case(t, binary, extras));
            }
        }
    }
    out
}

// ---- NIfTI-1

fn nifti_code(t: SampleType) -> (i16, i16) {
    match t {
        SampleType::U8 => (2, 8),
        SampleType::I16 => (4, 16),
        SampleType::U16 => (512, 16),
        SampleType::F32 => (16, 32),
    }
}

/// A NIfTI-1 header (dims 3x4x5, `code`/`bitpix`, pixdim = SPACING, qform
/// offset = ORIGIN, `sform` with the same scaling when asked), 4 bytes of
/// extension flags, then `data`.
fn nifti_bytes(code: i16, bitpix: i16, data: &[u8], big: bool, scale: (f32, f32), sform: bool) -> Vec<u8> {
    let mut h = vec![0u8; 352];
    let put = |h: &mut Vec<u8>, at: usize, b: &[u8]| h[at..at + b.len()].copy_from_slice(b);
    let i16b = |v: i16| if big { v.to_be_bytes() } else { v.to_le_bytes() };
    let i32b = |v: i32| if big { v.to_be_bytes() } else { v.to_le_bytes() };
    let f32b = |v: f32| if big { v.to_be_bytes() } else { v.to_le_bytes() };
    put(&mut h, 0, &i32b(348));
    for (i, d) in [3i16, 3, 4, 5, 1, 1, 1, 1].into_iter().enumerate() {
        put(&mut h, 40 + 2 * i, &i16b(d));
    }
    put(&mut h, 70, &i16b(code));
    put(&mut h, 72, &i16b(bitpix));
    for (i, p) in [1.0f32, 0.5, 1.25, 2.25].into_iter().enumerate() {
        put(&mut h, 76 + 4 * i, &f32b(p));
    }
    put(&mut h, 108, &f32b(352.0));
    put(&mut h, 112, &f32b(scale.0));
    put(&mut h, 116, &f32b(scale.1));
    put(&mut h, 252, &i16b(1));
    for (i, o) in ORIGIN.into_iter().enumerate() {
        put(&mut h, 268 + 4 * i, &f32b(o as f32));
    }
    if sform {
        put(&mut h, 254, &i16b(1));
        // Rows of the affine: a permutation-free scaling with signs (a
        // flip along y): only the scaling and translation are used.
        let rows = [[0.5f32, 0.0, 0.0, -1.0], [0.0, -1.25, 0.0, 2.0], [0.0, 0.0, 2.25, 3.5]];
        for (r, row) in rows.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                put(&mut h, 280 + 16 * r + 4 * c, &f32b(*v));
            }
        }
    }
    put(&mut h, 344, b"n+1\0");
    h.extend(data);
    h
}

fn nifti_case(t: SampleType, big: bool, gz: bool, sform: bool) -> Case {
    let s = samples_of(t);
    let (code, bitpix) = nifti_code(t);
    let mut b = nifti_bytes(code, bitpix, &sample_bytes(&s, big), big, (1.0, 0.0), sform);
    if gz {
        b = gzip(&b);
    }
    let file = format!(
        "brain_{}_{}_{}.{}",
        t.name(),
        if big { "be" } else { "le" },
        if sform { "sform" } else { "qform" },
        if gz { "nii.gz" } else { "nii" }
    );
    Case { file, bytes: b, data: None, expect: s, origin: ORIGIN }
}

fn nifti_cases() -> Vec<Case> {
    let mut out = Vec::new();
    for t in TYPES {
        for big in [false, true] {
            for gz in [false, true] {
                out.push(nifti_case(t, big, gz, big && !gz));
            }
        }
    }
    out
}

fn all_cases() -> Vec<Case> {
    let mut v = nrrd_cases();
    v.extend(vti_cases());
    v.extend(legacy_cases());
    v.extend(nifti_cases());
    v
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

// ------------------------------------------------------------- round trips

#[test]
fn every_variant_round_trips_through_bytes_and_paths() {
    let cases = all_cases();
    assert_eq!(cases.len(), 48 + 36 + 16 + 16);
    let tmp = tempfile::tempdir().unwrap();
    for c in &cases {
        let v = c.parse(&c.file, &c.bytes, c.data.as_ref().map(|d| &d.1[..])).unwrap_or_else(|e| panic!("{}: {e:#}", c.file));
        check(&v, &c.expect, c.origin, &c.file);
        // The same file from disk, the reader chosen by load_volume.
        let p = write(tmp.path(), &c.file, &c.bytes);
        if let Some((n, d)) = &c.data {
            write(tmp.path(), n, d);
        }
        let v = load_volume(&p).unwrap_or_else(|e| panic!("{}: {e:#}", c.file));
        check(&v, &c.expect, c.origin, &c.file);
        let stem = c.file.trim_end_matches(".gz").rsplit_once('.').unwrap().0;
        assert_eq!(v.name, stem);
    }
}

#[test]
fn vti_array_choice() {
    let c = vti_case(SampleType::I16, Fmt::AppendedRaw, true, false, false);
    let other = parse_vti_bytes("a.vti", &c.bytes, Some("other")).unwrap();
    assert_eq!(other.samples(), &Samples::U8(vec![7; N]));
    let e = parse_vti_bytes("a.vti", &c.bytes, Some("velocity")).unwrap_err().to_string();
    assert!(e.contains("'velocity' has 3 components"), "{e}");
    let e = parse_vti_bytes("a.vti", &c.bytes, Some("nope")).unwrap_err().to_string();
    assert!(e.contains("no point data array named 'nope'") && e.contains("'density' (1 components)"), "{e}");
    // The PointData's active Scalars wins over the first array.
    let active = replace(&c.bytes, "<PointData>", "<PointData Scalars=\"other\">");
    let v = parse_vti_bytes("a.vti", &active, None).unwrap();
    assert_eq!(v.samples(), &Samples::U8(vec![7; N]));
}

#[test]
fn nifti_scaling_and_conversions() {
    let s = samples_of(SampleType::I16);
    let raw = sample_bytes(&s, false);
    // slope 2, intercept -1: float32 samples.
    let v = parse_nifti_bytes("s.nii", &nifti_bytes(4, 16, &raw, false, (2.0, -1.0), false)).unwrap();
    let want: Vec<f32> = s.to_f32().iter().map(|&x| x * 2.0 - 1.0).collect();
    assert_eq!(v.samples(), &Samples::F32(want));
    // slope 0 means no scaling; slope 1, intercept 0 keeps the type.
    for scale in [(0.0, 5.0), (1.0, 0.0)] {
        let v = parse_nifti_bytes("s.nii", &nifti_bytes(4, 16, &raw, false, scale, false)).unwrap();
        assert_eq!(v.samples(), &s);
    }
    // int8 widens to int16; int32 narrows to what holds it exactly.
    let v = parse_nifti_bytes("s.nii", &nifti_bytes(256, 8, &(0..N).map(|i| (i as i8 - 30) as u8).collect::<Vec<_>>(), true, (1.0, 0.0), false)).unwrap();
    assert_eq!(v.samples(), &Samples::I16((0..N).map(|i| i as i16 - 30).collect()));
    let ints: Vec<u8> = (0..N as i32).flat_map(|i| (i * 1000).to_le_bytes()).collect();
    let v = parse_nifti_bytes("s.nii", &nifti_bytes(8, 32, &ints, false, (1.0, 0.0), false)).unwrap();
    assert_eq!(v.samples(), &Samples::U16((0..N).map(|i| (i * 1000) as u16).collect()));
    let ints: Vec<u8> = (0..N as i32).flat_map(|i| (i * 100_000 - 7).to_be_bytes()).collect();
    let v = parse_nifti_bytes("s.nii", &nifti_bytes(8, 32, &ints, true, (1.0, 0.0), false)).unwrap();
    assert_eq!(v.samples(), &Samples::F32((0..N).map(|i| (i as i32 * 100_000 - 7) as f32).collect()));
    // A 4th dimension of 1 is a 3D volume.
    let mut b = nifti_bytes(4, 16, &raw, false, (1.0, 0.0), false);
    b[40] = 4;
    assert_eq!(parse_nifti_bytes("s.nii", &b).unwrap().samples(), &s);
}

// --------------------------------------------------------- malformed input

/// `{e:#}` of the error, asserting it starts with `name: ` and says `what`.
fn assert_err(name: &str, r: Result<Volume>, what: &str) {
    let e = format!("{:#}", r.expect_err("malformed input must be an error"));
    assert!(e.starts_with(&format!("{name}: ")), "error does not start with the file name: {e}");
    assert!(e.contains(what), "expected '{what}' in: {e}");
}

fn replace(b: &[u8], from: &str, to: &str) -> Vec<u8> {
    let at = b.windows(from.len()).position(|w| w == from.as_bytes()).unwrap_or_else(|| panic!("'{from}' not in the test file"));
    [&b[..at], to.as_bytes(), &b[at + from.len()..]].concat()
}

#[test]
fn nrrd_malformed_files_name_the_file_and_the_problem() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let attached = nrrd_case(SampleType::F32, Enc::Raw, false, false, false);
    let a = &attached.bytes;
    let hlen = a.len() - 4 * N;
    let mut nan = a.clone();
    nan[hlen + 4 * 7..hlen + 4 * 8].copy_from_slice(&f32::NAN.to_le_bytes());
    let mut inf = a.clone();
    inf[hlen + 4 * 59..].copy_from_slice(&f32::NEG_INFINITY.to_le_bytes());
    let gz = nrrd_case(SampleType::I16, Enc::Gzip, true, false, false);
    let glen = gz.bytes.len();
    let ghead = glen - gzip(&sample_bytes(&samples_of(SampleType::I16), true)).len();
    let mut corrupt = gz.bytes.clone();
    for b in &mut corrupt[ghead + 12..ghead + 20] {
        *b ^= 0x5a;
    }
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (a[..a.len() - 1].to_vec(), "header/size mismatch: sizes 3 4 5 of float32 need 240 bytes, the attached data has 239"),
        ([a.clone(), vec![0]].concat(), "header/size mismatch"),
        (gz.bytes[..glen - 9].to_vec(), "gzip"),
        (corrupt, "gzip"),
        (replace(a, "type: float", "type: double"), "unsupported type 'double'"),
        (replace(a, "sizes: 3 4 5", "sizes: 3 0 5"), "size 0 along y"),
        (replace(a, "sizes: 3 4 5", "sizes: 3 4 99999999999"), "absurd size 99999999999 along z"),
        (replace(a, "sizes: 3 4 5", "sizes: 65536 65536 65536"), "more than the limit"),
        (replace(a, "sizes: 3 4 5", "sizes: 3 4 184467440737095516150"), "bad size"),
        (replace(a, "dimension: 3", "dimension: 2"), "only 3-dimensional"),
        (replace(a, "(0,1.25,0)", "(0.1,1.25,0)"), "only axis-aligned grids"),
        (nan, "sample 7 (i=1, j=2, k=0) is NaN"),
        (inf, "sample 59 (i=2, j=3, k=4) is -inf"),
        (replace(a, "NRRD0004", "NRRB0004"), "not a NRRD file"),
        (replace(a, "endian: little\n", ""), "'endian' is missing"),
    ];
    for (i, (bytes, what)) in cases.iter().enumerate() {
        let p = write(d, &format!("bad{i}.nrrd"), bytes);
        let name = p.display().to_string();
        let r = catch_unwind(|| load_volume(&p)).unwrap_or_else(|_| panic!("case {i} panicked"));
        assert_err(&name, r, what);
    }
    // Detached: a short data file, a missing one (its path is named).
    let det = nrrd_case(SampleType::U16, Enc::Raw, true, true, false);
    let (dn, data) = det.data.as_ref().unwrap();
    let p = write(d, &det.file, &det.bytes);
    write(d, dn, &data[..data.len() - 2]);
    assert_err(&p.display().to_string(), load_volume(&p), &format!("data file '{dn}' has 118"));
    std::fs::remove_file(d.join(dn)).unwrap();
    let e = format!("{:#}", load_volume(&p).unwrap_err());
    assert!(e.contains(&d.join(dn).display().to_string()), "{e}");
}

#[test]
fn vti_malformed_files_name_the_file_and_the_problem() {
    let z = vti_case(SampleType::F32, Fmt::AppendedRaw, true, false, false);
    let b = &z.bytes;
    let n = "bad.vti";
    // The raw appended payload: the pad array, then ours (header of 3 + 4 words, 4 blocks).
    let start = b.windows(4).position(|w| w == b"   _").unwrap() + 4;
    let (ph, pd) = vtk_binary(&[9u8; 12], true, false, false);
    let ours = start + ph.len() + pd.len();
    let mut corrupt = b.clone();
    let blocks_at = ours + 4 * 7;
    for x in &mut corrupt[blocks_at + 3..blocks_at + 9] {
        *x ^= 0xa5;
    }
    let mut wrong_total = b.clone();
    wrong_total[ours + 4..ours + 8].copy_from_slice(&65u32.to_le_bytes());
    let mut many_blocks = b.clone();
    many_blocks[ours..ours + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    let mut nan_text = vti_case(SampleType::F32, Fmt::Ascii, false, false, false).bytes;
    nan_text = replace(&nan_text, "-5.5 ", "-5.5e99 ");
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (b[..b.len() - 300].to_vec(), "truncated"),
        (corrupt, "zlib"),
        (wrong_total, "header/size mismatch"),
        (many_blocks, "4294967295 compressed blocks declared"),
        (replace(b, "type=\"Float32\" Name=\"density\"", "type=\"Float64\" Name=\"density\""), "unsupported DataArray type 'Float64'"),
        (replace(b, "WholeExtent=\"2 4 0 3 -1 3\"", "WholeExtent=\"2 1 0 3 -1 3\""), "size 0"),
        (replace(b, "WholeExtent=\"2 4 0 3 -1 3\"", "WholeExtent=\"0 9999999 0 3 -1 3\""), "absurd size 10000000 along x"),
        (replace(b, "Spacing=\"0.5 1.25 2.25\"", "Spacing=\"0.5 0 2.25\""), "spacing along y must be finite and non-zero"),
        (replace(b, "Direction=\"1 0 0 0 1 0 0 0 1\"", "Direction=\"0 1 0 1 0 0 0 0 1\""), "only axis-aligned"),
        (nan_text, "sample 0 (i=0, j=0, k=0) is -inf"),
        (replace(b, "</PointData>", "</PointDat>"), "bad XML"),
        (b"BM junk".to_vec(), "not a VTK XML file"),
        (replace(b, "vtkZLibDataCompressor", "vtkZstdDataCompressor"), "unsupported compressor 'vtkZstdDataCompressor'"),
        (replace(b, "type=\"ImageData\"", "type=\"UnstructuredGrid\""), "is not ImageData"),
        (replace(b, "<Piece Extent=\"2 4 0 3 -1 3\">", "<Piece Extent=\"2 4 0 3 -1 2\">"), "is not the WholeExtent"),
        (replace(b, "offset=\"", "offset=\"9"), "past the end"),
        (replace(b, "   _", "   X"), "'_' marker"),
    ];
    for (i, (bytes, what)) in cases.iter().enumerate() {
        let r = catch_unwind(|| parse_vti_bytes(n, bytes, None)).unwrap_or_else(|_| panic!("case {i} panicked"));
        assert_err(n, r, what);
    }
}

#[test]
fn legacy_malformed_files_name_the_file_and_the_problem() {
    let n = "bad.vtk";
    let a = legacy_case(SampleType::U8, false, false).bytes;
    let bin = legacy_case(SampleType::F32, true, false).bytes;
    let f = legacy_case(SampleType::F32, false, false).bytes;
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (bin[..bin.len() - 10].to_vec(), "truncated file: SCALARS 'density' needs 60 values of 4 bytes"),
        (a[..a.len() - 10].to_vec(), "truncated SCALARS 'density'"),
        (replace(&a, "POINT_DATA 60", "POINT_DATA 61"), "count mismatch: POINT_DATA 61"),
        (replace(&a, "\n11 ", "\n256 "), "value 256 in SCALARS 'density' (value 0, byte"),
        (replace(&a, "\n11 ", "\n-1 "), "is out of range for unsigned_char"),
        (replace(&a, "unsigned_char", "double"), "unsupported type 'double'"),
        (replace(&a, "DIMENSIONS 3 4 5", "DIMENSIONS 3 4 0"), "size 0 along z"),
        (replace(&a, "DIMENSIONS 3 4 5", "DIMENSIONS 3 4 1000000"), "absurd size 1000000"),
        (replace(&a, "DIMENSIONS 3 4 5", "DIMENSIONS 3 4 -5"), "bad DIMENSIONS value '-5'"),
        (replace(&f, "-5.5 ", "nan "), "sample 0 (i=0, j=0, k=0) is NaN"),
        (replace(&a, "# vtk", "# VTK"), "not a VTK legacy file"),
        (replace(&a, "STRUCTURED_POINTS", "UNSTRUCTURED_GRID"), "only STRUCTURED_POINTS"),
        (replace(&a, "SPACING 0.5 1.25 2.25", "SPACING 0.5 1.25 NaN"), "spacing along z must be finite"),
        (replace(&a, "SCALARS density unsigned_char 1", "SCALARS density unsigned_char 3"), "truncated file: SCALARS 'density' has 60 of 180 values"),
        (replace(&a, "POINT_DATA 60", "CELL_DATA 60"), "no point scalars: need POINT_DATA with a one-component SCALARS array; found none"),
        (replace(&a, "ORIGIN", "ORIGAMI"), "bad keyword 'ORIGAMI'"),
    ];
    for (i, (bytes, what)) in cases.iter().enumerate() {
        let r = catch_unwind(|| parse_structured_points_bytes(n, bytes)).unwrap_or_else(|_| panic!("case {i} panicked"));
        assert_err(n, r, what);
    }
}

#[test]
fn nifti_malformed_files_name_the_file_and_the_problem() {
    let n = "bad.nii";
    let s = samples_of(SampleType::F32);
    let raw = sample_bytes(&s, false);
    let ok = nifti_bytes(16, 32, &raw, false, (1.0, 0.0), false);
    let patch = |at: usize, b: &[u8]| {
        let mut v = ok.clone();
        v[at..at + b.len()].copy_from_slice(b);
        v
    };
    let gz = gzip(&ok);
    let mut corrupt = gz.clone();
    for x in &mut corrupt[40..60] {
        *x = !*x;
    }
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (ok[..ok.len() - 1].to_vec(), "header/size mismatch: 3x4x5 float32 at vox_offset 352 make 592 bytes, the file has 591"),
        (ok[..200].to_vec(), "truncated: 200 bytes"),
        (gz[..gz.len() - 20].to_vec(), "gzip"),
        (gz[..30].to_vec(), "gzip"),
        (corrupt, "gzip"),
        (patch(70, &64i16.to_le_bytes()), "unsupported datatype 64 (float64)"),
        (patch(72, &16i16.to_le_bytes()), "bitpix 16 does not match datatype 16"),
        (patch(44, &0i16.to_le_bytes()), "size 0 along y"),
        (patch(42, &(-3i16).to_le_bytes()), "dim[1] is -3"),
        (patch(40, &[4, 0, 3, 0, 4, 0, 5, 0, 2, 0]), "dim[4] is 2"),
        (patch(40, &2i16.to_le_bytes()), "a 2D image"),
        (patch(352 + 4 * 3, &f32::NAN.to_le_bytes()), "sample 3 (i=0, j=1, k=0) is NaN"),
        (patch(352, &f32::INFINITY.to_le_bytes()), "sample 0 (i=0, j=0, k=0) is inf"),
        (patch(344, b"n+2\0"), "bad NIfTI-1 magic"),
        (patch(344, b"ni1\0"), ".hdr/.img pair"),
        (patch(0, &347i32.to_le_bytes()), "not a NIfTI-1 file"),
        (patch(0, &540i32.to_le_bytes()), "NIfTI-2"),
        (patch(108, &351.5f32.to_le_bytes()), "bad vox_offset 351.5"),
        (patch(108, &1e30f32.to_le_bytes()), "bad vox_offset"),
        (patch(80, &0f32.to_le_bytes()), "voxel size 0 along x (from pixdim)"),
        (patch(112, &f32::NAN.to_le_bytes()), "scl_slope NaN"),
        (patch(112, &1e38f32.to_le_bytes()), "sample 0 (i=0, j=0, k=0) is -inf"),
    ];
    for (i, (bytes, what)) in cases.iter().enumerate() {
        let r = catch_unwind(|| parse_nifti_bytes(n, bytes)).unwrap_or_else(|_| panic!("case {i} panicked"));
        assert_err(n, r, what);
    }
}

#[test]
fn unsupported_and_mislabelled_files() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let p = write(d, "head.slc", b"slice data");
    let e = format!("{:#}", load_volume(&p).unwrap_err());
    assert!(e.starts_with(&p.display().to_string()) && e.contains("unsupported volume format (extension .slc)"), "{e}");
    for f in [".nrrd", ".vti", ".vtk", ".nii", ".nii.gz"] {
        assert!(e.contains(f), "{f} missing from: {e}");
    }
    assert!(load_volume(d.join("missing.slc")).unwrap_err().to_string().contains("unsupported volume format"));
    // A known extension with the wrong magic: that reader says so.
    for (f, what) in [
        ("x.nrrd", "not a NRRD file"),
        ("x.nhdr", "not a NRRD file"),
        ("x.vti", "not a VTK XML file"),
        ("x.vtk", "not a VTK legacy file"),
        ("x.nii", "truncated: 10 bytes"),
        ("x.nii.gz", "truncated: 10 bytes"),
    ] {
        let p = write(d, f, b"slice data");
        let e = format!("{:#}", load_volume(&p).unwrap_err());
        assert!(e.starts_with(&p.display().to_string()) && e.contains(what), "{f}: {e}");
    }
    // A file that starts like a format is read as it, whatever its name.
    let c = nrrd_case(SampleType::U8, Enc::Raw, false, false, false);
    let v = load_volume(write(d, "volume.dat", &c.bytes)).unwrap();
    check(&v, &c.expect, c.origin, "volume.dat");
    let c = nifti_case(SampleType::I16, true, false, false);
    check(&load_volume(write(d, "scan.img", &c.bytes)).unwrap(), &c.expect, c.origin, "scan.img");
    // Directories and FIFOs are refused by fsio before reading.
    let e = load_volume(d).unwrap_err().to_string();
    assert!(e.contains("unsupported volume format") || e.contains("directory"), "{e}");
}

// ------------------------------------------------------ mutation stand-in

/// A small deterministic generator (xorshift64*).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Parses `bytes` (and `data`) as `c`'s format: no panic; an error starts
/// with the name; a volume that loads is consistent.
fn must_not_panic(c: &Case, bytes: &[u8], data: Option<&[u8]>, label: &str) {
    let r = catch_unwind(AssertUnwindSafe(|| c.parse("mut.file", bytes, data)))
        .unwrap_or_else(|_| panic!("{} panicked ({label}); input {:?}", c.file, String::from_utf8_lossy(bytes)));
    match r {
        Ok(v) => {
            let [nx, ny, nz] = v.dims();
            assert_eq!(nx * ny * nz, v.len());
            assert!(v.spacing().iter().all(|s| s.is_finite() && *s > 0.0));
            let (lo, hi) = v.range();
            assert!(lo.is_finite() && hi.is_finite() && lo <= hi);
            assert!(v.to_f32().iter().all(|x| x.is_finite()));
        }
        Err(e) => {
            let e = format!("{e:#}");
            assert!(e.starts_with("mut.file: "), "{} ({label}): {e}", c.file);
        }
    }
}

fn mutate(rng: &mut Rng, b: &[u8]) -> Vec<u8> {
    let mut m = b.to_vec();
    if m.is_empty() {
        return m;
    }
    for _ in 0..1 + rng.below(4) {
        let at = rng.below(m.len());
        match rng.below(6) {
            0 => m[at] ^= 1 << rng.below(8),
            1 => m[at] = rng.next() as u8,
            2 => m[at] = b"0123456789 -.\n:=()_,<>\"eE"[rng.below(25)],
            3 => {
                m.remove(at);
            }
            4 => m.insert(at, rng.next() as u8),
            _ => {
                // Copy a run from elsewhere (duplicates keywords and numbers).
                let from = rng.below(m.len());
                let len = rng.below(12).min(m.len() - from);
                let run = m[from..from + len].to_vec();
                m.splice(at..at, run);
            }
        }
        if m.is_empty() {
            break;
        }
    }
    m
}

#[test]
fn truncations_and_byte_flips_never_panic() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let mut runs = 0usize;
    for c in all_cases() {
        let data = c.data.as_ref().map(|d| &d.1[..]);
        // Every truncation (small files; a stride through large ones).
        let step = (c.bytes.len() / 400).max(1);
        for cut in (0..c.bytes.len()).step_by(step) {
            must_not_panic(&c, &c.bytes[..cut], data, &format!("cut at {cut}"));
            runs += 1;
        }
        if let Some(d) = data {
            for cut in 0..d.len() {
                must_not_panic(&c, &c.bytes, Some(&d[..cut]), &format!("data cut at {cut}"));
                runs += 1;
            }
        }
        for i in 0..150 {
            let m = mutate(&mut rng, &c.bytes);
            must_not_panic(&c, &m, data, &format!("mutation {i}"));
            if let Some(d) = data {
                must_not_panic(&c, &c.bytes, Some(&mutate(&mut rng, d)), &format!("data mutation {i}"));
            }
            runs += 1;
        }
    }
    assert!(runs > 40_000, "{runs}");
}

/// Writes the fuzz seeds (`fuzz/seeds/volume_*/`) from the synthetic cases:
/// `cargo test --test volume_readers -- --ignored write_fuzz_seeds`.
#[test]
#[ignore]
fn write_fuzz_seeds() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/seeds");
    let pick = |cases: Vec<Case>, every: usize| cases.into_iter().step_by(every).collect::<Vec<_>>();
    let sets = [
        // Strides chosen so that the picks cover every encoding, format,
        // byte order and compression of each list.
        ("volume_nrrd", pick(nrrd_cases(), 5)),
        ("volume_vti", pick(vti_cases(), 4)),
        ("volume_vtk", pick(legacy_cases(), 1)),
        ("volume_nifti", pick(nifti_cases(), 3)),
    ];
    for (target, cases) in sets {
        let dir = root.join(target);
        std::fs::create_dir_all(&dir).unwrap();
        for c in cases {
            let mut bytes = c.bytes.clone();
            if let Some((_, d)) = &c.data {
                // The NRRD target's detached data follows this separator.
                bytes.extend(b"\0DATA\0");
                bytes.extend(d);
            }
            std::fs::write(dir.join(&c.file), bytes).unwrap();
        }
    }
}
