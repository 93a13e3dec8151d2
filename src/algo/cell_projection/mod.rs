//! Cell projection of tetrahedral meshes: VICP (Weiler, Kraus, Ertl) and
//! GPU-CPU balanced cell projection (Moreland). Both draw the same sorted cells
//! with the same fragment integration; they differ in what crosses to the
//! device per frame (132 vs 28 floats per tet) and where IntersectBackFace runs.
//!
//! A frame is: sort (shared, `sort`), `pack` (CPU, into host memory),
//! `upload` (host memory -> device-visible buffer, counted), `record_draw`.
//! The frame's setup and the mesh's scale, which every tetrahedral method
//! shares, are `algo::tet_mesh`'s.

pub mod atfs;
pub mod balanced;
pub mod cull;
pub mod device_sort;
pub mod mpvo;
pub mod near;
pub mod pt_compute;
pub mod radix;
pub mod render;
pub mod resident;
pub mod resident_gpusort;
pub mod sort;
pub mod vicp;

use std::sync::Arc;

use crate::algo::host_memory::HostMemory;
use crate::algo::integrate::{IntegrationTables, Integrator};
use crate::algo::tet_mesh::{render_origin, scalar_map, FrameConstants, FrameSetup, Interpolation};
use crate::mesh::{TetGeometry, TetMesh, TetPrecomputed};
use crate::vk::{
    upload_static_streamed, Buffer, DescriptorSetDesc,
    Blend, ColorTarget, CommandRecorder, Context, GraphicsPipelineKey, GraphicsState, Pipeline, PipelineKey, ShaderKey,
    ShaderStage, UploadCounter, VertexAttribute, VkResult,
};
use crate::vk::{BufferUsage, Cull, Topology, Winding};

/// With every tet positively oriented (see `mesh`), the faces as drawn
/// (VICP's face lists, the balanced strip 0,1,2,3,0,1) have right-handed
/// normals pointing into the tet, so faces the eye looks into (entry faces)
/// appear clockwise on screen.
pub const ENTRY_FACE_WINDING: Winding = Winding::Clockwise;

/// The faces of a tet as drawn, in the balanced strip's triangle order, each
/// with its vertices in the order that makes it an entry face when seen from
/// outside: (0,1,2) opposite 3, (1,3,2) opposite 0, (2,3,0) opposite 1,
/// (3,1,0) opposite 2.
pub const FACES: [[usize; 3]; 4] = [[0, 1, 2], [1, 3, 2], [2, 3, 0], [3, 1, 0]];

crate::choices! {
    /// How the balanced family draws each tet's four faces from its static,
    /// device-local index buffer (tet slot k's vertices are 4k..4k+3).
    #[derive(Default)]
    pub enum Primitives {
        /// The four faces (`FACES`) as a triangle list, 12 u32 per tet, no
        /// restart. Same triangles, same image as `strip`; on lavapipe the
        /// frame is ~15 % faster (README: the balanced method at its speed
        /// limit), so the default.
        #[default]
        List = "list",
        /// The thesis's: the strip 0,1,2,3,0,1 closed by a primitive-restart
        /// marker, 7 u32 per tet.
        Strip = "strip",
    }
}

/// The strip's 6 indices of tet slot 0 (plus the restart marker).
pub const STRIP: [u32; 6] = [0, 1, 2, 3, 0, 1];
pub const RESTART: u32 = u32::MAX;
/// The most indices a tet takes (`Primitives::List`).
pub const MAX_INDICES_PER_CELL: usize = 12;

impl Primitives {
    pub fn indices_per_cell(self) -> usize {
        match self {
            Primitives::Strip => STRIP.len() + 1,
            Primitives::List => MAX_INDICES_PER_CELL,
        }
    }

    pub fn topology(self) -> Topology {
        match self {
            Primitives::Strip => Topology::TriangleStrip,
            Primitives::List => Topology::TriangleList,
        }
    }

    pub fn primitive_restart(self) -> bool {
        self == Primitives::Strip
    }

    /// The static index data for `cells` tet slots.
    pub fn indices(self, cells: usize) -> Vec<u32> {
        let mut idx = vec![0; cells * self.indices_per_cell()];
        self.write_indices(0, &mut idx);
        idx
    }

    /// The indices of tet slots `first ..` into `out` (a whole number of
    /// slots).
    pub fn write_indices(self, first: usize, out: &mut [u32]) {
        for (slot, dst) in out.chunks_exact_mut(self.indices_per_cell()).enumerate() {
            let k = (first + slot) as u32;
            match self {
                Primitives::Strip => {
                    for (d, &i) in dst.iter_mut().zip(&STRIP) {
                        *d = 4 * k + i;
                    }
                    dst[STRIP.len()] = RESTART;
                }
                Primitives::List => {
                    for (d, &i) in dst.iter_mut().zip(FACES.iter().flatten()) {
                        *d = 4 * k + i as u32;
                    }
                }
            }
        }
    }
}

/// A balanced-family projector's static index buffer: every tet slot's four
/// faces as `Primitives` lays them out, uploaded once into device-local
/// memory (counted as static bytes).
pub struct StaticIndices {
    buffer: Buffer,
    per_cell: usize,
}

impl StaticIndices {
    /// Made chunk by chunk while streaming to the device (never held whole
    /// on the host).
    pub fn upload(ctx: &Arc<Context>, name: &str, primitives: Primitives, cells: usize, counter: &mut UploadCounter) -> VkResult<Self> {
        let slot_bytes = primitives.indices_per_cell() * 4;
        let size = (cells * slot_bytes) as u64;
        let buffer = upload_static_streamed(ctx, name, size, slot_bytes as u64, BufferUsage::INDEX, counter, |offset, chunk| {
            primitives.write_indices(offset as usize / slot_bytes, bytemuck::cast_slice_mut(chunk));
        })?;
        Ok(StaticIndices { buffer, per_cell: primitives.indices_per_cell() })
    }

    /// Bind the buffer and draw its first `cells` tet slots (inside dynamic
    /// rendering, after the pipeline and its inputs are bound).
    pub fn draw(&self, rec: &CommandRecorder, cells: usize) {
        rec.bind_index_buffer_u32(&self.buffer);
        rec.draw_indexed((cells * self.per_cell) as u32);
    }
}

/// The build-time drawing choices a projector is made with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DrawSettings {
    pub interpolation: Interpolation,
    pub integrator: Integrator,
    /// The balanced family's index layout (VICP draws its own face lists).
    pub primitives: Primitives,
}

impl DrawSettings {
    /// The defines of the family's build-time options, for every shader
    /// that integrates (`primitives` changes pipeline state only); the one
    /// place they are derived (`render::Settings::draw` makes it).
    pub fn defines(&self) -> Vec<(&'static str, &'static str)> {
        self.exit_defines().into_iter().chain(self.integrator.define()).collect()
    }

    /// The defines of a shader that writes exit data but integrates
    /// nothing (resident's expansion pass): the interpolation's.
    pub fn exit_defines(&self) -> Vec<(&'static str, &'static str)> {
        self.interpolation.defines().to_vec()
    }
}

/// One cell-projection method's per-frame work on the device side.
pub trait CellProjector {
    fn cells(&self) -> usize;
    /// Vertex records and floats each tet sends per frame, by construction.
    fn vertices_per_cell(&self) -> usize;
    fn floats_per_cell(&self) -> usize;
    /// Cells drawn per frame when a cell is drawn more than once (atfs:
    /// once per transfer-function interval); `floats_per_cell` is then per
    /// drawn piece. `None`: each cell once.
    fn pieces(&self) -> Option<usize> {
        None
    }
    /// Pieces the last `pack` wrote (`cull` may leave cells out); `pieces()`
    /// when nothing was left out.
    fn pieces_drawn(&self) -> usize {
        self.pieces().unwrap_or_else(|| self.drawn())
    }
    /// The codes of the pieces a cell's near cap is drawn with, back to
    /// front (`near`, `cap.vert`): one, 0, unless cells are drawn in pieces.
    fn cap_pieces(&self, _cell: usize, _frame: &FrameSetup, emit: &mut dyn FnMut(u32)) {
        emit(0);
    }
    /// The set the piece codes index (atfs's intervals), bound at set 1.
    fn pieces_set(&self) -> Option<&crate::vk::DescriptorSet> {
        None
    }
    /// The key of the pipeline it draws with (recorded in results).
    fn pipeline_key(&self) -> &PipelineKey;
    /// How its per-cell device data is split at the device's limits
    /// (`algo::chunks`; `details.device_chunks`), if it splits any.
    fn device_chunks(&self) -> serde_json::Value {
        serde_json::Value::Null
    }
    /// Count the host memory it keeps between frames, by structure
    /// (`details.host_memory`).
    fn host_bytes(&self, memory: &mut HostMemory);
    /// Cells the last `pack` wrote, i.e. the next draw draws (`cull` may
    /// leave cells out of `order`). A projector that ignores the order
    /// draws every cell.
    fn drawn(&self) -> usize {
        self.cells()
    }
    /// Write this frame's vertex data in `order` into host memory: a
    /// visibility order of every cell, or of the cells `cull` kept (then
    /// shorter than `cells()`; only those are uploaded and drawn).
    fn pack(&mut self, order: &[u32], frame: &FrameSetup);
    /// Copy the packed data to where the device reads it (counted).
    fn upload(&mut self, counter: &mut UploadCounter) -> VkResult<()>;
    /// Bind and draw (inside dynamic rendering). A projector that records
    /// its own passes (`record_composite` returns true) is never asked.
    fn record_draw(&self, _rec: &CommandRecorder, _tables: &IntegrationTables, _frame: &FrameSetup, _counter: &mut UploadCounter) -> VkResult<()> {
        Err(crate::vk::VkError::Invalid("this projector records its own passes (record_composite); it has no draw of its own".into()))
    }
    /// True when the projector orders the cells itself on the device: the
    /// CPU sort is skipped and `pack` gets an empty order.
    fn sorts_on_device(&self) -> bool {
        false
    }
    /// Device work before the draw, outside the rendering pass (a sort).
    fn record_before_draw(&self, _rec: &CommandRecorder, _frame: &FrameSetup, _counter: &mut UploadCounter) -> VkResult<()> {
        Ok(())
    }
    /// GPU times of the projector's own passes in the frame just waited
    /// for, as (phase, ms).
    fn device_phases(&self) -> VkResult<Vec<(&'static str, f64)>> {
        Ok(Vec::new())
    }
    /// CPU times of the parts of the last `pack` worth their own phase
    /// (pt-compute's binning), as (phase, ms).
    fn pack_phases(&self) -> Vec<(&'static str, f64)> {
        Vec::new()
    }
    /// Record the cells' passes into `target` itself: composite them in
    /// compute (pt-compute), or draw them in rendering passes of its own
    /// between device work (resident's batches); every pixel written, the
    /// first pass clearing, and the near caps are drawn over it after.
    /// `false`: the projector draws (`record_draw`).
    fn record_composite(
        &mut self,
        _rec: &CommandRecorder,
        _target: &crate::vk::Image,
        _tables: &IntegrationTables,
        _frame: &FrameSetup,
        _counter: &mut UploadCounter,
    ) -> VkResult<bool> {
        Ok(false)
    }
    /// The projector's own work counts of the last frame (results' `work`).
    fn work_counts(&self) -> Vec<(&'static str, u64)> {
        Vec::new()
    }
}

/// Test-only switch (docs/tracking.md): `VOLBENCH_TEST_EXTRA_FRAGMENT_WORK=N`
/// adds a loop of N dependent multiply-adds (a cost linear in N) to every
/// fragment of shaders/cell_projection/balanced.frag (balanced, its strip
/// variant, resident and resident-gpusort), the deliberate slowdown the
/// counted compare must catch. Unset in real runs; when set, every run says
/// so on stderr and a counted run records it in `count.pinned`.
pub const EXTRA_WORK_VAR: &str = crate::switches::TEST_EXTRA_FRAGMENT_WORK;

fn extra_fragment_work() -> VkResult<Option<String>> {
    static WARNED: std::sync::Once = std::sync::Once::new();
    Ok(crate::switches::int(EXTRA_WORK_VAR)?.map(|n| {
        WARNED.call_once(|| eprintln!("volbench: {EXTRA_WORK_VAR}={n} is set: balanced.frag carries a deliberate test-only slowdown"));
        n.to_string()
    }))
}

/// The pipeline every cell-projection method uses: premultiplied "over"
/// into RGBA32F, entry faces only, the integration tables bound at set 0
/// and `extra_sets` at sets 1, 2, ...
#[allow(clippy::too_many_arguments)] // one pipeline description; a struct for it is issue 23 item 1
pub(crate) fn build_pipeline(
    ctx: &Arc<Context>,
    vertex_path: &str,
    fragment_path: &str,
    stride: u32,
    attributes: &[VertexAttribute],
    topology: Topology,
    primitive_restart: bool,
    tables: &IntegrationTables,
    draw: &DrawSettings,
    extra_sets: &[DescriptorSetDesc],
    // More shader defines (e.g. the chunking of the stored cells, `algo::chunks`).
    more_defines: &[(&str, &str)],
) -> VkResult<(Arc<Pipeline>, PipelineKey)> {
    let mut defines = draw.defines();
    defines.extend_from_slice(more_defines);
    let extra = extra_fragment_work()?;
    if let Some(n) = &extra {
        defines.push(("EXTRA_WORK", n));
    }
    let key = PipelineKey::Graphics(GraphicsPipelineKey {
        vertex: ShaderKey::new(vertex_path, ShaderStage::Vertex, &defines),
        geometry: None,
        fragment: ShaderKey::new(fragment_path, ShaderStage::Fragment, &defines),
        state: GraphicsState {
            vertex_stride: stride,
            attributes: attributes.to_vec(),
            topology,
            primitive_restart,
            cull: Cull::Back,
            front_face: ENTRY_FACE_WINDING,
            targets: vec![ColorTarget::rgba32f(Blend::PremultipliedOver)],
            depth_test: false,
            // Faces are not clipped at the near and far planes: a cell cut
            // by the near plane keeps every entry-face fragment, and each
            // integrates from the near plane where its point lies in front
            // of it (common/clip.glsl `start_at_near`). The one clip plane
            // is the vertex stage's, just in front of the eye
            // (common/clip.glsl `eye_plane_distance`).
            depth_clamp: true,
        },
        push_constant_bytes: std::mem::size_of::<FrameConstants>() as u32,
        sets: std::iter::once(tables.set.desc.clone()).chain(extra_sets.iter().cloned()).collect(),
    });
    Ok((crate::algo::pipelines::get(ctx, &key)?, key))
}

/// Per-tet f32 data both methods derive from the mesh once: positions,
/// scalars, the 3-float opposite-face planes n' and the gradient. Degenerate
/// (zero-volume) tets are collapsed onto their first vertex with zero planes
/// and gradient, so they draw nothing but still send their full records.
#[derive(Debug, Clone, Copy, Default)]
pub struct CellF32 {
    pub pos: [[f32; 3]; 4],
    pub scalar: [f32; 4],
    pub plane3: [[f32; 3]; 4],
    pub gradient: [f32; 3],
}

impl CellF32 {
    /// A cell from its vertices and scalars and its planes and gradient;
    /// `None` (degenerate): collapsed onto its first vertex, zero planes
    /// and gradient.
    #[inline]
    pub fn assemble(pos: [[f32; 3]; 4], scalar: [f32; 4], planes: Option<&CellPlanes>) -> Self {
        match planes {
            Some(g) => CellF32 { pos, scalar, plane3: g.plane3, gradient: g.gradient },
            None => CellF32 { pos: [pos[0]; 4], scalar, plane3: [[0.0; 3]; 4], gradient: [0.0; 3] },
        }
    }
}

/// Positions are relative to `render_origin(mesh)` and scalars mapped by
/// `scalar_map(mesh)` (gradients scaled alike), both in f64 before the
/// conversion (far from the origin the f32 values would otherwise have lost
/// the mesh). Planes do not depend on either; the vertex-to-face distances
/// that scale them come from edge vectors, which are small wherever the
/// mesh is.
///
/// Each cell's f64 gradient and planes (`TetPrecomputed`) are computed
/// when the cell is made, and not kept: the f32 cell is all a method needs.
/// Methods that keep no f32 cells on the host (resident) make them chunk by
/// chunk while streaming them to the device.
#[derive(Debug, Clone, Copy)]
pub struct CellMaker {
    origin: [f64; 3],
    scalar_origin: f64,
    scalar_scale: f64,
}

impl CellMaker {
    pub fn new(mesh: &TetMesh) -> Self {
        let (scalar_origin, scalar_scale) = scalar_map(mesh);
        CellMaker { origin: render_origin(mesh), scalar_origin, scalar_scale }
    }

    /// The f32 cell of tet `t` of `mesh`.
    pub fn cell(&self, mesh: &TetMesh, t: usize) -> CellF32 {
        let (o, so, ss) = (self.origin, self.scalar_origin, self.scalar_scale);
        let rel = move |v: [f64; 3]| -> [f32; 3] { std::array::from_fn(|k| (v[k] - o[k]) as f32) };
        let (p, s64) = mesh.cell(mesh.tets[t]);
        CellF32::assemble(p.map(rel), s64.map(|v| ((v - so) / ss) as f32), self.planes(mesh, t).as_ref())
    }

    /// The view-independent f32 data of tet `t` beside its vertices: the
    /// planes and the (mapped) gradient; `None` for a degenerate tet (zero
    /// planes and gradient, collapsed onto its first vertex: `CellF32`).
    pub fn planes(&self, mesh: &TetMesh, t: usize) -> Option<CellPlanes> {
        let (p, s64) = mesh.cell(mesh.tets[t]);
        let g = &TetPrecomputed::from_vertices(p, s64);
        if g.degenerate {
            return None;
        }
        let mut plane3 = [[0f32; 3]; 4];
        for i in 0..4 {
            // Vertex i's distance to its opposite face from an edge
            // vector (n·(p_i - p_j), p_j on that face), not n·p_i + a:
            // far from the origin those two terms are as large as the
            // coordinates and cancel (at 1e14 an error of ~0.02 units).
            let [nx, ny, nz, _] = g.planes[i];
            let e = crate::mesh::geometry::sub(p[i], p[(i + 1) % 4]);
            let dist = nx * e[0] + ny * e[1] + nz * e[2];
            plane3[i] = if dist != 0.0 {
                [(nx / dist) as f32, (ny / dist) as f32, (nz / dist) as f32]
            } else {
                [0.0; 3]
            };
        }
        Some(CellPlanes { plane3, gradient: g.gradient.map(|x| (x / self.scalar_scale) as f32) })
    }
}

/// A cell's f32 planes and gradient (`CellF32` without its vertices): 60
/// bytes per tet, where the whole cell is 124. A method that keeps these
/// gathers the vertices from the shared relative mesh (`PlanesTable`).
#[derive(Debug, Clone, Copy, Default)]
pub struct CellPlanes {
    pub plane3: [[f32; 3]; 4],
    pub gradient: [f32; 3],
}

/// Every cell's planes and gradient with a bit per degenerate cell; with
/// the relative mesh (the same origin and scalar map as `CellMaker`) it
/// gives back each `CellF32` bit for bit: the relative f64 points and mapped
/// scalars are the numbers `CellMaker` converts.
#[derive(Debug)]
pub struct PlanesTable {
    planes: Vec<CellPlanes>,
    degenerate: Vec<u64>,
    relative: Arc<RelativeMesh>,
}

impl PlanesTable {
    /// `relative` must be `mesh`'s at `render_origin(mesh)` (checked).
    pub fn new(mesh: &TetMesh, relative: Arc<RelativeMesh>) -> VkResult<Self> {
        use rayon::prelude::*;
        if relative.origin != render_origin(mesh) || relative.tets.len() != mesh.tets.len() {
            return Err(crate::vk::VkError::Invalid(format!("mesh '{}': the relative mesh is not this mesh's", mesh.name)));
        }
        let maker = CellMaker::new(mesh);
        // Filled in place, 64 cells (one word of bits) at a time: no
        // intermediate vector of `Option`s.
        let mut planes = vec![CellPlanes::default(); mesh.tets.len()];
        let degenerate = planes
            .par_chunks_mut(64)
            .enumerate()
            .map(|(w, chunk)| {
                let mut bits = 0u64;
                for (i, p) in chunk.iter_mut().enumerate() {
                    match maker.planes(mesh, w * 64 + i) {
                        Some(made) => *p = made,
                        None => bits |= 1 << i,
                    }
                }
                bits
            })
            .collect();
        Ok(PlanesTable { planes, degenerate, relative })
    }

    pub fn len(&self) -> usize {
        self.planes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.planes.is_empty()
    }

    /// `CellMaker::cell` of tet `t`, from the kept data.
    #[inline]
    pub fn cell(&self, t: usize) -> CellF32 {
        let r = &*self.relative;
        let tet = r.tets[t];
        let pos = |v: u32| r.points[v as usize].map(|x| x as f32);
        let scalar = tet.map(|v| r.scalars[v as usize] as f32);
        let degenerate = self.degenerate[t / 64] >> (t % 64) & 1 == 1;
        CellF32::assemble(tet.map(pos), scalar, (!degenerate).then_some(&self.planes[t]))
    }

    /// Its own structures (the relative mesh is counted by its owner).
    pub fn host_bytes(&self, memory: &mut HostMemory) {
        memory.vec("projector: f32 planes and gradient (CellPlanes)", &self.planes);
        memory.vec("projector: degenerate-cell bits", &self.degenerate);
    }
}

/// The mesh as the per-frame CPU passes (culling, near caps) read it:
/// points relative to an origin (`render_origin`) and scalars mapped by
/// `scalar_map`, in f64 (the numbers the f32 data is converted from), and
/// the cells. One copy, shared by the passes of a method.
#[derive(Debug)]
pub struct RelativeMesh {
    pub origin: [f64; 3],
    pub points: Vec<[f64; 3]>,
    pub scalars: Vec<f64>,
    pub tets: Vec<[u32; 4]>,
}

impl RelativeMesh {
    pub fn new(mesh: &TetMesh, origin: [f64; 3]) -> Arc<Self> {
        let (so, ss) = scalar_map(mesh);
        Arc::new(RelativeMesh {
            origin,
            points: mesh.points.iter().map(|p| std::array::from_fn(|k| p[k] - origin[k])).collect(),
            scalars: mesh.scalars.iter().map(|s| (s - so) / ss).collect(),
            tets: mesh.tets.clone(),
        })
    }

    pub fn host_bytes(&self, memory: &mut HostMemory) {
        memory.vec("cull and near caps: relative points (f64)", &self.points);
        memory.vec("cull and near caps: mapped scalars (f64)", &self.scalars);
        memory.vec("cull and near caps: copy of the tets", &self.tets);
    }
}

/// Every cell of `mesh` as [`CellMaker`] makes it, in parallel.
pub fn cells_f32(mesh: &TetMesh) -> Vec<CellF32> {
    use rayon::prelude::*;
    let maker = CellMaker::new(mesh);
    (0..mesh.tets.len()).into_par_iter().map(|t| maker.cell(mesh, t)).collect()
}

pub fn centroids_f32(geometry: &TetGeometry) -> Vec<[f32; 3]> {
    geometry.centroids.iter().map(|c| c.map(|x| x as f32)).collect()
}

/// Centroids relative to `origin` (e.g. `MeshScale::origin`), subtracted in
/// f64: what the depth sort needs far from the world origin, where world
/// f32 centroids 1e7 away are 1 unit apart and the order is lost.
pub fn centroids_relative_f32(mesh: &TetMesh, origin: [f64; 3]) -> Vec<[f32; 3]> {
    use rayon::prelude::*;
    mesh.tets
        .par_iter()
        .map(|&t| {
            let c = mesh.centroid(t);
            std::array::from_fn(|k| (c[k] - origin[k]) as f32)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `PlanesTable` gathers each cell back exactly as `CellMaker` makes it
    /// (balanced's records depend on it), degenerate cells included, far
    /// from the origin (a relative origin) and near it.
    #[test]
    fn planes_table_gives_back_the_cells_bit_for_bit() {
        for offset in [0.0, 1e6] {
            let corners = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.3, 0.4, 0.0]];
            let mesh = TetMesh {
                name: "two".into(),
                points: corners.iter().map(|p: &[f64; 3]| p.map(|x| x + offset)).collect(),
                scalars: vec![0.0, 1.0, 2.5, 3.0, 7.0],
                // The second is flat: its fourth vertex lies on the first three's plane.
                tets: vec![[0, 1, 2, 3], [0, 1, 2, 4]],
                stats: Default::default(),
            };
            let maker = CellMaker::new(&mesh);
            assert!(maker.planes(&mesh, 0).is_some() && maker.planes(&mesh, 1).is_none());
            let table = PlanesTable::new(&mesh, RelativeMesh::new(&mesh, render_origin(&mesh))).unwrap();
            for t in 0..2 {
                // Debug prints an f32 by its shortest round-trip form: equal strings, equal bits.
                assert_eq!(format!("{:?}", table.cell(t)), format!("{:?}", maker.cell(&mesh, t)), "cell {t} at offset {offset}");
            }
            let other = RelativeMesh::new(&mesh, [offset + 1.0, 0.0, 0.0]);
            assert!(PlanesTable::new(&mesh, other).is_err(), "another origin's relative mesh is refused");
        }
    }
}
