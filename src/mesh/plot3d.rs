//! PLOT3D readers for the NASA structured grids (blunt fin, oxygen post).
//!
//! Only the variant those files use is supported: single grid, 3D, "whole"
//! (no Fortran record markers), big-endian float32 coordinates and solution,
//! int32 header and IBLANK. The readers load the whole file at once and check
//! every size before touching the data, so a malformed file gives an error that
//! names the file and the problem instead of a panic or silent garbage.
//!
//! Layout (`x` fastest): `*xyz`: `nx ny nz`, `x[nz][ny][nx]`, `y[..]`, `z[..]`,
//! optionally `iblank[nz][ny][nx]` (detected from the file size). `*q`:
//! `nx ny nz`, `fsmach alpha re time`, then five fields (density, momentum x,
//! y, z, stagnation energy); trailing bytes are ignored.
//!
//! Files in the layouts that are not supported get a message saying which
//! layout they look like: Fortran unformatted files (record markers around
//! the dimensions), multi-grid files (a grid count first) and little-endian
//! files (dimensions or floats that only make sense byte-swapped).

use anyhow::{bail, Context, Result};
use std::path::Path;

/// Largest accepted grid dimension along one axis. Real PLOT3D grids are far
/// smaller; anything bigger almost certainly means a wrong format/endianness.
pub const MAX_DIM: usize = 1 << 16;

/// A single structured grid. `points[i + nx*(j + ny*k)]`.
#[derive(Debug, Clone)]
pub struct Plot3dGrid {
    /// `[nx, ny, nz]`.
    pub dims: [usize; 3],
    pub points: Vec<[f64; 3]>,
    /// IBLANK per point when the file carries it (1 = normal, 0 = blanked /
    /// hole, negative = fringe point interpolated from grid |IBLANK|).
    pub iblank: Option<Vec<i32>>,
}

impl Plot3dGrid {
    pub fn num_points(&self) -> usize {
        self.points.len()
    }

    /// Points whose IBLANK is 0 (0 when the file has no IBLANK).
    pub fn blanked_points(&self) -> usize {
        self.iblank
            .as_ref()
            .map_or(0, |ib| ib.iter().filter(|&&b| b == 0).count())
    }

    /// Points with negative IBLANK (overset "fringe" points whose values come
    /// from grid |IBLANK|; not blanked). In `postxyz.bin` these are the O-grid
    /// seam rows j = 0, 74, 75 (IBLANK = -1: the grid interpolates from itself).
    pub fn fringe_points(&self) -> usize {
        self.iblank
            .as_ref()
            .map_or(0, |ib| ib.iter().filter(|&&b| b < 0).count())
    }

    /// Hexahedral cells with IBLANK = 0 at any of their 8 corners (the usual
    /// PLOT3D meaning of a blanked cell). 0 when the file has no IBLANK.
    pub fn blanked_cells(&self) -> usize {
        let Some(ib) = &self.iblank else { return 0 };
        let [nx, ny, nz] = self.dims;
        if nx < 2 || ny < 2 || nz < 2 {
            return 0;
        }
        let idx = |i: usize, j: usize, k: usize| i + nx * (j + ny * k);
        let mut n = 0;
        for k in 0..nz - 1 {
            for j in 0..ny - 1 {
                for i in 0..nx - 1 {
                    let blank = (0..8).any(|c| {
                        ib[idx(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1))] == 0
                    });
                    n += blank as usize;
                }
            }
        }
        n
    }
}

/// A PLOT3D solution (`q`) file: free-stream values and the five conserved
/// fields, each `nx*ny*nz` long in the grid's point order.
#[derive(Debug, Clone)]
pub struct Plot3dSolution {
    pub dims: [usize; 3],
    pub fsmach: f64,
    pub alpha: f64,
    pub re: f64,
    pub time: f64,
    /// `[density, momentum x, momentum y, momentum z, stagnation energy]`.
    pub fields: [Vec<f64>; 5],
}

impl Plot3dSolution {
    pub fn density(&self) -> &[f64] {
        &self.fields[0]
    }

    pub fn momentum(&self, point: usize) -> [f64; 3] {
        [self.fields[1][point], self.fields[2][point], self.fields[3][point]]
    }

    pub fn energy(&self) -> &[f64] {
        &self.fields[4]
    }

    /// `|momentum| / density` per point; 0 where the density is 0 (so the
    /// result is always finite for finite input).
    pub fn velocity_magnitude(&self) -> Vec<f64> {
        (0..self.fields[0].len())
            .map(|p| {
                let rho = self.fields[0][p];
                let [mx, my, mz] = self.momentum(p);
                let m = (mx * mx + my * my + mz * mz).sqrt();
                if rho == 0.0 {
                    0.0
                } else {
                    (m / rho).abs()
                }
            })
            .collect()
    }

    /// Error (naming both files) unless this solution belongs to `grid`.
    pub fn check_matches(&self, grid: &Plot3dGrid, q_path: &Path, xyz_path: &Path) -> Result<()> {
        if self.dims != grid.dims {
            bail!(
                "{}: solution dimensions {:?} do not match grid {} dimensions {:?}",
                q_path.display(),
                self.dims,
                xyz_path.display(),
                grid.dims
            );
        }
        Ok(())
    }
}

fn read_file(path: &Path) -> Result<Vec<u8>> {
    crate::fsio::read_input(path, "PLOT3D file", crate::fsio::MAX_INPUT_BYTES)
}

fn be_i32(b: &[u8], off: usize) -> i32 {
    i32::from_be_bytes([b[off], b[off + 1], b[off + 2], b[off + 3]])
}

fn be_f32(b: &[u8], off: usize) -> f32 {
    f32::from_be_bytes([b[off], b[off + 1], b[off + 2], b[off + 3]])
}

/// Reads and checks the `nx ny nz` header; returns dims and point count.
fn read_dims(path: &str, bytes: &[u8]) -> Result<([usize; 3], usize)> {
    if bytes.len() < 12 {
        bail!(
            "{}: truncated PLOT3D file: {} bytes, shorter than the 12-byte nx ny nz header",
            path,
            bytes.len()
        );
    }
    let raw = [be_i32(bytes, 0), be_i32(bytes, 4), be_i32(bytes, 8)];
    let ok = |d: i32| d >= 1 && (d as usize) <= MAX_DIM;
    if !raw.iter().all(|&d| ok(d)) {
        let le = [0, 4, 8].map(|o| i32::from_le_bytes(bytes[o..o + 4].try_into().unwrap()));
        let hint = if le.iter().all(|&d| ok(d)) {
            format!(" (read as little-endian they would be {le:?}; only big-endian is supported)")
        } else {
            String::from(" (expected a single-grid, whole, big-endian 3D file without record markers)")
        };
        bail!(
            "{}: invalid PLOT3D dimensions {:?}: each must be in 1..={}{}",
            path,
            raw,
            MAX_DIM,
            hint
        );
    }
    let dims = raw.map(|d| d as usize);
    let n = dims[0]
        .checked_mul(dims[1])
        .and_then(|v| v.checked_mul(dims[2]))
        .filter(|&n| n <= u32::MAX as usize)
        .with_context(|| format!("{path}: PLOT3D dimensions {dims:?} overflow the point count"))?;
    Ok((dims, n))
}

/// The unsupported layout a file of `kind` is in, when it is recognisably
/// one: checked before the single-grid reading, because a multi-grid
/// solution file would otherwise read as a (wrong) single grid with
/// trailing bytes. A single-grid, whole file cannot pass for either: its
/// first coordinates or free-stream values would have to be the bits of
/// small integers (subnormal floats).
fn other_layout(bytes: &[u8], kind: Kind) -> Option<String> {
    let int = |o: usize| bytes.get(o..o + 4).map(|b| i32::from_be_bytes([b[0], b[1], b[2], b[3]]));
    // Fortran unformatted: `12 | nx ny nz | 12` (record length before and after).
    if int(0) == Some(12) && int(16) == Some(12) {
        return Some(
            "this looks like a Fortran unformatted PLOT3D file (the dimensions are wrapped in 4-byte record \
             markers, 12 ... 12); only 'whole' files without record markers are supported"
                .into(),
        );
    }
    // Multi-grid: `ngrid | dims of each grid | data of each grid`, sizes adding up.
    let grids = int(0).filter(|&g| (1..=4096).contains(&g))? as usize;
    let mut sizes = [4 + 12 * grids as u128; 2];
    for g in 0..grids {
        let d = [int(4 + 12 * g)?, int(8 + 12 * g)?, int(12 + 12 * g)?];
        if !d.iter().all(|&x| x >= 1 && x as usize <= MAX_DIM) {
            return None;
        }
        let n = d.iter().map(|&x| x as u128).product::<u128>();
        match kind {
            Kind::Grid => {
                sizes[0] += 12 * n;
                sizes[1] += 16 * n;
            }
            Kind::Solution => {
                sizes[0] += 16 + 20 * n;
                sizes[1] += 16 + 20 * n;
            }
        }
    }
    let len = bytes.len() as u128;
    let fits = match kind {
        Kind::Grid => sizes.contains(&len),
        Kind::Solution => len >= sizes[0],
    };
    fits.then(|| {
        format!(
            "this looks like a multi-grid PLOT3D file ({grids} grid{}, the count before the dimensions); only \
             single-grid files are supported",
            if grids == 1 { "" } else { "s" }
        )
    })
}

#[derive(Clone, Copy)]
enum Kind {
    Grid,
    Solution,
}

/// Decodes `n` big-endian float32 starting at `off`, failing on NaN/Inf and
/// on arrays that look little-endian (`byte_order`).
fn read_floats(path: &str, bytes: &[u8], off: usize, n: usize, what: &str) -> Result<Vec<f64>> {
    let slice = &bytes[off..off + 4 * n];
    if let Some(evidence) = crate::bytes::byte_order::looks_little_endian(slice, 4) {
        bail!("{path}: {what} (byte offset {off}): {evidence}");
    }
    let out: Vec<f64> = slice
        .chunks_exact(4)
        .map(|c| f32::from_be_bytes([c[0], c[1], c[2], c[3]]) as f64)
        .collect();
    if let Some(i) = out.iter().position(|v| !v.is_finite()) {
        bail!(
            "{}: non-finite value {} in {} at point {} (byte offset {})",
            path,
            out[i],
            what,
            i,
            off + 4 * i
        );
    }
    Ok(out)
}

/// Reads a single-grid, whole, big-endian PLOT3D grid (`*xyz*`) file, with or
/// without IBLANK (decided by the file size).
pub fn read_xyz(path: impl AsRef<Path>) -> Result<Plot3dGrid> {
    let path = path.as_ref();
    parse_xyz_bytes(&path.display().to_string(), &read_file(path)?)
}

/// [`read_xyz`] on the bytes of a file already in memory; `path` (the file
/// name, or any label) is quoted in every error. Never panics on malformed
/// input: the file size is checked against the dimensions before anything is
/// allocated.
pub fn parse_xyz_bytes(path: &str, bytes: &[u8]) -> Result<Plot3dGrid> {
    if let Some(what) = other_layout(bytes, Kind::Grid) {
        bail!("{path}: {what}");
    }
    let (dims, n) = read_dims(path, bytes)?;
    let size = bytes.len() as u128;
    let n128 = n as u128;
    let plain = 12 + 12 * n128;
    let with_iblank = 12 + 16 * n128;
    let has_iblank = if size == plain {
        false
    } else if size == with_iblank {
        true
    } else if size < plain {
        bail!(
            "{}: truncated PLOT3D grid: dimensions {:?} need {} bytes of coordinates, file has {} bytes",
            path,
            dims,
            plain,
            size
        );
    } else {
        bail!(
            "{}: unexpected PLOT3D grid size {} bytes for dimensions {:?}: expected {} (no IBLANK) \
             or {} (with IBLANK); multi-grid, 2D and Fortran-record files are not supported",
            path,
            size,
            dims,
            plain,
            with_iblank
        );
    };
    let x = read_floats(path, bytes, 12, n, "x")?;
    let y = read_floats(path, bytes, 12 + 4 * n, n, "y")?;
    let z = read_floats(path, bytes, 12 + 8 * n, n, "z")?;
    let points = (0..n).map(|p| [x[p], y[p], z[p]]).collect();
    let iblank = has_iblank.then(|| (0..n).map(|p| be_i32(bytes, 12 + 12 * n + 4 * p)).collect());
    Ok(Plot3dGrid { dims, points, iblank })
}

/// Reads a single-grid, whole, big-endian PLOT3D solution (`*q*`) file.
/// Bytes after the five fields are ignored.
pub fn read_q(path: impl AsRef<Path>) -> Result<Plot3dSolution> {
    let path = path.as_ref();
    parse_q_bytes(&path.display().to_string(), &read_file(path)?)
}

/// [`read_q`] on the bytes of a file already in memory; `path` (the file
/// name, or any label) is quoted in every error. Never panics on malformed
/// input (sizes are checked before allocating).
pub fn parse_q_bytes(path: &str, bytes: &[u8]) -> Result<Plot3dSolution> {
    if let Some(what) = other_layout(bytes, Kind::Solution) {
        bail!("{path}: {what}");
    }
    let (dims, n) = read_dims(path, bytes)?;
    let need = 28 + 20 * n as u128;
    if (bytes.len() as u128) < need {
        bail!(
            "{}: truncated PLOT3D solution: dimensions {:?} need {} bytes (header + 4 free-stream \
             values + 5 fields), file has {} bytes",
            path,
            dims,
            need,
            bytes.len()
        );
    }
    let header: Vec<f64> = (0..4).map(|i| be_f32(bytes, 12 + 4 * i) as f64).collect();
    for (name, v) in ["fsmach", "alpha", "re", "time"].iter().zip(&header) {
        if !v.is_finite() {
            bail!("{path}: non-finite free-stream value {name} = {v}");
        }
    }
    let names = ["density", "momentum x", "momentum y", "momentum z", "stagnation energy"];
    let mut fields: [Vec<f64>; 5] = Default::default();
    for (f, field) in fields.iter_mut().enumerate() {
        *field = read_floats(path, bytes, 28 + 4 * n * f, n, names[f])?;
    }
    Ok(Plot3dSolution {
        dims,
        fsmach: header[0],
        alpha: header[1],
        re: header[2],
        time: header[3],
        fields,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    fn grid_bytes(dims: [i32; 3], iblank: bool) -> Vec<u8> {
        let n = (dims[0] * dims[1] * dims[2]).max(0) as usize;
        let mut b = Vec::new();
        for d in dims {
            b.extend_from_slice(&d.to_be_bytes());
        }
        for c in 0..3 {
            for p in 0..n {
                b.extend_from_slice(&((p * 3 + c) as f32).to_be_bytes());
            }
        }
        if iblank {
            for p in 0..n {
                b.extend_from_slice(&((p % 2) as i32).to_be_bytes());
            }
        }
        b
    }


    #[test]
    fn reads_small_grid_with_and_without_iblank() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let p = write(dir, "g.xyz", &grid_bytes([2, 3, 2], false));
        let g = read_xyz(&p).unwrap();
        assert_eq!(g.dims, [2, 3, 2]);
        assert_eq!(g.points.len(), 12);
        assert_eq!(g.points[5], [15.0, 16.0, 17.0]);
        assert!(g.iblank.is_none());
        let p = write(dir, "gi.xyz", &grid_bytes([2, 3, 2], true));
        let g = read_xyz(&p).unwrap();
        assert_eq!(g.iblank.as_ref().unwrap()[3], 1);
        assert_eq!(g.blanked_points(), 6);
        assert_eq!(g.blanked_cells(), 2);
    }

    #[test]
    fn bad_grids_are_errors_naming_the_file() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let full = grid_bytes([2, 3, 2], false);
        let cases: Vec<(&str, Vec<u8>, &str)> = vec![
            ("short.xyz", full[..8].to_vec(), "truncated"),
            ("trunc.xyz", full[..full.len() - 4].to_vec(), "truncated"),
            ("extra.xyz", [full.clone(), vec![0; 4]].concat(), "unexpected"),
            ("neg.xyz", grid_bytes([-2, 3, 2], false), "invalid"),
            ("zero.xyz", grid_bytes([0, 3, 2], false), "invalid"),
            ("le.xyz", {
                let mut b = full.clone();
                for (o, d) in [(0, 2i32), (4, 3), (8, 2)] {
                    b[o..o + 4].copy_from_slice(&d.to_le_bytes());
                }
                b
            }, "little-endian"),
        ];
        for (name, bytes, what) in cases {
            let p = write(dir, name, &bytes);
            let e = format!("{:#}", read_xyz(&p).unwrap_err());
            assert!(e.contains(&p.display().to_string()), "{e}");
            assert!(e.contains(what), "{name}: {e}");
        }
        let mut nan = full.clone();
        nan[12 + 4 * 7..12 + 4 * 8].copy_from_slice(&f32::NAN.to_be_bytes());
        let p = write(dir, "nan.xyz", &nan);
        let e = format!("{:#}", read_xyz(&p).unwrap_err());
        assert!(e.contains("non-finite") && e.contains("point 7"), "{e}");
        let e = format!("{:#}", read_xyz(dir.join("missing.xyz")).unwrap_err());
        assert!(e.contains("missing.xyz"), "{e}");
    }

    #[test]
    fn q_file_and_velocity() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let n = 2;
        let mut b = Vec::new();
        for d in [2i32, 1, 1] {
            b.extend_from_slice(&d.to_be_bytes());
        }
        for v in [0.5f32, 0.0, 1e6, 0.0] {
            b.extend_from_slice(&v.to_be_bytes());
        }
        let fields: [[f32; 2]; 5] = [[2.0, 0.0], [6.0, 1.0], [0.0, 0.0], [8.0, 0.0], [1.0, 1.0]];
        for f in fields {
            for v in &f[..n] {
                b.extend_from_slice(&v.to_be_bytes());
            }
        }
        b.extend_from_slice(&[0u8; 7]); // trailing bytes are allowed
        let p = write(dir, "s.q", &b);
        let q = read_q(&p).unwrap();
        assert_eq!(q.fsmach, 0.5);
        assert_eq!(q.density(), &[2.0, 0.0]);
        assert_eq!(q.velocity_magnitude(), vec![5.0, 0.0]);
        let p = write(dir, "t.q", &b[..40]);
        let e = format!("{:#}", read_q(&p).unwrap_err());
        assert!(e.contains("truncated") && e.contains(&p.display().to_string()), "{e}");
    }
}
