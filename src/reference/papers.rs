//! An f64 model of the papers' interpolation of exit data (the
//! cell-projection methods' `interpolation=paper`): what those methods
//! compute per ray, with the rounding taken out, so that the stress suite
//! can hold their rows to the integrator's bound against this model and
//! derive how far the model itself lies from the exact reference
//! (docs/stress.md, "How a row is judged").
//!
//! Per cell and ray, as `balanced.rs` `cell_records` and
//! `shaders/common/exit.glsl` do it: for each vertex k of the tet, t_k is the
//! distance along the ray through v_k to the plane opposite it
//! (−1 / (∇λ_k · dir(v_k)), clamped at ± the distance clamp), and the plane
//! is an exit for every ray through the tet when 0 < t_k < half the clamp.
//! At the ray's entry point p on a face the rasterizer interpolates
//! d_k = λ_k(p) t_k and the exit scalar s_k = s(p) + d_k (∇s · dir(v_k))
//! (perspective-correct: λ are p's barycentric weights on the face). The
//! segment is the nearest exit plane's: length min d_k (≥ 0), back scalar
//! that plane's s_k; none, or one longer than the mesh's longest edge (1 %
//! margin, `view_dir.w`), contributes nothing. Exact in orthographic views
//! (dir is the same for every ray), wrong under perspective by the factor
//! (∇λ_k · dir(p)) / (∇λ_k · dir(v_k)) between the vertex's and the ray's
//! directions to the plane.
//!
//! The cell holding the eye is drawn by a near cap (`near.rs`,
//! `cap.frag`): its section by a plane just behind the near plane
//! (`Camera::near_cap_depth`), fanned into triangles from its first corner,
//! with at each corner c the same records taken along c's own ray
//! (d_k = λ_k(c) t_k(dir(c)), s_k, w_k = λ_k(c)), which the rasterizer
//! interpolates (perspective-correct: p's weights on the triangle in 3-D).
//! [`PapersModel::cap_segment`] does the same; the exit planes are those
//! with 0 < d_k / w_k < half the clamp (`exit_planes`, its ratio test; the
//! shader's gradient form where |w_k| < 1e-3 is not modelled), and the
//! segment is extended back to the near plane as `cap.frag` extends it.

use crate::mesh::geometry::{cross, dot, plane_section, sub};

/// What the model needs beyond the cell: the view and the methods' clamps.
#[derive(Debug, Clone, Copy)]
pub struct PapersModel {
    /// Orthographic view direction (unit); also the direction for a vertex
    /// at the eye, as `FrameSetup::ray_direction` does.
    pub view_dir: [f64; 3],
    pub perspective: bool,
    /// |t_k| is clamped at this (`ExitTolerances::distance_clamp_diagonals`
    /// mesh diagonals).
    pub max_distance: f64,
    /// Segments longer than this contribute nothing (1.01 × longest edge).
    pub max_length: f64,
    /// View depths of the near plane and of the near caps' plane behind it
    /// (`Camera::near_cap_depth`).
    pub near: f64,
    pub cap_depth: f64,
}

impl PapersModel {
    /// The segment the papers' interpolation gives a ray entering the cell
    /// with vertices `v` (relative to the eye) and scalars `s` at point `p`
    /// (relative to the eye) of the face opposite vertex `f_in`, where the
    /// scalar is `s_front`: (length, scalar at its end). `None`: the cell
    /// contributes nothing on this ray (no exit plane, a flat cell, or
    /// longer than any cell).
    pub fn segment(&self, v: &[[f64; 3]; 4], s: &[f64; 4], f_in: usize, p: [f64; 3], s_front: f64) -> Option<(f64, f64)> {
        let grad = gradients(v)?;
        // p's weights on its face (the fourth is 0 there exactly, as on the GPU).
        let mut lambda: [f64; 4] = std::array::from_fn(|k| 1.0 + dot(grad[k], sub(p, v[k])));
        lambda[f_in] = 0.0;
        let sum: f64 = lambda.iter().sum();
        if sum == 0.0 || !sum.is_finite() {
            return None;
        }
        let lambda = lambda.map(|l| l / sum);
        let g: [f64; 3] = std::array::from_fn(|c| (0..4).map(|k| s[k] * grad[k][c]).sum());
        let mut best: Option<(f64, f64)> = None;
        for k in 0..4 {
            let dir = self.direction(v[k]);
            let t = (-1.0 / dot(grad[k], dir)).clamp(-self.max_distance, self.max_distance);
            if !(t > 0.0 && t < 0.5 * self.max_distance) {
                continue;
            }
            let d = lambda[k] * t;
            let len = d.max(0.0);
            if best.is_none_or(|(l, _)| len < l) {
                best = Some((len, s_front + d * dot(g, dir)));
            }
        }
        best.filter(|&(len, _)| len <= self.max_length)
    }

    /// The segment the near cap gives the ray with unit direction `d` from
    /// the eye (perspective) in the cell holding the eye (vertices `v` relative to the eye,
    /// scalars `s`): (t, scalar) at its start on the near plane and at its
    /// end. `None`: the cap draws nothing on this ray (the ray leaves the
    /// cell before the cap's plane, no exit plane, or longer than any cell).
    pub fn cap_segment(&self, v: &[[f64; 3]; 4], s: &[f64; 4], d: [f64; 3]) -> Option<((f64, f64), (f64, f64))> {
        let fwd = self.view_dir;
        let cos = dot(d, fwd);
        if cos <= 0.0 {
            return None;
        }
        let polygon = plane_section(v, &v.map(|q| dot(q, fwd)), self.cap_depth);
        let t_p = self.cap_depth / cos;
        let p = d.map(|x| x * t_p);
        // The fan's triangle holding p, and p's weights on it.
        let (corners, weights) = (1..polygon.len().saturating_sub(1)).find_map(|i| {
            let tri = [polygon[0], polygon[i], polygon[i + 1]];
            let n = cross(sub(tri[1], tri[0]), sub(tri[2], tri[0]));
            let area = dot(n, n);
            if area == 0.0 || !area.is_finite() {
                return None;
            }
            let w: [f64; 3] = std::array::from_fn(|j| {
                dot(n, cross(sub(tri[(j + 1) % 3], p), sub(tri[(j + 2) % 3], p))) / area
            });
            w.iter().all(|&x| x >= -1e-9).then_some((tri, w))
        })?;
        let grad = gradients(v)?;
        let g: [f64; 3] = std::array::from_fn(|c| (0..4).map(|k| s[k] * grad[k][c]).sum());
        // Each corner's record (near.rs `cap_records`), summed with p's weights.
        let (mut sf, mut dk, mut sk, mut wk) = (0.0, [0.0; 4], [0.0; 4], [0.0; 4]);
        for (c, &weight) in corners.iter().zip(&weights) {
            let l: [f64; 4] = std::array::from_fn(|k| 1.0 + dot(grad[k], sub(*c, v[k])));
            let sc: f64 = (0..4).map(|k| l[k] * s[k]).sum();
            let dir = self.direction(*c);
            let gd = dot(g, dir);
            sf += weight * sc;
            for k in 0..4 {
                let t = (-1.0 / dot(grad[k], dir)).clamp(-self.max_distance, self.max_distance);
                dk[k] += weight * l[k] * t;
                sk[k] += weight * (sc + gd * l[k] * t);
                wk[k] += weight * l[k];
            }
        }
        let mut best: Option<(f64, f64)> = None;
        for k in 0..4 {
            let (num, den) = (dk[k] * wk[k], wk[k] * wk[k]);
            if !(num > 0.0 && den > 0.0 && num < 0.5 * self.max_distance * den) {
                continue;
            }
            let len = dk[k].max(0.0);
            if best.is_none_or(|(l, _)| len < l) {
                best = Some((len, sk[k]));
            }
        }
        let (len, sb) = best.filter(|&(len, _)| len <= self.max_length)?;
        // Back to the near plane, the scalar extended linearly (cap.frag).
        let back = (self.cap_depth - self.near) / cos;
        let rate = if len > 0.0 { (sb - sf) / len } else { 0.0 };
        Some(((t_p - back, sf - rate * back), (t_p + len, sb)))
    }

    /// Unit direction of the ray through `q` (relative to the eye).
    fn direction(&self, q: [f64; 3]) -> [f64; 3] {
        if !self.perspective {
            return self.view_dir;
        }
        let n = dot(q, q).sqrt();
        if n > 0.0 {
            q.map(|x| x / n)
        } else {
            self.view_dir
        }
    }
}

/// The gradients of the tet's barycentric coordinates; `None` for a flat tet.
fn gradients(v: &[[f64; 3]; 4]) -> Option<[[f64; 3]; 4]> {
    let e = [sub(v[1], v[0]), sub(v[2], v[0]), sub(v[3], v[0])];
    let det = dot(e[0], cross(e[1], e[2]));
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let mut grad = [[0.0; 3]; 4];
    grad[1] = cross(e[1], e[2]).map(|x| x / det);
    grad[2] = cross(e[2], e[0]).map(|x| x / det);
    grad[3] = cross(e[0], e[1]).map(|x| x / det);
    grad[0] = std::array::from_fn(|c| -(grad[1][c] + grad[2][c] + grad[3][c]));
    Some(grad)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit corner tet; eye at the origin of relative coordinates.
    fn tet(offset: [f64; 3]) -> [[f64; 3]; 4] {
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
            .map(|q| std::array::from_fn(|c| q[c] + offset[c]))
    }

    fn model(perspective: bool, view_dir: [f64; 3]) -> PapersModel {
        PapersModel { view_dir, perspective, max_distance: 1e3, max_length: 1.01 * 2f64.sqrt(), near: 1e-3, cap_depth: 1e-3 }
    }

    #[test]
    fn orthographic_segments_are_exact() {
        // Looking along +z through the face z = 0 (opposite vertex 3): the
        // exit is the slanted face x + y + z = 1 at z = 1 - x - y.
        let v = tet([0.0, 0.0, 0.0]);
        let s = [0.0, 1.0, 2.0, 3.0]; // s = x + 2y + 3z
        let m = model(false, [0.0, 0.0, 1.0]);
        for (x, y) in [(0.2, 0.3), (0.6, 0.1), (0.05, 0.05)] {
            let p = [x, y, 0.0];
            let (len, sb) = m.segment(&v, &s, 3, p, x + 2.0 * y).unwrap();
            let exact = 1.0 - x - y;
            assert!((len - exact).abs() < 1e-12, "{len} vs {exact}");
            assert!((sb - (x + 2.0 * y + 3.0 * exact)).abs() < 1e-12);
        }
    }

    #[test]
    fn perspective_is_exact_at_the_vertices_and_off_between() {
        // The tet 4 units in front of the eye, seen along +z: at the vertex
        // of the entry face whose plane is the exit (λ_k = 1) the papers'
        // distance is t_k itself, exact; inside the face it is λ_k t_k, and
        // the exact distance differs by the directions' factor.
        let v = tet([0.1, 0.2, 4.0]);
        let s = [0.0; 4];
        let m = model(true, [0.0, 0.0, 1.0]);
        // Near vertex 0 (its opposite plane is the exit): λ_0 → 1.
        let p0 = [0.1 + 1e-9, 0.2 + 1e-9, 4.0];
        let (len0, _) = m.segment(&v, &s, 3, p0, 0.0).unwrap();
        let dir0 = m.direction(v[0]);
        let n = [1.0, 1.0, 1.0];
        let exact0 = 1.0 / dot(n, dir0);
        assert!((len0 - exact0).abs() < 1e-6, "{len0} vs {exact0}");
        // The face's centroid: the exact exit along the ray through it.
        let pc = [0.1 + 1.0 / 3.0, 0.2 + 1.0 / 3.0, 4.0];
        let (len, _) = m.segment(&v, &s, 3, pc, 0.0).unwrap();
        let dir = m.direction(pc);
        // Plane x + y + z = 0.1 + 0.2 + 4 + 1 = 5.3 from pc along dir.
        let exact = (5.3 - dot(n, pc)) / dot(n, dir);
        assert!((len - exact).abs() > 1e-2, "perspective must differ: {len} vs {exact}");
        // The papers' value: λ_0 = 1/3 of vertex 0's distance to its plane
        // along its own ray (planes 1, 2 and 3 lie behind their vertices).
        assert!((len - exact0 / 3.0).abs() < 1e-12, "{len} vs {}", exact0 / 3.0);
    }

    #[test]
    fn cap_interpolates_its_corners_records() {
        // The eye inside a unit corner tet (relative coordinates: the tet
        // moved by -eye) near its corner, looking along (1, 1, 1): the cap
        // is a triangle whose corners lie on the edges from vertex 0, and
        // every ray through it leaves by the slanted face, about 0.4 away.
        // Each corner's records are taken along its own ray, which grazes
        // that face: λ_0 t_0 = 2.26 at every corner, so the interpolated
        // exit is 2.26 away everywhere, farther than any cell, and the cap
        // draws nothing (as near.rs + cap.frag draw it: issue 20). Without
        // that guard the segment starts on the near plane with the exact
        // scalar (affine, interpolated exactly) and ends 2.26 away.
        let eye = [0.1, 0.1, 0.1];
        let v = tet(eye.map(|x| -x));
        let s = [0.0, 1.0, 2.0, 3.0]; // s = x + 2y + 3z
        let r = 1.0 / 3f64.sqrt();
        let mut m = model(true, [r, r, r]);
        (m.near, m.cap_depth) = (0.05, 0.05 + 1e-7);
        let c = plane_section(&v, &v.map(|q| dot(q, m.view_dir)), m.cap_depth);
        assert_eq!(c.len(), 3);
        let scalar = |d: [f64; 3], t: f64| (0..3).map(|k| [1.0, 2.0, 3.0][k] * (eye[k] + t * d[k])).sum::<f64>();
        // The corners' common d_0: λ_0(c) (-1 / (∇λ_0 · dir(c))).
        let corner = c[0].map(|x| x / dot(c[0], c[0]).sqrt());
        let d0 = (1.0 - eye.iter().sum::<f64>() - dot([1.0; 3], c[0])) / dot([1.0; 3], corner);
        assert!((d0 - 2.2637).abs() < 1e-3, "{d0}");
        let unguarded = PapersModel { max_length: 10.0, ..m };
        for i in 1..10 {
            for j in 1..10 - i {
                let w = [f64::from(i) / 10.0, f64::from(j) / 10.0, f64::from(10 - i - j) / 10.0];
                let q: [f64; 3] = std::array::from_fn(|k| w[0] * c[0][k] + w[1] * c[1][k] + w[2] * c[2][k]);
                let d = q.map(|x| x / dot(q, q).sqrt());
                assert!(m.cap_segment(&v, &s, d).is_none(), "{w:?}");
                let ((t0, s0), (t1, _)) = unguarded.cap_segment(&v, &s, d).unwrap();
                let t_p = m.cap_depth / dot(d, m.view_dir);
                assert!((t0 - m.near / dot(d, m.view_dir)).abs() < 1e-12, "starts on the near plane: {t0}");
                assert!((s0 - scalar(d, t0)).abs() < 1e-6, "{s0} vs {}", scalar(d, t0));
                assert!((t1 - t_p - d0).abs() < 1e-9, "{t1} vs {}", t_p + d0);
            }
        }
        // A ray that leaves the cell before the cap's plane: no cap.
        assert!(unguarded.cap_segment(&v, &s, [-r, -r, -r]).is_none());
    }
}
