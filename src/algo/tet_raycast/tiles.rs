//! The boundary faces a ray may enter, listed per screen tile per frame, so
//! that a ray's entry search tests its tile's faces instead of walking the
//! boundary BVH (walk.comp, `TILE_LISTS`).
//!
//! On llvmpipe a BVH step costs a node-pair test and a face test whichever a
//! lane needs (a branch's body runs for every lane of the SIMD vector), about
//! twice a cell step, and a search visits ~20 of them; a tile's list holds
//! the few faces whose projection reaches the tile, and every lane of a
//! vector (a row of 8 pixels: llvmpipe fills a vector with consecutive
//! invocations) reads the same list. Lists are used when every boundary
//! vertex is in front of the eye plane (perspective) or always
//! (orthographic); otherwise a ray's line meets the mesh behind the eye too,
//! and the BVH search runs.
//!
//! A face is listed in every tile its projected triangle, padded by `pad`
//! pixels, reaches (per row of tiles, the triangle's part within the row's
//! padded band): a superset of the pixels whose rays cross it. A face
//! of a solid cell that faces away from the eye (orthographic: from the view
//! direction) is left out: a ray crosses it leaving the mesh, never entering
//! (walk.comp's `enters` refuses that orientation). Faces seen nearly edge-on,
//! and those of flat cells (crossed either way), are listed.

use glam::DVec3;

/// Pixels per tile: a row of 8, the SIMD vector of llvmpipe's 8-lane
/// compute (WORKGROUP is 8 wide).
pub const TILE: [u32; 2] = [8, 1];

/// A face of a solid cell counts as facing away only beyond this share of
/// |n| |to eye| (the cosine): the shader decides crossings in f32, so a face
/// seen nearly edge-on is listed.
const EDGE_ON: f64 = 1e-4;

/// A point nearer the eye plane than this share of its distance from the
/// eye is not projected (its pixel coordinates would be too large to bin
/// within the pad): the BVH search runs instead.
const MIN_DEPTH: f64 = 1e-6;

/// The boundary faces as the tiles need them: per face (in the order of the
/// shader's face list), its three vertices as indices into the boundary
/// points, and whether its cell is solid.
#[derive(Debug, Default)]
pub struct Faces {
    pub corners: Vec<[u32; 3]>,
    pub solid: Vec<bool>,
}

impl Faces {
    /// Which way boundary face `i` faces the eye (orthographic: the view
    /// direction), from the points as the shader holds them: -1 towards it,
    /// 1 away, 0 nearly edge-on (within [`EDGE_ON`]) or a flat cell's face
    /// (crossed either way). The tile lists leave out the faces at 1; the
    /// silhouettes are the edges between faces of different sides.
    pub fn side(&self, i: usize, shader_points: &[[f32; 3]], shader_eye: [f64; 3], view: &View) -> i8 {
        if !self.solid[i] {
            return 0;
        }
        let [a, b, d] = self.corners[i].map(|k| DVec3::from(shader_points[k as usize].map(f64::from)));
        let n = (b - a).cross(d - a);
        let to = if view.perspective { a - DVec3::from(shader_eye) } else { DVec3::from(view.forward) };
        let dot = n.dot(to);
        let limit = EDGE_ON * n.length() * to.length();
        if dot > limit {
            1
        } else if dot < -limit {
            -1
        } else {
            0
        }
    }
}

/// One frame's lists: tile `t`'s faces are `faces[first[t]..first[t + 1]]`
/// (indices into the shader's face list), tiles row-major over the frame's
/// pixel rectangle from its corner.
#[derive(Debug, Default)]
pub struct TileLists {
    pub first: Vec<u32>,
    pub faces: Vec<u32>,
    /// Tiles across and down the rectangle.
    pub tiles: [u32; 2],
    /// The visit's (tile, face) pairs, kept between frames for their
    /// allocation.
    pairs: Vec<(u32, u32)>,
}

/// The camera as the lists see it: the eye, the view direction and the
/// image axes (`Camera::image_axes`: perpendicular to `forward`, scaled so
/// that ndc 1 is the image's edge), in world coordinates.
pub struct View {
    pub eye: [f64; 3],
    pub forward: [f64; 3],
    pub right: [f64; 3],
    pub up: [f64; 3],
    pub perspective: bool,
    pub size: [u32; 2],
}

impl View {
    /// Where `q` (relative to the eye) projects, in pixel coordinates (the
    /// pixel centre x + 0.5 of the shader's rays at x): None at or behind
    /// the eye plane, within [`MIN_DEPTH`] of it, or not finite.
    pub fn pixel(&self, q: [f64; 3]) -> Option<[f64; 2]> {
        let (q, f, r, u) = (DVec3::from(q), DVec3::from(self.forward), DVec3::from(self.right), DVec3::from(self.up));
        let depth = if self.perspective { q.dot(f) } else { 1.0 };
        if !(depth > MIN_DEPTH * q.length()) {
            return None;
        }
        let ndc = [q.dot(r) / (r.length_squared() * depth), -q.dot(u) / (u.length_squared() * depth)];
        let xy = [(ndc[0] + 1.0) * 0.5 * f64::from(self.size[0]) - 0.5, (ndc[1] + 1.0) * 0.5 * f64::from(self.size[1]) - 0.5];
        (xy[0].is_finite() && xy[1].is_finite()).then_some(xy)
    }
}

/// Where a set of points falls on the image ([`View::project`]).
#[derive(Debug, Clone, PartialEq)]
pub enum Projected {
    /// Every point in front of the eye: its pixel coordinates, in order.
    Pixels(Vec<[f64; 2]>),
    /// Every point at or behind the eye plane in perspective (or no
    /// points): nothing the rays integrate lies in their hull.
    NoneInFront,
    /// Points on both sides of the eye plane, or one too near it or not
    /// finite: a ray's line may meet their hull anywhere.
    Unplaced,
}

impl View {
    /// Projects `points` (world coordinates) once: for the frame's pixel
    /// rectangle (`pixel_rect`) and the tile lists ([`TileLists::build`]).
    pub fn project(&self, points: &[[f64; 3]]) -> Projected {
        let eye = DVec3::from(self.eye);
        let forward = DVec3::from(self.forward);
        let mut px = Vec::with_capacity(points.len());
        let mut behind = 0usize;
        for &p in points {
            let q = DVec3::from(p) - eye;
            let depth = if self.perspective { q.dot(forward) } else { 1.0 };
            if depth.is_nan() {
                return Projected::Unplaced;
            }
            if depth <= 0.0 {
                behind += 1;
                continue;
            }
            match self.pixel(q.into()) {
                Some(xy) => px.push(xy),
                None => return Projected::Unplaced,
            }
        }
        match behind {
            0 if !points.is_empty() => Projected::Pixels(px),
            b if b == points.len() => Projected::NoneInFront,
            _ => Projected::Unplaced,
        }
    }
}

/// The x extent of triangle `p`'s part within the band `y` in
/// [band[0], band[1]] (pixel coordinates), or None when it has none: the
/// extremes of the polygon the band cuts from the triangle lie at its
/// vertices within the band or where its edges cross the band's lines.
fn x_extent(p: &[[f64; 2]; 3], band: [f64; 2]) -> Option<[f64; 2]> {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    let mut take = |x: f64| {
        lo = lo.min(x);
        hi = hi.max(x);
    };
    for k in 0..3 {
        let (a, b) = (p[k], p[(k + 1) % 3]);
        if (band[0]..=band[1]).contains(&a[1]) {
            take(a[0]);
        }
        for y in band {
            // The edge crosses the line y (an edge along it has its vertices
            // taken above).
            if (a[1] - y) * (b[1] - y) < 0.0 {
                take(a[0] + (b[0] - a[0]) * (y - a[1]) / (b[1] - a[1]));
            }
        }
    }
    (lo <= hi).then_some([lo, hi])
}

impl TileLists {
    /// Lists `faces` over the tiles of `rect` (inclusive pixel bounds,
    /// non-empty): `projected` is the boundary points' projection
    /// ([`View::project`]), `shader_points` the same points as the shader
    /// holds them (f32, relative to the render origin) and `shader_eye` the
    /// eye likewise (what decides which way a face faces). Returns false,
    /// listing nothing, when the BVH search must run instead: a boundary
    /// point not in front of the eye or not placed ([`Projected`]), or more
    /// tiles or entries than `max_texels` (the device's texel-buffer limit).
    #[allow(clippy::too_many_arguments)]
    pub fn build(
        &mut self,
        faces: &Faces,
        projected: &Projected,
        shader_points: &[[f32; 3]],
        shader_eye: [f64; 3],
        view: &View,
        rect: [u32; 4],
        pad: f64,
        max_texels: u64,
    ) -> bool {
        self.first.clear();
        self.faces.clear();
        let Projected::Pixels(px) = projected else { return false };
        let [x0, y0, x1, y1] = rect;
        self.tiles = [(x1 - x0 + 1).div_ceil(TILE[0]), (y1 - y0 + 1).div_ceil(TILE[1])];
        let tiles_x = self.tiles[0];
        let n_tiles = u64::from(self.tiles[0]) * u64::from(self.tiles[1]);
        if n_tiles + 1 > max_texels {
            return false;
        }
        let n_tiles = n_tiles as usize;
        let listed = |i: usize| faces.side(i, shader_points, shader_eye, view) <= 0;
        // Per row of tiles a face reaches, the columns of tiles its
        // triangle's part within the row's band (padded) reaches.
        let rows = |p: &[[f64; 2]; 3]| -> Option<[u32; 2]> {
            let lo = p[0][1].min(p[1][1]).min(p[2][1]) - pad;
            let hi = p[0][1].max(p[1][1]).max(p[2][1]) + pad;
            let fy = [lo.floor().max(f64::from(y0)), hi.ceil().min(f64::from(y1))];
            (fy[0] <= fy[1]).then(|| [(fy[0] as u32 - y0) / TILE[1], (fy[1] as u32 - y0) / TILE[1]])
        };
        let columns = |p: &[[f64; 2]; 3], ty: u32| -> Option<[u32; 2]> {
            let band = [f64::from(y0 + ty * TILE[1]) - pad, f64::from(y0 + (ty + 1) * TILE[1] - 1) + pad];
            let [lx, hx] = x_extent(p, band)?;
            let fx = [(lx - pad).floor().max(f64::from(x0)), (hx + pad).ceil().min(f64::from(x1))];
            (fx[0] <= fx[1]).then(|| [(fx[0] as u32 - x0) / TILE[0], (fx[1] as u32 - x0) / TILE[0]])
        };
        let visit = |i: usize, f: &mut dyn FnMut(usize)| {
            if !listed(i) {
                return;
            }
            let p = faces.corners[i].map(|k| px[k as usize]);
            let Some([r0, r1]) = rows(&p) else { return };
            for ty in r0..=r1 {
                if let Some([c0, c1]) = columns(&p, ty) {
                    for tx in c0..=c1 {
                        f((ty * tiles_x + tx) as usize);
                    }
                }
            }
        };
        // One visit lists (tile, face) pairs, checking the total against
        // the limit as it goes; a counting sort by tile then keeps each
        // tile's faces in face order.
        let pairs = &mut self.pairs;
        pairs.clear();
        for i in 0..faces.corners.len() {
            visit(i, &mut |t| pairs.push((t as u32, i as u32)));
            if pairs.len() as u64 > max_texels {
                return false;
            }
        }
        let mut count = vec![0u32; n_tiles + 1];
        for &(t, _) in pairs.iter() {
            count[t as usize + 1] += 1;
        }
        for t in 0..n_tiles {
            count[t + 1] += count[t];
        }
        let mut next = count.clone();
        self.faces.resize(pairs.len(), 0);
        for &(t, i) in pairs.iter() {
            self.faces[next[t as usize] as usize] = i;
            next[t as usize] += 1;
        }
        self.first = count;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view(perspective: bool) -> View {
        // Looking down -z from z = 5; image axes scaled so that ndc 1 is the
        // edge of a 2 x 2 square at depth 1 (perspective) or of the plane.
        View { eye: [0.0, 0.0, 5.0], forward: [0.0, 0.0, -1.0], right: [1.0, 0.0, 0.0], up: [0.0, 1.0, 0.0], perspective, size: [64, 48] }
    }

    fn pixel(v: &View, p: [f64; 3]) -> [f64; 2] {
        v.pixel((DVec3::from(p) - DVec3::from(v.eye)).into()).unwrap()
    }

    /// The lists with the points as their own shader points (f32).
    fn build(l: &mut TileLists, faces: &Faces, points: &[[f64; 3]], v: &View, rect: [u32; 4], max: u64) -> bool {
        let shader: Vec<[f32; 3]> = points.iter().map(|p| p.map(|c| c as f32)).collect();
        l.build(faces, &v.project(points), &shader, v.eye, v, rect, 0.25, max)
    }

    fn listed(l: &TileLists, rect: [u32; 4], x: u32, y: u32) -> &[u32] {
        let t = ((y - rect[1]) / TILE[1] * l.tiles[0] + (x - rect[0]) / TILE[0]) as usize;
        &l.faces[l.first[t] as usize..l.first[t + 1] as usize]
    }

    #[test]
    fn every_pixel_inside_a_front_face_lists_it() {
        // Pseudo-random triangles at several depths, both windings, in both
        // projections and two rectangles: each pixel centre inside a
        // triangle facing the eye (or of a flat cell) finds it in its tile;
        // a solid cell's face turned away is listed nowhere.
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut points = Vec::new();
        let mut faces = Faces::default();
        for i in 0..60u32 {
            let z = -1.0 + 3.0 * rnd();
            let c = [rnd() * 4.0 - 2.0, rnd() * 3.0 - 1.5];
            for _ in 0..3 {
                points.push([c[0] + rnd() - 0.5, c[1] + rnd() - 0.5, z + 0.2 * rnd()]);
            }
            faces.corners.push([3 * i, 3 * i + 1, 3 * i + 2]);
            faces.solid.push(i % 5 != 0);
        }
        let mut hits = 0;
        for perspective in [true, false] {
            let v = view(perspective);
            for rect in [[0, 0, 63, 47], [5, 3, 50, 40]] {
                let mut lists = TileLists::default();
                assert!(build(&mut lists, &faces, &points, &v, rect, u64::MAX));
                assert_eq!(lists.first.len() as u32, lists.tiles[0] * lists.tiles[1] + 1);
                for (i, c) in faces.corners.iter().enumerate() {
                    let [a, b, d] = c.map(|k| DVec3::from(points[k as usize]));
                    let n = (b - a).cross(d - a);
                    let to = if perspective { a - DVec3::from(v.eye) } else { DVec3::from(v.forward) };
                    let front = n.dot(to) < 0.0;
                    let clearly_back = n.dot(to) > 1e-3 * n.length() * to.length();
                    let p = c.map(|k| pixel(&v, points[k as usize]));
                    for y in rect[1]..=rect[3] {
                        for x in rect[0]..=rect[2] {
                            let e = |s: [f64; 2], t: [f64; 2]| (t[0] - s[0]) * (y as f64 - s[1]) - (t[1] - s[1]) * (x as f64 - s[0]);
                            let w = [e(p[0], p[1]), e(p[1], p[2]), e(p[2], p[0])];
                            let inside = w.iter().all(|&w| w >= 0.0) || w.iter().all(|&w| w <= 0.0);
                            let has = listed(&lists, rect, x, y).contains(&(i as u32));
                            if inside && (front || !faces.solid[i]) {
                                assert!(has, "face {i} at pixel ({x}, {y}) not listed ({perspective}, {rect:?})");
                                hits += 1;
                            }
                            if faces.solid[i] && clearly_back {
                                assert!(!has, "face {i} faces away but is listed");
                            }
                        }
                    }
                }
            }
        }
        // The triangles cover a good share of the pixels.
        assert!(hits > 500, "{hits}");
        // A boundary point at or behind the eye plane in perspective: no
        // lists (the BVH search runs).
        let mut lists = TileLists::default();
        let mut behind = points.clone();
        behind.push([0.3, 0.0, 5.0]);
        assert!(!build(&mut lists, &faces, &behind, &view(true), [0, 0, 63, 47], u64::MAX));
        assert!(build(&mut lists, &faces, &behind, &view(false), [0, 0, 63, 47], u64::MAX));
        // More tiles or entries than the device's texel buffers hold: the
        // BVH instead.
        assert!(build(&mut lists, &faces, &points, &view(true), [0, 0, 63, 47], 10_000));
        let entries = lists.faces.len() as u64;
        assert!(!build(&mut lists, &faces, &points, &view(true), [0, 0, 63, 47], entries - 1));
        assert!(!build(&mut lists, &faces, &points, &view(true), [0, 0, 63, 47], 64 * 48 / 8));
    }
}
