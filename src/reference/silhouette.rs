//! Pixels whose ray passes within a tolerance of the mesh's silhouette: the
//! one place the comparison with the reference may set pixels aside.
//!
//! A pixel centre on a boundary edge seen edge-on (the silhouette) is a
//! measure-zero ambiguity: whether its ray enters the mesh, and how long its
//! segment through the corner is, is decided by rounding — the GPU snaps
//! vertices to the rasterizer's sub-pixel grid (1/256 pixel on lavapipe)
//! and transforms them in f32, the reference intersects in f64. Near the
//! silhouette the segment is as short as the ray's distance from it, and in
//! a medium opaque within that length (stress case `opaque-1e6`: 1e-6 world
//! units) the pixel is fully covered on one side and empty on the other.
//! [`silhouette_pixels`] marks the pixels whose centre lies within
//! `tolerance` pixels of the projection of a silhouette edge; the stress
//! suite leaves exactly those out of the max error and reports how many.
//!
//! A silhouette edge is an edge of the boundary surface whose boundary faces
//! do not all face the same way from the eye (front, back, or edge-on), or
//! that only one boundary face holds.

use std::collections::HashMap;

use glam::DVec3;

use crate::mesh::topology::Topology;
use crate::mesh::adjacency::FACE_VERTS;
use crate::mesh::split::hex_grid_to_tets;
use crate::mesh::TetMesh;
use crate::scene::{Camera, Projection};

/// The tolerance the stress suite uses, in pixels: how far snapping to
/// lavapipe's sub-pixel grid (8 bits: each vertex coordinate moves up to
/// 1/512 pixel) can move an edge across a pixel centre, √2/512 ≈ 2.8e-3.
/// Far below a pixel: a silhouette line of `L` pixels holds about
/// `2 · L · tolerance` such centres (2 or 3 in `opaque-1e6` at 64x64 to
/// 512x512). The f32 ray of a ray caster is placed to ~1e-4 pixel, well
/// within it.
pub const SILHOUETTE_TOLERANCE_PX: f64 = std::f64::consts::SQRT_2 / 512.0;

/// Per pixel (row 0 at the top, as the images): whether its centre is within
/// `tolerance` pixels of a silhouette edge of `mesh` seen by `camera`.
pub fn silhouette_pixels(mesh: &TetMesh, camera: &Camera, width: u32, height: u32, tolerance: f64) -> Vec<bool> {
    let mut mask = vec![false; width as usize * height as usize];
    let topo = Topology::build(mesh);
    let eye = DVec3::from(camera.eye);
    let fwd = camera.forward();
    // Facing of each boundary face: the sign of n · (face point − eye)
    // (orthographic: n · forward); 0 edge-on.
    let mut edges: HashMap<(u32, u32), Vec<i8>> = HashMap::new();
    for &slot in &topo.boundary {
        let (c, f) = (slot as usize / 4, slot as usize % 4);
        let t = mesh.tets[c];
        let v = FACE_VERTS[f].map(|k| t[k]);
        let p = v.map(|i| DVec3::from(mesh.points[i as usize]));
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        let towards = match camera.projection {
            Projection::Perspective { .. } => p[0] - eye,
            Projection::Orthographic { .. } => fwd,
        };
        let facing = n.dot(towards).partial_cmp(&0.0).map_or(0, |o| o as i8);
        for k in 0..3 {
            let (a, b) = (v[k], v[(k + 1) % 3]);
            edges.entry((a.min(b), a.max(b))).or_default().push(facing);
        }
    }
    for ((a, b), facings) in edges {
        if facings.len() > 1 && facings.iter().all(|&s| s == facings[0]) {
            continue;
        }
        let (pa, pb) = (DVec3::from(mesh.points[a as usize]), DVec3::from(mesh.points[b as usize]));
        let Some((qa, qb)) = visible_part(camera, pa, pb) else { continue };
        mark_near_segment(&mut mask, width, height, camera, qa, qb, tolerance);
    }
    mask
}

/// [`silhouette_pixels`] of an axis-aligned box (a regular volume's
/// domain, `min` to `max`): the box as a 5-tet mesh, whose boundary is the
/// box's 6 faces (each two triangles; the diagonals are never silhouette
/// edges, both halves face the same way). A ray caster's entry and exit
/// points come from the same box, rasterized (raycast-fragment) or clipped
/// in f32 (raycast-compute): a centre on its outline is the same
/// measure-zero ambiguity as a mesh's.
pub fn box_silhouette_pixels(
    min: [f64; 3],
    max: [f64; 3],
    camera: &Camera,
    width: u32,
    height: u32,
    tolerance: f64,
) -> Vec<bool> {
    let points = (0..8).map(|i| box_corner(min, max, i)).collect();
    // A flat box (one sample thick on an axis) has no solid tets: its
    // outline is every edge of it.
    let solid = (0..3).all(|a| max[a] > min[a]);
    match hex_grid_to_tets("box", [2, 2, 2], points, vec![0.0; 8]) {
        Ok(mesh) if solid => silhouette_pixels(&mesh, camera, width, height, tolerance),
        _ => flat_box_outline(min, max, camera, width, height, tolerance),
    }
}

/// Corner `i` of the box: bit `a` of `i` picks `max` on axis `a` (the
/// order `hex_grid_to_tets` reads 2x2x2 points in).
fn box_corner(min: [f64; 3], max: [f64; 3], i: usize) -> [f64; 3] {
    std::array::from_fn(|a| if (i >> a) & 1 == 1 { max[a] } else { min[a] })
}

/// The outline of a box flat on at least one axis: every edge of its
/// (degenerate) box, the only thing a ray can graze.
fn flat_box_outline(min: [f64; 3], max: [f64; 3], camera: &Camera, width: u32, height: u32, tol: f64) -> Vec<bool> {
    let mut mask = vec![false; width as usize * height as usize];
    let corner = |i: usize| DVec3::from(box_corner(min, max, i));
    for i in 0..8usize {
        for a in 0..3 {
            let j = i | (1 << a);
            if j != i {
                if let Some((qa, qb)) = visible_part(camera, corner(i), corner(j)) {
                    mark_near_segment(&mut mask, width, height, camera, qa, qb, tol);
                }
            }
        }
    }
    mask
}

/// The part of segment `a`–`b` in front of the near plane (perspective; the
/// whole segment for orthographic views), or `None`.
fn visible_part(camera: &Camera, a: DVec3, b: DVec3) -> Option<(DVec3, DVec3)> {
    if !camera.is_perspective() {
        return Some((a, b));
    }
    let fwd = camera.forward();
    let eye = DVec3::from(camera.eye);
    let (za, zb) = ((a - eye).dot(fwd), (b - eye).dot(fwd));
    let near = camera.near;
    match (za >= near, zb >= near) {
        (true, true) => Some((a, b)),
        (false, false) => None,
        (true, false) => Some((a, a + (b - a) * ((za - near) / (za - zb)))),
        (false, true) => Some((b + (a - b) * ((zb - near) / (zb - za)), b)),
    }
}

fn mark_near_segment(mask: &mut [bool], width: u32, height: u32, camera: &Camera, a: DVec3, b: DVec3, tol: f64) {
    let (ax, ay, _) = camera.image_position(a, width, height);
    let (bx, by, _) = camera.image_position(b, width, height);
    if ![ax, ay, bx, by].iter().all(|c| c.is_finite()) {
        return;
    }
    let x0 = (ax.min(bx) - tol).ceil().max(0.0);
    let x1 = (ax.max(bx) + tol).floor().min(width as f64 - 1.0);
    let y0 = (ay.min(by) - tol).ceil().max(0.0);
    let y1 = (ay.max(by) + tol).floor().min(height as f64 - 1.0);
    if x0 > x1 || y0 > y1 {
        return;
    }
    let (dx, dy) = (bx - ax, by - ay);
    let len2 = dx * dx + dy * dy;
    for y in y0 as u32..=y1 as u32 {
        for x in x0 as u32..=x1 as u32 {
            let (px, py) = (x as f64 - ax, y as f64 - ay);
            let s = if len2 > 0.0 { ((px * dx + py * dy) / len2).clamp(0.0, 1.0) } else { 0.0 };
            let (ex, ey) = (px - s * dx, py - s * dy);
            if ex * ex + ey * ey <= tol * tol {
                mask[(y * width + x) as usize] = true;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube() -> TetMesh {
        let points = (0..8).map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64]).collect();
        hex_grid_to_tets("cube", [2, 2, 2], points, vec![0.0; 8]).expect("a valid cube")
    }

    // The unit cube (5 tets) seen along -z, orthographic, 8 pixels per
    // world unit: its outline (x, y = 0 and 1) runs half a pixel from the
    // centres of columns and rows 3, 4, 11 and 12. A tolerance of 0.6 marks
    // those along the outline (not the four pixels beyond its corners, 0.71
    // away); the front face's diagonals and the side faces seen edge-on are
    // not silhouette edges, so nothing inside is marked.
    #[test]
    fn marks_the_outline_and_nothing_else() {
        let camera = Camera {
            eye: [0.5, 0.5, 3.0],
            target: [0.5, 0.5, 0.0],
            up: [0.0, 1.0, 0.0],
            projection: Projection::Orthographic { height: 2.0 },
            near: 0.1,
            far: 10.0,
        };
        let mask = silhouette_pixels(&cube(), &camera, 16, 16, 0.6);
        let (x0, _, _) = camera.image_position(DVec3::new(0.0, 0.5, 0.0), 16, 16);
        let (x1, _, _) = camera.image_position(DVec3::new(1.0, 0.5, 0.0), 16, 16);
        assert_eq!((x0, x1), (3.5, 11.5));
        for y in 0..16u32 {
            for x in 0..16u32 {
                let near_x = [3, 4, 11, 12].contains(&x) && (4..=11).contains(&y);
                let near_y = [3, 4, 11, 12].contains(&y) && (4..=11).contains(&x);
                assert_eq!(mask[(y * 16 + x) as usize], near_x || near_y, "pixel ({x}, {y})");
            }
        }
        // A tolerance below the half-pixel offset marks nothing.
        assert!(silhouette_pixels(&cube(), &camera, 16, 16, 0.4).iter().all(|&m| !m));
        // The box of a volume over the same cube: the same outline.
        assert_eq!(box_silhouette_pixels([0.0; 3], [1.0; 3], &camera, 16, 16, 0.6), mask);
        // Flat on z (one sample thick): seen along -z, its rectangle's
        // edges are the outline, the same pixels.
        assert_eq!(box_silhouette_pixels([0.0; 3], [1.0, 1.0, 0.0], &camera, 16, 16, 0.6), mask);
    }
}
