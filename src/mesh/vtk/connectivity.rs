//! A legacy VTK `CELLS` section in either layout, as offsets and
//! connectivity: version 5.x's `OFFSETS` / `CONNECTIVITY` arrays, or the
//! earlier flat list with a vertex count before each cell; and the check
//! that every vertex index names a point (a polyhedron's face stream read
//! as its faces).

use anyhow::{bail, Result};

use super::values::{swapped_hint, DType};
use crate::mesh::cells::PolyFaces;
use crate::mesh::polyhedron::{parse_face_stream, VTK_POLYHEDRON};
use crate::vtk_legacy::Lines as Reader;

/// Version 5.x: `a` offsets, then `b` connectivity entries; the offsets
/// must rise from 0 to `b`.
pub(super) fn offsets_and_connectivity(r: &mut Reader, a: usize, b: usize, version: &str) -> Result<(Vec<i64>, Vec<i64>)> {
    let h = r.keyword_line("OFFSETS")?;
    if !h[0].eq_ignore_ascii_case("OFFSETS") {
        bail!(r.err(format!(
            "expected OFFSETS after CELLS, found '{}': a version {version} file lists its cells \
             as OFFSETS and CONNECTIVITY arrays (files up to version 4.2 put a vertex count before \
             each cell)",
            h[0]
        )));
    }
    let dt = r.dtype(h.get(1), "OFFSETS")?;
    let offsets = r.values_i64(a, dt, "OFFSETS")?;
    let h = r.keyword_line("CONNECTIVITY")?;
    if !h[0].eq_ignore_ascii_case("CONNECTIVITY") {
        bail!(r.err(format!("expected CONNECTIVITY after OFFSETS, found '{}'", h[0])));
    }
    let dt = r.dtype(h.get(1), "CONNECTIVITY")?;
    let conn = r.values_i64(b, dt, "CONNECTIVITY")?;
    if offsets.first().is_some_and(|&o| o != 0) || offsets.last().is_some_and(|&o| o as usize != b) || offsets.windows(2).any(|w| w[1] < w[0]) {
        bail!(r.err(format!("count mismatch: OFFSETS must rise from 0 to the CONNECTIVITY size {b}")));
    }
    Ok((offsets, conn))
}

/// Versions up to 4.2: `a` cells in `b` values, each cell its vertex count
/// then its vertices.
pub(super) fn counted_cells(r: &mut Reader, a: usize, b: usize, version: &str) -> Result<(Vec<i64>, Vec<i64>)> {
    if r.peek_word().eq_ignore_ascii_case("OFFSETS") {
        bail!(r.err(format!("OFFSETS after CELLS: that layout needs file version 5.x, but the header says {version}")));
    }
    let flat = r.values_i64(b, DType::I32, "CELLS")?;
    // Each cell takes at least its vertex count, so `a <= b`,
    // and `b` values were just read: both bound the allocations.
    if a > b {
        bail!(r.err(format!("count mismatch: CELLS declares {a} cells in only {b} values")));
    }
    let mut offsets = Vec::with_capacity(a + 1);
    let mut conn = Vec::with_capacity(b - a);
    let mut i = 0usize;
    offsets.push(0);
    for c in 0..a {
        let Some(&k) = flat.get(i) else {
            bail!(r.err(format!("count mismatch: CELLS size {b} ends inside cell {c} of {a}")));
        };
        // `i < b`, so `b - i - 1` cannot underflow; comparing
        // against it cannot overflow whatever `k` is.
        if k < 0 || k as u64 > (b - i - 1) as u64 {
            bail!(r.err(format!(
                "count mismatch: cell {c} claims {k} vertices, beyond CELLS size {b}{}",
                swapped_hint(r.binary, k, 4)
            )));
        }
        let k = k as usize;
        conn.extend_from_slice(&flat[i + 1..i + 1 + k]);
        i += 1 + k;
        offsets.push(conn.len() as i64);
    }
    if i != b {
        bail!(r.err(format!("count mismatch: CELLS declares size {b} but its {a} cells use {i} values")));
    }
    Ok((offsets, conn))
}

/// The cells as offsets and u32 connectivity, every index checked against
/// the `np` points; a polyhedron's (type 42) entries are its face stream
/// (`nfaces, n0, ids..., ...`), which becomes its faces, its points listed
/// in the connectivity.
pub(super) fn cells_and_faces(
    r: &Reader,
    types: &[u8],
    offsets: &[usize],
    conn: &[i64],
    np: usize,
) -> Result<(Vec<usize>, Vec<u32>, PolyFaces)> {
    let nc = offsets.len().saturating_sub(1);
    let mut conn32 = Vec::with_capacity(conn.len());
    let mut out_offsets = Vec::with_capacity(nc + 1);
    out_offsets.push(0);
    let mut faces = PolyFaces::default();
    for c in 0..nc {
        let cell = &conn[offsets[c]..offsets[c + 1]];
        if types.get(c) == Some(&VTK_POLYHEDRON) {
            let fs = parse_face_stream(cell, np).map_err(|e| r.err(format!("cell {c} (polyhedron, type 42): {e}")))?;
            let mut pts: Vec<u32> = fs.iter().flatten().copied().collect();
            pts.sort_unstable();
            pts.dedup();
            conn32.extend_from_slice(&pts);
            faces.push_cell(c, &fs);
        } else {
            for &v in cell {
                if v < 0 || v as usize >= np {
                    bail!(r.err(format!("cell {c} has vertex index {v} out of range (file has {np} points)")));
                }
                conn32.push(v as u32);
            }
        }
        out_offsets.push(conn32.len());
    }
    Ok((out_offsets, conn32, faces))
}
