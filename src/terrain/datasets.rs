//! The elevation grid shipped in `data/terrain/` (provenance in
//! `data/README.md`), by name: `jacksboro`, the USGS model of the Jacksboro
//! fault as packaged by matplotlib. Its spacing is in degrees; here it is
//! turned into metres at the grid's mean latitude (so heights and
//! distances share a unit) and its rows, stored north to south, are turned
//! so that +y is north (x east, y north, z up: a right-handed world).

use std::path::Path;

use anyhow::{bail, Context as _, Result};

use super::Heightmap;

/// The names [`load_named`] accepts.
pub const NAMES: [&str; 1] = ["jacksboro"];

pub const JACKSBORO: &str = "terrain/jacksboro_fault_dem.npz";

/// Metres per degree of latitude, and of longitude at the equator (WGS84,
/// rounded: the spacing needs three significant digits, not geodesy).
const M_PER_DEG_LAT: f64 = 110_574.0;
const M_PER_DEG_LON: f64 = 111_320.0;

pub fn file_of(name: &str) -> Option<&'static str> {
    (name == "jacksboro").then_some(JACKSBORO)
}

pub fn load_named(name: &str, data_dir: &Path) -> Result<Heightmap> {
    let Some(file) = file_of(name) else {
        bail!("unknown terrain '{name}'; known: {}", NAMES.join(", "));
    };
    let path = data_dir.join(file);
    let label = path.display().to_string();
    let bytes = crate::fsio::read_input(&path, "elevation grid", super::MAX_FILE_BYTES)?;
    let (mut map, s) = super::npy::parse_npz_grid(&label, &bytes, Some("elevation"))?;
    let get = |k: &str| s.get(k).copied().with_context(|| format!("{label}: no scalar '{k}'"));
    let (dx, dy, ymin, ymax) = (get("dx")?, get("dy")?, get("ymin")?, get("ymax")?);
    let lat = (0.5 * (ymin + ymax)).to_radians();
    map.spacing = [dx.abs() * M_PER_DEG_LON * lat.cos(), dy.abs() * M_PER_DEG_LAT];
    if ymin > ymax {
        // Stored north to south: turn the rows so y grows northwards.
        let nx = map.nx;
        let rows: Vec<Vec<f32>> = map.heights.chunks_exact(nx).rev().map(<[f32]>::to_vec).collect();
        map.heights = rows.concat();
    }
    map.name = name.to_string();
    Ok(map)
}
