//! NIfTI-1 reader (.nii, and .nii.gz by its gzip magic): any bytes give a
//! volume or an error naming the file, never a panic; a volume that loads is
//! consistent.
#![no_main]

use libfuzzer_sys::fuzz_target;
use volbench::volume::nifti::parse_nifti_bytes;

fuzz_target!(|data: &[u8]| {
    match parse_nifti_bytes("fuzz.nii", data) {
        Ok(v) => {
            let [nx, ny, nz] = v.dims();
            assert_eq!(nx * ny * nz, v.len());
            assert!(v.spacing().iter().all(|s| s.is_finite() && *s > 0.0));
            let (lo, hi) = v.range();
            assert!(lo.is_finite() && hi.is_finite() && lo <= hi);
            assert!(v.to_f32().iter().all(|x| x.is_finite()));
        }
        Err(e) => assert!(format!("{e:#}").starts_with("fuzz.nii: "), "{e:#}"),
    }
});
