//! The one camera every method and the CPU reference share. Rays and matrices
//! are built in f64 from the same parameters so that the GPU rasterizer and the
//! reference agree on which pixel sees what.
//!
//! Pixel convention: pixel (x, y) has its centre at (x + 0.5, y + 0.5); row 0 is
//! the top of the image. Clip space is Vulkan's: y points down, depth in [0, 1].

use glam::{DMat4, DVec3, DVec4};
use serde::Serialize;

use crate::mesh::Bounds;

#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Projection {
    /// Vertical field of view in degrees.
    Perspective { fovy_deg: f64 },
    /// Height of the view volume in world units.
    Orthographic { height: f64 },
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Camera {
    pub eye: [f64; 3],
    pub target: [f64; 3],
    pub up: [f64; 3],
    pub projection: Projection,
    pub near: f64,
    pub far: f64,
}

impl Camera {
    /// A camera on a circle around the bounds' centre, `angle` radians around
    /// the box's thinnest axis (ties: y), raised 25 degrees above the plane of
    /// the orbit, far enough that the whole box fits. The thinnest axis is
    /// "up" so that flat domains (the oxygen post's disk, the blunt fin's
    /// plate) are seen obliquely rather than face-on.
    pub fn orbit(bounds: &Bounds, angle: f64, projection: Projection) -> Camera {
        let c = DVec3::from(bounds.center());
        let r = 0.5 * bounds.diagonal().max(f64::MIN_POSITIVE);
        let fovy = match projection {
            Projection::Perspective { fovy_deg } => fovy_deg.to_radians(),
            Projection::Orthographic { .. } => 30f64.to_radians(),
        };
        let dist = r / (0.5 * fovy).sin() * 1.05;
        let extent = DVec3::from(bounds.max) - DVec3::from(bounds.min);
        let up_axis = if extent.x < extent.y && extent.x < extent.z {
            0
        } else if extent.z < extent.y {
            2
        } else {
            1
        };
        // (up, the orbit's 0-angle direction, the third axis), right-handed.
        let axes = [DVec3::X, DVec3::Y, DVec3::Z];
        let up = axes[up_axis];
        let a0 = axes[(up_axis + 2) % 3];
        let a1 = axes[(up_axis + 1) % 3];
        let elevation = 25f64.to_radians();
        let dir = (a0 * angle.cos() + a1 * angle.sin()) * elevation.cos() + up * elevation.sin();
        let eye = c + dir * dist;
        let projection = match projection {
            Projection::Orthographic { .. } => Projection::Orthographic { height: 2.1 * r },
            p => p,
        };
        Camera {
            eye: eye.into(),
            target: c.into(),
            up: up.into(),
            projection,
            near: (dist - r * 1.01).max(dist * 1e-3),
            far: dist + r * 1.01,
        }
    }

    pub fn is_perspective(&self) -> bool {
        matches!(self.projection, Projection::Perspective { .. })
    }

    /// View depth of the plane the near caps lie on (the cell-projection
    /// methods' `near.rs`, and the papers' model of them): just behind the
    /// near plane, by a part of the near distance and of the depth range, so
    /// that rounding does not clip it.
    pub fn near_cap_depth(&self) -> f64 {
        self.near + 1e-5 * self.near.abs() + 1e-6 * (self.far - self.near)
    }

    /// Unit vector from the eye towards the target.
    pub fn forward(&self) -> DVec3 {
        (DVec3::from(self.target) - DVec3::from(self.eye)).normalize()
    }

    /// World-to-view transform (right-handed, camera looks down -z).
    pub fn view(&self) -> DMat4 {
        let eye = DVec3::from(self.eye);
        let f = self.forward();
        let s = f.cross(DVec3::from(self.up)).normalize();
        let u = s.cross(f);
        DMat4::from_cols(
            DVec4::new(s.x, u.x, -f.x, 0.0),
            DVec4::new(s.y, u.y, -f.y, 0.0),
            DVec4::new(s.z, u.z, -f.z, 0.0),
            DVec4::new(-s.dot(eye), -u.dot(eye), f.dot(eye), 1.0),
        )
    }

    /// View-to-clip transform for Vulkan (y down, depth 0..1).
    pub fn proj(&self, aspect: f64) -> DMat4 {
        let (n, f) = (self.near, self.far);
        match self.projection {
            Projection::Perspective { fovy_deg } => {
                let t = 1.0 / (0.5 * fovy_deg.to_radians()).tan();
                DMat4::from_cols(
                    DVec4::new(t / aspect, 0.0, 0.0, 0.0),
                    DVec4::new(0.0, -t, 0.0, 0.0),
                    DVec4::new(0.0, 0.0, f / (n - f), -1.0),
                    DVec4::new(0.0, 0.0, n * f / (n - f), 0.0),
                )
            }
            Projection::Orthographic { height } => {
                let h = 0.5 * height;
                let w = h * aspect;
                DMat4::from_cols(
                    DVec4::new(1.0 / w, 0.0, 0.0, 0.0),
                    DVec4::new(0.0, -1.0 / h, 0.0, 0.0),
                    DVec4::new(0.0, 0.0, 1.0 / (n - f), 0.0),
                    DVec4::new(0.0, 0.0, n / (n - f), 1.0),
                )
            }
        }
    }

    pub fn view_proj(&self, width: u32, height: u32) -> DMat4 {
        self.proj(width as f64 / height as f64) * self.view()
    }

    /// The same eye and target with the field of view narrowed `factor`
    /// times (perspective: tan of the half angle divided; orthographic: the
    /// view volume's height divided), so the image zooms in on the target by
    /// that factor and cells away from it leave the view.
    pub fn zoomed(&self, factor: f64) -> Camera {
        let projection = match self.projection {
            Projection::Perspective { fovy_deg } => {
                let t = (0.5 * fovy_deg.to_radians()).tan() / factor;
                Projection::Perspective { fovy_deg: 2.0 * t.atan().to_degrees() }
            }
            Projection::Orthographic { height } => Projection::Orthographic { height: height / factor },
        };
        Camera { projection, ..*self }
    }

    /// The same eye looking the opposite way (the target mirrored through
    /// the eye), with the same projection, near and far. A camera outside
    /// the dataset's bounding sphere that looked at it (the orbit) then has
    /// the whole dataset behind it: nothing is in view. The runner's `fixed`
    /// frames use it to measure what a frame costs with nothing to draw.
    pub fn turned_away(&self) -> Camera {
        Camera { target: std::array::from_fn(|k| 2.0 * self.eye[k] - self.target[k]), ..*self }
    }

    /// The same camera moved by `by` (eye and target; the view is unchanged).
    pub fn translated(&self, by: [f64; 3]) -> Camera {
        Camera {
            eye: std::array::from_fn(|k| self.eye[k] + by[k]),
            target: std::array::from_fn(|k| self.target[k] + by[k]),
            ..*self
        }
    }

    /// [`Self::view_proj`] for points given relative to `origin` (it maps
    /// `p - origin` where `view_proj` maps `p`): the one place geometry far
    /// from the world origin is made relative. The camera is moved by
    /// `-origin` first, so the matrix holds the eye's offset from `origin`
    /// (small for a camera near the mesh) instead of `view_proj`'s
    /// translation by `-eye` followed by `+origin`, two terms as large as
    /// the coordinates that cancel in f64: at 1e14 from the world origin
    /// that loses ~0.02 world units, visible error on a unit-sized mesh.
    /// Callers subtract `origin` from their points in f64 (exact for
    /// points near it) before projecting or converting to f32.
    pub fn view_proj_relative(&self, origin: [f64; 3], width: u32, height: u32) -> DMat4 {
        self.translated(origin.map(|c| -c)).view_proj(width, height)
    }

    /// Where `p` lands in the image, the inverse of [`Self::ray`]: (x, y)
    /// with pixel (x, y)'s centre at integers, and the view depth
    /// `(p − eye)·forward` (perspective: only meaningful when positive).
    pub fn image_position(&self, p: DVec3, width: u32, height: u32) -> (f64, f64, f64) {
        let aspect = width as f64 / height as f64;
        let fwd = self.forward();
        let right = fwd.cross(DVec3::from(self.up)).normalize();
        let up = right.cross(fwd);
        let v = p - DVec3::from(self.eye);
        let depth = v.dot(fwd);
        let (sx, sy) = match self.projection {
            Projection::Perspective { fovy_deg } => {
                let t = (0.5 * fovy_deg.to_radians()).tan();
                (depth * t * aspect, depth * t)
            }
            Projection::Orthographic { height: h } => (0.5 * h * aspect, 0.5 * h),
        };
        let (ndc_x, ndc_y) = (v.dot(right) / sx, -v.dot(up) / sy);
        ((ndc_x + 1.0) * 0.5 * width as f64 - 0.5, (ndc_y + 1.0) * 0.5 * height as f64 - 0.5, depth)
    }

    /// The ray through the centre of pixel (x, y): origin and unit direction.
    /// For perspective the origin is the eye; for orthographic it lies on the
    /// near plane's parallel through the eye.
    pub fn ray(&self, x: f64, y: f64, width: u32, height: u32) -> (DVec3, DVec3) {
        let ndc_x = 2.0 * (x + 0.5) / width as f64 - 1.0;
        let ndc_y = 2.0 * (y + 0.5) / height as f64 - 1.0;
        let fwd = self.forward();
        let (right, up) = self.image_axes(width, height);
        let eye = DVec3::from(self.eye);
        if self.is_perspective() {
            (eye, (fwd + right * ndc_x - up * ndc_y).normalize())
        } else {
            (eye + right * ndc_x - up * ndc_y, fwd)
        }
    }

    /// The image's right and up axes scaled so that NDC x = 1 (y = -1) is
    /// the image's right (top) edge: at unit distance along `forward` under
    /// perspective, on the plane through the eye for orthographic views.
    /// The ray through NDC (x, y) is `forward + right x - up y` from the eye
    /// (perspective), or `forward` from `eye + right x - up y`.
    pub fn image_axes(&self, width: u32, height: u32) -> (DVec3, DVec3) {
        let aspect = width as f64 / height as f64;
        let fwd = self.forward();
        let right = fwd.cross(DVec3::from(self.up)).normalize();
        let up = right.cross(fwd);
        let (sx, sy) = match self.projection {
            Projection::Perspective { fovy_deg } => {
                let t = (0.5 * fovy_deg.to_radians()).tan();
                (t * aspect, t)
            }
            Projection::Orthographic { height: h } => (0.5 * h * aspect, 0.5 * h),
        };
        (right * sx, up * sy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // A point along the ray through a pixel's centre lands on that centre.
    #[test]
    fn image_position_inverts_ray() {
        for projection in [Projection::Perspective { fovy_deg: 30.0 }, Projection::Orthographic { height: 2.5 }] {
            let c = Camera { eye: [2.3, 1.7, 2.9], target: [0.5, 0.5, 0.5], up: [0.0, 1.0, 0.0], projection, near: 0.9, far: 9.0 };
            for (x, y) in [(0.0, 0.0), (17.0, 5.0), (47.0, 31.0)] {
                let (o, d) = c.ray(x, y, 48, 32);
                let (px, py, depth) = c.image_position(o + 3.0 * d, 48, 32);
                assert!((px - x).abs() < 1e-9 && (py - y).abs() < 1e-9, "{projection:?}: ({x}, {y}) -> ({px}, {py})");
                assert!(depth > 0.0);
            }
        }
    }

    fn bounds() -> Bounds {
        Bounds { min: [-1.0, -2.0, 0.0], max: [3.0, 1.0, 2.0] }
    }

    /// Zooming by 2 halves the image-plane extent: a point at NDC x
    /// lands at 2x.
    #[test]
    fn zoom_scales_the_image() {
        for projection in [Projection::Perspective { fovy_deg: 30.0 }, Projection::Orthographic { height: 1.0 }] {
            let cam = Camera::orbit(&bounds(), 0.3, projection);
            let z = cam.zoomed(2.0);
            let p = DVec3::from(cam.target) + DVec3::new(0.1, 0.05, -0.02);
            let ndc = |c: &Camera| {
                let v = c.view_proj(64, 64) * p.extend(1.0);
                (v.x / v.w, v.y / v.w)
            };
            let (a, b) = (ndc(&cam), ndc(&z));
            assert!((2.0 * a.0 - b.0).abs() < 1e-12 && (2.0 * a.1 - b.1).abs() < 1e-12, "{a:?} {b:?}");
        }
    }

    /// The orbit camera turned away sees none of the box: every corner
    /// lies behind the eye (view-space z > -near), at two orbit angles and
    /// both projections.
    #[test]
    fn turned_away_sees_nothing_of_the_box() {
        let b = bounds();
        for projection in [Projection::Perspective { fovy_deg: 30.0 }, Projection::Orthographic { height: 1.0 }] {
            for angle in [0.0, 2.5] {
                let cam = Camera::orbit(&b, angle, projection).turned_away();
                assert_eq!(cam.eye, Camera::orbit(&b, angle, projection).eye);
                for i in 0..8 {
                    let p = DVec3::new(
                        if i & 1 == 0 { b.min[0] } else { b.max[0] },
                        if i & 2 == 0 { b.min[1] } else { b.max[1] },
                        if i & 4 == 0 { b.min[2] } else { b.max[2] },
                    );
                    let v = cam.view() * p.extend(1.0);
                    assert!(v.z > -cam.near, "{projection:?} angle {angle}: corner {p} at view z {}", v.z);
                }
            }
        }
    }

    /// A point on a pixel's ray must project back to that pixel's centre.
    #[test]
    fn rays_project_to_their_pixels() {
        for projection in [
            Projection::Perspective { fovy_deg: 40.0 },
            Projection::Orthographic { height: 1.0 },
        ] {
            let cam = Camera::orbit(&bounds(), 0.7, projection);
            let (w, h) = (64u32, 48u32);
            let vp = cam.view_proj(w, h);
            for &(x, y) in &[(0.0, 0.0), (10.0, 40.0), (63.0, 47.0), (31.5, 23.5)] {
                let (o, d) = cam.ray(x, y, w, h);
                let p = o + d * (0.5 * (cam.near + cam.far));
                let c = vp * p.extend(1.0);
                let ndc = c.truncate() / c.w;
                let px = (ndc.x + 1.0) * 0.5 * w as f64 - 0.5;
                let py = (ndc.y + 1.0) * 0.5 * h as f64 - 0.5;
                assert!((px - x).abs() < 1e-9 && (py - y).abs() < 1e-9, "{projection:?} {x},{y} -> {px},{py}");
                assert!(ndc.z > 0.0 && ndc.z < 1.0);
            }
        }
    }
}
