//! Regular-grid volumes: the data type every volume method reads, and the
//! readers that make one from a file.
//!
//! A [`Volume`] is a 3D grid of scalar samples, x fastest, kept in the type
//! the file stores (`u8`, `i16`, `u16` or `f32`: a 256³ CT stays 16 MiB of
//! bytes, not 64 MiB of floats) with its spacing (anisotropic: the shipped
//! chest CT is 1.8× thicker along z), origin and value range. A volume is
//! checked once, when it is made ([`Volume::new`]): dims within limits and
//! matching the sample count, spacing positive and finite, every float sample
//! finite. Code that holds a `Volume` can rely on all of it.
//!
//! Readers, one module per format, each with a path loader that reads through
//! [`crate::fsio::read_input`] and a byte-level parser (fuzzed, see
//! `fuzz/README.md`): [`nrrd`], [`vti`] (VTK XML ImageData), [`vtk_sp`] (VTK
//! legacy `STRUCTURED_POINTS`), [`nifti`] (NIfTI-1) and [`metaimage`]
//! (ITK's MetaImage, `.mhd`/`.mha`). [`load_volume`] picks
//! one by extension and magic. Shared decoding (sample types, byte order,
//! ASCII values, bounded decompression) lives in `decode`. Every error starts
//! with the file name; sizes from headers are checked, with checked
//! arithmetic, against the limits here and against the bytes present before
//! anything is allocated from them.
//!
//! Nothing here knows about Vulkan.

pub(crate) mod decode;
pub mod datasets;
pub mod metaimage;
pub mod nifti;
pub mod nrrd;
pub mod vti;
pub mod vtk_sp;

use std::path::Path;

use anyhow::{anyhow, bail, Result};

use crate::mesh::Bounds;

/// Largest size along any axis (larger than any GPU's 3D image limit, far
/// smaller than what an absurd header can claim).
pub const MAX_AXIS: usize = 1 << 16;
/// Largest number of samples in a volume (2 Gi: 8 GiB as `f32`).
pub const MAX_VOXELS: usize = 1 << 31;

/// The sample type a volume keeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
pub enum SampleType {
    U8,
    I16,
    U16,
    F32,
}

impl SampleType {
    /// Bytes per sample.
    pub fn size(self) -> usize {
        match self {
            SampleType::U8 => 1,
            SampleType::I16 | SampleType::U16 => 2,
            SampleType::F32 => 4,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            SampleType::U8 => "uint8",
            SampleType::I16 => "int16",
            SampleType::U16 => "uint16",
            SampleType::F32 => "float32",
        }
    }
}

/// A volume's samples in their native type, x fastest, then y, then z.
#[derive(Debug, Clone, PartialEq)]
pub enum Samples {
    U8(Vec<u8>),
    I16(Vec<i16>),
    U16(Vec<u16>),
    F32(Vec<f32>),
}

impl Samples {
    pub fn len(&self) -> usize {
        match self {
            Samples::U8(v) => v.len(),
            Samples::I16(v) => v.len(),
            Samples::U16(v) => v.len(),
            Samples::F32(v) => v.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn sample_type(&self) -> SampleType {
        match self {
            Samples::U8(_) => SampleType::U8,
            Samples::I16(_) => SampleType::I16,
            Samples::U16(_) => SampleType::U16,
            Samples::F32(_) => SampleType::F32,
        }
    }

    /// Sample `index` as f64 (exact for every type), or `None` past the end.
    pub fn get(&self, index: usize) -> Option<f64> {
        match self {
            Samples::U8(v) => v.get(index).map(|&x| x as f64),
            Samples::I16(v) => v.get(index).map(|&x| x as f64),
            Samples::U16(v) => v.get(index).map(|&x| x as f64),
            Samples::F32(v) => v.get(index).map(|&x| x as f64),
        }
    }

    /// Keeps the first `n` samples and gives the rest's memory back (a
    /// method releasing what it has copied to the device, from the end).
    pub fn truncate(&mut self, n: usize) {
        fn go<T>(v: &mut Vec<T>, n: usize) {
            v.truncate(n);
            v.shrink_to_fit();
        }
        match self {
            Samples::U8(v) => go(v, n),
            Samples::I16(v) => go(v, n),
            Samples::U16(v) => go(v, n),
            Samples::F32(v) => go(v, n),
        }
    }

    /// The samples' bytes as they are in memory (native byte order).
    pub fn as_bytes(&self) -> &[u8] {
        match self {
            Samples::U8(v) => v,
            Samples::I16(v) => bytemuck::cast_slice(v),
            Samples::U16(v) => bytemuck::cast_slice(v),
            Samples::F32(v) => bytemuck::cast_slice(v),
        }
    }

    /// All samples as f32 (exact for every type).
    pub fn to_f32(&self) -> Vec<f32> {
        match self {
            Samples::U8(v) => v.iter().map(|&x| x as f32).collect(),
            Samples::I16(v) => v.iter().map(|&x| x as f32).collect(),
            Samples::U16(v) => v.iter().map(|&x| x as f32).collect(),
            Samples::F32(v) => v.clone(),
        }
    }

    /// Index of the first NaN or infinite sample.
    fn first_non_finite(&self) -> Option<usize> {
        match self {
            Samples::F32(v) => v.iter().position(|x| !x.is_finite()),
            _ => None,
        }
    }

    /// (min, max) of non-empty, finite samples.
    fn min_max(&self) -> (f64, f64) {
        fn mm<T: Copy + PartialOrd + Into<f64>>(v: &[T]) -> (f64, f64) {
            let Some(&first) = v.first() else { return (0.0, 0.0) };
            let (mut lo, mut hi) = (first, first);
            for &x in v {
                if x < lo {
                    lo = x;
                }
                if x > hi {
                    hi = x;
                }
            }
            (lo.into(), hi.into())
        }
        match self {
            Samples::U8(v) => mm(v),
            Samples::I16(v) => mm(v),
            Samples::U16(v) => mm(v),
            Samples::F32(v) => mm(v),
        }
    }
}

/// A regular grid of scalar samples in world space: sample (i, j, k) sits at
/// `origin + (i, j, k) * spacing` (axis-aligned; spacing per axis).
#[derive(Debug, Clone, PartialEq)]
pub struct Volume {
    /// Short name (dataset name or file stem) used in results.
    pub name: String,
    dims: [usize; 3],
    spacing: [f64; 3],
    origin: [f64; 3],
    samples: Samples,
    range: (f64, f64),
}

impl Volume {
    /// A checked volume. `source` (the file) starts every error: dims must
    /// pass [`check_dims`] and match the sample count, spacing must be
    /// positive and finite, the origin finite, and every float sample finite
    /// (the first bad index is named).
    pub fn new(
        source: &str,
        name: impl Into<String>,
        dims: [usize; 3],
        spacing: [f64; 3],
        origin: [f64; 3],
        samples: Samples,
    ) -> Result<Volume> {
        let dims = check_dims(source, dims.map(|d| d as u64))?;
        let n = dims[0] * dims[1] * dims[2];
        if samples.len() != n {
            bail!(
                "{source}: {} samples for a {}x{}x{} grid ({n} needed)",
                samples.len(),
                dims[0],
                dims[1],
                dims[2]
            );
        }
        for (a, &s) in spacing.iter().enumerate() {
            if !(s.is_finite() && s > 0.0) {
                bail!("{source}: spacing {s} along {} must be positive and finite", AXES[a]);
            }
        }
        if let Some(a) = origin.iter().position(|o| !o.is_finite()) {
            bail!("{source}: origin {} along {} is not finite", origin[a], AXES[a]);
        }
        let far = std::array::from_fn(|a| origin[a] + spacing[a] * (dims[a].max(2) - 1) as f64);
        crate::mesh::geometry::check_box(source, "volume", origin, far)?;
        if let Some(i) = samples.first_non_finite() {
            let v = samples.get(i).unwrap_or(f64::NAN);
            let (x, y, z) = (i % dims[0], i / dims[0] % dims[1], i / (dims[0] * dims[1]));
            bail!("{source}: sample {i} (i={x}, j={y}, k={z}) is {v}; float samples must be finite");
        }
        let range = samples.min_max();
        Ok(Volume { name: name.into(), dims, spacing, origin, samples, range })
    }

    /// Samples along x, y, z.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// World distance between neighbouring samples along x, y, z (positive).
    pub fn spacing(&self) -> [f64; 3] {
        self.spacing
    }

    /// World position of sample (0, 0, 0).
    pub fn origin(&self) -> [f64; 3] {
        self.origin
    }

    pub fn samples(&self) -> &Samples {
        &self.samples
    }

    pub fn into_samples(self) -> Samples {
        self.samples
    }

    /// Moves the samples out, leaving none of the same type: for their last
    /// reader (a single run's method, which gives them back to the system
    /// as it copies them to the device). The grid (dims, spacing, origin,
    /// range, [`Volume::len`]) stays; sample reads ([`Volume::get`]) find
    /// nothing after.
    pub fn take_samples(&mut self) -> Samples {
        let empty = match self.samples {
            Samples::U8(_) => Samples::U8(Vec::new()),
            Samples::I16(_) => Samples::I16(Vec::new()),
            Samples::U16(_) => Samples::U16(Vec::new()),
            Samples::F32(_) => Samples::F32(Vec::new()),
        };
        std::mem::replace(&mut self.samples, empty)
    }

    /// Puts back samples [`Volume::take_samples`] took, unused (a method
    /// that failed before reading them). Others are ignored: a caller's bug.
    pub fn give_samples_back(&mut self, samples: Samples) {
        if samples.len() == self.len() && samples.sample_type() == self.sample_type() {
            self.samples = samples;
        }
    }

    pub fn sample_type(&self) -> SampleType {
        self.samples.sample_type()
    }

    /// Number of samples of the grid (also after [`Volume::take_samples`]).
    pub fn len(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// Never true (a volume has at least one sample); for clippy's sake.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Bytes of the samples in their native type.
    pub fn byte_size(&self) -> usize {
        self.len() * self.sample_type().size()
    }

    /// (min, max) sample value.
    pub fn range(&self) -> (f64, f64) {
        self.range
    }

    /// Linear index of sample (i, j, k), or `None` outside the grid.
    pub fn index(&self, i: usize, j: usize, k: usize) -> Option<usize> {
        let [nx, ny, nz] = self.dims;
        (i < nx && j < ny && k < nz).then(|| i + nx * (j + ny * k))
    }

    /// Sample (i, j, k) as f64, or `None` outside the grid.
    pub fn get(&self, i: usize, j: usize, k: usize) -> Option<f64> {
        self.index(i, j, k).and_then(|n| self.samples.get(n))
    }

    /// Sample (i, j, k) as f64. Panics outside the grid, as slice indexing
    /// does (a caller's bug, never bad input); see [`Volume::get`].
    pub fn value(&self, i: usize, j: usize, k: usize) -> f64 {
        match self.get(i, j, k) {
            Some(v) => v,
            None => panic!("sample ({i}, {j}, {k}) is outside the {:?} grid of volume '{}' (or its samples were taken)", self.dims, self.name),
        }
    }

    /// World position of sample (i, j, k) (any indices, also outside).
    pub fn position(&self, i: usize, j: usize, k: usize) -> [f64; 3] {
        let ijk = [i, j, k];
        std::array::from_fn(|a| self.origin[a] + ijk[a] as f64 * self.spacing[a])
    }

    /// World bounds of the sample positions (the first to the last sample).
    pub fn bounds(&self) -> Bounds {
        Bounds { min: self.origin, max: self.position(self.dims[0] - 1, self.dims[1] - 1, self.dims[2] - 1) }
    }

    /// All samples as f32 (exact for every sample type).
    pub fn to_f32(&self) -> Vec<f32> {
        self.samples.to_f32()
    }
}

const AXES: [&str; 3] = ["x", "y", "z"];

/// Checks header dims before anything is allocated from them: each at least
/// 1 and at most [`MAX_AXIS`], and their product at most [`MAX_VOXELS`].
/// The fields of a text header (MetaImage, NRRD), each with its value and
/// header line, keyed by the format's field name; `name` is the file's, for
/// errors.
pub(crate) struct Header<'h, K> {
    pub name: &'h str,
    pub fields: std::collections::HashMap<K, (&'h str, usize)>,
}

impl<'h, K: std::borrow::Borrow<str> + std::hash::Hash + Eq> Header<'h, K> {
    pub fn get(&self, f: &str) -> Option<&'h str> {
        self.fields.get(f).map(|&(v, _)| v)
    }

    pub fn need(&self, f: &str) -> Result<&'h str> {
        self.get(f).ok_or_else(|| anyhow!("{}: the required field '{f}' is missing", self.name))
    }
}

pub fn check_dims(source: &str, dims: [u64; 3]) -> Result<[usize; 3]> {
    for (a, &d) in dims.iter().enumerate() {
        if d == 0 {
            bail!("{source}: size 0 along {}: a volume needs at least one sample per axis", AXES[a]);
        }
        if d > MAX_AXIS as u64 {
            bail!("{source}: absurd size {d} along {} (the limit is {MAX_AXIS})", AXES[a]);
        }
    }
    let n = dims.iter().try_fold(1u64, |acc, &d| acc.checked_mul(d));
    match n {
        Some(n) if n <= MAX_VOXELS as u64 => Ok(dims.map(|d| d as usize)),
        _ => bail!(
            "{source}: {}x{}x{} samples is more than the limit of {MAX_VOXELS}",
            dims[0],
            dims[1],
            dims[2]
        ),
    }
}

/// A volume from a grid whose index axes step by `steps[a]` in world space
/// (a NRRD's `space directions`, a VTI's `Direction` times `Spacing`) and
/// whose sample (0, 0, 0) is at `origin`. The steps must be axis-aligned and
/// in order (axis a along world axis a); a negative step is undone by
/// reversing the samples along that axis and moving the origin to what was
/// the last sample, so that the volume's spacing is positive.
fn from_steps(
    source: &str,
    name: String,
    dims: [usize; 3],
    steps: [[f64; 3]; 3],
    mut origin: [f64; 3],
    mut samples: Samples,
) -> Result<Volume> {
    let mut spacing = [0.0; 3];
    for a in 0..3 {
        let d = steps[a][a];
        let off = (0..3).filter(|&b| b != a).map(|b| steps[a][b].abs()).fold(0.0, f64::max);
        if steps[a].iter().any(|s| !s.is_finite()) || (d == 0.0 && off == 0.0) {
            bail!(
                "{source}: index axis {a} steps by ({}, {}, {}) in world space: the spacing along {} must be \
                 finite and non-zero",
                steps[a][0],
                steps[a][1],
                steps[a][2],
                AXES[a]
            );
        }
        if off > 1e-6 * d.abs() {
            bail!(
                "{source}: index axis {a} steps by ({}, {}, {}) in world space: only axis-aligned grids \
                 (a diagonal direction matrix, axis {a} along {}) are supported",
                steps[a][0],
                steps[a][1],
                steps[a][2],
                AXES[a]
            );
        }
        spacing[a] = d.abs();
        if d < 0.0 {
            origin[a] += (dims[a] - 1) as f64 * d;
            flip(&mut samples, dims, a);
        }
    }
    Volume::new(source, name, dims, spacing, origin, samples)
}

/// Reverses `samples` (of `dims`) along `axis`.
fn flip(samples: &mut Samples, dims: [usize; 3], axis: usize) {
    fn go<T>(v: &mut [T], dims: [usize; 3], axis: usize) {
        let [nx, ny, nz] = dims;
        if v.len() != nx * ny * nz {
            return;
        }
        let idx = |i: usize, j: usize, k: usize| i + nx * (j + ny * k);
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let (m, half) = match axis {
                        0 => (idx(nx - 1 - i, j, k), i < nx / 2),
                        1 => (idx(i, ny - 1 - j, k), j < ny / 2),
                        _ => (idx(i, j, nz - 1 - k), k < nz / 2),
                    };
                    if half {
                        v.swap(idx(i, j, k), m);
                    }
                }
            }
        }
    }
    match samples {
        Samples::U8(v) => go(v, dims, axis),
        Samples::I16(v) => go(v, dims, axis),
        Samples::U16(v) => go(v, dims, axis),
        Samples::F32(v) => go(v, dims, axis),
    }
}

/// What a reader calls to read a data file named by the header at
/// `header` (a NRRD's `data file`, a MetaImage's `ElementDataFile`): the
/// name as written, relative to the header's directory, read through
/// [`crate::fsio::read_input`] (a regular file within its cap; `what` names
/// it in errors).
pub fn data_file_loader(header: &Path, what: &'static str) -> impl FnMut(&str) -> Result<Vec<u8>> {
    let dir = match header.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => Path::new(".").to_path_buf(),
    };
    move |file: &str| crate::fsio::read_input(&dir.join(file), what, crate::fsio::MAX_INPUT_BYTES)
}

/// The file name without its extension (both of `.nii.gz`), naming a volume.
fn stem_of(name: &str) -> String {
    let file = Path::new(name).file_name().map_or_else(|| name.to_string(), |f| f.to_string_lossy().into_owned());
    let lower = file.to_ascii_lowercase();
    let cut = if lower.ends_with(".nii.gz") {
        file.len() - 7
    } else {
        file.rfind('.').filter(|&i| i > 0).unwrap_or(file.len())
    };
    file[..cut].to_string()
}

/// The formats [`load_volume`] reads, for messages.
pub const SUPPORTED_FORMATS: &str = "NRRD (.nrrd, .nhdr: raw, gzip or ascii; uint8, int16, uint16, float32, int8, int32), \
     VTK XML ImageData (.vti: ascii, binary or appended data, zlib or uncompressed), \
     VTK legacy STRUCTURED_POINTS (.vtk: ASCII or BINARY), NIfTI-1 (.nii, .nii.gz) and \
     MetaImage (.mha, .mhd with a data file, list or pattern: raw, zlib or ascii; MET_UCHAR, MET_CHAR, MET_USHORT, \
     MET_SHORT, MET_UINT, MET_INT, MET_FLOAT, MET_DOUBLE)";

/// The file formats a volume can come in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Nrrd,
    Vti,
    VtkLegacy,
    Nifti,
    MetaImage,
}

/// The format `bytes` start like, if any.
pub fn sniff(bytes: &[u8]) -> Option<Format> {
    let start = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let first = start.iter().position(|c| !c.is_ascii_whitespace()).map_or(&[][..], |i| &start[i..]);
    if bytes.starts_with(b"NRRD000") {
        Some(Format::Nrrd)
    } else if bytes.starts_with(b"# vtk DataFile") {
        Some(Format::VtkLegacy)
    } else if first.starts_with(b"<?xml") || first.starts_with(b"<VTKFile") {
        Some(Format::Vti)
    } else if nifti::is_nifti(bytes) || (bytes.starts_with(&[0x1f, 0x8b]) && gzip_holds_nifti(bytes)) {
        Some(Format::Nifti)
    } else if metaimage::is_metaimage(bytes) {
        Some(Format::MetaImage)
    } else {
        None
    }
}

/// Whether a gzip stream starts with a NIfTI-1 header (a `.nii.gz` under
/// another name): only the header's 348 bytes are inflated.
fn gzip_holds_nifti(bytes: &[u8]) -> bool {
    crate::bytes::inflate::gunzip_prefix("", "", bytes, 348).is_ok_and(|h| nifti::is_nifti(&h))
}

/// The format a file name's extension says, if any.
pub fn format_of_extension(path: &Path) -> Option<Format> {
    let file = path.file_name()?.to_string_lossy().to_ascii_lowercase();
    let ext = file.rsplit('.').next()?;
    if file.ends_with(".nii.gz") || ext == "nii" {
        return Some(Format::Nifti);
    }
    match ext {
        "nrrd" | "nhdr" => Some(Format::Nrrd),
        "vti" => Some(Format::Vti),
        "vtk" => Some(Format::VtkLegacy),
        "mha" | "mhd" => Some(Format::MetaImage),
        _ => None,
    }
}

/// Reads a volume file, choosing the reader by its magic bytes (a file that
/// starts like one of the formats is read as that format whatever its name)
/// or, failing that, by its extension (whose reader then names the wrong
/// magic). An unsupported file is an error naming it and listing
/// [`SUPPORTED_FORMATS`]. VTI files give their first one-component point
/// array (see [`vti`]).
pub fn load_volume(path: impl AsRef<Path>) -> Result<Volume> {
    let path = path.as_ref();
    let name = path.display().to_string();
    let by_ext = format_of_extension(path);
    let unsupported = || {
        let file = path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
        let ext = file.rfind('.').filter(|&i| i > 0).map_or("none".to_string(), |i| file[i..].to_string());
        anyhow!("{name}: unsupported volume format (extension {ext}); supported: {SUPPORTED_FORMATS}")
    };
    if by_ext.is_none() && crate::fsio::check_input(path, "volume", crate::fsio::MAX_INPUT_BYTES).is_err() {
        return Err(unsupported());
    }
    let bytes = crate::fsio::read_input(path, "volume", crate::fsio::MAX_INPUT_BYTES)?;
    match sniff(&bytes).or(by_ext) {
        Some(Format::Nrrd) => nrrd::parse_nrrd_bytes(&name, &bytes, &mut nrrd::data_file_loader(path)),
        Some(Format::Vti) => vti::parse_vti_bytes(&name, &bytes, None),
        Some(Format::VtkLegacy) => vtk_sp::parse_structured_points_bytes(&name, &bytes),
        Some(Format::Nifti) => nifti::parse_nifti_bytes(&name, &bytes),
        Some(Format::MetaImage) => {
            metaimage::parse_metaimage_bytes(&name, &bytes, &mut data_file_loader(path, "MetaImage data file"))
        }
        None => Err(unsupported()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(dims: [usize; 3]) -> Samples {
        Samples::I16((0..dims.iter().product::<usize>() as i16).collect())
    }

    #[test]
    fn accessors_and_bounds() {
        let v = Volume::new("t", "t", [2, 3, 4], [1.0, 0.5, 2.5], [1.0, 2.0, 3.0], ramp([2, 3, 4])).unwrap();
        assert_eq!(v.len(), 24);
        assert_eq!(v.byte_size(), 48);
        assert_eq!(v.range(), (0.0, 23.0));
        assert_eq!(v.value(1, 2, 3), (1 + 2 * 2 + 6 * 3) as f64);
        assert_eq!(v.get(2, 0, 0), None);
        assert_eq!(v.index(1, 1, 1), Some(1 + 2 + 6));
        let b = v.bounds();
        assert_eq!((b.min, b.max), ([1.0, 2.0, 3.0], [2.0, 3.0, 10.5]));
        assert_eq!(v.to_f32()[23], 23.0);
        assert_eq!(v.sample_type(), SampleType::I16);
    }

    #[test]
    fn new_checks_everything() {
        let e = |r: Result<Volume>| format!("{:#}", r.unwrap_err());
        let s = ramp([2, 2, 2]);
        assert!(e(Volume::new("f.x", "f", [2, 2, 3], [1.0; 3], [0.0; 3], s.clone())).contains("8 samples for a 2x2x3"));
        assert!(e(Volume::new("f.x", "f", [2, 2, 2], [1.0, 0.0, 1.0], [0.0; 3], s.clone())).contains("spacing 0 along y"));
        assert!(e(Volume::new("f.x", "f", [2, 2, 2], [1.0; 3], [0.0, 0.0, f64::NAN], s)).contains("origin NaN along z"));
        let mut f = vec![0.5f32; 8];
        f[5] = f32::INFINITY;
        let m = e(Volume::new("f.x", "f", [2, 2, 2], [1.0; 3], [0.0; 3], Samples::F32(f)));
        assert!(m.starts_with("f.x: sample 5 (i=1, j=0, k=1) is inf"), "{m}");
        assert!(e(Volume::new("f.x", "f", [0, 2, 2], [1.0; 3], [0.0; 3], Samples::U8(vec![]))).contains("size 0 along x"));
        assert!(check_dims("f", [65537, 1, 1]).unwrap_err().to_string().contains("absurd size 65537 along x"));
        assert!(check_dims("f", [65536, 65536, 65536]).unwrap_err().to_string().contains("more than the limit"));
        assert!(check_dims("f", [u64::MAX, u64::MAX, u64::MAX]).is_err());
    }

    #[test]
    fn negative_steps_flip_and_skew_is_refused() {
        let dims = [2, 3, 2];
        let steps = [[-1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, -0.5]];
        let v = from_steps("t", "t".into(), dims, steps, [10.0, 0.0, 5.0], ramp(dims)).unwrap();
        assert_eq!(v.spacing(), [1.0, 2.0, 0.5]);
        assert_eq!(v.origin(), [9.0, 0.0, 4.5]);
        // Sample (0,0,0) now is the file's (1,0,1) = 1 + 6 = 7, at the same world place.
        assert_eq!(v.value(0, 0, 0), 7.0);
        assert_eq!(v.value(1, 2, 1), 4.0);
        let skew = [[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let e = from_steps("t.nrrd", "t".into(), dims, skew, [0.0; 3], ramp(dims)).unwrap_err().to_string();
        assert!(e.contains("t.nrrd") && e.contains("axis-aligned"), "{e}");
    }

    #[test]
    fn names_and_formats() {
        assert_eq!(stem_of("/a/b/head.nii.gz"), "head");
        assert_eq!(stem_of("x.nhdr"), "x");
        assert_eq!(stem_of(".hidden"), ".hidden");
        assert_eq!(format_of_extension(Path::new("a.NII.GZ")), Some(Format::Nifti));
        assert_eq!(format_of_extension(Path::new("a.slc")), None);
        assert_eq!(format_of_extension(Path::new("a.MHD")), Some(Format::MetaImage));
        assert_eq!(sniff(b"ObjectType = Image\nNDims = 3\n"), Some(Format::MetaImage));
        let e = load_volume("/nonexistent/brain.slc").unwrap_err().to_string();
        assert!(e.contains("brain.slc") && e.contains(".slc") && e.contains("NRRD") && e.contains(".nii.gz"), "{e}");
        assert!(e.contains("MetaImage (.mha, .mhd"), "{e}");
    }
}
