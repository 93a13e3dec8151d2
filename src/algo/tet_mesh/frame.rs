//! The frame as every tetrahedral method sets it up: where its f32 data is
//! relative to (`render_origin`, `scalar_map`, [`MeshScale`]), the exit
//! data's interpolation and tolerances, and [`FrameSetup`], the camera made
//! into the push constants the shaders share (`shaders/common/frame.glsl`)
//! and the CPU's copy of the same rules.

use serde::Serialize;

use crate::algo::integrate::{IntegrationTables, TableMap};
use glam::Vec3;
use crate::mesh::TetMesh;
use crate::scene::Camera;

crate::choices! {
    /// How view-dependent exit data is carried across a face under perspective.
    #[derive(Default)]
    pub enum Interpolation {
        /// The same records as `paper` with the plane ratio u = h/e and
        /// g.(v - eye) in the two view-dependent slots, which interpolate
        /// exactly under perspective (`shaders/common/exit.glsl`). Identical
        /// to `paper` for orthographic views. The default: same records and
        /// bytes, within the error bar.
        #[default]
        Exact = "exact",
        /// As the papers do: ray-plane distance and exit scalar at each vertex,
        /// interpolated across the face (exact for orthographic views only).
        Paper = "paper",
    }
}

impl Interpolation {
    pub(crate) fn defines(self) -> &'static [(&'static str, &'static str)] {
        match self {
            Interpolation::Paper => &[],
            Interpolation::Exact => &[("EXACT_PERSPECTIVE", "1")],
        }
    }
}

/// Run-time tolerances of the exit-plane choice (push constants), named and
/// recorded with results. Why each exists is explained in
/// `shaders/common/frame.glsl` and `shaders/common/exit.glsl`; the defaults
/// come from the sweep in the README (error against the f64 reference).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ExitTolerances {
    /// |ray-plane distance| at a vertex is clamped to this many mesh diagonals
    /// (`paper` interpolation).
    pub distance_clamp_diagonals: f64,
    /// |u| = |h/e| is clamped to this (`exact` interpolation).
    pub plane_ratio_max: f32,
    /// A plane whose interpolated barycentric weight is below this counts as
    /// passing through the fragment (exit at distance 0). Off by default: it
    /// removes rare specks but drops whole segments of rays grazing a face.
    pub edge_eps: f32,
}

/// Sizes of a mesh that bound what any ray segment through one of its cells
/// can be, and the origins its f32 data is expressed relative to.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MeshScale {
    pub diagonal: f64,
    /// The longest edge of any cell: no segment through a cell is longer.
    pub max_cell_extent: f64,
    /// `render_origin(mesh)`: positions sent to the device are relative to it.
    pub origin: [f64; 3],
    /// `scalar_map(mesh)`: scalars are sent as (s - origin) / scale.
    pub scalar_origin: f64,
    pub scalar_scale: f64,
}

/// The point every f32 position is relative to (stress cases
/// "translate-1e3/1e5/1e7"). f32 keeps 24 bits: a mesh of size 1 placed 1e5
/// from the world origin keeps 7 of them for its own extent (0.18 max
/// error), at 1e7 none (the mesh collapses). Positions are therefore sent
/// relative to the mesh's bounding-box centre, the subtraction done in f64
/// before the f32 conversion, and the eye and the view-projection matrix
/// are moved by the same f64 offset (`FrameSetup::new`). Meshes within one
/// diagonal of the world origin keep origin 0 (nothing to gain; their data
/// stays bit-identical to world coordinates, which `FrameSetup::for_camera`
/// assumes). The origin is per mesh, not per frame, so VICP's records stay
/// view-independent and both methods see the same numbers.
pub fn render_origin(mesh: &TetMesh) -> [f64; 3] {
    let b = mesh.bounds();
    let c = b.center();
    let dist = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
    if dist > b.diagonal() {
        c
    } else {
        [0.0; 3]
    }
}

/// How scalars are sent to the device: as (s - origin) / scale with the
/// mesh's scalar range [origin, origin + scale], mapped in f64 before the
/// f32 conversion, gradients divided by the same scale and the transfer
/// function's range mapped alike (`FrameSetup::new`). Only the transfer
/// function reads scalars, through this same affine map, so nothing changes
/// but the f32 rounding, which is now relative to the range: scalars in
/// 1e6 + [0, 1] were 0.0625 apart in f32 (stress case "scalars-offset-1e6",
/// max error 0.33), and scalars and g.(v - eye) near 1e37 left no headroom
/// below f32's maximum for the interpolation ("scalars-1e37", max error
/// 5e-2). Scale 1 for a constant field.
pub fn scalar_map(mesh: &TetMesh) -> (f64, f64) {
    let (lo, hi) = mesh.scalar_range();
    let w = hi - lo;
    (lo, if w > 0.0 && w.is_finite() { w } else { 1.0 })
}

impl MeshScale {
    pub fn of(mesh: &TetMesh) -> Self {
        use rayon::prelude::*;
        let max_edge = mesh
            .tets
            .par_iter()
            .map(|t| {
                let p = t.map(|i| mesh.points[i as usize]);
                let mut m = 0f64;
                for a in 0..4 {
                    for b in a + 1..4 {
                        let d = [p[a][0] - p[b][0], p[a][1] - p[b][1], p[a][2] - p[b][2]];
                        m = m.max(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                    }
                }
                m
            })
            .reduce(|| 0.0, f64::max)
            .sqrt();
        MeshScale {
            diagonal: mesh.bounds().diagonal(),
            max_cell_extent: max_edge,
            origin: render_origin(mesh),
            scalar_origin: scalar_map(mesh).0,
            scalar_scale: scalar_map(mesh).1,
        }
    }
}

impl Default for ExitTolerances {
    fn default() -> Self {
        ExitTolerances { distance_clamp_diagonals: 1e3, plane_ratio_max: 1e3, edge_eps: 0.0 }
    }
}

/// Push constants shared by every cell-projection shader
/// (`shaders/common/frame.glsl`, `Frame`; `tests/shader_interfaces.rs`
/// checks the two agree).
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FrameConstants {
    /// World (relative to the render origin) -> Vulkan clip space.
    pub view_proj: [[f32; 4]; 4],
    /// The eye, relative to the render origin.
    pub eye: Vec3,
    /// 1 perspective, 0 orthographic.
    pub perspective: f32,
    /// Unit viewing direction (orthographic rays).
    pub view_dir: Vec3,
    /// The longest cell edge (+1% for f32 rounding): no segment through a
    /// cell is longer (`shaders/common/exit.glsl`).
    pub max_segment: f32,
    pub table: TableMap,
    /// Clamp of vertex ray-plane distances (`ExitTolerances`).
    pub distance_clamp: f32,
    /// Clamp of |u| (`ExitTolerances`).
    pub plane_ratio_max: f32,
    /// Edge epsilon (`ExitTolerances`).
    pub edge_eps: f32,
}

/// What every method needs to know about the frame being drawn.
#[derive(Debug, Clone, Copy)]
pub struct FrameSetup {
    pub constants: FrameConstants,
    /// The eye relative to `origin` (what the f32 positions are relative to).
    pub eye: [f32; 3],
    /// `render_origin` of the mesh (0 from `for_camera`).
    pub origin: [f64; 3],
    pub view_dir: [f32; 3],
    pub perspective: bool,
    /// Bound on |ray-plane distance| (see `ExitTolerances`).
    pub max_distance: f32,
    /// Bound on |u| (see `ExitTolerances`).
    pub plane_ratio_max: f32,
    pub interpolation: Interpolation,
    /// The image's size in pixels (pt-compute bins cells into its tiles);
    /// zero from `for_camera`.
    pub size: [u32; 2],
}

impl FrameSetup {
    pub fn new(
        camera: &Camera,
        width: u32,
        height: u32,
        tables: &IntegrationTables,
        scale: &MeshScale,
        interpolation: Interpolation,
        tolerances: &ExitTolerances,
    ) -> Self {
        let mut setup = Self::for_camera(camera, scale.diagonal, interpolation, tolerances);
        // Positions are relative to the mesh's render origin (see
        // `render_origin`): move the eye and the matrix by it in f64, then
        // convert. (Translating in f32 would cancel 1e7-sized terms.)
        let o = scale.origin;
        setup.origin = o;
        setup.eye = std::array::from_fn(|k| (camera.eye[k] - o[k]) as f32);
        let vp = camera.view_proj_relative(o, width, height).to_cols_array_2d();
        setup.size = [width, height];
        setup.constants = FrameConstants {
            view_proj: vp.map(|c| c.map(|x| x as f32)),
            eye: setup.eye.into(),
            perspective: if setup.perspective { 1.0 } else { 0.0 },
            view_dir: setup.view_dir.into(),
            // No segment through a cell is longer than its longest edge (1%
            // margin for f32 rounding); see shaders/common/exit.glsl.
            max_segment: (1.01 * scale.max_cell_extent) as f32,
            // Scalars arrive mapped by `scalar_map`: the table's range alike.
            table: tables.map(scale.scalar_origin, scale.scalar_scale),
            distance_clamp: setup.max_distance,
            plane_ratio_max: setup.plane_ratio_max,
            edge_eps: tolerances.edge_eps,
        };
        setup
    }

    /// The CPU side only (what the balanced method's packing reads); the
    /// shader constants are left zero. World coordinates: right for meshes
    /// whose `render_origin` is 0 (within a diagonal of the world origin);
    /// `new` handles any mesh.
    pub fn for_camera(
        camera: &Camera,
        mesh_diagonal: f64,
        interpolation: Interpolation,
        tolerances: &ExitTolerances,
    ) -> Self {
        let f = camera.forward();
        FrameSetup {
            constants: bytemuck::Zeroable::zeroed(),
            eye: camera.eye.map(|v| v as f32),
            origin: [0.0; 3],
            view_dir: [f.x as f32, f.y as f32, f.z as f32],
            perspective: camera.is_perspective(),
            max_distance: (tolerances.distance_clamp_diagonals * mesh_diagonal).max(1e-30) as f32,
            plane_ratio_max: tolerances.plane_ratio_max,
            interpolation,
            size: [0, 0],
        }
    }

    /// Unit ray direction through world point `p` (same rule as the shaders).
    #[inline]
    pub fn ray_direction(&self, p: [f32; 3]) -> [f32; 3] {
        if self.perspective {
            let d = [p[0] - self.eye[0], p[1] - self.eye[1], p[2] - self.eye[2]];
            let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            if len > 0.0 {
                [d[0] / len, d[1] / len, d[2] / len]
            } else {
                self.view_dir
            }
        } else {
            self.view_dir
        }
    }

    /// IntersectBackFace with the 3-float plane (same rule as the shaders).
    #[inline]
    pub fn distance_to_opposite_plane(&self, plane3: [f32; 3], dir: [f32; 3]) -> f32 {
        let nd = plane3[0] * dir[0] + plane3[1] * dir[1] + plane3[2] * dir[2];
        (-1.0 / nd).clamp(-self.max_distance, self.max_distance)
    }

    /// Exact perspective: the plane ratio u = h/e (same rule as
    /// `perspective_plane_ratio` in the shaders) for vertex offset `rel` = v - eye.
    #[inline]
    pub fn perspective_plane_ratio(&self, plane3: [f32; 3], rel: [f32; 3]) -> f32 {
        let nr = plane3[0] * rel[0] + plane3[1] * rel[1] + plane3[2] * rel[2];
        (1.0 / (1.0 - nr)).clamp(-self.plane_ratio_max, self.plane_ratio_max)
    }

    /// Whether vertex records carry the exact-perspective quantities.
    pub fn exact_perspective(&self) -> bool {
        self.perspective && self.interpolation == Interpolation::Exact
    }
}
