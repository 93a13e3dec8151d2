//! VTK XML UnstructuredGrid reader: any bytes give a mesh or an error naming
//! the file, never a panic; a mesh that loads is validated (split cells
//! included), so its per-tet precomputation must be finite.
#![no_main]

use libfuzzer_sys::fuzz_target;
use volbench::mesh::vtu::parse_vtu_bytes;

#[path = "common/mesh_check.rs"]
mod mesh_check;

fuzz_target!(|data: &[u8]| {
    mesh_check::check("fuzz.vtu", parse_vtu_bytes("fuzz.vtu", data, None));
});
