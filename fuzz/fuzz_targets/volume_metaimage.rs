//! MetaImage reader: any bytes give a volume or an error naming the file, never a
//! panic. The input is the header (with any attached data); after a
//! `\0DATA\0` separator come the bytes every data file (`ElementDataFile`) reads as.
//! A volume that loads is consistent (see `check`).
#![no_main]

use libfuzzer_sys::fuzz_target;
use volbench::volume::metaimage::parse_metaimage_bytes;
use volbench::volume::Volume;

const SEP: &[u8] = b"\0DATA\0";

fn check(v: &Volume) {
    let [nx, ny, nz] = v.dims();
    assert_eq!(nx * ny * nz, v.len());
    assert!(v.spacing().iter().all(|s| s.is_finite() && *s > 0.0));
    let (lo, hi) = v.range();
    assert!(lo.is_finite() && hi.is_finite() && lo <= hi);
    assert!(v.to_f32().iter().all(|x| x.is_finite()));
}

fuzz_target!(|data: &[u8]| {
    let (header, detached) = match data.windows(SEP.len()).position(|w| w == SEP) {
        Some(at) => (&data[..at], Some(&data[at + SEP.len()..])),
        None => (data, None),
    };
    let mut load = |f: &str| -> anyhow::Result<Vec<u8>> {
        detached.map(|d| d.to_vec()).ok_or_else(|| anyhow::anyhow!("{f}: no such file"))
    };
    match parse_metaimage_bytes("fuzz.mhd", header, &mut load) {
        Ok(v) => check(&v),
        Err(e) => assert!(format!("{e:#}").starts_with("fuzz.mhd: "), "{e:#}"),
    }
});
