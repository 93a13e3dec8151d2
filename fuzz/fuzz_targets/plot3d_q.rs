//! PLOT3D solution reader: any bytes give a solution or an error naming the
//! file, never a panic; the fields of a solution that loads are finite, and so
//! is the velocity magnitude derived from them.
#![no_main]

use libfuzzer_sys::fuzz_target;
use volbench::mesh::plot3d::parse_q_bytes;

fuzz_target!(|data: &[u8]| {
    match parse_q_bytes("fuzz.q", data) {
        Ok(q) => {
            let n = q.dims.iter().product::<usize>();
            assert!(q.fields.iter().all(|f| f.len() == n && f.iter().all(|v| v.is_finite())));
            assert!(q.velocity_magnitude().iter().all(|v| v.is_finite()));
        }
        Err(e) => assert!(format!("{e:#}").starts_with("fuzz.q: "), "{e:#}"),
    }
});
