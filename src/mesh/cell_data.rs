//! Which array of an unstructured file is the scalar, and how cell data
//! (one value per cell) becomes the per-vertex scalar every renderer reads.
//!
//! Two treatments of a cell array, chosen with `--cell-data`:
//! - [`CellData::Constant`] (the default: the data as it is): every tet
//!   carries its file cell's value, constant inside it. Each tet gets its
//!   own four vertices (copies of the file's points) holding that value, so
//!   linear interpolation inside a tet *is* the constant, every integrator
//!   is exact on the cell (one colour and extinction per segment) and the
//!   f64 reference integrates the same piecewise-constant field. The copies
//!   remember the point they copy (`MeshStats::vertex_origin`): the walks'
//!   face adjacency (`topology`) matches faces through it, so a ray still
//!   crosses from cell to cell. Costs 4 points per tet.
//! - [`CellData::Average`]: the cell values averaged to the points as VTK's
//!   `vtkCellDataToPointData` does by default (checked against VTK 9.7.2):
//!   the *plain mean* (not volume-weighted) of the values of the cells that
//!   use the point, counted once per use in the connectivity (a cell listing
//!   a point twice counts twice), over every cell of the file (lines and
//!   surface cells too, which are not rendered), before the cells are split;
//!   a point no cell uses gets 0. Vectors are averaged component by
//!   component, then their magnitude taken (what VTK colours by).
//!
//! Vector arrays are shown by magnitude, computed without overflow
//! ([`magnitude`]); a magnitude beyond f32's range (the renderers compute in
//! f32) is an error that says so.

use anyhow::{bail, Result};
use serde::Serialize;

use super::geometry::MAX_ABS_VALUE;

/// How a cell array is shown (module docs).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum CellData {
    /// Constant per cell (the default).
    #[default]
    Constant,
    /// Averaged to the points as `vtkCellDataToPointData`.
    Average,
}

impl CellData {
    pub const NAMES: [&'static str; 2] = ["constant", "average"];

    pub fn name(self) -> &'static str {
        match self {
            CellData::Constant => "constant",
            CellData::Average => "average",
        }
    }
}

impl std::str::FromStr for CellData {
    type Err = anyhow::Error;
    fn from_str(s: &str) -> Result<CellData> {
        match s {
            "constant" => Ok(CellData::Constant),
            "average" => Ok(CellData::Average),
            _ => bail!(
                "--cell-data '{}': unknown treatment of cell data; the choices are 'constant' (each cell shows its own \
                 value, the default) and 'average' (averaged to the points as VTK's vtkCellDataToPointData does)",
                s.escape_debug()
            ),
        }
    }
}

/// Whose values an array holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Association {
    Point,
    Cell,
}

impl Association {
    pub fn name(self) -> &'static str {
        match self {
            Association::Point => "point",
            Association::Cell => "cell",
        }
    }
}

/// What a mesh's scalar is, recorded in its stats (so in every result's
/// `dataset.stats`): `scalar_array`, `scalar_association` ("point" or
/// "cell"), `scalar_components` (magnitude when more than 1) and, for cell
/// data, `cell_data` ("constant" or "average").
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct ScalarInfo {
    #[serde(rename = "scalar_array")]
    pub array: String,
    #[serde(rename = "scalar_association")]
    pub association: Association,
    #[serde(rename = "scalar_components")]
    pub components: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cell_data: Option<CellData>,
    /// Chosen because the file has no point array to use (the caller
    /// notes it on stderr).
    #[serde(skip)]
    pub fallback: bool,
}

impl ScalarInfo {
    /// The note printed when a cell array was picked because the file has
    /// no point scalar, else `None`.
    pub fn fallback_note(&self, source: &str) -> Option<String> {
        (self.fallback && self.association == Association::Cell).then(|| {
            format!(
                "note: {source} has no point array to use as the scalar; using its cell array '{}'{} ({}; \
                 --cell-data constant|average, --scalar NAME to choose)",
                self.array,
                if self.components > 1 { format!(" ({} components, by magnitude)", self.components) } else { String::new() },
                match self.cell_data.unwrap_or_default() {
                    CellData::Constant => "constant per cell",
                    CellData::Average => "averaged to the points as vtkCellDataToPointData",
                }
            )
        })
    }
}

/// The caller's choice of scalar: an array by name (point data first, then
/// cell data), and how cell data is shown.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ScalarChoice<'a> {
    pub array: Option<&'a str>,
    pub cell_data: CellData,
}

/// The length of `c` (one value as is), scaled so that no square overflows
/// or underflows: `m·sqrt(Σ(x/m)²)`, `m = max |x|`. Non-finite components
/// give a non-finite result.
pub fn magnitude(c: &[f64]) -> f64 {
    if let [x] = c {
        return *x;
    }
    let m = c.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if m == 0.0 || !m.is_finite() || c.iter().any(|x| x.is_nan()) {
        return if c.iter().any(|x| x.is_nan()) { f64::NAN } else { m };
    }
    m * c.iter().map(|x| (x / m) * (x / m)).sum::<f64>().sqrt()
}

/// One value per tuple of `values` (`k` components each): the value, or
/// the vector's magnitude. `what` names the array, `unit` the tuple
/// ("point", "cell") in the error for a magnitude of finite components
/// that is beyond f32's range (non-finite components are left to
/// validation, which names them).
pub fn magnitudes(values: Vec<f64>, k: usize, what: &str, unit: &str) -> Result<Vec<f64>> {
    if k <= 1 {
        return Ok(values);
    }
    values.chunks_exact(k).enumerate().map(|(i, c)| tuple_magnitude(c, i, what, unit)).collect()
}

/// The magnitude of tuple `i` (`c`, its components), or an error saying it
/// overflowed the f32 range the renderers compute in.
pub fn tuple_magnitude(c: &[f64], i: usize, what: &str, unit: &str) -> Result<f64> {
    let m = magnitude(c);
    if c.iter().all(|x| x.is_finite()) && m > MAX_ABS_VALUE {
        let comps: Vec<String> = c.iter().map(|x| format!("{x:e}")).collect();
        bail!(
            "{what}: the magnitude of the vector at {unit} {i} ({}) overflowed: it is {}, beyond the f32 range \
             (|s| <= {MAX_ABS_VALUE:e}) the renderers compute in",
            comps.join(", "),
            if m.is_finite() { format!("{m:e}") } else { "beyond even f64's range".to_string() }
        );
    }
    Ok(m)
}

/// `vtkCellDataToPointData`'s default (module docs): per point, the mean
/// of `values` (`k` components per cell) over the cells' uses of it in
/// `conn` (cell `c` is `conn[offsets[c]..offsets[c + 1]]`); 0 for a point no
/// cell uses. Returns `np·k` values. Errors on an index out of range.
pub fn average_to_points(np: usize, offsets: &[usize], conn: &[u32], values: &[f64], k: usize, source: &str) -> Result<Vec<f64>> {
    let n = offsets.len().saturating_sub(1);
    if values.len() != n * k {
        bail!("{source}: {} cell values for {n} cells of {k} components", values.len());
    }
    let mut sum = vec![0.0f64; np * k];
    let mut uses = vec![0u32; np];
    for c in 0..n {
        let (a, b) = (offsets[c], offsets[c + 1]);
        let Some(cell) = conn.get(a..b) else { bail!("{source}: cell {c}: offsets {a}..{b} outside the connectivity") };
        for &v in cell {
            let v = v as usize;
            if v >= np {
                bail!("{source}: cell {c} has vertex index {v} out of range (the file has {np} points)");
            }
            uses[v] = uses[v].saturating_add(1);
            for j in 0..k {
                sum[v * k + j] += values[c * k + j];
            }
        }
    }
    for (v, &u) in uses.iter().enumerate() {
        if u > 0 {
            for s in &mut sum[v * k..(v + 1) * k] {
                *s /= u as f64;
            }
        }
    }
    Ok(sum)
}

/// Gives every tet of `mesh` its own four vertices, copies of its points,
/// holding `value[t]` (the constant treatment, module docs), and records
/// which point each copy is in `stats.vertex_origin`. Errors when the
/// copies do not fit 32-bit indices.
pub fn constant_per_cell(mesh: &mut super::TetMesh, value: &[f64], source: &str) -> Result<()> {
    let nt = mesh.tets.len();
    if value.len() != nt {
        bail!("{source}: {} cell values for {nt} tets", value.len());
    }
    if nt.checked_mul(4).is_none_or(|n| n > u32::MAX as usize) {
        bail!(
            "{source}: {nt} tets with a constant value each need {} vertices of their own (--cell-data constant), \
             more than 32-bit indices hold; use --cell-data average",
            nt as u128 * 4
        );
    }
    let mut points = Vec::with_capacity(4 * nt);
    let mut scalars = Vec::with_capacity(4 * nt);
    let mut origin = Vec::with_capacity(4 * nt);
    for (t, tet) in mesh.tets.iter_mut().enumerate() {
        for v in tet.iter_mut() {
            origin.push(*v);
            points.push(mesh.points[*v as usize]);
            scalars.push(value[t]);
            *v = (points.len() - 1) as u32;
        }
    }
    mesh.points = points;
    mesh.scalars = scalars;
    mesh.stats.vertex_origin = origin;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn magnitude_does_not_overflow() {
        assert_eq!(magnitude(&[3.0, 4.0]), 5.0);
        assert_eq!(magnitude(&[-2.5]), -2.5);
        assert_eq!(magnitude(&[0.0, 0.0, 0.0]), 0.0);
        let big = magnitude(&[3e300, 4e300, 0.0]);
        assert!((big - 5e300).abs() < 1e286, "{big:e}");
        let tiny = magnitude(&[3e-300, 4e-300]);
        assert!((tiny - 5e-300).abs() < 1e-314, "{tiny:e}");
        assert!(magnitude(&[f64::NAN, 1.0]).is_nan());
        assert_eq!(magnitude(&[f64::INFINITY, 1.0]), f64::INFINITY);
        // The true magnitude beyond f64.
        assert_eq!(magnitude(&[f64::MAX, f64::MAX]), f64::INFINITY);
    }

    #[test]
    fn magnitudes_say_when_they_overflow() {
        assert_eq!(magnitudes(vec![3.0, 4.0, 0.0, 6.0, 8.0, 0.0], 3, "v", "point").unwrap(), vec![5.0, 10.0]);
        // Two sizes of the bound: just inside f32's range passes, beyond fails.
        let inside = (f32::MAX as f64) / 2.0;
        magnitudes(vec![inside, inside, 0.0], 3, "v", "point").unwrap();
        let e = magnitudes(vec![1.0, 2.0, 3.0, 1e300, 1e300, 1e300], 3, "array 'v'", "cell").unwrap_err().to_string();
        assert!(e.contains("array 'v'") && e.contains("cell 1") && e.contains("overflowed") && e.contains("1.7320508"), "{e}");
        let e = magnitudes(vec![f64::MAX, f64::MAX], 2, "v", "point").unwrap_err().to_string();
        assert!(e.contains("overflowed") && e.contains("beyond even f64"), "{e}");
        // Non-finite components are validation's to name.
        assert!(magnitudes(vec![f64::INFINITY, 0.0], 2, "v", "point").unwrap()[0].is_infinite());
    }

    #[test]
    fn cell_data_names_and_refusal() {
        assert_eq!("constant".parse::<CellData>().unwrap(), CellData::Constant);
        assert_eq!("average".parse::<CellData>().unwrap(), CellData::Average);
        let e = "mean".parse::<CellData>().unwrap_err().to_string();
        assert!(e.contains("--cell-data 'mean'") && e.contains("'constant'") && e.contains("'average'"), "{e}");
        assert_eq!(CellData::default(), CellData::Constant);
        for n in CellData::NAMES {
            assert_eq!(n.parse::<CellData>().unwrap().name(), n);
        }
    }

    /// The numbers VTK 9.7.2's vtkCellDataToPointData gives (run by hand
    /// with the wheel: two tets, a triangle and a line listing point 4
    /// twice; point 5 unused): 50.5, 37, 37, 5.5, 670, 0.
    #[test]
    fn average_matches_vtk() {
        let offsets = [0, 4, 8, 11, 13];
        let conn = [0, 1, 2, 3, 1, 2, 3, 4, 0, 1, 2, 4, 4];
        let got = average_to_points(6, &offsets, &conn, &[1.0, 10.0, 100.0, 1000.0], 1, "m").unwrap();
        assert_eq!(got, vec![50.5, 37.0, 37.0, 5.5, 670.0, 0.0]);
        // Components averaged one by one.
        let v = average_to_points(6, &offsets, &conn, &[1.0, 2.0, 10.0, 20.0, 100.0, 200.0, 1000.0, 2000.0], 2, "m").unwrap();
        assert_eq!(&v[..4], &[50.5, 101.0, 37.0, 74.0]);
        let e = average_to_points(4, &offsets, &conn, &[1.0; 4], 1, "m").unwrap_err().to_string();
        assert!(e.contains("cell 1 has vertex index 4 out of range"), "{e}");
    }
}
