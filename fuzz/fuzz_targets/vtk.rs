//! VTK legacy reader: any bytes give a mesh or an error naming the file, never
//! a panic; a mesh that loads is validated, so its per-tet precomputation must
//! be finite.
#![no_main]

use libfuzzer_sys::fuzz_target;
use volbench::mesh::vtk::parse_vtk_bytes;

#[path = "common/mesh_check.rs"]
mod mesh_check;

fuzz_target!(|data: &[u8]| {
    mesh_check::check("fuzz.vtk: ", parse_vtk_bytes("fuzz.vtk", data));
});
