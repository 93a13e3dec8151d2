//! The TIN patches of a hybrid model: their shapes (the default corridor and
//! site, or the heightmap's own), their placement in grid units with the
//! checks a model needs (simple, disjoint, inside the grid, off the
//! lattice), and each one's TB: its boundary with a vertex at every grid
//! line it crosses.

use anyhow::{bail, Context as _, Result};

use super::geometry::{inside, segments_meet, signed_area};
use super::{Heightmap, Patch};

/// A patch shape in domain fractions.
struct PatchSpec {
    name: &'static str,
    polygon: Vec<[f64; 2]>,
}

/// The corridor along the fault (a band around a polyline running
/// south-west to north-east, as the Jacksboro fault does across the
/// model) and an L-shaped site to the north-west of it.
fn default_patches() -> Vec<PatchSpec> {
    let line = [[0.08, 0.22], [0.5, 0.47], [0.92, 0.8]];
    let half_width = 0.045;
    vec![PatchSpec { name: "fault corridor", polygon: band(&line, half_width) }, PatchSpec { name: "site", polygon: site() }]
}

/// A band of `half` around a polyline (mitred joints).
fn band(line: &[[f64; 2]], half: f64) -> Vec<[f64; 2]> {
    let n = line.len();
    let normal = |a: [f64; 2], b: [f64; 2]| {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let l = (dx * dx + dy * dy).sqrt();
        [-dy / l, dx / l]
    };
    let offsets: Vec<[f64; 2]> = (0..n)
        .map(|i| {
            let a = if i > 0 { normal(line[i - 1], line[i]) } else { normal(line[0], line[1]) };
            let b = if i + 1 < n { normal(line[i], line[i + 1]) } else { a };
            let m = [a[0] + b[0], a[1] + b[1]];
            let dot = (m[0] * a[0] + m[1] * a[1]).max(1e-3);
            [m[0] / dot * half, m[1] / dot * half]
        })
        .collect();
    let mut poly: Vec<[f64; 2]> = (0..n).map(|i| [line[i][0] - offsets[i][0], line[i][1] - offsets[i][1]]).collect();
    poly.extend((0..n).rev().map(|i| [line[i][0] + offsets[i][0], line[i][1] + offsets[i][1]]));
    poly
}

fn site() -> Vec<[f64; 2]> {
    let shape = [[0.0, 0.0], [1.0, 0.0], [1.0, 0.45], [0.5, 0.45], [0.5, 1.0], [0.0, 1.0]];
    let (c, size, angle) = ([0.2, 0.72], 0.16, 20f64.to_radians());
    shape
        .iter()
        .map(|p| {
            let (x, y) = ((p[0] - 0.5) * size, (p[1] - 0.5) * size);
            [c[0] + x * angle.cos() - y * angle.sin(), c[1] + x * angle.sin() + y * angle.cos()]
        })
        .collect()
}

/// The patches of `map` in grid units (`domain` finest cells), counter-
/// clockwise, with their TBs appended to one list (a patch's `tb` range
/// indexes it). Refuses patches that cross, overlap or leave the grid.
pub(super) fn place(map: &Heightmap, domain: [u32; 2]) -> Result<(Vec<Patch>, Vec<[f64; 2]>)> {
    let name = &map.name;
    let (dw, dh) = (domain[0] as f64, domain[1] as f64);
    // Patches in grid units, nudged off the lattice, counter-clockwise.
    let mut patches = Vec::new();
    let mut tb_xy: Vec<[f64; 2]> = Vec::new();
    let specs = if map.patches.is_empty() {
        default_patches()
    } else {
        map.patches.iter().map(|p| PatchSpec { name: "given patch", polygon: p.clone() }).collect()
    };
    for spec in specs {
        if spec.polygon.len() < 3 || spec.polygon.iter().flatten().any(|c| !c.is_finite()) {
            bail!("'{name}': TIN patch '{}' needs at least 3 finite vertices", spec.name);
        }
        // Arbitrary sub-sample offsets (they only keep patch corners off
        // grid lines), not 1/pi and e/10.
        #[allow(clippy::approx_constant)]
        let mut poly: Vec<[f64; 2]> = spec.polygon.iter().map(|p| [p[0] * dw + 0.3183, p[1] * dh + 0.2718]).collect();
        if signed_area(&poly) < 0.0 {
            poly.reverse();
        }
        let tb = boundary(spec.name, &poly).with_context(|| format!("'{name}': building the TIN boundary"))?;
        let start = tb_xy.len() as u32;
        tb_xy.extend(tb);
        patches.push(Patch { name: spec.name, polygon: poly, tb: start..tb_xy.len() as u32 });
    }
    // Patches must be simple, disjoint and inside the domain.
    let edges: Vec<(usize, [f64; 2], [f64; 2])> = patches
        .iter()
        .enumerate()
        .flat_map(|(pi, p)| (0..p.polygon.len()).map(move |i| (pi, p.polygon[i], p.polygon[(i + 1) % p.polygon.len()])))
        .collect();
    for (i, e) in edges.iter().enumerate() {
        for f in &edges[i + 1..] {
            let adjacent = e.0 == f.0 && (e.2 == f.1 || f.2 == e.1);
            if !adjacent && segments_meet(e.1, e.2, f.1, f.2) {
                bail!("'{name}': TIN patch edges cross ({:?}-{:?} and {:?}-{:?})", e.1, e.2, f.1, f.2);
            }
        }
        if !(e.1[0] > 0.0 && e.1[1] > 0.0 && e.1[0] < dw && e.1[1] < dh) {
            bail!("'{name}': TIN patch vertex {:?} is outside the grid", e.1);
        }
    }
    for (i, p) in patches.iter().enumerate() {
        for q in &patches[i + 1..] {
            if inside(&q.polygon, p.polygon[0]) || inside(&p.polygon, q.polygon[0]) {
                bail!("'{name}': TIN patches '{}' and '{}' overlap", p.name, q.name);
            }
        }
    }
    Ok((patches, tb_xy))
}

/// How close (grid units) a TB crossing may come to a grid vertex, and a
/// patch vertex to a grid line: closer is refused (the model needs every
/// TB vertex on exactly one grid line).
const LATTICE_EPS: f64 = 1e-6;

/// The TB of a polygon: its vertices plus every crossing with the lines
/// x = i and y = j, in order. Crossing coordinates on a line are exact.
fn boundary(name: &str, poly: &[[f64; 2]]) -> Result<Vec<[f64; 2]>> {
    let mut out = Vec::new();
    let n = poly.len();
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        for c in a {
            if (c - c.round()).abs() < LATTICE_EPS {
                bail!("patch '{name}': vertex {a:?} lies on a grid line");
            }
        }
        out.push(a);
        let mut hits: Vec<(f64, [f64; 2])> = Vec::new();
        for axis in 0..2 {
            let (lo, hi) = (a[axis].min(b[axis]), a[axis].max(b[axis]));
            let mut k = lo.ceil();
            while k < hi {
                let t = (k - a[axis]) / (b[axis] - a[axis]);
                let other = a[1 - axis] + t * (b[1 - axis] - a[1 - axis]);
                if (other - other.round()).abs() < LATTICE_EPS {
                    bail!("patch '{name}': edge {a:?}-{b:?} passes through grid vertex near ({k}, {other})");
                }
                let mut p = [0.0; 2];
                p[axis] = k;
                p[1 - axis] = other;
                hits.push((t, p));
                k += 1.0;
            }
        }
        hits.sort_by(|x, y| x.0.total_cmp(&y.0));
        out.extend(hits.into_iter().map(|h| h.1));
    }
    Ok(out)
}
