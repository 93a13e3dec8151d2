//! NIfTI-1 reader: single-file `.nii`, and `.nii.gz` (gzip of the same).
//!
//! The 348-byte header in either byte order (found from `sizeof_hdr`);
//! datatypes uint8, int16, uint16, float32 (int8 and int32 convert, see
//! `decode`); 3D only (`dim[0]` 3, or up to 7 with every extra dimension 1);
//! the data at `vox_offset`, which must hold exactly the grid's bytes.
//! `scl_slope`/`scl_inter` are applied when they change anything (slope 0
//! means "no scaling", as the standard says): the samples then become
//! float32; otherwise they keep their type.
//!
//! Placement: the voxel size is the scaling of the file's transform (the
//! column lengths of the sform when `sform_code > 0`, else `pixdim[1..3]`)
//! and the origin its translation (the sform's last column, else the qform's
//! `qoffset`, else 0). Rotations and flips of the transform are not applied:
//! the grid is placed axis-aligned, in index order. Spacing is in the file's
//! units (`xyzt_units`, usually mm).
//!
//! A `.nii.gz` is decompressed in two steps: the header first, then the whole
//! stream bounded by the `vox_offset + data` bytes that header promises.

use anyhow::{anyhow, bail, Result};
use std::path::Path;

use super::decode::{byte_len, decode_binary, RawType};
use crate::bytes::inflate::{gunzip_prefix, inflate_after, Wrapper};
use crate::bytes::Endian;
use super::{check_dims, stem_of, Samples, Volume, AXES};

/// Size of a NIfTI-1 header.
pub const HEADER_BYTES: usize = 348;

/// Reads a `.nii` or `.nii.gz` file.
pub fn read_nifti(path: impl AsRef<Path>) -> Result<Volume> {
    let path = path.as_ref();
    let bytes = crate::fsio::read_input(path, "NIfTI file", crate::fsio::MAX_INPUT_BYTES)?;
    parse_nifti_bytes(&path.display().to_string(), &bytes)
}

/// Whether `bytes` start with an uncompressed NIfTI-1 header.
pub fn is_nifti(bytes: &[u8]) -> bool {
    bytes.len() >= HEADER_BYTES
        && (bytes[..4] == 348i32.to_le_bytes() || bytes[..4] == 348i32.to_be_bytes())
        && (&bytes[344..348] == b"n+1\0" || &bytes[344..348] == b"ni1\0")
}

/// The fields volbench uses.
struct Header {
    endian: Endian,
    ty: RawType,
    dims: [usize; 3],
    vox_offset: usize,
    /// (slope, intercept), `None` when they change nothing.
    scale: Option<(f64, f64)>,
    spacing: [f64; 3],
    origin: [f64; 3],
}

/// The header's bytes read in its byte order.
struct Fields<'a> {
    b: &'a [u8],
    endian: Endian,
}

impl Fields<'_> {
    fn i16_at(&self, o: usize) -> i16 {
        self.endian.read::<i16>(&self.b[o..])
    }

    fn f32_at(&self, o: usize) -> f32 {
        self.endian.read::<f32>(&self.b[o..])
    }
}

impl Header {
    fn parse(name: &str, b: &[u8]) -> Result<Header> {
        let h = Fields { b, endian: byte_order(name, b)? };
        let dims = dims(name, &h)?;
        let ty = sample_type(name, h.i16_at(70), h.i16_at(72))?;
        let vox = h.f32_at(108);
        if !(vox.is_finite() && vox >= HEADER_BYTES as f32 && vox.fract() == 0.0 && vox < 1e15) {
            bail!("{name}: bad vox_offset {vox}: it must be a whole number of bytes, at least {HEADER_BYTES}");
        }
        let scale = scaling(name, h.f32_at(112), h.f32_at(116))?;
        let (spacing, origin) = placement(name, &h)?;
        Ok(Header { endian: h.endian, ty, dims, vox_offset: vox as usize, scale, spacing, origin })
    }
}

/// The header's byte order, from `sizeof_hdr` (348), after checking the
/// length and the single-file magic.
fn byte_order(name: &str, b: &[u8]) -> Result<Endian> {
    if b.len() < HEADER_BYTES {
        bail!("{name}: truncated: {} bytes, shorter than the {HEADER_BYTES}-byte NIfTI-1 header", b.len());
    }
    let sizeof_hdr = |e: Endian| e.read::<i32>(b);
    let endian = if sizeof_hdr(Endian::Little) == 348 {
        Endian::Little
    } else if sizeof_hdr(Endian::Big) == 348 {
        Endian::Big
    } else if sizeof_hdr(Endian::Little) == 540 || sizeof_hdr(Endian::Big) == 540 {
        bail!("{name}: a NIfTI-2 file (sizeof_hdr 540); only NIfTI-1 is supported");
    } else {
        bail!("{name}: not a NIfTI-1 file (sizeof_hdr is neither 348 little- nor big-endian)");
    };
    match &b[344..348] {
        b"n+1\0" => {}
        b"ni1\0" => bail!("{name}: the header of a .hdr/.img pair (magic 'ni1'); only single-file .nii is supported"),
        m => bail!("{name}: bad NIfTI-1 magic {:?}, expected \"n+1\\0\"", String::from_utf8_lossy(m)),
    }
    Ok(endian)
}

/// The three dimensions of a 3D volume (`dim`; further ones must be 1).
fn dims(name: &str, h: &Fields) -> Result<[usize; 3]> {
    let dim: [i16; 8] = std::array::from_fn(|i| h.i16_at(40 + 2 * i));
    let ndim = dim[0];
    if !(1..=7).contains(&ndim) {
        bail!("{name}: bad dim[0] {ndim}: it must be 1 to 7");
    }
    if ndim < 3 {
        bail!("{name}: a {ndim}D image: only 3D volumes are supported");
    }
    for (i, &d) in dim.iter().enumerate().take(ndim as usize + 1).skip(4) {
        if d != 1 {
            bail!("{name}: dim[{i}] is {d}: only 3D volumes (further dimensions of size 1) are supported");
        }
    }
    let mut d = [0u64; 3];
    for a in 0..3 {
        d[a] = u64::try_from(dim[a + 1]).map_err(|_| anyhow!("{name}: dim[{}] is {}", a + 1, dim[a + 1]))?;
    }
    check_dims(name, d)
}

/// The sample type of `datatype` `code`, checked against `bitpix`.
fn sample_type(name: &str, code: i16, bitpix: i16) -> Result<RawType> {
    let ty = match code {
        2 => RawType::U8,
        4 => RawType::I16,
        8 => RawType::I32,
        16 => RawType::F32,
        256 => RawType::I8,
        512 => RawType::U16,
        _ => {
            let what = match code {
                1 => "binary",
                32 => "complex64",
                64 => "float64",
                128 => "rgb24",
                768 => "uint32",
                1024 => "int64",
                1280 => "uint64",
                1536 => "float128",
                1792 => "complex128",
                2048 => "complex256",
                2304 => "rgba32",
                _ => "unknown",
            };
            bail!(
                "{name}: unsupported datatype {code} ({what}); supported: uint8 (2), int16 (4), uint16 (512), \
                 float32 (16), int8 (256), int32 (8)"
            );
        }
    };
    if bitpix as i32 != 8 * ty.size() as i32 {
        bail!("{name}: bitpix {bitpix} does not match datatype {code} ({}, {} bits)", ty.name(), 8 * ty.size());
    }
    Ok(ty)
}

/// (slope, intercept) from `scl_slope` and `scl_inter`; `None` when they
/// change nothing.
fn scaling(name: &str, slope: f32, inter: f32) -> Result<Option<(f64, f64)>> {
    Ok(if slope == 0.0 {
        None
    } else if !slope.is_finite() || !inter.is_finite() {
        bail!("{name}: scl_slope {slope} / scl_inter {inter} are not finite");
    } else if slope == 1.0 && inter == 0.0 {
        None
    } else {
        Some((slope as f64, inter as f64))
    })
}

/// Voxel size and origin: from the sform when there is one, else `pixdim`
/// and (with a qform) its offset.
fn placement(name: &str, h: &Fields) -> Result<([f64; 3], [f64; 3])> {
    let pixdim: [f32; 8] = std::array::from_fn(|i| h.f32_at(76 + 4 * i));
    let (qform, sform) = (h.i16_at(252), h.i16_at(254));
    let (spacing, origin, from): ([f64; 3], [f64; 3], &str) = if sform > 0 {
        let row = |r: usize| -> [f64; 4] { std::array::from_fn(|c| h.f32_at(280 + 16 * r + 4 * c) as f64) };
        let m = [row(0), row(1), row(2)];
        let spacing = std::array::from_fn(|a| (0..3).map(|r| m[r][a] * m[r][a]).sum::<f64>().sqrt());
        (spacing, [m[0][3], m[1][3], m[2][3]], "the sform's column length")
    } else {
        let spacing = std::array::from_fn(|a| (pixdim[a + 1] as f64).abs());
        let origin = if qform > 0 { std::array::from_fn(|a| h.f32_at(268 + 4 * a) as f64) } else { [0.0; 3] };
        (spacing, origin, "pixdim")
    };
    for (a, &s) in spacing.iter().enumerate() {
        if !(s.is_finite() && s > 0.0) {
            bail!("{name}: voxel size {s} along {} (from {from}) must be positive and finite", AXES[a]);
        }
    }
    Ok((spacing, origin))
}

/// Parses a NIfTI-1 file from its bytes, `.nii` or (by its gzip magic)
/// `.nii.gz`. `name` starts every error and its stem names the volume. Never
/// panics on malformed input; decompression is bounded by what the header
/// promises.
pub fn parse_nifti_bytes(name: &str, bytes: &[u8]) -> Result<Volume> {
    let gz = bytes.starts_with(&[0x1f, 0x8b]);
    let header_bytes;
    let h = if gz {
        header_bytes = gunzip_prefix(name, "NIfTI-1 header", bytes, HEADER_BYTES)?;
        Header::parse(name, &header_bytes)?
    } else {
        Header::parse(name, bytes)?
    };
    let count = h.dims[0] * h.dims[1] * h.dims[2];
    let needed = byte_len(name, count, h.ty)?;
    let total = h
        .vox_offset
        .checked_add(needed)
        .ok_or_else(|| anyhow!("{name}: vox_offset {} plus the data overflows", h.vox_offset))?;
    let shape = format!("{}x{}x{} {}", h.dims[0], h.dims[1], h.dims[2], h.ty.name());
    let inflated;
    let data: &[u8] = if gz {
        let what = format!("the gzip stream ({shape} at vox_offset {})", h.vox_offset);
        inflated = inflate_after(name, &what, Wrapper::Gzip, bytes, h.vox_offset, needed)?;
        &inflated
    } else {
        if bytes.len() != total {
            bail!(
                "{name}: header/size mismatch: {shape} at vox_offset {} make {total} bytes, the file has {}",
                h.vox_offset,
                bytes.len()
            );
        }
        &bytes[h.vox_offset..]
    };
    let mut samples = decode_binary(name, data.into(), h.ty, h.endian, count)?;
    if let Some((slope, inter)) = h.scale {
        let f = samples.to_f32();
        samples = Samples::F32(f.into_iter().map(|v| (v as f64 * slope + inter) as f32).collect());
    }
    Volume::new(name, stem_of(name), h.dims, h.spacing, h.origin, samples)
}
