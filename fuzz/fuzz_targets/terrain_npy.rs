//! NumPy .npy elevation reader: any bytes give a height grid or an error
//! naming the file, never a panic; a grid that loads is consistent.
#![no_main]

use libfuzzer_sys::fuzz_target;
use volbench::terrain::npy::parse_npy_heightmap;

fuzz_target!(|data: &[u8]| {
    match parse_npy_heightmap("fuzz.npy", data) {
        Ok(m) => {
            assert_eq!(m.nx * m.ny, m.heights.len());
            assert!(m.heights.iter().all(|h| h.is_finite()));
        }
        Err(e) => assert!(format!("{e:#}").starts_with("fuzz.npy"), "{e:#}"),
    }
});
