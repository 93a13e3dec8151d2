//! The red team's classes (issue 21), each through the binary with an
//! input of the class that is not its reproduction: inputs never replaced,
//! outputs whole and with their mode, blank pictures and loose files
//! refused, closed pipes quiet. docs/bad-input.md states the rules.

use std::io::Write as _;
use std::os::unix::fs::PermissionsExt as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

mod common;

fn volbench() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_volbench"));
    c.env("VOLBENCH_VALIDATION", "1");
    c
}

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// A refused command: exit 1 (no panic, no signal) and `want` in its message.
fn refused(o: &Output, want: &str) {
    assert_eq!(o.status.code(), Some(1), "{}", text(o));
    assert!(text(o).contains(want), "expected '{want}' in: {}", text(o));
    assert!(!text(o).contains("panicked"), "{}", text(o));
}

const RUN: [&str; 7] = ["run", "--size", "16x16", "--frames", "1", "--warmup", "0"];

#[test]
fn no_output_replaces_an_input_by_any_name() {
    let d = tempfile::tempdir().unwrap();
    let mesh = d.path().join("mesh.vtk");
    std::fs::copy(repo("data/unstructured/post_tets_vtkdata.vtk"), &mesh).unwrap();
    let tf = d.path().join("tf.json");
    std::fs::copy(repo("data/tf/post-small.json"), &tf).unwrap();
    let (mesh_bytes, tf_bytes) = (std::fs::read(&mesh).unwrap(), std::fs::read(&tf).unwrap());
    let link = d.path().join("link.png");
    std::os::unix::fs::symlink(&tf, &link).unwrap();
    for (option, out) in [("--json", mesh.clone()), ("--png", tf.clone()), ("--diff-png", link)] {
        let o = volbench().args(RUN).args(["--method", "balanced", "--data"]).arg(&mesh).arg("--tf").arg(&tf).arg(option).arg(&out).output().unwrap();
        refused(&o, "is an input of this command");
    }
    assert_eq!(std::fs::read(&mesh).unwrap(), mesh_bytes);
    assert_eq!(std::fs::read(&tf).unwrap(), tf_bytes);
}

#[test]
fn outputs_are_whole_keep_their_mode_and_reach_stdout_by_any_name() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("o.json");
    std::fs::write(&out, vec![b'x'; 300_000]).unwrap();
    std::fs::set_permissions(&out, std::fs::Permissions::from_mode(0o600)).unwrap();
    let o = volbench().args(RUN).args(["--method", "balanced", "--data", "post-small", "--json"]).arg(&out).output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).expect("the whole file is the JSON");
    assert_eq!(v["schema_version"], 2);
    assert_eq!(std::fs::metadata(&out).unwrap().permissions().mode() & 0o777, 0o600);
    // Standard output named as a path, going to a pipe: written to it.
    for name in ["/dev/stdout", "/proc/self/fd/1"] {
        let o = volbench().args(RUN).args(["--method", "balanced", "--data", "post-small", "--json", name]).output().unwrap();
        assert!(o.status.success(), "{name}: {}", text(&o));
        let _: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("{name}: stdout is not the JSON alone: {e}"));
    }
}

#[test]
fn closed_and_full_standard_output() {
    let mut child = volbench().arg("list").stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(0), "a closed pipe is a quiet exit: {}", text(&o));
    assert!(o.stderr.is_empty(), "{}", text(&o));
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    let o = volbench().arg("list").stdout(full).output().unwrap();
    refused(&o, "No space left on device");
}

#[test]
fn options_that_do_not_apply_and_bad_environment_are_errors() {
    for extra in [&["--no-times"][..], &["--gha", "g.json"]] {
        let o = volbench().args(["compare", "--data", "post-small"]).args(extra).output().unwrap();
        refused(&o, "applies only to benchmark tracking");
    }
    use std::os::unix::ffi::OsStrExt as _;
    for var in ["VOLBENCH_VALIDATION", "VOLBENCH_DEVICE"] {
        let o = volbench().env(var, std::ffi::OsStr::from_bytes(b"o\xffn")).args(RUN).args(["--method", "balanced", "--data", "post-small"]).output().unwrap();
        refused(&o, var);
    }
}

#[test]
fn loose_and_hostile_files_are_refused_with_what_is_wrong() {
    let d = tempfile::tempdir().unwrap();
    let npy = |descr: &str, shape: &str, extra_key: &str, data: &[u8]| {
        common::npy_bytes(&format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, {extra_key}}}"), data)
    };
    let heights: Vec<u8> = (0..9u8).flat_map(|i| (f64::from(i) * 10.0).to_le_bytes()).collect();
    let mut trailing = heights.clone();
    trailing.push(0);
    let deep = format!("<VTKFile type=\"ImageData\">{}{}</VTKFile>", "<x>".repeat(5000), "</x>".repeat(5000));
    let mut far_heights = Vec::new();
    for z in [0.0f64, 1.0, 3e38, 2.0] {
        far_heights.extend(z.to_le_bytes());
    }
    let cases: Vec<(&str, Vec<u8>, &str, &str)> = vec![
        ("trail.npy", npy("<f8", "(3, 3)", "", &trailing), "hm-cpu", "bytes after the data"),
        ("twice.npy", npy("<f8", "(3, 3)", "'shape': (9,), ", &heights), "hm-cpu", "'shape' 2 times"),
        ("high.npy", npy("<f8", "(2, 2)", "", &far_heights), "hm-cpu", "outside the supported"),
        ("deep.vti", deep.into_bytes(), "raycast-compute", "nested more than"),
        // NRRD content under another name, far outside the supported box.
        ("vol.raw", b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nspacings: 1e300 1 1\nencoding: raw\n\n\x00\x01\x02\x03\x04\x05\x06\x07".to_vec(), "raycast-compute", "outside the supported"),
        ("brain.slc", b"not a format at all".to_vec(), "raycast-compute", "renders volume datasets"),
    ];
    for (name, bytes, method, want) in cases {
        let p = d.path().join(name);
        std::fs::File::create(&p).unwrap().write_all(&bytes).unwrap();
        let o = volbench().args(RUN).args(["--method", method, "--data"]).arg(&p).output().unwrap();
        refused(&o, want);
    }
}

#[test]
fn a_gzip_offset_is_skipped_not_stored() {
    // 64 MiB of skipped zeros in a ~64 kB file: the error comes without
    // holding them (peak RSS well below the offset).
    let d = tempfile::tempdir().unwrap();
    let skip = 64usize << 20;
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    gz.write_all(&vec![0u8; skip]).unwrap();
    let mut bytes = format!("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 1 1 1\nencoding: gzip\nbyte skip: {skip}\n\n").into_bytes();
    bytes.extend(gz.finish().unwrap());
    let p = d.path().join("skip.nrrd");
    std::fs::write(&p, bytes).unwrap();
    let o = Command::new("/usr/bin/time")
        .args(["-f", "maxrss_kb=%M"])
        .arg(env!("CARGO_BIN_EXE_volbench"))
        .args(RUN)
        .args(["--method", "raycast-compute", "--data"])
        .arg(&p)
        .output()
        .unwrap();
    let t = text(&o);
    assert!(t.contains("decompresses to") && !t.contains("panicked"), "{t}");
    let rss: u64 = t.split("maxrss_kb=").nth(1).and_then(|s| s.trim().parse().ok()).expect("time -f printed the peak");
    assert!(rss < 48 << 10, "peak RSS {rss} kB holds the 64 MiB offset");
}

#[test]
fn a_transfer_function_transparent_over_the_data_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let tf = d.path().join("far.json");
    std::fs::write(
        &tf,
        r#"{"points": [{"scalar": 0, "color": [1, 1, 1], "attenuation": 0},
            {"scalar": 1e9, "color": [1, 1, 1], "attenuation": 0},
            {"scalar": 2e9, "color": [1, 1, 1], "attenuation": 5}]}"#,
    )
    .unwrap();
    for (method, data) in [("balanced", "post-small"), ("raycast-compute", "headsq")] {
        let o = volbench().args(RUN).args(["--method", method, "--data", data, "--tf"]).arg(&tf).output().unwrap();
        refused(&o, "nothing would be visible");
    }
}

/// Peak RSS (kB) of `volbench ARGS` as `/usr/bin/time` reports it, and the output.
fn peak_rss(args: &[&str], data: &Path) -> (Output, u64) {
    let o = Command::new("/usr/bin/time")
        .args(["-f", "maxrss_kb=%M"])
        .arg(env!("CARGO_BIN_EXE_volbench"))
        .args(args)
        .arg("--data")
        .arg(data)
        .output()
        .unwrap();
    let rss = text(&o).split("maxrss_kb=").nth(1).and_then(|s| s.trim().parse().ok()).expect("time -f printed the peak");
    (o, rss)
}

#[test]
fn a_volume_costs_twice_its_bytes_plus_a_fixed_overhead() {
    // A 384³ 8-bit volume of zeros (54 MiB, a 55 kB gzip NRRD) against a
    // 2³ one rendered the same way: issue 21's bound, at most the samples
    // twice and 32 MiB (the 8 MiB staging slab, allocator slack). A single
    // run holds the samples about once (docs/bad-input.md, "Memory"); it
    // was 16× (268 MB at 256³), then 2× + the distance map + the slab.
    let d = tempfile::tempdir().unwrap();
    let nrrd = |n: usize| {
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        gz.write_all(&vec![0u8; n * n * n]).unwrap();
        let mut bytes = format!("NRRD0004\ntype: uint8\ndimension: 3\nsizes: {n} {n} {n}\nencoding: gzip\n\n").into_bytes();
        bytes.extend(gz.finish().unwrap());
        let p = d.path().join(format!("z{n}.nrrd"));
        std::fs::write(&p, bytes).unwrap();
        p
    };
    let args = ["run", "--size", "32x32", "--frames", "1", "--warmup", "0", "--method", "raycast-compute"];
    let (small_out, small) = peak_rss(&args, &nrrd(2));
    let (big_out, big) = peak_rss(&args, &nrrd(384));
    assert!(small_out.status.success() && big_out.status.success(), "{}{}", text(&small_out), text(&big_out));
    let n_kb = (384u64 * 384 * 384) >> 10;
    let bound = 2 * n_kb + (32 << 10);
    assert!(big.saturating_sub(small) <= bound, "384³ peaks at {big} kB, 2³ at {small} kB: more than {bound} kB for 54 MiB of samples");
}

#[test]
fn closed_or_full_standard_error_loses_messages_not_the_run() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("o.json");
    // Standard error closed: the JSON (the first file opened) must not take
    // its descriptor and receive the table.
    let o = Command::new("sh")
        .arg("-c")
        .arg("exec \"$0\" \"$@\" 2>&-")
        .arg(env!("CARGO_BIN_EXE_volbench"))
        .env("VOLBENCH_VALIDATION", "1")
        .args(RUN)
        .args(["--method", "balanced", "--data", "post-small", "--json"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let _: serde_json::Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).expect("the JSON alone");
    // Standard error full: the table sent there (the JSON takes stdout) is lost.
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    let o = volbench().args(RUN).args(["--method", "balanced", "--data", "post-small", "--json", "-"]).stderr(full).output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let _: serde_json::Value = serde_json::from_slice(&o.stdout).expect("stdout is the JSON");
}

#[test]
fn a_view_covering_less_than_a_pixel_is_refused_before_rendering() {
    for (method, data) in [("balanced", "post-small"), ("raycast-compute", "headsq")] {
        let o = volbench().args(["run", "--size", "32x32", "--frames", "1", "--zoom", "0.01", "--method", method, "--data", data]).output().unwrap();
        refused(&o, "less than a pixel");
    }
}

#[test]
fn a_broken_preset_transfer_function_is_named_not_replaced() {
    let d = tempfile::tempdir().unwrap();
    std::os::unix::fs::symlink(repo("data/volumes"), d.path().join("volumes")).unwrap();
    std::fs::create_dir(d.path().join("tf")).unwrap();
    std::fs::write(d.path().join("tf/headsq.json"), "{\"points\": [").unwrap();
    let o = volbench().env("VOLBENCH_DATA", d.path()).args(RUN).args(["--method", "raycast-compute", "--data", "headsq"]).output().unwrap();
    refused(&o, "preset transfer function of 'headsq'");
}

#[test]
fn a_gzip_nifti_without_extension_is_read_by_its_content() {
    let mut header = vec![0u8; 348];
    header[..4].copy_from_slice(&348i32.to_le_bytes());
    for (k, d) in [3i16, 4, 4, 4, 1, 1, 1, 1].iter().enumerate() {
        header[40 + 2 * k..42 + 2 * k].copy_from_slice(&d.to_le_bytes());
    }
    header[70..72].copy_from_slice(&2i16.to_le_bytes()); // uint8
    header[72..74].copy_from_slice(&8i16.to_le_bytes());
    for k in 0..8 {
        header[76 + 4 * k..80 + 4 * k].copy_from_slice(&1f32.to_le_bytes());
    }
    header[108..112].copy_from_slice(&352f32.to_le_bytes());
    header[344..348].copy_from_slice(b"n+1\0");
    header.extend([0u8; 4]);
    header.extend(0..64u8);
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    gz.write_all(&header).unwrap();
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("scan");
    std::fs::write(&p, gz.finish().unwrap()).unwrap();
    let o = volbench().args(RUN).args(["--method", "raycast-compute", "--data"]).arg(&p).output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
}

/// A one-strip, uncompressed, 16-bit grey TIFF of `w` x `h` whose strip
/// holds `data` (fewer bytes than the image needs when only the header is
/// meant to be read), with GeoTIFF's pixel scale `scale`.
fn grey16_tiff(w: u32, h: u32, scale: f64, data: &[u8]) -> Vec<u8> {
    let tags: [(u16, u16, u32, u32); 11] = [
        (256, 4, 1, w),
        (257, 4, 1, h),
        (258, 3, 1, 16),
        (259, 3, 1, 1),
        (262, 3, 1, 1),
        (273, 4, 1, 0), // strip offset, filled below
        (277, 3, 1, 1),
        (278, 4, 1, h),
        (279, 4, 1, data.len() as u32),
        (339, 3, 1, 1),
        (33550, 12, 3, 0), // ModelPixelScale, at the offset filled below
    ];
    let scale_at = 8 + 2 + 12 * tags.len() as u32 + 4;
    let data_at = scale_at + 24;
    let mut b = b"II*\0".to_vec();
    b.extend(8u32.to_le_bytes());
    b.extend((tags.len() as u16).to_le_bytes());
    for (tag, kind, count, value) in tags {
        let value = match tag {
            273 => data_at,
            33550 => scale_at,
            _ => value,
        };
        b.extend(tag.to_le_bytes());
        b.extend(kind.to_le_bytes());
        b.extend(count.to_le_bytes());
        if kind == 3 {
            b.extend((value as u16).to_le_bytes());
            b.extend([0, 0]);
        } else {
            b.extend(value.to_le_bytes());
        }
    }
    b.extend(0u32.to_le_bytes());
    for s in [scale, scale, 0.0] {
        b.extend(s.to_le_bytes());
    }
    b.extend(data);
    b
}

#[test]
fn a_terrain_that_would_render_nothing_or_not_fit_is_refused_at_load() {
    let d = tempfile::tempdir().unwrap();
    let heights: Vec<u8> = (0..16 * 16u16).flat_map(|i| (i % 50).to_le_bytes()).collect();
    // 15e-300 wide, heights spanning 49: a needle seen from above (it
    // loaded, then "rendered an empty image although the camera frames it").
    let needle = d.path().join("needle.tif");
    std::fs::write(&needle, grey16_tiff(16, 16, 1e-300, &heights)).unwrap();
    let o = volbench().args(RUN).args(["--method", "hm-cpu", "--data"]).arg(&needle).output().unwrap();
    refused(&o, "seen from above it would cover a pixel or none");
    // 20000 x 5000 in a few bytes: refused from the header, before decoding
    // (the hybrid model of 10^8 samples would need ~20 GB).
    let wide = d.path().join("wide.tif");
    std::fs::write(&wide, grey16_tiff(16384, 5000, 30.0, &[0; 64])).unwrap();
    let o = Command::new("/usr/bin/time").args(["-f", "maxrss_kb=%M"]).arg(env!("CARGO_BIN_EXE_volbench")).args(RUN).args(["--method", "hm-cpu", "--data"]).arg(&wide).output().unwrap();
    refused(&o, "more than the 67108864 (8192x8192) volbench accepts");
    let rss: u64 = text(&o).split("maxrss_kb=").nth(1).and_then(|s| s.trim().parse().ok()).expect("time -f printed the peak");
    assert!(rss < 64 << 10, "peak RSS {rss} kB: the grid was decoded before its size was checked");
    // A narrow but honest grid (0.1 spacing, heights spanning 49) renders.
    let narrow = d.path().join("narrow.tif");
    std::fs::write(&narrow, grey16_tiff(16, 16, 0.1, &heights)).unwrap();
    let o = volbench().args(RUN).args(["--method", "hm-cpu", "--data"]).arg(&narrow).output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
}

#[test]
fn help_and_version_on_a_full_or_closed_stdout() {
    for args in [&["--help"][..], &["--version"], &["run", "--help"]] {
        let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
        let o = volbench().args(args).stdout(full).output().unwrap();
        refused(&o, "No space left on device");
        let mut child = volbench().args(args).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
        drop(child.stdout.take());
        let o = child.wait_with_output().unwrap();
        assert_eq!(o.status.code(), Some(0), "{args:?} into a closed pipe: {}", text(&o));
        assert!(o.stderr.is_empty(), "{}", text(&o));
    }
    let o = volbench().arg("--no-such-option").output().unwrap();
    assert_eq!(o.status.code(), Some(2), "a usage error stays clap's: {}", text(&o));
}
