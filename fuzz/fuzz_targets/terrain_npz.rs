//! NumPy .npz elevation reader (zip of .npy): any bytes give a height grid
//! or an error naming the file, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use volbench::terrain::npy::parse_npz_grid;

fuzz_target!(|data: &[u8]| {
    match parse_npz_grid("fuzz.npz", data, None) {
        Ok((m, _)) => {
            assert_eq!(m.nx * m.ny, m.heights.len());
            assert!(m.heights.iter().all(|h| h.is_finite()));
            assert!(m.spacing.iter().all(|s| s.is_finite() && *s > 0.0));
        }
        Err(e) => assert!(format!("{e:#}").starts_with("fuzz.npz"), "{e:#}"),
    }
});
