//! Plane geometry of the hybrid model: polygon area and containment,
//! segment tests in f64 (patch placement, TIN points), and the f32 ear
//! clipping that the PC tessellation shares with its shader.

use anyhow::{bail, Result};

pub fn signed_area(p: &[[f64; 2]]) -> f64 {
    (0..p.len()).map(|i| {
        let (a, b) = (p[i], p[(i + 1) % p.len()]);
        a[0] * b[1] - b[0] * a[1]
    }).sum::<f64>() * 0.5
}

/// Even-odd point-in-polygon test.
pub fn inside(poly: &[[f64; 2]], p: [f64; 2]) -> bool {
    let mut c = false;
    let n = poly.len();
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + n - 1) % n]);
        if (a[1] > p[1]) != (b[1] > p[1]) && p[0] < (b[0] - a[0]) * (p[1] - a[1]) / (b[1] - a[1]) + a[0] {
            c = !c;
        }
    }
    c
}

pub fn cross(o: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
}

/// Whether segments ab and cd cross or touch.
pub fn segments_meet(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> bool {
    let (d1, d2) = (cross(a, b, c), cross(a, b, d));
    let (d3, d4) = (cross(c, d, a), cross(c, d, b));
    d1.signum() != d2.signum() && d3.signum() != d4.signum() || [d1, d2, d3, d4].contains(&0.0)
}

/// Distance from p to segment ab.
pub fn segment_distance(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let l2 = dx * dx + dy * dy;
    let t = if l2 > 0.0 { (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2).clamp(0.0, 1.0) } else { 0.0 };
    let (qx, qy) = (a[0] + t * dx - p[0], a[1] + t * dy - p[1]);
    (qx * qx + qy * qy).sqrt()
}

/// Twice the area (cell-local units²) below which a ring vertex counts as
/// collinear with its neighbours when no ear is left (f32 rounding of
/// coordinates up to 16 is ~1e-6; see `ear_clip`).
pub const FLAT_AREA: f32 = 1e-4;

/// Twice the signed area of triangle o, a, b in f32, evaluated in this
/// order (the shader's `cross2` is the same expression, `precise`).
pub fn cross_f32(o: [f32; 2], a: [f32; 2], b: [f32; 2]) -> f32 {
    let p = (a[0] - o[0]) * (b[1] - o[1]);
    let q = (a[1] - o[1]) * (b[0] - o[0]);
    p - q
}

/// Ear clipping of a simple counter-clockwise ring (cell-local positions
/// `pts`, geometry indices `ids`), in f32 (see `HybridModel::tessellate`):
/// the first convex vertex, in ring order, whose triangle holds no other
/// ring vertex is clipped, again and again. When nothing else can be
/// clipped, the first (nearly) collinear vertex is clipped as a flat
/// triangle (every ring edge stays an edge: dropping it would leave a
/// T-junction against the TIN or the neighbour, which the rasterizer's
/// snapping turns into gaps or overlaps).
pub fn ear_clip(pts: &[[f32; 2]], ids: &[u32], out: &mut Vec<u32>) -> Result<()> {
    let mut ring: Vec<usize> = (0..pts.len()).collect();
    while ring.len() > 3 {
        let n = ring.len();
        let mut clip = None;
        for k in 0..n {
            let (a, b, c) = (ring[(k + n - 1) % n], ring[k], ring[(k + 1) % n]);
            if cross_f32(pts[a], pts[b], pts[c]) <= 0.0 {
                continue;
            }
            let blocked = ring.iter().any(|&o| {
                o != a && o != b && o != c && {
                    let p = pts[o];
                    cross_f32(pts[a], pts[b], p) >= 0.0 && cross_f32(pts[b], pts[c], p) >= 0.0 && cross_f32(pts[c], pts[a], p) >= 0.0
                }
            });
            if !blocked {
                clip = Some(k);
                break;
            }
        }
        if clip.is_none() {
            clip = (0..n).find(|&k| cross_f32(pts[ring[(k + n - 1) % n]], pts[ring[k]], pts[ring[(k + 1) % n]]).abs() <= FLAT_AREA);
        }
        let Some(k) = clip else { bail!("no ear in a ring of {n} vertices (not simple or not counter-clockwise)") };
        out.extend([ids[ring[(k + n - 1) % n]], ids[ring[k]], ids[ring[(k + 1) % n]]]);
        ring.remove(k);
    }
    if ring.len() == 3 {
        out.extend(ring.iter().map(|&r| ids[r]));
    }
    Ok(())
}
