//! The real volumes shipped in `data/volumes/` (provenance in
//! `data/README.md`), by name:
//!
//! - `chest-ct`: a contrast chest CT from LIDC-IDRI, 256×256×133 uint8,
//!   spacing 1.40625 × 1.40625 × 2.5 mm (NRRD, detached raw).
//! - `headsq`: VTK's "headsq" CT at quarter resolution, 64×64×93 int16,
//!   spacing 3.2 × 3.2 × 1.5 (NRRD, detached raw, little-endian).
//! - `hydrogen`: a hydrogen-atom orbital probability density, 64³ float32
//!   (VTK XML ImageData, zlib-compressed base64).

use std::path::Path;

use anyhow::{bail, Result};

use super::Volume;

/// The names [`load_named`] accepts.
pub const NAMES: [&str; 3] = ["chest-ct", "headsq", "hydrogen"];

pub const CHEST_CT: &str = "volumes/lidc2_chest_ct_256x256x133_uint8.nhdr";
pub const HEADSQ: &str = "volumes/headsq_64x64x93_int16le.nhdr";
pub const HYDROGEN: &str = "volumes/hydrogen.vti";

/// The file of a named volume, relative to the data directory.
pub fn file_of(name: &str) -> Option<&'static str> {
    match name {
        "chest-ct" => Some(CHEST_CT),
        "headsq" => Some(HEADSQ),
        "hydrogen" => Some(HYDROGEN),
        _ => None,
    }
}

/// One of [`NAMES`] from `data_dir` (the repository's `data/`), named as
/// given.
pub fn load_named(name: &str, data_dir: &Path) -> Result<Volume> {
    let Some(file) = file_of(name) else {
        bail!("unknown volume '{name}'; known: {}", NAMES.join(", "));
    };
    let mut v = super::load_volume(data_dir.join(file))?;
    v.name = name.to_string();
    Ok(v)
}
