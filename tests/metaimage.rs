//! MetaImage reader: the fixtures VTK's vtkMetaImageWriter wrote
//! (`tests/fixtures/metaimage/`, made and checked against VTK's reader by
//! `make.py` there) load with the right grid and samples, for every element
//! type, both byte orders, raw and zlib, `.mhd` + data file and `.mha`;
//! slice lists and file patterns read their files; malformed files (lying
//! sizes, truncated data, missing or special data files, header and zlib
//! bombs) give an error naming the file and the problem; truncations and
//! byte flips never panic (the stable stand-in for the `volume_metaimage`
//! fuzz target).

use std::io::Write as _;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

use volbench::volume::metaimage::parse_metaimage_bytes;
use volbench::volume::{load_volume, Samples};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/metaimage")
}

const N: usize = 60;
const TYPES: [&str; 8] = ["uchar", "char", "ushort", "short", "uint", "int", "float", "double"];

/// What `make.py` wrote for `ty`, as the Volume keeps it.
fn expected(ty: &str) -> Samples {
    let i = 0..N as i64;
    match ty {
        "uchar" => Samples::U8(i.map(|i| ((i * 37 + 11) % 256) as u8).collect()),
        "char" => Samples::I16(i.map(|i| (i * 4 - 120) as i16).collect()),
        "ushort" => Samples::U16(i.map(|i| (i * 1100 + 7) as u16).collect()),
        "short" => Samples::I16(i.map(|i| (i * 1031 - 30000) as i16).collect()),
        // Past uint16 and int16: float32, exactly.
        "uint" => Samples::F32(i.map(|i| (i * 70001 + 5) as f32).collect()),
        "int" => Samples::F32(i.map(|i| (100 - i * 70001) as f32).collect()),
        // make.py computes in float64, then stores float32 (or float64,
        // which the reader rounds to float32): the same values.
        "float" | "double" => Samples::F32(i.map(|i| ((i as f64) * 0.37 - 5.5) as f32).collect()),
        _ => unreachable!(),
    }
}

#[test]
fn vtk_written_files_load_for_every_type_order_and_compression() {
    let d = fixtures();
    let mut loaded = 0;
    for ty in TYPES {
        for order in ["le", "be"] {
            for comp in ["raw", "z"] {
                for ext in ["mha", "mhd"] {
                    let p = d.join(format!("{ty}_{order}_{comp}.{ext}"));
                    if !p.exists() {
                        // VTK writes native (little-endian) order only; the
                        // big-endian fixtures are .mha files made from VTK's.
                        assert!(order == "be" && (ext == "mhd" || ty.ends_with("char")), "{}", p.display());
                        continue;
                    }
                    let v = load_volume(&p).unwrap_or_else(|e| panic!("{}: {e:#}", p.display()));
                    assert_eq!(v.dims(), [3, 4, 5], "{}", p.display());
                    assert_eq!(v.spacing(), [0.5, 1.25, 2.25], "{}", p.display());
                    assert_eq!(v.origin(), [-1.0, 2.0, 3.5], "{}", p.display());
                    assert_eq!(v.samples(), &expected(ty), "{}", p.display());
                    assert_eq!(v.name, format!("{ty}_{order}_{comp}"));
                    loaded += 1;
                }
            }
        }
    }
    // 8 types x 2 compressions x (.mha + .mhd) little-endian, 6 x 2 big-endian.
    assert_eq!(loaded, 32 + 12);
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn zlib(b: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
    e.write_all(b).unwrap();
    e.finish().unwrap()
}

fn replace(b: &[u8], from: &str, to: &str) -> Vec<u8> {
    let at = b.windows(from.len()).position(|w| w == from.as_bytes()).unwrap_or_else(|| panic!("'{from}' not in the file"));
    [&b[..at], to.as_bytes(), &b[at + from.len()..]].concat()
}

/// `{e:#}` of loading `p`, asserting it starts with the path and says `what`.
fn assert_err(p: &Path, what: &str) {
    let r = catch_unwind(|| load_volume(p)).unwrap_or_else(|_| panic!("{} panicked", p.display()));
    let e = format!("{:#}", r.expect_err("malformed input must be an error"));
    assert!(e.starts_with(&p.display().to_string()), "error does not start with the file name: {e}");
    assert!(e.contains(what), "{}: expected '{what}' in: {e}", p.display());
}

#[test]
fn slice_lists_and_patterns_read_one_file_per_slice() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let raw = std::fs::read(fixtures().join("short_le_raw.raw")).unwrap();
    let head = std::fs::read_to_string(fixtures().join("short_le_raw.mhd")).unwrap();
    let head = head.split("ElementDataFile").next().unwrap().to_string();
    let slice = raw.len() / 5;
    for k in 0..5 {
        write(d, &format!("sl{:03}.raw", 10 + 2 * k), &raw[k * slice..(k + 1) * slice]);
        write(d, &format!("list_{k}.raw"), &raw[k * slice..(k + 1) * slice]);
    }
    let pattern = write(d, "p.mhd", format!("{head}ElementDataFile = sl%03d.raw 10 18 2\n").as_bytes());
    let list = write(d, "l.mhd", format!("{head}ElementDataFile = LIST 2D\n{}", (0..5).map(|k| format!("list_{k}.raw\n")).collect::<String>()).as_bytes());
    for p in [&pattern, &list] {
        let v = load_volume(p).unwrap_or_else(|e| panic!("{}: {e:#}", p.display()));
        assert_eq!(v.samples(), &expected("short"));
    }
    // A short slice file, and one slice too many in the pattern.
    write(d, "list_3.raw", &raw[..slice - 1]);
    assert_err(&list, &format!("data file 'list_3.raw' has {}", slice - 1));
    let p = write(d, "p6.mhd", format!("{head}ElementDataFile = sl%03d.raw 10 20 2\n").as_bytes());
    assert_err(&p, "names 6 files; DimSize's z needs 5");
}

#[test]
fn malformed_files_name_the_file_and_the_problem() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let f = fixtures();
    let mha = std::fs::read(f.join("float_le_raw.mha")).unwrap();
    let zmha = std::fs::read(f.join("short_le_z.mha")).unwrap();
    let hlen = zmha.windows(6).position(|w| w == b"LOCAL\n").unwrap() + 6;
    let mut corrupt = zmha.clone();
    for b in &mut corrupt[hlen + 10..hlen + 20] {
        *b ^= 0x5a;
    }
    // A zlib bomb: 64 MiB of zeros in ~65 KB, under a header promising 120 bytes.
    let bomb = zlib(&vec![0u8; 64 << 20]);
    let bomb_file = [
        replace(&zmha[..hlen], "CompressedDataSize = 131", &format!("CompressedDataSize = {}", bomb.len())),
        bomb.clone(),
    ]
    .concat();
    // A tiny stream promising 65536^2 x 2 samples: refused before inflating.
    let tiny = replace(&replace(&zmha, "DimSize = 3 4 5", "DimSize = 65536 32768 1"), "MET_SHORT", "MET_CHAR");
    let mut nan = mha.clone();
    let at = mha.len() - 4 * N + 4 * 7;
    nan[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (mha[..mha.len() - 1].to_vec(), "header/size mismatch: DimSize 3 4 5 of MET_FLOAT need 240 bytes, the data after the header has 239"),
        ([mha.clone(), vec![0]].concat(), "the data after the header has 241"),
        (replace(&mha, "DimSize = 3 4 5", "DimSize = 3 4 6"), "need 288 bytes"),
        (replace(&mha, "DimSize = 3 4 5", "DimSize = 65536 65536 65536"), "more than the limit"),
        (replace(&mha, "DimSize = 3 4 5", "DimSize = 3 4 99999999999999999999999"), "bad DimSize"),
        (replace(&mha, "NDims = 3", "NDims = 2"), "NDims 2: only 3-dimensional"),
        (replace(&mha, "NDims = 3", "NDims = 4"), "NDims 4: only 3-dimensional"),
        (replace(&mha, "MET_FLOAT", "MET_ULONG_LONG"), "unsupported ElementType 'MET_ULONG_LONG'"),
        (replace(&mha, "TransformMatrix = 1 0 0 0 1 0 0 0 1", "TransformMatrix = 0 1 0 1 0 0 0 0 1"), "only axis-aligned"),
        (replace(&mha, "ElementType", "ElementNumberOfChannels = 3\nElementType"), "ElementNumberOfChannels 3"),
        (nan, "sample 7 (i=1, j=2, k=0) is NaN"),
        (zmha[..zmha.len() - 9].to_vec(), "CompressedDataSize 131, the data after the header has 122"),
        (replace(&zmha[..zmha.len() - 9], "CompressedDataSize = 131\n", ""), "zlib"),
        (corrupt, "corrupt zlib data"),
        (bomb_file, "decompresses to more than the 120 bytes"),
        (tiny, "cannot hold"),
        ([format!("Comment = {}\n", "x".repeat(1 << 20)).into_bytes(), mha.clone()].concat(), "no 'ElementDataFile' line within"),
    ];
    for (i, (bytes, what)) in cases.iter().enumerate() {
        assert_err(&write(d, &format!("bad{i}.mha"), bytes), what);
    }

    // .mhd: a truncated, a missing, a directory and a device as data file.
    let mhd = std::fs::read_to_string(f.join("ushort_le_raw.mhd")).unwrap();
    let raw = std::fs::read(f.join("ushort_le_raw.raw")).unwrap();
    let with_data = |name: &str, data: &str| write(d, name, mhd.replace("ElementDataFile = ushort_le_raw.raw", &format!("ElementDataFile = {data}")).as_bytes());
    write(d, "short.raw", &raw[..raw.len() - 2]);
    assert_err(&with_data("t.mhd", "short.raw"), "data file 'short.raw' has 118");
    let missing = with_data("m.mhd", "nothere.raw");
    assert_err(&missing, &d.join("nothere.raw").display().to_string());
    std::fs::create_dir(d.join("dir.raw")).unwrap();
    assert_err(&with_data("dir.mhd", "dir.raw"), "is a directory");
    assert_err(&with_data("dev.mhd", "/dev/zero"), "is not a regular file");
    // A compressed .mhd whose data file is a bomb.
    write(d, "bomb.zraw", &bomb);
    let zmhd = std::fs::read_to_string(f.join("ushort_le_z.mhd")).unwrap();
    let zmhd = zmhd.replace("ElementDataFile = ushort_le_z.zraw", "ElementDataFile = bomb.zraw");
    let zmhd = zmhd.lines().filter(|l| !l.starts_with("CompressedDataSize")).collect::<Vec<_>>().join("\n") + "\n";
    assert_err(&write(d, "zb.mhd", zmhd.as_bytes()), "decompresses to more than the 120 bytes");
}

#[test]
fn unsupported_files_list_metaimage_among_the_formats() {
    let tmp = tempfile::tempdir().unwrap();
    let p = write(tmp.path(), "x.slc", b"junk");
    let e = format!("{:#}", load_volume(&p).unwrap_err());
    assert!(e.contains("MetaImage (.mha, .mhd"), "{e}");
}

/// Tiny deterministic generator (xorshift).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

#[test]
fn truncations_and_byte_flips_never_panic() {
    let mut rng = Rng(0x2545_f491_4f6c_dd1d);
    let mut runs = 0;
    for name in ["uchar_le_raw.mha", "short_le_z.mha", "double_be_z.mha", "int_le_raw.mhd", "float_le_z.mhd"] {
        let header = std::fs::read(fixtures().join(name)).unwrap();
        let data = name.ends_with(".mhd").then(|| {
            let text = String::from_utf8_lossy(&header).into_owned();
            let file = text.lines().last().unwrap().split('=').nth(1).unwrap().trim().to_string();
            std::fs::read(fixtures().join(file)).unwrap()
        });
        let go = |bytes: &[u8], data: Option<&[u8]>, label: &str| {
            let mut load = |f: &str| -> anyhow::Result<Vec<u8>> {
                data.map(<[u8]>::to_vec).ok_or_else(|| anyhow::anyhow!("{f}: no such file"))
            };
            let r = catch_unwind(AssertUnwindSafe(|| parse_metaimage_bytes("mut.mha", bytes, &mut load)))
                .unwrap_or_else(|_| panic!("{name} panicked ({label})"));
            match r {
                Ok(v) => {
                    assert!(v.spacing().iter().all(|s| s.is_finite() && *s > 0.0));
                    assert!(v.to_f32().iter().all(|x| x.is_finite()));
                }
                Err(e) => assert!(format!("{e:#}").starts_with("mut.mha: "), "{name} ({label}): {e:#}"),
            }
        };
        for cut in 0..header.len() {
            go(&header[..cut], data.as_deref(), "cut");
            runs += 1;
        }
        for _ in 0..400 {
            let mut m = header.clone();
            for _ in 0..1 + rng.below(3) {
                let at = rng.below(m.len());
                match rng.below(4) {
                    0 => m[at] ^= 1 << rng.below(8),
                    1 => m[at] = b"0123456789 -.\n=%LISTlocal"[rng.below(25)],
                    2 => {
                        m.remove(at);
                    }
                    _ => m.insert(at, rng.next() as u8),
                }
            }
            go(&m, data.as_deref(), "mutation");
            runs += 1;
        }
    }
    assert!(runs > 3000, "{runs}");
}

/// Writes the fuzz seeds (`fuzz/seeds/volume_metaimage/`) from the fixtures
/// (a `.mhd`'s data file after `\0DATA\0`):
/// `cargo test --test metaimage -- --ignored write_fuzz_seeds`.
#[test]
#[ignore]
fn write_fuzz_seeds() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/seeds/volume_metaimage");
    std::fs::create_dir_all(&dir).unwrap();
    for name in ["uchar_le_raw.mha", "short_be_z.mha", "double_le_z.mha", "int_le_raw.mhd", "float_le_z.mhd"] {
        let mut bytes = std::fs::read(fixtures().join(name)).unwrap();
        if name.ends_with(".mhd") {
            let text = String::from_utf8_lossy(&bytes).into_owned();
            let file = text.lines().last().unwrap().split('=').nth(1).unwrap().trim().to_string();
            bytes.extend(b"\0DATA\0");
            bytes.extend(std::fs::read(fixtures().join(file)).unwrap());
        }
        std::fs::write(dir.join(name), bytes).unwrap();
    }
}
