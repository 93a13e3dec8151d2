//! Near caps: the cells around the eye, for every tetrahedral
//! cell-projection method. A cell is drawn from its entry faces, unclipped
//! at the near plane (depth clamp): a face fragment in front of the plane
//! integrates from it (`start_at_near`, common/clip.glsl), so a cell the
//! near plane cuts needs nothing more, unless it holds the eye: every face
//! of such a cell faces away from the eye, none is drawn, and every ray
//! starts inside it. So each frame the CPU finds the cells that hold the
//! eye (none unless the eye is in the mesh's bounding box) and reach past
//! the near plane, and sends the section of each by a plane just behind the
//! near plane (`Camera::near_cap_depth`) as one or two triangles, with the records
//! `cap.frag` needs at each corner. They are drawn after all cells: on any
//! ray the segment from the near plane is the first one, so "over" puts it
//! on top. `cap.frag` integrates from the near plane to the exit, stopped
//! at the far plane. (Caps for every cut cell, with a test for where the
//! entry face takes over, left single pixels along the section with the
//! cell twice or never: the clipped faces' vertices are snapped to the
//! rasterizer's sub-pixel grid and the cap's test used interpolated
//! values with the same error.) The per-frame bytes are counted with the
//! cells' records.

use std::sync::Arc;

use rayon::prelude::*;

use super::{build_pipeline, CellProjector, DrawSettings, RelativeMesh};
use crate::algo::tet_mesh::FrameSetup;
use crate::algo::integrate::IntegrationTables;
use crate::mesh::geometry::plane_section;
use crate::scene::Camera;
use crate::vk::{
    Buffer, BufferDesc, CommandRecorder, Context, DescriptorSet, DescriptorSetDesc, Pipeline, UploadClass, UploadCounter,
    VertexAttribute, VkResult,
};
use crate::vk::{BufferUsage, Format, Topology};

/// pos 3, s_f 1, d 4, s 4, w 4, g 1, code 1.
pub const FLOATS_PER_VERTEX: usize = 18;

pub struct NearCaps {
    /// Positions relative to the mesh's render origin, and scalars mapped as
    /// the device sees them (`scalar_map`), in f64; shared with the culler.
    mesh: Arc<RelativeMesh>,
    /// The points' bounding box (relative to `origin`).
    bounds: ([f64; 3], [f64; 3]),
    records: Vec<f32>,
    vertices: usize,
    buffer: Option<Buffer>,
    pipeline: Arc<Pipeline>,
}

impl NearCaps {
    pub fn host_bytes(&self, memory: &mut crate::algo::host_memory::HostMemory) {
        memory.vec("near caps: records", &self.records);
    }
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

/// The barycentric coordinates of a tet as affine functions: lambda_k(p) =
/// grad[k] . (p - v0) + base[k]. None for a flat tet.
fn barycentric(v: &[[f64; 3]; 4]) -> Option<([[f64; 3]; 4], [f64; 4])> {
    let (e1, e2, e3) = (sub(v[1], v[0]), sub(v[2], v[0]), sub(v[3], v[0]));
    let det = dot(e1, cross(e2, e3));
    let scale = (dot(e1, e1) * dot(e2, e2) * dot(e3, e3)).sqrt();
    if det.abs() <= 1e-12 * scale || !det.is_finite() {
        return None;
    }
    // Rows of the inverse of [e1 e2 e3]: gradients of lambda_1..3.
    let g1 = cross(e2, e3).map(|x| x / det);
    let g2 = cross(e3, e1).map(|x| x / det);
    let g3 = cross(e1, e2).map(|x| x / det);
    let g0 = [-(g1[0] + g2[0] + g3[0]), -(g1[1] + g2[1] + g3[1]), -(g1[2] + g2[2] + g3[2])];
    Some(([g0, g1, g2, g3], [1.0, 0.0, 0.0, 0.0]))
}

impl NearCaps {
    pub fn new(
        ctx: &Arc<Context>,
        mesh: Arc<RelativeMesh>,
        tables: &IntegrationTables,
        draw: &DrawSettings,
        pieces_set: Option<DescriptorSetDesc>,
    ) -> VkResult<Self> {
        let f = |location, format, floats: u32| VertexAttribute { location, format, offset: floats * 4 };
        let attributes = [
            f(0, Format::Rgb32Float, 0),
            f(1, Format::R32Float, 3),
            f(2, Format::Rgba32Float, 4),
            f(3, Format::Rgba32Float, 8),
            f(4, Format::Rgba32Float, 12),
            f(5, Format::R32Float, 16),
            f(6, Format::R32Float, 17),
        ];
        let (vertex, fragment) = if pieces_set.is_some() {
            ("cell_projection/cap_pieces.vert", "cell_projection/cap_pieces.frag")
        } else {
            ("cell_projection/cap.vert", "cell_projection/cap.frag")
        };
        let (pipeline, _) = build_pipeline(
            ctx,
            vertex,
            fragment,
            (FLOATS_PER_VERTEX * 4) as u32,
            &attributes,
            Topology::TriangleList,
            false,
            tables,
            draw,
            pieces_set.as_slice(),
            &[],
        )?;
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for p in &mesh.points {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        Ok(NearCaps {
            mesh,
            bounds: (lo, hi),
            records: Vec::new(),
            vertices: 0,
            buffer: None,
            pipeline,
        })
    }

    /// This frame's caps (empty unless the near plane meets the mesh).
    pub fn prepare(&mut self, camera: &Camera, frame: &FrameSetup, projector: &dyn CellProjector) {
        self.records.clear();
        self.vertices = 0;
        let eye = sub(camera.eye, self.mesh.origin);
        let fwd = camera.forward();
        let fwd = [fwd.x, fwd.y, fwd.z];
        let depth = |p: [f64; 3]| dot(sub(p, eye), fwd);
        // Just behind the near plane (`cap.frag` integrates from the plane itself).
        let cap = camera.near_cap_depth();
        // Quick reject: the eye is outside the points' bounding box.
        let (lo, hi) = self.bounds;
        if (0..3).any(|k| eye[k] < lo[k] || eye[k] > hi[k]) {
            return;
        }
        let points = &self.mesh.points;
        let cut: Vec<usize> = self
            .mesh
            .tets
            .par_iter()
            .enumerate()
            .filter(|(_, tet)| {
                let v = tet.map(|i| points[i as usize]);
                let z = v.map(depth);
                let zmax = z.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                cap < zmax && holds(&v, eye)
            })
            .map(|(t, _)| t)
            .collect();
        let mut codes = Vec::new();
        for t in cut {
            let tet = self.mesh.tets[t];
            let v = tet.map(|i| self.mesh.points[i as usize]);
            let s = tet.map(|i| self.mesh.scalars[i as usize]);
            let polygon = plane_section(&v, &v.map(depth), cap);
            codes.clear();
            projector.cap_pieces(t, frame, &mut |code| codes.push(code));
            cap_records(&v, &s, &polygon, eye, fwd, frame, &codes, &mut self.records);
        }
        self.vertices = self.records.len() / FLOATS_PER_VERTEX;
    }

    /// Copy this frame's caps to the device (counted with the cells' records).
    pub fn upload(&mut self, ctx: &Arc<Context>, counter: &mut UploadCounter) -> VkResult<()> {
        if self.vertices == 0 {
            return Ok(());
        }
        let bytes = (self.records.len() * 4) as u64;
        if self.buffer.as_ref().is_none_or(|b| b.size() < bytes) {
            // Grown to twice what is needed, so an orbit does not reallocate every frame.
            self.buffer = Some(Buffer::new(ctx, BufferDesc::upload("near caps", bytes * 2, BufferUsage::VERTEX))?);
        }
        match self.buffer.as_mut() {
            Some(b) => b.write(0, bytemuck::cast_slice(&self.records), counter, UploadClass::FrameCells),
            None => Ok(()),
        }
    }

    /// Draw the caps after every cell (inside the same rendering).
    pub fn record(
        &self,
        rec: &CommandRecorder,
        tables: &IntegrationTables,
        pieces: Option<&DescriptorSet>,
        frame: &FrameSetup,
        counter: &mut UploadCounter,
    ) -> VkResult<()> {
        let Some(buffer) = self.buffer.as_ref().filter(|_| self.vertices > 0) else { return Ok(()) };
        match pieces {
            Some(set) => rec.bind_graphics(&self.pipeline, &[&tables.set, set])?,
            None => rec.bind_graphics(&self.pipeline, &[&tables.set])?,
        }
        rec.push_constants(&self.pipeline, bytemuck::bytes_of(&frame.constants), counter);
        rec.bind_vertex_buffer(buffer);
        rec.draw(self.vertices as u32);
        Ok(())
    }

    /// Cap vertices this frame.
    pub fn vertices(&self) -> usize {
        self.vertices
    }
}

/// Whether the tet holds point `p` (inside or on its boundary, up to
/// rounding): every barycentric coordinate >= -1e-9. The eye on a shared
/// vertex, edge or face is held by all the tets around it; each ray from
/// it runs into one of them, whose section it crosses.
fn holds(v: &[[f64; 3]; 4], p: [f64; 3]) -> bool {
    let Some((grad, _)) = barycentric(v) else { return false };
    let r = sub(p, v[0]);
    let l: [f64; 3] = std::array::from_fn(|k| dot(grad[k + 1], r));
    let l0 = 1.0 - l[0] - l[1] - l[2];
    l0 >= -1e-9 && l.iter().all(|&x| x >= -1e-9)
}

/// The records of a cap polygon's triangles, once per piece code, each
/// triangle wound as an entry face (its right-handed normal pointing away
/// from the eye, like the cells' faces: the pipeline culls the others).
#[allow(clippy::too_many_arguments)]
fn cap_records(
    v: &[[f64; 3]; 4],
    s: &[f64; 4],
    polygon: &[[f64; 3]],
    eye: [f64; 3],
    fwd: [f64; 3],
    frame: &FrameSetup,
    codes: &[u32],
    out: &mut Vec<f32>,
) {
    let Some((grad, _)) = barycentric(v) else { return };
    if polygon.len() < 3 {
        return;
    }
    let lambda = |p: [f64; 3]| -> [f64; 4] {
        let r = sub(p, v[0]);
        let l1 = dot(grad[1], r);
        let l2 = dot(grad[2], r);
        let l3 = dot(grad[3], r);
        [1.0 - l1 - l2 - l3, l1, l2, l3]
    };
    // The scalar's gradient: sum of s_k grad lambda_k.
    let g: [f64; 3] = std::array::from_fn(|c| (0..4).map(|k| s[k] * grad[k][c]).sum());
    let exact = frame.exact_perspective();
    let max_distance = f64::from(frame.max_distance);
    let ratio_max = f64::from(frame.plane_ratio_max);
    let lambda_eye = lambda(eye);
    let record = |p: [f64; 3], code: u32| -> [f32; FLOATS_PER_VERTEX] {
        let l = lambda(p);
        let sf: f64 = (0..4).map(|k| l[k] * s[k]).sum();
        let rel = sub(p, eye);
        let (mut d, mut sk) = ([0f64; 4], [sf; 4]);
        let gslot;
        if exact {
            // lambda_k u_k with u_k = 1 / lambda_k(eye), clamped as the
            // shaders clamp the plane ratio.
            for k in 0..4 {
                let u = (1.0 / lambda_eye[k]).clamp(-ratio_max, ratio_max);
                d[k] = l[k] * if u.is_finite() { u } else { 0.0 };
            }
            gslot = dot(g, rel);
        } else {
            let dir = if frame.perspective {
                let n = dot(rel, rel).sqrt();
                if n > 0.0 { rel.map(|x| x / n) } else { fwd }
            } else {
                fwd
            };
            let gd = dot(g, dir);
            for k in 0..4 {
                // Vertex k's distance to its opposite plane along `dir`,
                // clamped as the shaders clamp it, times lambda_k.
                let t = (-1.0 / dot(grad[k], dir)).clamp(-max_distance, max_distance);
                d[k] = l[k] * t;
                sk[k] = sf + gd * d[k];
            }
            gslot = sf;
        }
        let mut r = [0f32; FLOATS_PER_VERTEX];
        r[..3].copy_from_slice(&p.map(|x| x as f32));
        r[3] = sf as f32;
        for k in 0..4 {
            r[4 + k] = d[k] as f32;
            r[8 + k] = sk[k] as f32;
            r[12 + k] = l[k] as f32;
        }
        r[16] = gslot as f32;
        r[17] = code as f32;
        r
    };
    for &code in codes {
        for i in 1..polygon.len() - 1 {
            let (a, mut b, mut c) = (polygon[0], polygon[i], polygon[i + 1]);
            if dot(cross(sub(b, a), sub(c, a)), sub(a, eye)) < 0.0 {
                std::mem::swap(&mut b, &mut c);
            }
            for p in [a, b, c] {
                out.extend_from_slice(&record(p, code));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sections_are_polygons_on_the_plane() {
        let v = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let z = v.map(|p| p[2]);
        let tri = plane_section(&v, &z, 0.5);
        assert_eq!(tri.len(), 3);
        assert!(tri.iter().all(|p| (p[2] - 0.5).abs() < 1e-12));
        let z = v.map(|p| p[0] + p[1]);
        let quad = plane_section(&v, &z, 0.5);
        assert_eq!(quad.len(), 4);
        // Consecutive corners share a face of the tet: the quad is not self-crossing.
        let area = |a: [f64; 3], b: [f64; 3], c: [f64; 3]| cross(sub(b, a), sub(c, a));
        let n1 = area(quad[0], quad[1], quad[2]);
        let n2 = area(quad[0], quad[2], quad[3]);
        assert!(dot(n1, n2) > 0.0);
        assert!(plane_section(&v, &z, 5.0).is_empty());
        let (grad, _) = barycentric(&v).unwrap();
        assert_eq!(grad[1], [1.0, 0.0, 0.0]);
    }
}
