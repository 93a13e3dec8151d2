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

/// Pixels per tile: a row of 8, the SIMD vector of llvmpipe's 8-lane
/// compute (WORKGROUP is 8 wide).
pub const TILE: [u32; 2] = [8, 1];

/// Relative tolerance under which a face counts as seen edge-on (listed).
const EDGE_ON: f64 = 1e-6;

/// The boundary faces as the tiles need them: per face (in the order of the
/// shader's face list), its three vertices as indices into the boundary
/// points, and whether its cell is solid.
#[derive(Debug, Default)]
pub struct Faces {
    pub corners: Vec<[u32; 3]>,
    pub solid: Vec<bool>,
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
    /// Per face, the rows of tiles it reaches this frame (`[_, first, _,
    /// last]`; first > last: none), reused between frames.
    span: Vec<[u32; 4]>,
}

/// The camera as the lists see it: the eye, the view direction and the
/// image axes (`Camera::image_axes`), in world coordinates.
pub struct View {
    pub eye: [f64; 3],
    pub forward: [f64; 3],
    pub right: [f64; 3],
    pub up: [f64; 3],
    pub perspective: bool,
    pub size: [u32; 2],
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
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
    /// Lists `faces` (vertices in `points`, world coordinates) over the tiles
    /// of `rect` (inclusive pixel bounds, non-empty). Returns false, listing
    /// nothing, when a boundary vertex is at or behind the eye plane in
    /// perspective (the BVH search must run) or a projection is not finite.
    pub fn build(&mut self, faces: &Faces, points: &[[f64; 3]], view: &View, rect: [u32; 4], pad: f64) -> bool {
        self.first.clear();
        self.faces.clear();
        let (rr, uu) = (dot(view.right, view.right), dot(view.up, view.up));
        // Every boundary point in pixel coordinates, as pixel_rect maps them.
        let mut px = Vec::with_capacity(points.len());
        for &p in points {
            let q = sub(p, view.eye);
            let depth = if view.perspective { dot(q, view.forward) } else { 1.0 };
            if !(depth > 0.0) {
                return false;
            }
            let ndc = [dot(q, view.right) / (rr * depth), -dot(q, view.up) / (uu * depth)];
            let xy = [(ndc[0] + 1.0) * 0.5 * f64::from(view.size[0]) - 0.5, (ndc[1] + 1.0) * 0.5 * f64::from(view.size[1]) - 0.5];
            if !(xy[0].is_finite() && xy[1].is_finite()) {
                return false;
            }
            px.push(xy);
        }
        let [x0, y0, x1, y1] = rect;
        self.tiles = [(x1 - x0 + 1).div_ceil(TILE[0]), (y1 - y0 + 1).div_ceil(TILE[1])];
        let n_tiles = self.tiles[0] as usize * self.tiles[1] as usize;
        let mut count = vec![0u32; n_tiles + 1];
        self.span.clear();
        self.span.resize(faces.corners.len(), [1, 1, 0, 0]);
        for (i, c) in faces.corners.iter().enumerate() {
            let [a, b, d] = c.map(|k| points[k as usize]);
            if faces.solid[i] {
                let n = cross(sub(b, a), sub(d, a));
                let to = if view.perspective { sub(a, view.eye) } else { view.forward };
                let facing = dot(n, to);
                if facing > EDGE_ON * dot(n, n).sqrt() * dot(to, to).sqrt() {
                    continue;
                }
            }
            let p = c.map(|k| px[k as usize]);
            let lo_y = p[0][1].min(p[1][1]).min(p[2][1]) - pad;
            let hi_y = p[0][1].max(p[1][1]).max(p[2][1]) + pad;
            // The rows of tiles the padded box reaches, clamped to the
            // rectangle; per row, the columns of tiles the triangle's part
            // within the row's band (padded) reaches.
            let fy = [lo_y.floor().max(f64::from(y0)), hi_y.ceil().min(f64::from(y1))];
            if fy[0] > fy[1] {
                continue;
            }
            let rows = [(fy[0] as u32 - y0) / TILE[1], (fy[1] as u32 - y0) / TILE[1]];
            let mut any = false;
            for ty in rows[0]..=rows[1] {
                let band = [f64::from(y0 + ty * TILE[1]) - pad, f64::from(y0 + (ty + 1) * TILE[1] - 1) + pad];
                let Some([lx, hx]) = x_extent(&p, band) else { continue };
                let fx = [(lx - pad).floor().max(f64::from(x0)), (hx + pad).ceil().min(f64::from(x1))];
                if fx[0] > fx[1] {
                    continue;
                }
                any = true;
                for tx in (fx[0] as u32 - x0) / TILE[0]..=(fx[1] as u32 - x0) / TILE[0] {
                    count[(ty * self.tiles[0] + tx) as usize + 1] += 1;
                }
            }
            if any {
                self.span[i] = [0, rows[0], 0, rows[1]];
            }
        }
        for t in 0..n_tiles {
            count[t + 1] += count[t];
        }
        self.faces.resize(count[n_tiles] as usize, 0);
        let mut next = count.clone();
        for (i, t) in self.span.iter().enumerate() {
            if t[0] > t[2] || t[1] > t[3] {
                continue;
            }
            let p = faces.corners[i].map(|k| px[k as usize]);
            for ty in t[1]..=t[3] {
                let band = [f64::from(y0 + ty * TILE[1]) - pad, f64::from(y0 + (ty + 1) * TILE[1] - 1) + pad];
                let Some([lx, hx]) = x_extent(&p, band) else { continue };
                let fx = [(lx - pad).floor().max(f64::from(x0)), (hx + pad).ceil().min(f64::from(x1))];
                if fx[0] > fx[1] {
                    continue;
                }
                for tx in (fx[0] as u32 - x0) / TILE[0]..=(fx[1] as u32 - x0) / TILE[0] {
                    let slot = &mut next[(ty * self.tiles[0] + tx) as usize];
                    self.faces[*slot as usize] = i as u32;
                    *slot += 1;
                }
            }
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
        let q = sub(p, v.eye);
        let depth = if v.perspective { dot(q, v.forward) } else { 1.0 };
        let ndc = [dot(q, v.right) / depth, -dot(q, v.up) / depth];
        [(ndc[0] + 1.0) * 0.5 * f64::from(v.size[0]) - 0.5, (ndc[1] + 1.0) * 0.5 * f64::from(v.size[1]) - 0.5]
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
                assert!(lists.build(&faces, &points, &v, rect, 0.25));
                assert_eq!(lists.first.len() as u32, lists.tiles[0] * lists.tiles[1] + 1);
                for (i, c) in faces.corners.iter().enumerate() {
                    let [a, b, d] = c.map(|k| points[k as usize]);
                    let n = cross(sub(b, a), sub(d, a));
                    let to = if perspective { sub(a, v.eye) } else { v.forward };
                    let front = dot(n, to) < 0.0;
                    let p = [a, b, d].map(|q| pixel(&v, q));
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
                            if faces.solid[i] && !front {
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
        points.push([0.0, 0.0, 5.0]);
        let mut lists = TileLists::default();
        assert!(!lists.build(&faces, &points, &view(true), [0, 0, 63, 47], 2.0));
        assert!(lists.build(&faces, &points, &view(false), [0, 0, 63, 47], 2.0));
    }
}
