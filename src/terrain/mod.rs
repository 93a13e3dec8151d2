//! Terrain: regular elevation grids and the hybrid model built on them.
//!
//! A [`Heightmap`] is a regular grid of heights (row-major, row 0 first as
//! stored in the file) with a horizontal spacing per axis, read from NumPy
//! `.npy` / `.npz` or single-band GeoTIFF by the readers here. Every reader
//! takes bytes (so the fuzz targets drive them directly) and names the file
//! in every error; sizes are checked before anything is allocated. Samples
//! that are NaN or equal to the file's nodata value are filled with the
//! lowest valid height and counted (`nodata_filled`), so a hole in a DEM is
//! visible in results rather than drawn as a spike; a grid with no valid
//! sample at all is an error.

pub mod datasets;
pub mod geotiff;
pub mod hybrid;
pub mod npy;

use std::path::Path;

use anyhow::{bail, Result};

/// Largest grid side accepted (samples): 16384 keeps a grid of f32 heights
/// within 1 GiB and every index within u32.
pub const MAX_SIDE: usize = 16384;

/// Largest grid accepted (samples, 8192²): every terrain method renders the
/// hybrid model, which holds about 200 bytes per sample (grid and TIN
/// vertices, per-level index lists, their device copies; measured in
/// docs/bad-input.md), so a 16384² grid would need over 50 GB. Checked
/// from the header, before any sample is decoded.
pub const MAX_SAMPLES: usize = 1 << 26;

/// Refuse a grid of `nx` x `ny` samples outside [`MAX_SIDE`] per side or
/// [`MAX_SAMPLES`] in all, naming `file`.
pub fn check_grid(file: &str, nx: usize, ny: usize) -> Result<()> {
    if nx < 2 || ny < 2 {
        bail!("{file}: a height grid needs at least 2x2 samples, got {nx}x{ny}");
    }
    if nx > MAX_SIDE || ny > MAX_SIDE {
        bail!("{file}: a {nx}x{ny} grid exceeds the {MAX_SIDE} samples per side volbench accepts");
    }
    if nx.saturating_mul(ny) > MAX_SAMPLES {
        bail!(
            "{file}: a {nx}x{ny} grid has {} samples, more than the {MAX_SAMPLES} (8192x8192) volbench accepts: the \
             terrain methods' hybrid model holds about 200 bytes per sample ({} GB here); crop or subsample it",
            nx * ny,
            nx * ny * 200 / 1_000_000_000
        );
    }
    Ok(())
}

/// Narrowest horizontal extent of a terrain file accepted, as a fraction
/// of its heights' span (see `check_proportions`).
pub const MIN_WIDTH_PER_HEIGHT: f64 = 1e-3;

/// A regular grid of heights (see the module note).
#[derive(Debug, Clone, PartialEq)]
pub struct Heightmap {
    pub name: String,
    /// Samples along x (columns) and y (rows).
    pub nx: usize,
    pub ny: usize,
    /// Distance between neighbouring samples along x and y (world units).
    pub spacing: [f64; 2],
    /// Heights, `heights[x + nx * y]`, all finite.
    pub heights: Vec<f32>,
    /// Samples that were NaN or nodata and were filled (see the module note).
    pub nodata_filled: usize,
    /// TIN patch outlines in fractions of the domain (simple, disjoint,
    /// inside it); empty: the default corridor and site
    /// (`hybrid::HybridModel::build`). Files never set them; tests do.
    pub patches: Vec<Vec<[f64; 2]>>,
}

impl Heightmap {
    /// Build from samples as f64; `nodata` marks missing samples besides
    /// NaN. Errors name `file`.
    pub fn from_samples(file: &str, nx: usize, ny: usize, samples: &[f64], nodata: Option<f64>, spacing: [f64; 2]) -> Result<Self> {
        Self::from_fn(file, nx, ny, samples.len(), |i| samples[i], nodata, spacing)
    }

    /// [`Heightmap::from_samples`] with sample `i` (of `len`) given by
    /// `sample`: a reader converts from its file's type as the heights are
    /// made, without a second copy of the grid as f64.
    pub fn from_fn(file: &str, nx: usize, ny: usize, len: usize, sample: impl Fn(usize) -> f64, nodata: Option<f64>, spacing: [f64; 2]) -> Result<Self> {
        check_grid(file, nx, ny)?;
        if nx.checked_mul(ny) != Some(len) {
            bail!("{file}: {len} samples for a {nx}x{ny} grid");
        }
        if !spacing.iter().all(|s| s.is_finite() && *s > 0.0) {
            bail!("{file}: grid spacing {spacing:?} must be finite and positive");
        }
        let missing = |v: f64| !v.is_finite() || nodata.is_some_and(|n| v == n);
        let valid = || (0..len).map(&sample).filter(|&v| !missing(v));
        let lowest = valid().fold(f64::INFINITY, f64::min);
        if !lowest.is_finite() {
            bail!("{file}: no valid height (every sample is NaN, infinite or nodata)");
        }
        let highest = valid().fold(f64::NEG_INFINITY, f64::max);
        if lowest < -(f32::MAX as f64) || highest > f32::MAX as f64 {
            bail!("{file}: heights [{lowest}, {highest}] do not fit in 32-bit floats");
        }
        let far = [(nx - 1) as f64 * spacing[0], (ny - 1) as f64 * spacing[1], highest];
        crate::mesh::geometry::check_box(file, "terrain", [0.0, 0.0, lowest], far)?;
        let mut filled = 0;
        let heights = (0..len)
            .map(&sample)
            .map(|v| {
                if missing(v) {
                    filled += 1;
                    lowest as f32
                } else {
                    v as f32
                }
            })
            .collect();
        Ok(Heightmap { name: file.to_string(), nx, ny, spacing, heights, nodata_filled: filled, patches: Vec::new() })
    }

    pub fn height(&self, x: usize, y: usize) -> f32 {
        self.heights[x + self.nx * y]
    }

    /// Lowest and highest height.
    pub fn range(&self) -> (f64, f64) {
        let lo = self.heights.iter().copied().fold(f32::INFINITY, f32::min) as f64;
        let hi = self.heights.iter().copied().fold(f32::NEG_INFINITY, f32::max) as f64;
        (lo, hi)
    }

    /// World extent along x and y (sample 0 at the origin).
    pub fn extent(&self) -> [f64; 2] {
        [(self.nx - 1) as f64 * self.spacing[0], (self.ny - 1) as f64 * self.spacing[1]]
    }
}

/// The elevation formats, by file extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Npy,
    Npz,
    GeoTiff,
}

/// The elevation format `bytes` start like, if any.
pub fn sniff(bytes: &[u8]) -> Option<Format> {
    if bytes.starts_with(b"\x93NUMPY") {
        Some(Format::Npy)
    } else if bytes.starts_with(b"PK\x03\x04") || bytes.starts_with(b"PK\x05\x06") {
        Some(Format::Npz)
    } else if bytes.starts_with(b"II*\0") || bytes.starts_with(b"MM\0*") || bytes.starts_with(b"II+\0") || bytes.starts_with(b"MM\0+") {
        Some(Format::GeoTiff)
    } else {
        None
    }
}

pub fn format_of_extension(path: &Path) -> Option<Format> {
    let ext = path.extension()?.to_str()?.to_ascii_lowercase();
    match ext.as_str() {
        "npy" => Some(Format::Npy),
        "npz" => Some(Format::Npz),
        "tif" | "tiff" => Some(Format::GeoTiff),
        _ => None,
    }
}

/// Largest elevation file read (bytes).
pub const MAX_FILE_BYTES: u64 = crate::fsio::MAX_INPUT_BYTES;

/// Read an elevation grid; `array` picks the array of an `.npz` by name.
pub fn load_heightmap(path: &Path, array: Option<&str>) -> Result<Heightmap> {
    let name = path.display().to_string();
    let bytes = crate::fsio::read_input(path, "elevation grid", MAX_FILE_BYTES)?;
    // The content first: an extension may lie.
    let Some(format) = sniff(&bytes).or_else(|| format_of_extension(path)) else {
        bail!("{name}: not an elevation grid (expected NumPy .npy, .npz or GeoTIFF .tif/.tiff content)");
    };
    if array.is_some() && format != Format::Npz {
        bail!("{name}: an array name can only be given for an .npz archive");
    }
    let mut map = match format {
        Format::Npy => npy::parse_npy_heightmap(&name, &bytes)?,
        Format::Npz => npy::parse_npz_heightmap(&name, &bytes, array)?,
        Format::GeoTiff => geotiff::parse_geotiff_bytes(&name, &bytes)?,
    };
    check_proportions(&name, &map)?;
    map.name = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or(name);
    Ok(map)
}

/// Seen from above (the fly-over), a grid far narrower than its heights'
/// span is a needle of a pixel or none (1/300 of the span drew 2 pixels of
/// 16x16, 1/1000 none): refused, naming the likely cause. Checked on files
/// as given (the shipped grid's spacing is in degrees until its loader
/// turns it into metres).
fn check_proportions(file: &str, map: &Heightmap) -> Result<()> {
    let [ex, ey] = map.extent();
    let (lo, hi) = map.range();
    let narrow = ex.min(ey);
    if narrow < MIN_WIDTH_PER_HEIGHT * (hi - lo) {
        bail!(
            "{file}: the terrain is {narrow:e} wide (spacing {:?}) but its heights span {:e}: narrower than \
             {MIN_WIDTH_PER_HEIGHT} of that span, seen from above it would cover a pixel or none; check its spacing \
             (degrees with heights in metres?)",
            map.spacing,
            hi - lo
        );
    }
    Ok(())
}
